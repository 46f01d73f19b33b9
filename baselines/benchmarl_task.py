"""Deprecated: ``baselines.benchmarl_task`` moved to :mod:`baselines.marl.benchmarl_task` (issue 61);
this path is removed in KoopNav 0.2.0. Every name is read from the new module."""

from baselines import _moved_module

__getattr__, __dir__ = _moved_module("baselines.benchmarl_task", "baselines.marl.benchmarl_task")
