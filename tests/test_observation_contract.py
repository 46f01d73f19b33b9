"""The typed observation contract (issue 61): the writer and its readers checked against
:class:`koopman_envs.layout.ObservationLayout` under every setting that adds or removes a part
(both tasks, lidar or the state, a radio or none, movers or none), and the stages in front of a
controller returning new :class:`koopman_envs.Observed` values instead of editing the one given.

Each block entry is read here through the layout alone (``layout.items(blocks, part)[..., entry]``
with the entries named by ``ITEM_ENTRIES``) and compared with what it must hold, computed from
the robots' beliefs (:meth:`Observed.from_info`): a writer that put one part or one field of an
item anywhere else, or a bound given to the wrong entry, fails here.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import controllers
from controllers.base import over_the_radio
from controllers.estimation import PoseFrontEnd
from controllers.perception.front import LidarPerception
from koopman_envs import MessageEntry, MoverEntry, Observed, ObstacleEntry, TeamEntry
from koopman_envs.layout import ITEM_ENTRIES, PART_NAMES, PART_WIDTH
from koopman_envs.settings import MoverConfig
from koopman_envs.tasks.observation import AGE_MAX, FAR, feature_bounds

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"
RADIO = {"latency": 2, "drop": 0.3}


def _grid(mover_counts: tuple[int, ...]) -> list[tuple[str, str, bool, int]]:
    """Both tasks x lidar or the state x a radio or none x each count of movers."""
    return [
        (task, sensing, radio, movers)
        for task in (TR, FO)
        for sensing in ("state", "lidar")
        for radio in (False, True)
        for movers in mover_counts
    ]


#: every combination of the settings that add or remove a part of the block
GRID = _grid((0, 3))
STEPS = 8


def _env(task: str, sensing: str, radio: bool, movers: int) -> gym.Env:
    kwargs: dict[str, Any] = {"sensing": sensing, "max_episode_steps": 50}
    if radio:
        kwargs["comm"] = RADIO
    if movers:
        kwargs["movers"] = {"count": movers}
    return gym.make(task, **kwargs)


def _ids(case: tuple) -> str:
    task, sensing, radio, movers = case
    return f"{task[8:12]}-{sensing}-{'radio' if radio else 'instant'}-{movers}movers"


def _body(c: float, s: float, dx: float, dy: float) -> tuple[float, float]:
    return c * dx + s * dy, c * dy - s * dx


@pytest.mark.parametrize("case", GRID, ids=[_ids(c) for c in GRID])
def test_the_layout_offsets_and_bounds_are_its_parts(case: tuple) -> None:
    env = _env(*case)
    env.reset(seed=0)
    scenario = env.unwrapped.scenario
    layout = scenario.observation_layout
    names = [name for name, _ in layout.parts]
    assert names == [name for name in PART_NAMES if layout.has(name)]  # one order, PART_NAMES
    offsets = layout.offsets
    for name, width in layout.parts:
        assert layout[name] == slice(getattr(offsets, name), getattr(offsets, name) + width)
        if name in PART_WIDTH:
            assert layout.count(name) * PART_WIDTH[name] == width
    assert offsets.size == layout.size
    assert layout.has("beams") == (case[1] == "lidar") and layout.has("messages") == case[2]
    listed = MoverConfig().observed if case[1] == "state" and case[3] else 0  # movers.observed listed
    assert layout.has("formation_error") == (case[0] == FO) and layout.movers == listed
    # the observation space's bounds, read part by part and entry by entry
    n = scenario.n_robots
    low = env.observation_space.low.reshape(n, -1)[0].astype(np.float64)
    high = env.observation_space.high.reshape(n, -1)[0].astype(np.float64)
    lidar_range = float(scenario.lidar_range) if layout.beams else 0.0
    np.testing.assert_array_equal(
        np.c_[low, high], np.c_[feature_bounds(layout, lidar_range)].astype(np.float32)
    )
    expected = {
        ("team", TeamEntry.CLEARANCE): (-60.0, 60.0),
        ("team", TeamEntry.DX): (-40.0, 40.0),
        ("obstacles", ObstacleEntry.CLEARANCE): (-60.0, 60.0),
        ("obstacles", ObstacleEntry.DY): (-40.0, 40.0),
        ("messages", MessageEntry.AGE): (0.0, AGE_MAX),
        ("messages", MessageEntry.HEARD): (0.0, 1.0),
        ("movers", MoverEntry.VX): (-5.0, 5.0),
        ("movers", MoverEntry.CLEARANCE): (-60.0, 60.0),
        ("beams", 0): (0.0, lidar_range),
    }
    for (part, entry), (lower, upper) in expected.items():
        if layout.count(part):
            assert (layout.items(low, part)[:, entry] == np.float32(lower)).all(), (part, entry)
            assert (layout.items(high, part)[:, entry] == np.float32(upper)).all(), (part, entry)
    assert (low[layout["target_distance"]], high[layout["target_distance"]]) == (0.0, 60.0)


def _check_block(i: int, block: np.ndarray, layout: Any, observed: Observed, scenario: Any) -> None:
    """Robot ``i``'s block against its beliefs, every part read through the layout."""
    n, radius = scenario.n_robots, scenario.robot_radius
    x, y, theta = observed.observed_poses[i]
    c, s = math.cos(theta), math.sin(theta)
    near = {"rtol": 1e-6, "atol": 1e-5}
    np.testing.assert_allclose(block[layout["position"]], [x, y], **near)
    np.testing.assert_allclose(block[layout["heading"]], [c, s], **near)
    tx, ty, ttheta = observed.targets[i]
    np.testing.assert_allclose(block[layout["target"]], _body(c, s, tx - x, ty - y), **near)
    np.testing.assert_allclose(block[layout.entry("target_distance")], observed.distances[i], **near)
    np.testing.assert_allclose(
        block[layout["target_heading"]], [math.cos(ttheta - theta), math.sin(ttheta - theta)], **near
    )
    team = layout.items(block, "team")
    assert team.shape == (n - 1, len(ITEM_ENTRIES["team"]))
    for slot, j in enumerate(j for j in range(n) if j != i):
        age = observed.message_age[i, j]
        if age < 0:
            np.testing.assert_array_equal(team[slot], [0.0, 0.0, FAR])
            continue
        dx, dy = observed.known_poses[i, j, 0] - x, observed.known_poses[i, j, 1] - y
        np.testing.assert_allclose(team[slot, [TeamEntry.DX, TeamEntry.DY]], _body(c, s, dx, dy), **near)
        gap = math.hypot(dx, dy) - radius[i] - radius[j]
        np.testing.assert_allclose(team[slot, TeamEntry.CLEARANCE], gap, **near)
        if layout.has("messages"):
            message = layout.items(block, "messages")[slot]
            np.testing.assert_array_equal(
                message[[MessageEntry.AGE, MessageEntry.HEARD]], [min(age, AGE_MAX), 1.0]
            )
    if layout.has("messages"):
        unheard = [
            slot for slot, j in enumerate(j for j in range(n) if j != i) if observed.message_age[i, j] < 0
        ]
        messages = layout.items(block, "messages")
        np.testing.assert_array_equal(messages[unheard], np.tile([AGE_MAX, 0.0], (len(unheard), 1)))
    if layout.has("beams"):
        assert observed.lidar_ranges is not None
        np.testing.assert_allclose(layout.items(block, "beams")[:, 0], observed.lidar_ranges[i], **near)
    else:
        obstacles = np.asarray(scenario.obstacles).reshape(-1, 3)
        gaps = np.sort(np.hypot(obstacles[:, 0] - x, obstacles[:, 1] - y) - obstacles[:, 2] - radius[i])
        listed = layout.items(block, "obstacles")
        count = min(len(gaps), layout.count("obstacles"))
        np.testing.assert_allclose(listed[:count, ObstacleEntry.CLEARANCE], gaps[:count], **near)
        assert (listed[count:, ObstacleEntry.CLEARANCE] == FAR).all()
    if layout.has("formation_error"):
        if observed.message_age[i, 0] >= 0:
            offset = scenario.formation_offsets[i]
            leader = observed.known_poses[i, 0]
            np.testing.assert_allclose(
                block[layout["formation_error"]],
                [x - leader[0] - offset[0], y - leader[1] - offset[1]],
                **near,
            )
    if layout.movers:
        assert observed.observed_movers is not None and observed.mover_tracked is not None
        movers = observed.observed_movers[observed.mover_tracked]
        gaps = np.hypot(movers[:, 0] - x, movers[:, 1] - y) - radius[i] - scenario.mover_radius
        order = np.argsort(gaps, kind="stable")[: layout.movers]
        listed = layout.items(block, "movers")
        for slot, m in enumerate(order):
            mx, my, vx, vy = movers[m]
            np.testing.assert_allclose(
                listed[slot, [MoverEntry.DX, MoverEntry.DY]], _body(c, s, mx - x, my - y), **near
            )
            np.testing.assert_allclose(
                listed[slot, [MoverEntry.VX, MoverEntry.VY]], _body(c, s, vx, vy), **near
            )
            np.testing.assert_allclose(listed[slot, MoverEntry.CLEARANCE], gaps[m], **near)
        assert (listed[len(order) :, MoverEntry.CLEARANCE] == FAR).all()


@pytest.mark.parametrize("case", GRID, ids=[_ids(c) for c in GRID])
def test_the_writer_puts_every_named_entry_where_the_layout_says(case: tuple) -> None:
    env = _env(*case)
    obs, info = env.reset(seed=4)
    scenario = env.unwrapped.scenario
    layout = scenario.observation_layout
    n = scenario.n_robots
    rng = np.random.default_rng(0)
    for _ in range(STEPS):
        observed = Observed.from_info(info)
        # the readers' side of the contract: what the observed value has, the layout lists
        assert (observed.lidar_ranges is not None) == layout.has("beams")
        if observed.lidar_ranges is not None:
            assert observed.lidar_ranges.shape == (n, layout.count("beams"))
        assert (observed.observed_movers is not None) == (case[1] == "state" and case[3] > 0)
        blocks = obs.reshape(n, layout.size).astype(np.float64)
        for i in range(n):
            _check_block(i, blocks[i], layout, observed, scenario)
        obs, _, terminated, truncated, info = env.step(rng.uniform([-0.1, -0.5], [0.5, 0.5], (n, 2)).ravel())
        if terminated or truncated:
            break


def test_items_reads_each_field_of_every_item_by_name() -> None:
    from koopman_envs.layout import ObservationLayout

    layout = ObservationLayout(4, 3, formation=True, comm=True, movers=2)
    blocks = np.arange(2 * layout.size, dtype=np.float64).reshape(2, layout.size)  # every entry its index
    for part, entries in ITEM_ENTRIES.items():
        items = layout.items(blocks, part)
        assert items.shape == (2, layout.count(part), len(entries))
        for k in range(layout.count(part)):
            for entry in entries:
                assert items[1, k, entry] == blocks[1, layout.entry(part, k * len(entries) + entry)]
    assert layout.count("beams") == 0
    with pytest.raises(ValueError, match=r"part 'heading' is not one of the parts that list items"):
        layout.count("heading")


def test_the_absent_clearance_and_the_mover_width_are_the_layouts() -> None:
    """FAR and a mover's width are defined once, by the layout: the movers' field writes the
    layout's FAR (it held a copy of its own), the set features' MOVER_SIZE is the layout's width."""
    import koopman_envs
    import koopman_envs.layout as layout_module
    import koopman_envs.sim.movers.field as field
    import koopman_envs.tasks.observation as observation
    from baselines.features.set_features import MOVER_SIZE

    assert not hasattr(field, "_FAR")
    assert field.FAR is observation.FAR is koopman_envs.FAR is layout_module.FAR
    assert MOVER_SIZE == PART_WIDTH["movers"] == len(MoverEntry)


@pytest.mark.parametrize("beams", [0, 8])
@pytest.mark.parametrize("comm", [False, True])
@pytest.mark.parametrize("formation", [False, True])
def test_split_movers_takes_the_layouts_movers_part(beams, comm, formation) -> None:
    """baselines' split_movers cuts the movers off a block's end: the movers part is the last
    of every layout, so the cut is the layout's ``movers`` slice and the rest its other parts."""
    from baselines.features.set_features import split_movers
    from koopman_envs.layout import ObservationLayout

    assert PART_NAMES[-1] == "movers"
    layout = ObservationLayout.for_settings(3, 2, formation, beams, comm, 0 if beams else 2)
    blocks = np.arange(2 * 3 * layout.size, dtype=np.float64).reshape(2, 3, layout.size)
    rest, movers = split_movers(blocks, layout)
    if layout.has("movers"):
        np.testing.assert_array_equal(movers, layout.items(blocks, "movers"), strict=True)
    else:  # with lidar the beams hit the movers: none listed
        assert movers.shape == (2, 3, 0, PART_WIDTH["movers"])
    np.testing.assert_array_equal(rest, blocks[..., : layout.without_movers().size], strict=True)


def _split_movers_by_count(team_blocks: np.ndarray, mover_slots: int) -> tuple[np.ndarray, np.ndarray]:
    """split_movers as it was before issue 61's layout-driven split: cut by the count of listed
    movers at the block's end (the reference the layout's split must equal bit for bit)."""
    blocks = np.asarray(team_blocks, dtype=np.float64)
    begins = blocks.shape[-1] - 5 * mover_slots
    return blocks[..., :begins], blocks[..., begins:].reshape(blocks.shape[:-1] + (mover_slots, 5))


#: the settings of the split's check: both tasks, lidar or the state, a radio or none, 0 or 4 movers
SPLIT_GRID = _grid((0, 4))


@pytest.mark.parametrize("case", SPLIT_GRID, ids=[_ids(c) for c in SPLIT_GRID])
def test_split_movers_follows_the_env_layout_bit_for_bit(case: tuple) -> None:
    """On real observations of every setting (gym.make, after a reset and some steps), the
    layout-driven split_movers returns what the count-driven cut did, bit for bit, and what the
    layout names: the movers are ``layout.items(blocks, "movers")``, the rest is every other part
    in order, of ``layout.without_movers().size`` entries."""
    from baselines.features.set_features import split_movers, state_layout, without_message_ages

    env = _env(*case)
    obs, _ = env.reset(seed=3)
    env.action_space.seed(3)
    layout = env.unwrapped.scenario.observation_layout
    n = layout.n_robots
    listed = MoverConfig().observed if case[1] == "state" and case[3] else 0
    assert layout.count("movers") == listed
    seen = [obs]
    for _ in range(3):
        obs, *_ = env.step(env.action_space.sample())
        seen.append(obs)
    blocks = np.stack(seen).reshape(len(seen), n, -1)  # (steps, N, F), float32 as the env gives them
    rest, movers = split_movers(blocks, layout)
    old_rest, old_movers = _split_movers_by_count(blocks, listed)
    np.testing.assert_array_equal(rest, old_rest, strict=True)
    np.testing.assert_array_equal(movers, old_movers, strict=True)
    assert rest.shape == (len(seen), n, layout.without_movers().size)
    assert movers.shape == (len(seen), n, listed, PART_WIDTH["movers"])
    if listed:
        np.testing.assert_array_equal(movers, layout.items(blocks.astype(np.float64), "movers"), strict=True)
        assert (movers[..., MoverEntry.CLEARANCE] < FAR).any()  # real movers listed, not only absent ones
    for name, _ in layout.without_movers().parts:  # every other part where the layout without movers has it
        np.testing.assert_array_equal(rest[..., layout.without_movers()[name]], blocks[..., layout[name]])
    if layout.comm:  # the SB3 readers drop the messages next: the layout's messages part, the rest's last
        assert PART_NAMES[-2:] == ("messages", "movers")
        kept = np.delete(rest, layout.without_movers()["messages"], axis=-1).reshape(len(seen), -1)
        np.testing.assert_array_equal(without_message_ages(rest.reshape(len(seen), -1), n), kept, strict=True)
    if case[1] == "state":  # a policy handed the observations alone finds the env's layout from their width
        assert (
            state_layout(layout.size, n, formation=layout.formation, comm=layout.comm, movers=listed)
            == layout
        )
        assert (
            state_layout(layout.size, n, comm=layout.comm, movers=listed) == layout
        )  # the task told by the width
    env.close()


def test_split_movers_and_state_layout_refuse_what_fits_no_layout() -> None:
    from baselines.features.set_features import split_movers, state_layout
    from koopman_envs.layout import ObservationLayout

    layout = ObservationLayout(3, 2, movers=2)
    with pytest.raises(ValueError, match=f"do not hold .*{layout.size}"):
        split_movers(np.zeros((3, layout.size + 1)), layout)
    with pytest.raises(TypeError, match="ObservationLayout, not int"):
        split_movers(np.zeros((3, layout.size)), 2)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="a block of 30 entries .* hold 25 \\+ 3 per listed obstacle"):
        state_layout(30, 3, formation=False, movers=2)  # 15 + 10 + 5: no whole count of obstacles
    with pytest.raises(ValueError, match="a block of 5 entries .* hold 15 or 17 \\+ 3"):
        state_layout(5, 3)
    with pytest.raises(ValueError, match="a block of 28 entries"):
        state_layout(28, 3)  # 15 + 13, 17 + 11: neither task
    assert state_layout(layout.size, 3, formation=False, movers=2) == layout
    assert state_layout(layout.size + 2, 3, movers=2) == ObservationLayout(3, 2, True, movers=2)
    with pytest.raises(ValueError, match="a block of 31 entries"):
        state_layout(layout.size, 3, formation=True, movers=2)


# --------------------------------------------------------------------------- the stages
def _snapshot(observed: Observed) -> dict[str, Any]:
    """Every field of ``observed``, its arrays copied."""
    return {f.name: copy.deepcopy(getattr(observed, f.name)) for f in dataclasses.fields(observed)}


def _unchanged(observed: Observed, before: dict[str, Any]) -> None:
    for name, value in before.items():
        now = getattr(observed, name)
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(now, value, strict=True, err_msg=name)
        else:
            assert now == value, name


def test_a_stage_returns_a_new_value_and_leaves_the_one_given_as_it_was() -> None:
    env = gym.make(
        FO,
        uncertainty="harsh",
        sensing="lidar",
        lidar={"map_known": False},
        movers={"count": 3},
        max_episode_steps=50,
    )
    _, info = env.reset(seed=1)
    scenario = env.unwrapped.scenario.planner_view()
    estimator = PoseFrontEnd(delay=1, position_std=0.05, heading_std=0.02)
    estimator.reset(scenario)
    perception = LidarPerception()
    perception.reset(scenario)
    for _ in range(6):
        given = Observed.from_info(info)
        stages = [
            lambda o: over_the_radio(o, 0, scenario.starts),
            estimator.view,
            perception.view,
        ]
        for stage in stages:
            before = _snapshot(given)
            out = stage(given)
            assert out is not given
            _unchanged(given, before)
            given = out
        assert given.pose_age is not None and given.pose_covariance is not None
        assert given.perceived and given.mover_radii is not None and given.perceived_obstacles is not None
        estimator.sent(np.zeros(6))
        _, _, _, _, info = env.step(np.tile([0.2, 0.1], 3))


def test_a_controller_leaves_the_observed_value_a_wrapper_hands_it_as_it_was() -> None:
    """A controller behind a wrapper runs its own stages on the value handed on: it too makes
    new values, so the wrapper's own value (which it goes on planning from) is unchanged."""
    env = gym.make(TR, uncertainty="harsh", max_episode_steps=50)
    obs, info = env.reset(seed=2)
    inner = controllers.make("consensus", estimator="realistic")
    inner.reset(env, seed=2)
    inner.radio_station = 0  # hears the team over robot 0's radio as well
    for _ in range(4):
        given = Observed.from_info(info)
        before = _snapshot(given)
        command = inner.act(obs, given)
        _unchanged(given, before)
        obs, _, _, _, info = env.step(command)
