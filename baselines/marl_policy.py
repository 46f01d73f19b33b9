"""Deprecated: ``baselines.marl_policy`` moved to :mod:`baselines.marl.marl_policy` (issue 61); this
path is removed in KoopNav 0.2.0. Every name is read from the new module."""

from baselines import _moved_module

__getattr__, __dir__ = _moved_module("baselines.marl_policy", "baselines.marl.marl_policy")
