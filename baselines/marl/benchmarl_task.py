"""KoopNav's two tasks as BenchMARL tasks (the ``[benchmarl]`` extra).

BenchMARL (MAPPO, IPPO, MADDPG, ... on TorchRL) runs a task through a :class:`TaskClass` that
builds TorchRL envs; this one wraps KoopNav's PettingZoo parallel env in TorchRL's
``PettingZooWrapper`` unchanged, one group ``"agents"`` holding every robot::

    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig
    from baselines.marl.benchmarl_task import KoopNavTask

    task = KoopNavTask.FORMATION.get_task()          # the defaults of TASK_CONFIGS["formation"]
    task.config.update({"n_robots": 5, "slip": "high"})  # any env keyword
    experiment = Experiment(
        task=task,
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=ExperimentConfig.get_from_yaml(),
    )
    experiment.run()

The task's config is the env keywords of :mod:`koopman_envs.engine.keywords` (``map``, ``slip``,
``n_robots``, ``max_cycles``, ...); unknown ones fail when the env is built, naming the
allowed ones. ``TASK_CONFIGS`` holds the defaults (random maps, random slip, 100 cycles, like
BenchMARL's MPE tasks) and :func:`write_task_yaml` writes them as BenchMARL's YAML files.

``vectorized`` (default True, not an env keyword) picks how BenchMARL gets its batch of
environments: True, one compiled vector env as one batched TorchRL env
(:class:`baselines.marl.torchrl_env.KoopNavMultiAgentEnv`, as VMAS does); False, one PettingZoo
env per TorchRL env, which BenchMARL batches with a ``SerialEnv`` (every environment stepped
through Python: about a tenth of the frames per second, ``bench/benchmarl_speed.py``). With the
vector env, ``collision_penalty``, ``precision_shaping`` and ``mover_shaping`` (not env keywords
either; default 0) add the training terms the PPO policies train with (:mod:`baselines.shaping`),
and ``observation_stats`` (``[mean, std]``, lists per entry of a robot's block) standardizes the
observations (:class:`baselines.marl.torchrl_env.KoopNavMultiAgentEnv`); ``reward_scale`` (either
path) multiplies the rewards before BenchMARL uses them.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from benchmarl.environments.common import Task, TaskClass
from torchrl.data import Composite
from torchrl.envs import EnvBase, PettingZooWrapper
from torchrl.envs.transforms import RewardScaling, Transform

from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.files import MAX_TEXT_BYTES, read_text, write_atomic

__all__ = ["TASK_CONFIGS", "KoopNavTask", "KoopNavTaskClass", "write_task_yaml"]

#: the default config of each task: env keywords of the PettingZoo parallel env
TASK_CONFIGS: dict[str, dict[str, Any]] = {
    "target_reaching": {
        "n_robots": 3,
        "map": "random",
        "slip": "random",
        "max_cycles": 100,
        "vectorized": True,
    },
    "formation": {"n_robots": 3, "map": "random", "slip": "random", "max_cycles": 100, "vectorized": True},
}
#: the Gymnasium ids of the tasks (the vectorized env's)
_ENV_IDS = {"target_reaching": "KoopNav-TargetReaching-v0", "formation": "KoopNav-Formation-v0"}
_MODULES = {"target_reaching": target_reaching_v0, "formation": formation_v0}


class KoopNavTaskClass(TaskClass):
    """Builds TorchRL envs of one KoopNav task from its config (env keywords)."""

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        config = copy.deepcopy(self.config)
        config.pop("reward_scale", None)  # a transform of the task's (get_env_transforms), not an env keyword
        name = self.name.lower()
        if config.pop("vectorized", True):
            # every environment in one compiled vector env: BenchMARL takes it as already batched
            from baselines.marl.torchrl_env import KoopNavMultiAgentEnv

            config["max_episode_steps"] = config.pop("max_cycles", 600)
            stats = config.pop("observation_stats", None)  # [mean, std] lists (a YAML-able config)
            if stats is not None:
                config["observation_stats"] = tuple(np.asarray(v, dtype=np.float32) for v in stats)

            def make() -> EnvBase:
                env = KoopNavMultiAgentEnv(_ENV_IDS[name], num_envs, device=device, **config)
                if seed is not None:
                    env.set_seed(seed)
                return env

            return make
        module = _MODULES[name]
        # one KoopNav env per TorchRL env: BenchMARL batches them with a SerialEnv / ParallelEnv
        return lambda: PettingZooWrapper(
            module.parallel_env(**config), use_mask=True, categorical_actions=True, device=device, seed=seed
        )

    def get_env_transforms(self, env: EnvBase) -> list[Transform]:
        """``reward_scale`` (config, default 1): every robot's reward times it, before BenchMARL
        sums the returns (its logged returns are then scaled alike)."""
        scale = float(self.config.get("reward_scale", 1.0))
        if not scale > 0:
            raise ValueError(f"reward_scale={scale!r} must be > 0")
        if scale == 1.0:
            return []
        group = next(iter(self.group_map(env)))
        return [RewardScaling(0.0, scale, in_keys=[(group, "reward")])]

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return False

    def has_render(self, env: EnvBase) -> bool:
        return False

    def max_steps(self, env: EnvBase) -> int:
        return int(self.config.get("max_cycles", 600))

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return env.group_map

    def _group_entries(self, env: EnvBase, keep: str) -> Composite:
        # BenchMARL builds its networks from the specs of one environment (a batched env's
        # unbatched specs; for an unbatched env they are its specs)
        spec = env.full_observation_spec_unbatched.clone()
        for group in self.group_map(env):
            for key in list(spec[group].keys()):
                if key != keep:
                    del spec[group][key]
        return spec

    def observation_spec(self, env: EnvBase) -> Composite:
        return self._group_entries(env, "observation")

    def info_spec(self, env: EnvBase) -> Composite | None:
        return None

    def state_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec_unbatched

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        return None

    @staticmethod
    def env_name() -> str:
        return "koopnav"


class KoopNavTask(Task):
    """The KoopNav tasks for BenchMARL: ``KoopNavTask.FORMATION``, ``KoopNavTask.TARGET_REACHING``."""

    TARGET_REACHING = None
    FORMATION = None

    @staticmethod
    def associated_class() -> type[TaskClass]:
        return KoopNavTaskClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        """The task with the config of ``path`` (a YAML file), default :data:`TASK_CONFIGS`."""
        if path is None:
            return self.get_task(config=copy.deepcopy(TASK_CONFIGS[self.name.lower()]))
        import yaml

        config = (
            yaml.safe_load(read_text(path, MAX_TEXT_BYTES, what="task config", expected="a YAML task config"))
            or {}
        )
        config.pop("defaults", None)
        return self.get_task(config=config)


def write_task_yaml(directory: str | Path) -> list[Path]:
    """Write ``koopnav/<task>.yaml`` under ``directory`` (BenchMARL's ``conf/task`` layout)."""
    import yaml

    written = []
    for name, config in TASK_CONFIGS.items():
        path = Path(directory) / "koopnav" / f"{name}.yaml"
        write_atomic(path, yaml.safe_dump(config, sort_keys=False))
        written.append(path)
    return written
