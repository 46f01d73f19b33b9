"""Deprecated: ``koopman_envs.keywords`` moved to ``koopman_envs.builder.keywords``; this path is removed in
KoopNav 0.2.0. Every name is read from where it lives now."""

from koopman_envs.deprecated import moved_module

__getattr__, __dir__ = moved_module("koopman_envs.keywords", ("koopman_envs.builder.keywords",))
