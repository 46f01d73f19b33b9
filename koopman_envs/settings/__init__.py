"""The environments' settings, one frozen dataclass per setting, each checking itself: what an env
keyword or a reset option may hold, and the named presets.

- :mod:`koopman_envs.settings.uncertainty`: the runtime uncertainty beyond wheel slip (the env
  keywords ``pose_noise``, ``sensing``/``lidar``, ``comm``, ``actuation_delay`` and the presets of
  ``uncertainty``);
- :mod:`koopman_envs.settings.moving_obstacles`: the moving obstacles and people (the env keyword
  ``movers``);
- :mod:`koopman_envs.settings.reset_options`: ``reset(options=...)`` of every front, the keys and
  their one check.

The package is their face: the other packages import ``from koopman_envs.settings import
MoverConfig``; the environment's own modules import the module that defines a name. What simulates
a setting lives in ``sim/`` (``sim/perception.py``, ``sim/lidar.py``, ``sim/movers/``).
"""

from koopman_envs.settings.moving_obstacles import MOVER_BEHAVIOURS, MOVER_FEATURES, MoverConfig, parse_movers
from koopman_envs.settings.reset_options import RESET_OPTIONS, ResetOptions, parse_reset_options
from koopman_envs.settings.uncertainty import (
    SENSING_MODES,
    UNCERTAINTY_PRESETS,
    CommConfig,
    LidarConfig,
    PoseNoise,
    UncertaintyPreset,
    parse_setting,
)

__all__ = [
    "CommConfig",
    "LidarConfig",
    "MOVER_BEHAVIOURS",
    "MOVER_FEATURES",
    "MoverConfig",
    "PoseNoise",
    "RESET_OPTIONS",
    "ResetOptions",
    "SENSING_MODES",
    "UNCERTAINTY_PRESETS",
    "UncertaintyPreset",
    "parse_movers",
    "parse_reset_options",
    "parse_setting",
]
