"""Leader-follower consensus formation control for nonholonomic robots (SPEC section 4).

After the consensus-based formation law of Liu et al. (2020) that the paper compares against:
each robot controls a "hand" point a distance ``hand`` ahead of its axle, which turns the
unicycle into a fully actuated point (feedback linearization). The leader drives its hand to its
target; every follower runs a consensus protocol on the formation-corrected positions
(h_i - delta_i) with the leader and the other followers, plus the leader's velocity as
feed-forward. With ``collision_avoidance=True`` a repulsive velocity pushes each robot away from
obstacles and other robots inside an influence distance; this is what keeps the followers from
reaching their slots in cluttered maps. On the target-reaching task every robot runs the
leader's law toward its own target.
"""

from __future__ import annotations

import time
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController
from controllers.estimation import FRONT_END_LEVERS, estimator_choices, front_end_option
from controllers.movers import (
    MOVER_PREDICTIONS,
    check_mover_prediction,
    observed_mover_radii,
    observed_movers,
)
from controllers.tuning.search_space import Search
from koopman_envs import Observed
from koopman_envs.checks import Range
from koopman_envs.scenario import Scenario

__all__ = ["CONSENSUS_LEVERS", "ConsensusController"]

#: the levers of the estimator consensus can switch off (``ablate``): it has no margins to tighten
#: and no plan to settle
CONSENSUS_LEVERS = FRONT_END_LEVERS


class ConsensusController(BaseController):
    """Consensus-based leader-follower formation control.

    Parameters
    ----------
    collision_avoidance : bool
        Add the repulsive term near obstacles and robots (the variant the paper tabulates).
    goal_gain : float
        Gain of the leader's (and target-reaching robots') hand toward the target [1/s].
    consensus_gain : float
        Gain of the consensus term among followers and leader [1/s].
    hand : float
        Distance of the controlled point ahead of the axle [m].
    influence : float
        Clearance below which the repulsion acts [m].
    repulsion_gain : float
        Strength of the repulsion [m^2/s].
    mover_prediction : str
        (ours) Where the repulsion sees a moving obstacle (``movers`` keyword), one of
        :data:`controllers.movers.MOVER_PREDICTIONS`: ``"constant_velocity"`` (default) the
        point of its path over the next ``mover_lookahead`` seconds nearest to the robot (so the
        robot gives way before the mover arrives); ``"static"`` where it is seen now.
    mover_lookahead : float
        (ours) Seconds of a mover's path the constant-velocity repulsion looks ahead [s].
    estimator : str
        (ours) ``"auto"`` (default): the estimator front-end with everything identified online
        (:func:`controllers.estimation.auto_front_end`: delay compensated, noise filtered; a
        no-op without either); ``"realistic"``: the same told the ``realistic`` preset's delay
        and noise (mis-specified when the team has others); ``"none"``: the paper's, steering
        from every measured pose (:data:`controllers.estimation.ESTIMATORS`).
    ablate : str
        (ours) ``"none"`` (default), or one lever of the estimator switched off for the
        ablation: ``"estimation"`` (no filter) or ``"delay_compensation"``.
    """

    name = "consensus"
    #: the allowed values of the text options (:mod:`controllers.option_spec`)
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        "mover_prediction": MOVER_PREDICTIONS,
        **estimator_choices(),
    }
    #: the allowed range of every numeric option (:mod:`controllers.option_spec`; ours)
    OPTION_RANGES: ClassVar[dict[str, Range]] = {
        "goal_gain": Range(0, 100, low_open=True, note="1/s"),
        "consensus_gain": Range(0, 100, low_open=True),
        "hand": Range(0, 1, low_open=True, note="m"),
        "influence": Range(0, 10, low_open=True, note="m"),
        "repulsion_gain": Range(0, 100, low_open=True),
        "mover_lookahead": Range(0, 60, low_open=True, note="s"),
    }
    #: what the tuner searches (:mod:`evaluation.tune`; ours): the law's three gains (towards
    #: the goal, towards the team's consensus, away from obstacles) and the two lengths of the
    #: repulsion (the hand, the influence distance). Mover settings are left: the suites have
    #: no movers.
    TUNABLE: ClassVar[dict[str, Search]] = {
        "goal_gain": Search(0.2, 3.0, log=True),
        "consensus_gain": Search(0.3, 5.0, log=True),
        "hand": Search(0.01, 0.2),
        "influence": Search(0.1, 1.0),
        "repulsion_gain": Search(0.01, 0.5, log=True),
    }

    def __init__(
        self,
        collision_avoidance: bool = True,
        goal_gain: float = 0.8,
        consensus_gain: float = 1.5,
        hand: float = 0.05,
        influence: float = 0.25,
        repulsion_gain: float = 0.05,
        mover_prediction: str = "constant_velocity",
        mover_lookahead: float = 1.0,
        estimator: str = "auto",
        ablate: str = "none",
    ) -> None:
        super().__init__()
        self.front_end = front_end_option(estimator, ablate)
        self.estimator, self.ablate = estimator, ablate
        for key, value in dict(
            goal_gain=goal_gain,
            consensus_gain=consensus_gain,
            hand=hand,
            influence=influence,
            repulsion_gain=repulsion_gain,
            mover_lookahead=mover_lookahead,
        ).items():
            self.OPTION_RANGES[key].check(key, value)  # a number (not text, not a flag) in range
        self.collision_avoidance = bool(collision_avoidance)
        self.goal_gain, self.consensus_gain = goal_gain, consensus_gain
        self.hand, self.influence, self.repulsion_gain = hand, influence, repulsion_gain
        self.mover_prediction = check_mover_prediction(mover_prediction)
        self.mover_lookahead = mover_lookahead
        self._movers = np.zeros((0, 4))
        self._mover_radii = np.zeros(0)

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        heading = np.column_stack([np.cos(scenario.targets[:, 2]), np.sin(scenario.targets[:, 2])])
        # hand-point targets: the axle then rests on the target when the heading matches
        self._hand_targets = scenario.targets[:, :2] + self.hand * heading

    def _hand_velocity_to_target(self, hands: NDArray, targets: NDArray, v_max: float) -> NDArray:
        velocity = -self.goal_gain * (hands - targets)
        speed = np.linalg.norm(velocity, axis=-1, keepdims=True)
        return velocity * np.minimum(1.0, v_max / np.maximum(speed, 1e-12))

    def _repulsion(self, positions: NDArray, goal_velocity: NDArray, heard: NDArray | None = None) -> NDArray:
        """Velocity away from obstacles and robots closer than ``influence`` (clearance).

        Besides the radial push, the avoidance slides along the obstacle (the tangent on the
        side of the goal direction), the usual cure for a robot stalling where attraction and
        repulsion cancel in front of a disc.
        """
        sc = self.scenario
        assert sc is not None  # only called by _act, after act() checked it
        push = np.zeros_like(positions)
        movers = self._movers
        centres = np.vstack([sc.obstacles[:, :2], positions, movers[:, :2]])
        radii = np.concatenate([sc.obstacles[:, 2], sc.robot_radius, self._mover_radii])
        robots = slice(len(sc.obstacles), len(sc.obstacles) + len(positions))
        for i, p in enumerate(positions):
            if len(movers) and self.mover_prediction == "constant_velocity":
                centres[robots.stop :] = _nearest_on_path(p, movers, self.mover_lookahead)
            delta = p - centres
            dist = np.linalg.norm(delta, axis=1)
            clearance = dist - radii - sc.robot_radius[i]
            near = (clearance < self.influence) & (dist > 1e-9)
            near[len(sc.obstacles) + i] = False  # not itself
            if heard is not None:  # nor a robot it has heard nothing of
                near[robots] &= heard
            if near.any():
                c = np.maximum(clearance[near], 0.02)
                strength = self.repulsion_gain * (1.0 / c - 1.0 / self.influence) / c**2
                normal = delta[near] / dist[near, None]
                tangent = np.column_stack([-normal[:, 1], normal[:, 0]])
                # products written out, not `@` / `norm`: NumPy hands those to the BLAS, whose
                # kernel (chosen by CPU) fuses multiply-adds on some machines and not on others
                gx, gy = goal_velocity[i]
                side = np.sign(tangent[:, 0] * gx + tangent[:, 1] * gy)
                side[side == 0] = 1.0
                speed = np.sqrt(gx * gx + gy * gy)
                push[i] = (strength[:, None] * normal).sum(axis=0) + speed * (side[:, None] * tangent).sum(
                    axis=0
                )
        return push

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        """Every robot's command from what it knows: its own pose estimate and its last messages
        of the others (``known_poses`` row i; robots it has heard nothing of are left out). When
        every robot knows the same (instant messages) one team computation serves all."""
        start = time.perf_counter()
        self._movers = observed_movers(observed)
        assert self.scenario is not None  # act() checked it
        self._mover_radii = observed_mover_radii(observed, self.scenario.mover_radius)
        known, ages = observed.known_poses, observed.message_age
        if (ages == 0).all() and (known == known[:1]).all():
            command = self._team_command(known[0])
        else:
            command = np.stack([self._team_command(known[i], ages[i] >= 0)[i] for i in range(known.shape[0])])
        self._stats.solve_times.append(time.perf_counter() - start)
        return command.reshape(-1)

    def _team_command(self, poses: NDArray, heard: NDArray | None = None) -> NDArray[np.float64]:
        """(N, 2) commands from the team poses ``poses`` (N, 3) as one robot knows them; ``heard``
        (N,) marks the robots it knows of (None: all)."""
        sc = self.scenario
        assert sc is not None  # act() checked it
        theta = poses[:, 2]
        heading = np.column_stack([np.cos(theta), np.sin(theta)])
        hands = poses[:, :2] + self.hand * heading
        if sc.is_formation:
            lead = sc.leader
            offsets = sc.formation_offsets
            lead_velocity = self._hand_velocity_to_target(hands[lead], self._hand_targets[lead], sc.v_max)
            if heard is not None and not heard[lead]:
                lead_velocity = np.zeros(2)  # no feed-forward from a leader not yet heard of
            corrected = hands - offsets  # where each robot "thinks" the leader's hand should be
            velocity = np.empty_like(hands)
            velocity[lead] = lead_velocity
            for i in range(sc.n_robots):
                if i == lead:
                    continue
                # consensus with every other robot (complete graph) plus leader feed-forward
                others = corrected if heard is None else corrected[heard]
                disagreement = (corrected[i] - others).sum(axis=0)
                velocity[i] = lead_velocity - self.consensus_gain * disagreement
        else:
            velocity = self._hand_velocity_to_target(hands, self._hand_targets, sc.v_max)
        if self.collision_avoidance:
            velocity = velocity + self._repulsion(poses[:, :2], velocity, heard)
        # hand-point feedback linearization: [v, omega] = [[c, s], [-s/l, c/l]] hand velocity
        v = heading[:, 0] * velocity[:, 0] + heading[:, 1] * velocity[:, 1]
        omega = (-heading[:, 1] * velocity[:, 0] + heading[:, 0] * velocity[:, 1]) / self.hand
        return np.column_stack([np.clip(v, -sc.v_max, sc.v_max), np.clip(omega, -sc.omega_max, sc.omega_max)])


def _nearest_on_path(point: NDArray, movers: NDArray, lookahead: float) -> NDArray[np.float64]:
    """Per mover (C, 4: x, y, vx, vy), the point of its straight path over the next
    ``lookahead`` seconds nearest to ``point`` (2,), shape (C, 2)."""
    start, travel = movers[:, :2], lookahead * movers[:, 2:4]
    length2 = (travel * travel).sum(axis=1)
    along = np.where(length2 > 0, ((point - start) * travel).sum(axis=1) / np.maximum(length2, 1e-12), 0.0)
    return start + np.clip(along, 0.0, 1.0)[:, None] * travel
