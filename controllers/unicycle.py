"""Deprecated: ``controllers.unicycle`` moved to ``controllers.mpc.models``; this path is removed in
KoopNav 0.2.0. Every name is read from where it lives now."""

from controllers.deprecated_paths import moved_module

__getattr__, __dir__ = moved_module(__name__, ("controllers.mpc.models",))
