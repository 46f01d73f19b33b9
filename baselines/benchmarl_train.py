"""Deprecated: ``baselines.benchmarl_train`` moved to :mod:`baselines.marl.benchmarl_train` (issue
61); this path is removed in KoopNav 0.2.0. Every name is read from the new module. ``python -m
baselines.benchmarl_train`` runs ``python -m baselines.marl.benchmarl_train`` (with a warning)."""

from baselines import _moved_module, _run_moved_command

__getattr__, __dir__ = _moved_module("baselines.benchmarl_train", "baselines.marl.benchmarl_train")

if __name__ == "__main__":
    _run_moved_command("baselines.benchmarl_train", "baselines.marl.benchmarl_train")
