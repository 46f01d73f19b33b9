"""Deprecated: ``koopman_envs.episode_layout`` moved to ``koopman_envs.builder.episode_layout``; this path is removed in
KoopNav 0.2.0. Every name is read from where it lives now."""

from koopman_envs.deprecated import moved_module

__getattr__, __dir__ = moved_module("koopman_envs.episode_layout", ("koopman_envs.builder.episode_layout",))
