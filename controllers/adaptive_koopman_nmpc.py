"""Deprecated: ``controllers.adaptive_koopman_nmpc`` moved to ``controllers.mpc.variants``; this path is removed in
KoopNav 0.2.0. Every name is read from where it lives now."""

from controllers.deprecated_paths import moved_module

__getattr__, __dir__ = moved_module(__name__, ("controllers.mpc.variants",))
