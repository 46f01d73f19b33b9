"""Deprecated (``python -m koopman_envs.demo`` still runs the demo): ``koopman_envs.demo`` moved to ``koopman_envs.fronts.demo``; this path is removed in
KoopNav 0.2.0. Every name is read from where it lives now."""

from koopman_envs.deprecated import moved_module

__getattr__, __dir__ = moved_module("koopman_envs.demo", ("koopman_envs.fronts.demo",))

if __name__ == "__main__":
    from koopman_envs.fronts.demo import main

    raise SystemExit(main())
