"""Deprecated: ``baselines.select`` moved to :mod:`baselines.sb3.select` (issue 61); this path is
removed in KoopNav 0.2.0. Every name is read from the new module. ``python -m baselines.select``
runs ``python -m baselines.sb3.select`` (with a warning)."""

from baselines import _moved_module, _run_moved_command

__getattr__, __dir__ = _moved_module("baselines.select", "baselines.sb3.select")

if __name__ == "__main__":
    _run_moved_command("baselines.select", "baselines.sb3.select")
