"""Deprecated: ``baselines.train`` moved to :mod:`baselines.sb3.train` (issue 61); this path is
removed in KoopNav 0.2.0. Every name is read from the new module. ``python -m baselines.train``
runs ``python -m baselines.sb3.train`` (with a warning)."""

from baselines import _moved_module, _run_moved_command

__getattr__, __dir__ = _moved_module("baselines.train", "baselines.sb3.train")

if __name__ == "__main__":
    _run_moved_command("baselines.train", "baselines.sb3.train")
