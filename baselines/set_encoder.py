"""Deprecated: ``baselines.set_encoder`` moved to :mod:`baselines.sb3.set_encoder` (issue 61); this
path is removed in KoopNav 0.2.0. Every name is read from the new module."""

from baselines import _moved_module

__getattr__, __dir__ = _moved_module("baselines.set_encoder", "baselines.sb3.set_encoder")
