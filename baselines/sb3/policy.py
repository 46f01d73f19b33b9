"""A trained stable-baselines3 policy behind the common controller protocol (``rl-ppo``)."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, TypedDict, cast

import numpy as np
from numpy.typing import NDArray

from baselines.features.set_features import MAX_TEAM, SetFeatureConfig
from baselines.safe_load import PolicyLoadError, UnsafePolicyFile, load_model, load_npz, read_json
from baselines.sb3.inference import (
    command_of,
    deterministic_action,
    policy_command,
    policy_inputs,
    success_rate,
)
from controllers.base import BaseController
from koopman_envs import TASKS, Observed
from koopman_envs.checks import Range, choice_message
from koopman_envs.files import write_atomic
from koopman_envs.scenario import Scenario

__all__ = [
    "ObsNorm",
    "norm_of",
    "save_policy",
    "PolicyFiles",
    "RLPolicyController",
    "RLSetPolicyController",
    "RLSetV0PolicyController",
    "RLSetPhysicsPolicyController",
    "RLSetRealisticPolicyController",
    "RLSetMoversPolicyController",
    "load_policy",
    "PolicyLoadError",
    "policy_command",
    "policy_inputs",
    "command_of",
    "policy_dir",
    "success_rate",
]

SHIPPED = Path(__file__).resolve().parents[1] / "policies"
REGENERATE = (
    "python -m baselines.sb3.train --env {env_id} --algo {algo} --out runs/{task}` then "
    "`python -m baselines.sb3.select --run runs/{task} --out baselines/policies/{task}"
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
    # each file whole or not at all (koopman_envs.files.write_atomic): a full disk leaves no torn policy
    write_atomic(files.model, model.save)
    write_atomic(files.norm, lambda tmp: np.savez(tmp, **norm_of(vec_normalize)))
    write_atomic(files.metadata, json.dumps(metadata, indent=1) + "\n")


def _checked_norm(path: Path, norm: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``norm`` if it can normalize an observation: ``mean`` and ``var`` finite vectors of one
    length with ``var >= 0``, ``clip > 0`` (inf: no clipping) and ``epsilon`` finite and >= 0.
    Otherwise a :class:`PolicyLoadError` naming the file, the array and the first bad entry: a
    NaN mean or a negative variance was accepted and every episode then failed with "action
    contains a non-finite value"."""
    mean, var = np.asarray(norm["mean"]), np.asarray(norm["var"])
    if mean.ndim != 1 or var.shape != mean.shape:
        raise PolicyLoadError(f"{path}: mean {mean.shape} and var {var.shape} must be vectors of one length")
    for name, values, ok in (
        ("mean", mean, np.isfinite(mean)),
        ("var", var, np.isfinite(var) & (var >= 0)),
    ):
        if not ok.all():
            index = int(np.flatnonzero(~ok)[0])
            allowed = "finite and >= 0" if name == "var" else "finite"
            raise PolicyLoadError(f"{path}: {name}[{index}]={float(values[index])!r}; allowed: {allowed}")
    clip, epsilon = np.asarray(norm["clip"]), np.asarray(norm["epsilon"])
    if clip.shape != () or np.isnan(clip) or not clip > 0:
        raise PolicyLoadError(f"{path}: clip={float(clip)!r}; allowed: a number > 0 (inf: no clipping)")
    if epsilon.shape != () or not np.isfinite(epsilon) or epsilon < 0:
        raise PolicyLoadError(f"{path}: epsilon={float(epsilon)!r}; allowed: a finite number >= 0")
    return norm


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
        norm = _checked_norm(files.norm, load_npz(files.norm, ("mean", "var", "clip", "epsilon")))
        name = metadata.get("algo", algo)
        if name not in algorithms:
            raise PolicyLoadError(choice_message(f"{files.metadata}: algo", name, algorithms))
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


#: policies loaded in this process, by directory and the files' sizes and times (a batched
#: evaluation builds one controller per team: they share one loaded policy and compiled actor)
_LOADED: dict[tuple, tuple[Any, dict, dict, Any]] = {}


def _loaded_policy(directory: Path, task: str, algo: str, allow_pickle: bool) -> tuple[Any, dict, dict, Any]:
    """:func:`load_policy`'s (model, norm, metadata) and the model's compiled actor (the model
    itself when it does not compile), loaded once per process for unchanged files."""
    from baselines.sb3.actor import compile_actor

    folder = os.path.abspath(directory)
    stamps: list[tuple[int, int] | None] = []
    for name in ("policy.zip", "obs_norm.npz", "metadata.json"):  # PolicyFiles' names
        try:
            stat = os.stat(os.path.join(folder, name))
            stamps.append((stat.st_size, stat.st_mtime_ns))
        except OSError:
            stamps.append(None)  # load_policy names what is missing
    key = (folder, task, algo, allow_pickle, tuple(stamps))
    if key not in _LOADED:
        model, norm, metadata = load_policy(directory, task, algo, allow_pickle=allow_pickle)
        _LOADED[key] = (model, norm, metadata, compile_actor(model) or model)
    return _LOADED[key]


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
    #: the folder under ``baselines/policies`` of the shipped policies this name loads ("": the
    #: folder itself, rl-ppo's)
    shipped = ""
    #: a policy reads its observation (the beams themselves under lidar), not the perception's tracks
    perceives = False
    #: one forward pass of the compiled actor serves many teams (:meth:`act_many`)
    acts_in_batch = True
    #: the allowed values of the text option (:mod:`controllers.option_spec`): load_policy's algorithms
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"algo": ("ppo", "sac")}
    #: the allowed range of the numeric option (:mod:`controllers.option_spec`): torch threads
    OPTION_RANGES: ClassVar[dict[str, Range]] = {
        "threads": Range(1, 256, integer=True, note="or None (null)")
    }

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
        self.threads = None if threads is None else self.OPTION_RANGES["threads"].check("threads", threads)
        self.allow_pickle = bool(allow_pickle)
        import importlib.util

        if importlib.util.find_spec("stable_baselines3") is None:
            raise ValueError(
                "rl-ppo needs stable-baselines3: pip install torch==2.13.0 && pip install -e '.[rl]'"
            )
        if not any(policy_dir(task, self.policy_root).exists() for task in TASK_ENV):
            # no task is known yet (the scenario comes at reset): each task's command
            commands = "; ".join(
                f"{task}: `{REGENERATE.format(env_id=env_id, algo=algo, task=task)}`"
                for task, env_id in TASK_ENV.items()
            )
            raise ValueError(
                f"policy_root={str(self.policy_root)!r} holds no trained policy; train one per task with {commands}"
            )
        self._loaded: dict[str, tuple[Any, dict, dict, Any]] = {}

    @classmethod
    def weight_files(cls, options: Mapping[str, Any], task: str) -> list[Path]:
        """The files a controller of this class built with ``options`` loads for ``task`` (its
        policy's :class:`PolicyFiles`), found without building it: a run's header records their
        digest, so that a resume on other weights is refused (:mod:`evaluation.run.weights`)."""
        root = options.get("policy_root") or (SHIPPED / cls.shipped if cls.shipped else SHIPPED)
        files = PolicyFiles(policy_dir(task, root))
        return [files.model, files.norm, files.metadata]

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        if self.threads is not None:
            import torch

            torch.set_num_threads(self.threads)
        if scenario.task not in self._loaded:
            self._loaded[scenario.task] = _loaded_policy(
                policy_dir(scenario.task, self.policy_root), scenario.task, self.algo, self.allow_pickle
            )
        self._model, self._norm, self.metadata, self._actor = self._loaded[scenario.task]
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

    def _observed(self, observation: NDArray, observed: Observed) -> tuple[NDArray, int]:
        """This team's observation as the policy reads it, and the movers each block lists."""
        sc = self.scenario  # the planner's: under lidar with the map unknown, the local map's obstacles
        assert sc is not None  # act() checked it
        if sc.lidar_beams:  # the perceived obstacles and movers, listed as a state env lists them
            from baselines.features.perceived import LISTED_MOVERS, perceived_blocks

            return perceived_blocks(observed, sc).astype(np.float32), LISTED_MOVERS
        return observation, sc.mover_slots

    def _inputs(self, observation: NDArray, mover_slots: int) -> tuple[NDArray[np.float32], tuple[int, ...]]:
        """The network's rows of this controller's observation (or a batch of observations of
        teams in the same settings) and their batch shape."""
        sc = self.scenario
        assert sc is not None  # act() checked it
        return policy_inputs(
            self._norm,
            self._layout,
            observation,
            sc.n_robots,
            self._features,
            self._neighbours,
            set_config=self._set_config,
            formation=self._formation,
            message_ages=sc.message_ages,
            mover_slots=mover_slots,
        )

    def _command(self, action: NDArray, batch_shape: tuple[int, ...]) -> NDArray[np.float64]:
        sc = self.scenario
        assert sc is not None  # act() checked it
        return command_of(action, self._layout, sc.n_robots, sc.v_max, sc.omega_max, batch_shape)

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        rows, batch_shape = self._inputs(*self._observed(observation, observed))
        return self._command(deterministic_action(self._actor, rows), batch_shape)

    def _batch_key(self, observation: NDArray, mover_slots: int) -> tuple:
        """Teams with equal keys go through :func:`policy_inputs`, the actor and
        :func:`command_of` as one batch: the same policy, settings and observation size."""
        sc = self.scenario
        assert sc is not None  # act() checked it
        return (
            id(self._actor),
            id(self._norm),
            self._layout,
            self._features,
            self._neighbours,
            self._set_config,
            self._formation,
            sc.n_robots,
            sc.v_max,
            sc.omega_max,
            sc.message_ages,
            mover_slots,
            np.shape(observation),
        )

    @classmethod
    def act_many(
        cls,
        controllers: Sequence[BaseController],
        observations: Sequence[NDArray],
        infos: Sequence[dict[str, Any]],
    ) -> list[NDArray[np.float64]]:
        """Every team's command, computed for all teams of the same policy and settings at once
        (their observations stacked through :func:`policy_inputs`, one forward pass of the
        compiled actor, :func:`command_of`): equal, bit for bit, to each controller's
        :meth:`act`, since every step acts on each row alone (elementwise arithmetic, per-row
        sorts, the actor's batch-independent rows, :mod:`baselines.sb3.actor`). Each team's decision
        time is its own preparation plus its share of the batch's computation."""
        if not all(isinstance(c, RLPolicyController) for c in controllers):
            return super().act_many(controllers, observations, infos)
        teams = cast("list[RLPolicyController]", list(controllers))
        seen: list[tuple[NDArray, int]] = []
        seconds = [0.0] * len(teams)
        groups: dict[tuple, list[int]] = {}
        for i, (ctrl, observation, info) in enumerate(zip(teams, observations, infos, strict=True)):
            view = ctrl._view(info)
            start = time.perf_counter()
            seen.append(ctrl._observed(observation, view))
            groups.setdefault(ctrl._batch_key(*seen[i]), []).append(i)
            seconds[i] = time.perf_counter() - start
        commands: list[NDArray[np.float64] | None] = [None] * len(teams)
        for members in groups.values():
            start = time.perf_counter()
            lead = teams[members[0]]
            stacked = np.stack([seen[i][0] for i in members])
            rows, batch_shape = lead._inputs(stacked, seen[members[0]][1])
            batch = lead._command(deterministic_action(lead._actor, rows), batch_shape)
            share = (time.perf_counter() - start) / len(members)
            for j, i in enumerate(members):
                commands[i] = batch[j]
                seconds[i] += share
        for i, ctrl in enumerate(teams):
            ctrl._acted(cast("NDArray[np.float64]", commands[i]), seconds[i])
        return cast("list[NDArray[np.float64]]", commands)


class RLSetPolicyController(RLPolicyController):
    """The set-encoder PPO policies (``rl-ppo-set``): one network for any team size and layout.

    Each robot reads its own state and goal and the sets of its nearest team-mates and obstacles
    (:mod:`baselines.features.set_features`), encoded by :class:`baselines.sb3.set_encoder.SetEncoder`.
    Each task's shipped policy is the training seed chosen on validation: every seed the driver
    plans (``data/training/run.sh``) trained on koopnav-bench-v1's train layouts, its checkpoint
    chosen on the validation layouts, the seed picked by
    :func:`evaluation.experiments.seeds.chosen_seed` and shipped by ``--ship`` (docs/rl.md). The
    curriculum-trained policies shipped before are ``rl-ppo-set-v0``
    (:class:`RLSetV0PolicyController`). Parameters as :class:`RLPolicyController`; the default
    ``policy_root`` is ``baselines/policies/set``.
    """

    name = "rl-ppo-set"
    #: the folder under ``baselines/policies`` of the shipped policies this name loads
    shipped = "set"
    #: under lidar a set policy reads the perceived obstacles and movers (:mod:`baselines.features.perceived`)
    perceives = True

    def __init__(
        self,
        policy_root: str | os.PathLike | None = None,
        algo: str = "ppo",
        threads: int | None = 1,
        allow_pickle: bool = False,
    ) -> None:
        super().__init__(policy_root or SHIPPED / self.shipped, algo, threads, allow_pickle)


class RLSetV0PolicyController(RLSetPolicyController):
    """``rl-ppo-set-v0``: the curriculum-trained set policies rl-ppo-set shipped before its seeds.

    The policies trained on the random-layout curriculum of :mod:`baselines.curriculum`
    (``baselines/policies/set_v0``), which ``rl-ppo-set`` shipped before its training seeds chosen
    on validation; kept for comparison, and run only when asked for by name (a comparison variant,
    as the tuned presets' ``<name>-v0``). The rows of ``rl-ppo-set`` in results published before
    that change were measured with these policies."""

    name = "rl-ppo-set-v0"
    shipped = "set_v0"


class RLSetRealisticPolicyController(RLSetPolicyController):
    """``rl-ppo-set-realistic``: the set policies fine-tuned under ``uncertainty="realistic"``
    (pose noise, lossy and late messages, a period of actuation delay) from ``rl-ppo-set-v0``'s
    (the curriculum-trained ones; ``baselines/policies/set_realistic``; docs/rl.md)."""

    name = "rl-ppo-set-realistic"
    shipped = "set_realistic"


class RLSetPhysicsPolicyController(RLSetPolicyController):
    """``rl-ppo-set-physics``: the set policies fine-tuned on the physics plant
    (``plant="mujoco"``) from ``rl-ppo-set-v0``'s, on koopnav-bench-v1's train layouts at carpet and
    ice (``slip`` nominal and high), the checkpoint chosen on its validation layouts on the same
    plant and floors (``baselines/policies/set_physics``; docs/rl.md). The sim-to-sim protocol's
    fine-tuned row (docs/physics.md): the others there run as trained on the kinematic plant."""

    name = "rl-ppo-set-physics"
    shipped = "set_physics"


class RLSetMoversPolicyController(RLSetPolicyController):
    """``rl-ppo-set-movers``: set policies trained from scratch with 4 constant-velocity movers
    (0.3 m/s) in every stage of ``rl-ppo-set-v0``'s curriculum, which they see as a third set (each mover's
    body-frame offset, velocity and clearance), and a proximity cost within 0.5 m of a mover
    (``baselines.sb3.train --movers ... --mover-shaping 0.3``; ``baselines/policies/set_movers``;
    docs/rl.md). In an env without movers the mover set is empty (masked)."""

    name = "rl-ppo-set-movers"
    shipped = "set_movers"
