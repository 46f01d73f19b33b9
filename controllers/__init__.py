"""Controllers for the KoopNav environments.

>>> import controllers
>>> controllers.available()
['adaptive-koopman-nmpc', 'consensus', 'consensus-free', 'koopman-nmpc', 'koopman-nmpc-robust', 'nominal-nmpc', 'nominal-nmpc-robust']
>>> ctrl = controllers.make("koopman-nmpc")
>>> ctrl.calibrate(koopman_envs.make_plant(env), seed=0)   # learns from the env's robots (cached)
>>> ctrl.reset(env.unwrapped.scenario, seed=0)
>>> action = ctrl.act(obs, info)

Every controller follows :class:`controllers.base.Controller`; other packages register their
own through the ``koopnav.controllers`` entry-point group (see :mod:`controllers.registry`).
Any of them runs behind the CBF safety filter of :mod:`controllers.safety` as ``safe:<name>``.
"""

from controllers.base import BaseController, Controller, ControllerStats
from controllers.estimation.options import ESTIMATOR_OPTION_PREFIX
from controllers.option_spec import options
from controllers.registry import ENTRY_POINT_GROUP, available, make, register, register_wrapper, split_name
from controllers.safety.options import FILTER_OPTION_PREFIX
from controllers.tuning.presets import register_builtins
from koopman_envs.deprecation import register_moved_paths

#: the previous release's module paths that docs/ named (the modules of its API page,
#: docs/api/controllers.md) and that moved into a folder by concept (issue 61), kept one release
#: with a DeprecationWarning by koopman_envs.deprecation's import hook (no file at the old path;
#: CHANGELOG.md, Deprecated). The other moved root modules were never documented and are gone
#: (tests/test_architecture.py, REMOVED_PATHS).
MOVED_PATHS = {
    "controllers.presets": "controllers.tuning.presets",
    "controllers.search_space": "controllers.tuning.search_space",
}
register_moved_paths(MOVED_PATHS)

register_builtins(register)
# any controller behind the CBF safety filter: "safe:<name>", filter options prefixed "safety_"
register_wrapper(
    "safe",
    "controllers.safety:wrap",
    options=(
        "controllers.safety.options:SafetyOptions",
        FILTER_OPTION_PREFIX,
        "behind the CBF safety filter",
    ),
)
# any controller reading an EKF estimate of every robot's pose: "ekf:<name>", options prefixed "ekf_"
register_wrapper(
    "ekf",
    "controllers.estimation:wrap",
    options=(
        "controllers.estimation.options:EstimatorOptions",
        ESTIMATOR_OPTION_PREFIX,
        "with an EKF on every robot's pose",
    ),
)

__all__ = [
    "BaseController",
    "Controller",
    "ControllerStats",
    "ENTRY_POINT_GROUP",
    "available",
    "make",
    "options",
    "register",
    "register_wrapper",
    "split_name",
]
