"""A trained stable-baselines3 policy behind the common controller protocol (``rl-ppo``)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict, cast

import numpy as np
from numpy.typing import NDArray

from baselines.safe_load import PolicyLoadError, UnsafePolicyFile, load_model, load_npz, read_json
from baselines.set_features import MAX_TEAM, SetFeatureConfig, set_features, split_movers
from controllers.base import BaseController
from koopman_envs.scenario import Scenario
from koopman_envs.tasks.base import TASKS

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs.fronts.vector_env import KoopNavVectorEnv

__all__ = [
    "ObsNorm",
    "norm_of",
    "save_policy",
    "PolicyFiles",
    "RLPolicyController",
    "RLSetPolicyController",
    "RLSetRealisticPolicyController",
    "RLSetMoversPolicyController",
    "load_policy",
    "PolicyLoadError",
    "policy_command",
    "policy_dir",
    "success_rate",
]

SHIPPED = Path(__file__).resolve().parent / "policies"
REGENERATE = (
    "python -m baselines.train --env {env_id} --algo {algo} --out runs/{task}` then "
    "`python -m baselines.select --run runs/{task} --out baselines/policies/{task}"
)
TASK_ENV = {name: spec.env_id for name, spec in TASKS.items()}  # the task table's ids


def policy_dir(task: str, root: str | os.PathLike | None = None) -> Path:
    """Directory of the policy of a task (``root``, default the shipped ``baselines/policies``)."""
    return Path(root or SHIPPED) / task


class PolicyFiles:
    """The files of one trained policy: ``policy.zip`` (SB3), ``obs_norm.npz``, ``metadata.json``."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.model = self.directory / "policy.zip"
        self.norm = self.directory / "obs_norm.npz"
        self.metadata = self.directory / "metadata.json"


class ObsNorm(TypedDict):
    """The observation statistics of ``VecNormalize``, as saved in ``obs_norm.npz``."""

    mean: np.ndarray
    var: np.ndarray
    clip: np.float64
    epsilon: np.float64


def norm_of(vec_normalize: Any) -> ObsNorm:
    """The observation statistics of a ``VecNormalize`` (the identity when it does not normalize)."""
    if not vec_normalize.norm_obs:
        # set observations are scaled by hand: saved as the identity (mean 0, var 1, no clipping)
        size = vec_normalize.observation_space.shape[0]
        return {
            "mean": np.zeros(size),
            "var": np.ones(size),
            "clip": np.float64(np.inf),
            "epsilon": np.float64(0.0),
        }
    rms = vec_normalize.obs_rms
    return {
        "mean": rms.mean.astype(np.float64),
        "var": rms.var.astype(np.float64),
        "clip": np.float64(vec_normalize.clip_obs),
        "epsilon": np.float64(vec_normalize.epsilon),
    }


def save_policy(out: Path, model, vec_normalize, metadata: dict) -> None:
    """Write policy.zip, obs_norm.npz and metadata.json to ``out``."""
    files = PolicyFiles(out)
    out.mkdir(parents=True, exist_ok=True)
    model.save(files.model)
    np.savez(files.norm, **norm_of(vec_normalize))
    files.metadata.write_text(json.dumps(metadata, indent=1) + "\n", encoding="utf-8")


def load_policy(
    directory: str | os.PathLike, task: str = "formation", algo: str = "ppo", *, allow_pickle: bool = False
) -> tuple[Any, dict, dict]:
    """Load (model, observation normalization, metadata); clear errors for missing or corrupt files.

    The model is loaded without running any pickle stored in ``policy.zip``
    (:func:`baselines.safe_load.load_model`); ``allow_pickle=True`` loads any SB3 zip the plain way,
    which runs the code pickled in it: for files you trust only. Both zips (``policy.zip`` and
    ``obs_norm.npz``) and ``metadata.json`` are checked against the size limits of
    :mod:`baselines.safe_load` before they are unpacked or parsed.

    Raises
    ------
    PolicyLoadError
        (a ``ValueError``) Missing or corrupt files, or files beyond the limits: the message names
        the file, what is wrong and how to regenerate the policy;
        :class:`~baselines.safe_load.UnsafePolicyFile` (a ``PolicyLoadError``) for a zip that
        cannot be loaded without running its pickles (and ``allow_pickle`` is false).
    ValueError
        stable-baselines3 is not installed.
    """
    files = PolicyFiles(Path(directory))
    hint = REGENERATE.format(env_id=TASK_ENV.get(task, task), algo=algo, task=task)
    missing = [p.name for p in (files.model, files.norm, files.metadata) if not p.exists()]
    if missing:
        raise PolicyLoadError(
            f"policy files {missing} are missing in {files.directory}; regenerate with `{hint}`"
        )
    try:
        from stable_baselines3 import PPO, SAC
    except ImportError:
        raise ValueError(
            "the RL baseline needs stable-baselines3: pip install torch==2.13.0 && pip install -e '.[rl]'"
        ) from None
    algorithms: dict[str, type[PPO] | type[SAC]] = {"ppo": PPO, "sac": SAC}
    try:
        metadata = read_json(files.metadata)
        norm = load_npz(files.norm, ("mean", "var", "clip", "epsilon"))
        name = metadata.get("algo", algo)
        if name not in algorithms:
            raise PolicyLoadError(f"{files.metadata}: algo={name!r} is not one of {list(algorithms)}")
        model = load_model(files.model, algorithms[name], allow_pickle=allow_pickle)
    except UnsafePolicyFile:
        raise
    except PolicyLoadError as exc:  # names the file and what is wrong
        raise PolicyLoadError(
            f"policy in {files.directory} is corrupt or unreadable: {exc}; regenerate with `{hint}`"
        ) from exc
    except Exception as exc:  # noqa: BLE001 - any other failure here still means a broken file set
        raise PolicyLoadError(
            f"policy in {files.directory} is corrupt or unreadable ({type(exc).__name__}: {exc}); regenerate with `{hint}`"
        ) from exc
    return model, norm, metadata


def deterministic_action(model: Any, obs: NDArray[np.float32]) -> NDArray[np.float32]:
    """``model.predict(obs, deterministic=True)``'s actions, computed with less overhead.

    For a PPO policy (an actor-critic with a Gaussian head) the deterministic action is the
    actor's mean, clipped into the action space as ``predict`` clips it; computing only that,
    without the critic, the distribution object and ``predict``'s input checks, takes about a
    third less time (0.48 against 0.78 ms for 16 robots on one core). Other models go through
    ``predict``.
    """
    policy = model.policy
    if not (hasattr(policy, "mlp_extractor") and hasattr(policy, "action_net")) or policy.squash_output:
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action)
    import torch

    with torch.inference_mode():
        features = policy.extract_features(torch.as_tensor(obs), policy.pi_features_extractor)
        mean = policy.action_net(policy.mlp_extractor.forward_actor(features)).numpy()
    space = model.action_space
    return np.clip(mean, space.low, space.high)


def policy_command(
    model: Any,
    norm: dict,
    layout: str,
    observation: NDArray,
    n_robots: int,
    v_max: float,
    omega_max: float,
    features: str = "bearing",
    neighbours: int | None = None,
    set_config: SetFeatureConfig | None = None,
    formation: bool = False,
    message_ages: bool = False,
    mover_slots: int = 0,
) -> NDArray[np.float64]:
    """Deterministic joint command (v, omega per robot, flat; batched like the input) of a policy.

    Parameters
    ----------
    model : stable_baselines3 model
    norm : dict
        Observation normalization (``mean``, ``var``, ``clip``, ``epsilon``) saved with the model.
    layout : str
        ``"robot"``: the shared policy sees each robot's block (plus
        :func:`baselines.vec_env.robot_features`) and commands that robot;
        ``"team"``: it sees the flat team observation and commands everybody.
    observation : ndarray, shape (N * F,) or (K, N * F)
        The centralized observation of the Gymnasium env (or a batch of them).
    n_robots : int
    v_max, omega_max : float
        Actuation limits: the policy acts in [-1, 1].
    features : str
        ``"robot"`` layout: the feature set the policy was trained with (its metadata).
    neighbours : int, optional
        ``"robot"`` layout: team-mates per block the policy was trained with (N_train - 1); a
        team of another size then shows each robot its nearest ones (see
        :func:`baselines.vec_env.robot_features`). Default: all.
    set_config : SetFeatureConfig, optional
        A set policy's observation settings (its metadata): each robot then reads
        :func:`baselines.set_features.set_features`, for any team size, and ``features`` and
        ``neighbours`` are ignored.
    formation : bool
        Whether the observation is the formation task's (set policies only).
    message_ages : bool
        Whether each robot's block ends with the team-mates' message ages and arrival flags (an
        env with a ``comm`` setting); they are dropped before the network.
    mover_slots : int
        Movers listed at the end of each robot's block (an env with ``movers``): a set policy with
        mover slots reads them, every other policy has them dropped.
    """
    from baselines.vec_env import robot_features, scale_action, without_message_ages

    obs = np.asarray(observation, dtype=np.float64)
    batch_shape = obs.shape[:-1]
    blocks, movers = split_movers(obs.reshape(batch_shape + (n_robots, -1)), mover_slots)
    obs = blocks.reshape(batch_shape + (-1,))
    if message_ages:
        obs = without_message_ages(obs, n_robots)
    if set_config is not None:
        blocks = obs.reshape(batch_shape + (n_robots, -1))
        listed = obs.shape[-1] // n_robots - 9 - 3 * (n_robots - 1) - (2 if formation else 0)
        obs = set_features(blocks, listed // 3, formation, set_config, movers).astype(np.float64)
        obs = obs.reshape(-1, obs.shape[-1])
    elif layout == "robot":
        blocks = obs.reshape(batch_shape + (n_robots, -1))
        obs = robot_features(blocks, features, neighbours).astype(np.float64)
        obs = obs.reshape(-1, obs.shape[-1])
    if obs.shape[-1] != norm["mean"].shape[-1]:
        raise ValueError(
            f"the policy takes {norm['mean'].shape[-1]} inputs per {'robot' if layout == 'robot' else 'team'}, "
            f"this env gives {obs.shape[-1]}: a {layout!r}-layout policy runs only with the env settings "
            "it was trained on (n_obstacle_obs; for the 'team' layout also n_robots)"
        )
    obs = (obs - norm["mean"]) / np.sqrt(norm["var"] + norm["epsilon"])
    obs = np.clip(obs, -norm["clip"], norm["clip"]).astype(np.float32)
    action = deterministic_action(model, obs)
    high = np.array([v_max, omega_max])
    if layout == "team":
        high = np.tile(high, n_robots)
    return scale_action(np.asarray(action, dtype=np.float64), -high, high).reshape(batch_shape + (-1,))


def success_rate(
    model: Any,
    norm: dict,
    layout: str,
    features: str,
    env_id: str,
    episodes: int,
    seed: int,
    *,
    set_config: SetFeatureConfig | None = None,
    **env_kwargs: Any,
) -> float:
    """Success rate of the deterministic policy over ``episodes`` episodes, played as one batch.

    Episode i runs in sub-env i of ``gym.make_vec(env_id, num_envs=episodes, **env_kwargs)``
    reset with ``seed``, i.e. seeded ``seed + i`` like the single env. ``set_config``: a set
    policy's observation settings (see :func:`policy_command`).
    """
    import gymnasium as gym

    venv = gym.make_vec(env_id, num_envs=episodes, **env_kwargs)
    obs, _ = venv.reset(seed=seed)
    # a KoopNav id's vector entry point is a KoopNavVectorEnv (make_vec types it as any VectorEnv)
    engine = cast("KoopNavVectorEnv", venv.unwrapped).engine
    layout_of_env = cast("KoopNavVectorEnv", venv.unwrapped).observation_layout
    n_robots = engine.config.n_robots
    v_max, omega_max = float(engine.command_high[0]), float(engine.command_high[1])
    done = np.zeros(episodes, dtype=bool)
    success = np.zeros(episodes, dtype=bool)
    while not done.all():
        action = policy_command(
            model,
            norm,
            layout,
            obs,
            n_robots,
            v_max,
            omega_max,
            features,
            set_config=set_config,
            formation=engine.config.task.formation,
            message_ages=layout_of_env.comm,
            mover_slots=layout_of_env.movers,
        )
        obs, _, terminated, truncated, info = venv.step(action)
        ended = (terminated | truncated) & ~done
        success[ended] = info["is_success"][ended]
        done |= ended
    venv.close()
    return float(success.mean())


class RLPolicyController(BaseController):
    """Plays a trained policy deterministically: normalized observation in, physical command out.

    Parameters
    ----------
    policy_root : path, optional
        Directory holding one sub-directory per task (default: the shipped policies).
    algo : str
        ``"ppo"`` or ``"sac"`` (recorded in the metadata of each policy).
    threads : int, optional
        torch intra-op threads for inference (default 1: a 128-wide MLP gains nothing from more,
        and evaluator workers running side by side would oversubscribe the cores); None leaves
        torch's setting alone.
    allow_pickle : bool
        Load policy zips that only load by running the code pickled in them (another SB3
        version's or a hand-made file): for files you trust only. The default loads KoopNav's
        policies without running any (:mod:`baselines.safe_load`).
    """

    name = "rl-ppo"
    #: a policy reads its observation (the beams themselves under lidar), not the perception's tracks
    perceives = False

    def __init__(
        self,
        policy_root: str | os.PathLike | None = None,
        algo: str = "ppo",
        threads: int | None = 1,
        allow_pickle: bool = False,
    ) -> None:
        super().__init__()
        self.policy_root = Path(policy_root) if policy_root else SHIPPED
        self.algo = algo
        self.threads = threads
        self.allow_pickle = bool(allow_pickle)
        import importlib.util

        if importlib.util.find_spec("stable_baselines3") is None:
            raise ValueError(
                "rl-ppo needs stable-baselines3: pip install torch==2.13.0 && pip install -e '.[rl]'"
            )
        if not any(policy_dir(task, self.policy_root).exists() for task in TASK_ENV):
            raise ValueError(
                f"no trained policy in {self.policy_root}; train one with "
                f"`{REGENERATE.format(env_id=TASK_ENV['formation'], algo=algo, task='formation')}`"
            )
        self._loaded: dict[str, tuple[Any, dict, dict]] = {}

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        if self.threads is not None:
            import torch

            torch.set_num_threads(self.threads)
        if scenario.task not in self._loaded:
            self._loaded[scenario.task] = load_policy(
                policy_dir(scenario.task, self.policy_root),
                scenario.task,
                self.algo,
                allow_pickle=self.allow_pickle,
            )
        self._model, self._norm, self.metadata = self._loaded[scenario.task]
        self._layout = self.metadata.get("layout", "team")
        self._features = self.metadata.get("features", "bearing")
        # policies trained before the team size was recorded were all trained with the paper's 3
        self._neighbours = int(self.metadata.get("n_robots") or 3) - 1
        set_fields = self.metadata.get("set_config")
        self._set_config = SetFeatureConfig(**set_fields) if set_fields else None
        if self._set_config is not None and not 1 <= scenario.n_robots <= MAX_TEAM:
            raise ValueError(
                f"a set policy runs teams of 1..{MAX_TEAM} robots, not n_robots={scenario.n_robots}"
            )
        self._formation = TASKS[scenario.task].formation
        if scenario.lidar_beams and not self.perceives:
            raise ValueError(
                f"{self.name} reads the listed obstacles of sensing='state'; this env has sensing='lidar' "
                f"({scenario.lidar_beams} beams): the set policies (rl-ppo-set*) read the perceived ones"
            )

    def _act(self, observation: NDArray, info: dict[str, Any]) -> NDArray[np.float64]:
        import time

        start = time.perf_counter()
        sc = self.scenario  # the planner's: under lidar with the map unknown, the local map's obstacles
        assert sc is not None  # act() checked it
        mover_slots = sc.mover_slots
        if sc.lidar_beams:  # the perceived obstacles and movers, listed as a state env lists them
            from baselines.perceived import LISTED_MOVERS, perceived_blocks

            observation = perceived_blocks(info, sc).astype(np.float32)
            mover_slots = LISTED_MOVERS
        command = policy_command(
            self._model,
            self._norm,
            self._layout,
            observation,
            sc.n_robots,
            sc.v_max,
            sc.omega_max,
            self._features,
            self._neighbours,
            set_config=self._set_config,
            formation=self._formation,
            message_ages=sc.message_ages,
            mover_slots=mover_slots,
        )
        self._stats.solve_times.append(time.perf_counter() - start)
        return command


class RLSetPolicyController(RLPolicyController):
    """The set-encoder PPO policies (``rl-ppo-set``): one network for any team size and layout.

    Each robot reads its own state and goal and the sets of its nearest team-mates and obstacles
    (:mod:`baselines.set_features`), encoded by :class:`baselines.set_encoder.SetEncoder`; the
    policies were trained on the random-layout curriculum of :mod:`baselines.curriculum`.
    Parameters as :class:`RLPolicyController`; the default ``policy_root`` is
    ``baselines/policies/set``.
    """

    name = "rl-ppo-set"
    #: the folder under ``baselines/policies`` of the shipped policies this name loads
    shipped = "set"
    #: under lidar a set policy reads the perceived obstacles and movers (:mod:`baselines.perceived`)
    perceives = True

    def __init__(
        self,
        policy_root: str | os.PathLike | None = None,
        algo: str = "ppo",
        threads: int | None = 1,
        allow_pickle: bool = False,
    ) -> None:
        super().__init__(policy_root or SHIPPED / self.shipped, algo, threads, allow_pickle)


class RLSetRealisticPolicyController(RLSetPolicyController):
    """``rl-ppo-set-realistic``: the set policies fine-tuned under ``uncertainty="realistic"``
    (pose noise, lossy and late messages, a period of actuation delay) from ``rl-ppo-set``'s
    (``baselines/policies/set_realistic``; docs/rl.md)."""

    name = "rl-ppo-set-realistic"
    shipped = "set_realistic"


class RLSetMoversPolicyController(RLSetPolicyController):
    """``rl-ppo-set-movers``: set policies trained from scratch with 4 constant-velocity movers
    (0.3 m/s) in every stage of the curriculum, which they see as a third set (each mover's
    body-frame offset, velocity and clearance), and a proximity cost within 0.5 m of a mover
    (``baselines.train --movers ... --mover-shaping 0.3``; ``baselines/policies/set_movers``;
    docs/rl.md). In an env without movers the mover set is empty (masked)."""

    name = "rl-ppo-set-movers"
    shipped = "set_movers"
