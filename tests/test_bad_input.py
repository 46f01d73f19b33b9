"""Every bad input named by the environments issue raises a clear ValueError."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401
from koopman_envs import formation_v0

ENV = "KoopNav-TargetReaching-v0"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (
            {"map": "map9"},
            r"map='map9' is not one of \['map1', 'map2', 'map3', 'map4', 'map5', 'map6', 'map7', 'map8', 'random'\]",
        ),
        ({"slip": "extreme"}, r"slip='extreme' is not one of \['nominal', 'low', 'high'\]"),
        ({"slip": [0.0, -0.1, 0.2]}, r"negative lambda; allowed: lambda >= 0"),
        ({"slip": [0.0, float("nan"), 0.2]}, r"non-finite lambda"),
        ({"slip": [0.0, float("inf"), 0.2]}, r"non-finite lambda"),
        ({"slip": [0.0, 0.1]}, r"has 2 values; expected one lambda per robot \(3\)"),
        ({"n_robots": 0}, r"n_robots=0 must be an integer >= 1"),
        ({"n_robots": 4}, r"n_robots=4 is larger than map 'map1' supports \(1..3\)"),
        ({"goal_tolerance": -0.1}, r"goal_tolerance=-0.1 must be a finite number > 0"),
        ({"render_mode": "ascii"}, r"render_mode='ascii' is not one of \['human', 'rgb_array'\]"),
        (
            {"map": "random", "random_map": {"obstacles": 2}},
            r"random_map has unknown fields \['obstacles'\] \(did you mean 'n_obstacles'\?\); allowed",
        ),
        ({"map": "random", "random_map": 3}, r"random_map=3 must be a RandomMapConfig, a dict"),
        ({"start_noise": -0.1}, r"start_noise=-0.1 must be a finite number >= 0"),
        ({"start_noise": -1}, r"start_noise=-1 must be a finite number >= 0"),
        ({"start_noise": float("nan")}, r"start_noise=nan must be a finite number >= 0"),
        ({"start_noise": float("inf")}, r"start_noise=inf must be a finite number >= 0"),
        ({"start_noise": "0.1"}, r"start_noise='0.1' must be a finite number >= 0"),
        ({"start_noise": None}, r"start_noise=None must be a finite number >= 0"),
        ({"start_noise": True}, r"start_noise=True must be a finite number >= 0"),
        ({"start_noise": [0.1, 0.2]}, r"start_noise=\[0.1, 0.2\] must be a finite number >= 0"),
        # issue 31: a boolean was read as lambda 1, a negative count reached numpy
        ({"slip": True}, r"slip=True is a boolean; allowed: a name in \['nominal', 'low', 'high'\]"),
        ({"slip": [0.0, True, 0.2]}, r"slip=\[0.0, True, 0.2\] is a boolean"),
        ({"map": "random", "random_map": {"n_obstacles": -1}}, r"n_obstacles=-1 must be an integer >= 0"),
        (
            {"map": "random", "random_map": {"travel": (5, 2)}},
            r"travel=\(5, 2\) must be a finite \(low, high\)",
        ),
        ({"map": "random", "random_map": {"gap": -1}}, r"gap=-1 must be a finite number >= 0"),
        ({"map": "random", "random_map": {"obstacle_radius": (0, 1)}}, r"obstacle_radius=\(0, 1\) must be"),
    ],
)
def test_bad_constructor_arguments(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, **kwargs)


def test_bad_arguments_in_every_front() -> None:
    with pytest.raises(ValueError, match="slip='extreme'"):
        formation_v0.parallel_env(slip="extreme")
    with pytest.raises(ValueError, match="map='nowhere'"):
        gym.make_vec(ENV, num_envs=2, map="nowhere")
    with pytest.raises(ValueError, match="start_noise=-0.5 must be a finite number >= 0"):
        formation_v0.parallel_env(start_noise=-0.5)
    with pytest.raises(ValueError, match="start_noise=False must be a finite number >= 0"):
        gym.make_vec(ENV, num_envs=2, start_noise=False)


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        ((0, -2), {"beams": -3}, r"n_robots=0 must be an integer >= 1"),
        ((3, -2), {"beams": -3}, r"n_obstacle_obs=-2 must be an integer >= 0"),
        ((3, 2.5), {}, r"n_obstacle_obs=2.5 must be an integer >= 0"),
        ((3.0,), {}, r"n_robots=3.0 must be an integer >= 1"),
        ((3,), {"beams": -3}, r"beams=-3 must be an integer >= 0"),
        ((3,), {"movers": True}, r"movers=True must be an integer >= 0"),
        ((3,), {"formation": 1}, r"formation=1 is not a flag; allowed: true or false"),
        ((3,), {"comm": "yes"}, r"comm='yes' is not a flag"),
    ],
)
def test_bad_observation_layouts_are_refused_by_name(args, kwargs, message) -> None:
    """issue 61: ObservationLayout(0, -2, beams=-3) and ObservationLayout(3, 2.5) were accepted."""
    from koopman_envs.layout import ObservationLayout

    with pytest.raises(ValueError, match=message):
        ObservationLayout(*args, **kwargs)


def test_an_observation_layout_takes_numpy_numbers_as_pythons() -> None:
    from koopman_envs.layout import ObservationLayout

    layout = ObservationLayout(np.int64(3), np.int32(2), np.bool_(True), comm=np.True_)  # type: ignore[arg-type]
    assert layout == ObservationLayout(3, 2, True, comm=True)
    assert type(layout.n_robots) is int and type(layout.formation) is bool


def test_an_unknown_part_to_count_is_named_with_the_parts_that_list_items() -> None:
    from koopman_envs.layout import ObservationLayout

    with pytest.raises(
        ValueError,
        match=r"^part 'heading' is not one of the parts that list items "
        r"\['beams', 'messages', 'movers', 'obstacles', 'team'\]$",
    ):
        ObservationLayout(3).count("heading")
    with pytest.raises(ValueError, match=r"part 'mover' is not one of .* \(did you mean 'movers'\?\)"):
        ObservationLayout(3).count("mover")


def test_a_random_maps_formation_and_spacing_are_checked_each_by_name() -> None:
    """The formation's name is checked as a choice, not recognised by the text of the shape's
    error: a bad spacing whose value reads "is not one of" was blamed on the formation."""
    from koopman_envs.sim.maps.generator_config import RandomMapConfig

    with pytest.raises(ValueError, match=r"formation='star' is not one of \['auto', 'wedge'"):
        RandomMapConfig(formation="star")
    with pytest.raises(ValueError, match=r"^spacing='is not one of' must be a finite number > 0 \[m\]$"):
        RandomMapConfig(formation="wedge", spacing="is not one of")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^spacing=-1.0 must be a finite number > 0 \[m\]$"):
        RandomMapConfig(spacing=-1.0)


def test_overlapping_starts_in_a_map_file(tmp_path) -> None:
    path = tmp_path / "bad.json"
    path.write_text(
        json.dumps(
            {
                "obstacles": [],
                "starts": [[0, 0, 0], [0.3, 0, 0], [3, 3, 0]],
                "targets": [[5, 0, 0], [5, 2, 0], [5, 4, 0]],
            }
        )
    )
    with pytest.raises(ValueError, match="overlapping starts of robots 0 and 1"):
        gym.make(ENV, map=str(path))


def test_start_inside_an_obstacle(tmp_path) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"obstacles": [[0, 0, 1]], "starts": [[0.5, 0, 0]], "targets": [[5, 0, 0]]}))
    with pytest.raises(ValueError, match="start of robot 0 .* overlaps obstacle 0"):
        gym.make(ENV, map=str(path), n_robots=1)


@pytest.mark.parametrize("content", ["{not json", "[1, 2]", '{"obstacles": []}'])
def test_malformed_map_files(tmp_path, content) -> None:
    path = tmp_path / "broken.json"
    path.write_text(content)
    with pytest.raises(ValueError, match="broken"):
        gym.make(ENV, map=str(path))


def test_missing_map_file() -> None:
    with pytest.raises(ValueError, match="cannot be read"):
        gym.make(ENV, map="/no/such/map.json")


@pytest.mark.parametrize("action", [np.zeros(5), np.zeros((2, 3)), np.zeros(7)])
def test_wrong_action_shape(action) -> None:
    env = gym.make(ENV)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action has shape .*; expected \(6,\) or \(3, 2\)"):
        env.unwrapped.step(action)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action(bad) -> None:
    env = gym.make(ENV)
    env.reset(seed=0)
    action = np.zeros(6)
    action[3] = bad
    with pytest.raises(ValueError, match="non-finite value at index"):
        env.unwrapped.step(action)
    # the state is untouched: no silent NaN
    assert np.isfinite(env.unwrapped.engine.poses).all()


def test_bad_parallel_actions() -> None:
    env = formation_v0.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="missing \\['robot_2'\\]"):
        env.step({"robot_0": [0, 0], "robot_1": [0, 0]})
    with pytest.raises(ValueError, match="action of robot_0 has shape"):
        env.step({"robot_0": [0, 0, 0], "robot_1": [0, 0], "robot_2": [0, 0]})
    with pytest.raises(ValueError, match="non-finite"):
        env.step({"robot_0": [np.nan, 0], "robot_1": [0, 0], "robot_2": [0, 0]})


def test_bad_vector_actions() -> None:
    venv = gym.make_vec(ENV, num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"expected \(2, 6\) or \(2, 3, 2\)"):
        venv.step(np.zeros((3, 6)))


BASE_MAP = {
    "obstacles": [],
    "starts": [[0, 0, 0], [0, 1, 0], [0, 2, 0]],
    "targets": [[4, 0, 0], [4, 1, 0], [4, 2, 0]],
}
C = [1, 1, 0.5]  # a valid circle


@pytest.mark.parametrize(
    "zone, message",
    [
        ({"circle": C, "lambda": -0.1}, r"lambda=-0.1 must be a finite number >= 0"),
        ({"circle": C, "lambda": float("nan")}, r"lambda=nan must be a finite number >= 0"),
        ({"circle": C, "lambda": [0.1, -0.2, 0.3]}, r"lambda=\[0.1, -0.2, 0.3\] must be a finite"),
        (
            {"circle": C, "lambda": [0.1, 0.2]},
            r"has 2 values; allowed: one number for every robot or one per robot of the map \(3\)",
        ),
        (
            {"circle": [1, 1, 0.0], "lambda": 0.3},
            r"circle=\[1.0, 1.0, 0.0\] has radius 0; allowed: radius > 0",
        ),
        ({"circle": [1, 1, -2], "lambda": 0.3}, r"has radius -2; allowed: radius > 0"),
        ({"circle": [1, 1], "lambda": 0.3}, r"circle=\[1, 1\] must be 3 finite numbers \[x, y, radius\]"),
        (
            {"rect": [2, 0, 1, 1], "lambda": 0.3},
            r"rect=\[2.0, 0.0, 1.0, 1.0\] is empty; allowed: .*xmin < xmax",
        ),
        ({"rect": [0, 1, 1, 1], "lambda": 0.3}, r"is empty; allowed: .* ymin < ymax"),
        (
            {"circle": C, "lambda": 0.3, "mode": "multiply"},
            r"mode='multiply' is not one of \['replace', 'add'\]",
        ),
        (
            {"disc": C, "lambda": 0.3},
            r"unknown keys \['disc'\]; allowed: \['circle', 'rect', 'lambda', 'mode', 'surface'\]",
        ),
        ({"lambda": 0.3}, r"must have exactly one shape key, 'circle': \[x, y, radius\] or 'rect'"),
        ({"circle": C, "rect": [0, 0, 1, 1], "lambda": 0.3}, r"must have exactly one shape key"),
        ({"circle": C}, r"has no 'lambda'"),
        ("ice", r"'ice' must be an object"),
    ],
)
def test_bad_slip_zones_in_a_map_file(tmp_path, zone, message) -> None:
    path = tmp_path / "zoned.json"
    path.write_text(json.dumps({**BASE_MAP, "slip_zones": [zone]}))
    with pytest.raises(ValueError, match=r"map 'zoned': slip zone 0: .*" + message):
        gym.make(ENV, map=str(path))
    with pytest.raises(ValueError, match=message):
        gym.make_vec(ENV, num_envs=2, map=str(path))


@pytest.mark.parametrize(
    "slip, message",
    [
        (
            [(0.5, "low"), (1.0, "high")],
            r"slip schedule entry 0: time=0.5; the schedule must start at time 0",
        ),
        (
            [(0.0, "low"), (2.0, "high"), (2.0, "nominal")],
            r"entry 2: time=2.0 is not after the previous entry's 2.0; allowed: strictly increasing times",
        ),
        ([(0.0, "low"), (3.0, "high"), (1.0, "nominal")], r"entry 2: time=1.0 is not after"),
        (
            [(0.0, [0.1, 0.2])],
            r"entry 0 at time 0.0: slip=\[0.1, 0.2\] has 2 values; expected one lambda per robot",
        ),
        (
            [(0.0, "low"), (1.0, [0.1, -0.2, 0.0])],
            r"entry 1 at time 1.0: .* negative lambda; allowed: lambda >= 0",
        ),
        ([(0.0, "low"), (float("nan"), "high")], r"entry 1: time=nan must be a finite number of seconds"),
        ([(0.0, "low", 3)], r"entry 0 \(0.0, 'low', 3\) is not a \(time \[s\], lambdas\) pair"),
        ([(0.0, "icy")], r"entry 0 at time 0.0: slip='icy' is not one of"),
        ("drifting", r"slip='drifting' is not one of \['nominal', 'low', 'high'\] .*'drift'"),
    ],
)
def test_bad_slip_schedules(slip, message) -> None:
    for make in (lambda: gym.make(ENV, slip=slip), lambda: formation_v0.parallel_env(slip=slip)):
        with pytest.raises(ValueError, match=message):
            make()


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"n_slip_zones": -1}, r"n_slip_zones=-1 must be an integer >= 0"),
        ({"n_slip_zones": 1.5}, r"n_slip_zones=1.5 must be an integer >= 0"),
        (
            {"slip_zone_radius": (0.0, 1.0)},
            r"slip_zone_radius=\(0.0, 1.0\) must be a finite \(low, high\) pair with low > 0",
        ),
        ({"slip_zone_radius": (2.0, 1.0)}, r"slip_zone_radius=\(2.0, 1.0\) .* and low <= high"),
        (
            {"slip_zone_lambda": (-0.1, 0.3)},
            r"slip_zone_lambda=\(-0.1, 0.3\) must be a finite \(low, high\) pair with low >= 0",
        ),
        ({"slip_zone_lambda": 0.3}, r"slip_zone_lambda=0.3 must be a \(low, high\) pair of numbers"),
        ({"slip_zone_mode": "max"}, r"slip_zone_mode='max' is not one of \['replace', 'add'\]"),
    ],
)
def test_bad_random_zone_settings(settings, message) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, map="random", random_map=settings)


def test_unknown_keyword_error_carries_pythons_phrase() -> None:
    """Wrappers such as TorchRL's GymEnv drop a keyword (frameskip) when the error says so."""
    import gymnasium as gym

    with pytest.raises(TypeError) as info:
        gym.make("KoopNav-Formation-v0", frameskip=1)
    assert "unexpected keyword argument 'frameskip'" in str(info.value)


def test_misspelt_controller_and_map_names_get_a_suggestion() -> None:
    import gymnasium as gym

    import controllers

    with pytest.raises(
        ValueError, match=r"controller 'koopman-nmcp' is not one of .* \(did you mean 'koopman-nmpc'\?\)"
    ):
        controllers.make("koopman-nmcp")
    with pytest.raises(ValueError, match=r"map='mpa3' is not one of .* \(did you mean 'map3'\?\)"):
        gym.make("KoopNav-Formation-v0", map="mpa3")


def test_a_map_file_with_an_unknown_key_is_refused_by_name(tmp_path) -> None:
    """Issue 31: unknown keys of a map JSON were ignored (a typo lost the obstacles silently)."""
    path = tmp_path / "mine.json"
    path.write_text(
        json.dumps(
            {"obstacle": [[1, 1, 0.3]], "obstacles": [], "starts": [[0, 0, 0]], "targets": [[1, 0, 0]]}
        )
    )
    with pytest.raises(
        ValueError, match=r"map 'mine': unknown keys \['obstacle'\].*did you mean 'obstacles'"
    ):
        gym.make(ENV, map=str(path), n_robots=1)


# ------------------------------------------------------------------ issue 41, item 9: the messages
def test_fast_movers_are_refused_naming_the_speed() -> None:
    """``movers=dict(count=2, speed=100.0)`` said "no free place for mover 1 ... use fewer or
    smaller movers": the cause was the speed (movers keep speed x 1 s from every start and
    target). The speed is bounded now, and a placement that fails only for the speed names it."""
    from koopman_envs.params import LIMITS

    with pytest.raises(
        ValueError, match=rf"movers.speed=100.0 must be a finite number >= 0 <= {LIMITS.mover_speed}"
    ):
        gym.make(ENV, movers=dict(count=2, speed=100.0))
    env = gym.make(ENV, movers=dict(count=30, speed=2.0))  # 30 fit map1 at 0.5 m/s, 21 at 2 m/s
    with pytest.raises(
        ValueError,
        match=r"movers: no free place for mover \d+ of 30 .* movers.speed=2.0 m/s keeps them 2.2 m "
        r"\(robot radius 0.2 m \+ speed x 1 s\) from every start and target; at movers.speed <= 0.5 "
        r"they fit: use a lower speed",
    ):
        env.reset(seed=0)
    gym.make(ENV, movers=dict(count=30, speed=0.5)).reset(seed=0)  # the same movers, slower: placed
    with pytest.raises(ValueError, match=r"no free place for mover .* use fewer or smaller movers"):
        gym.make(ENV, movers=dict(count=400, radius=0.5)).reset(seed=0)  # not the speed: not named


#: numpy scalars, as every numpy user passes them, and the Python number they stand for
NUMPY_SCALARS = [
    ("movers", np.int64(3), 3),
    ("movers", {"count": np.int32(2), "speed": np.float32(0.25), "aware": np.True_, "behaviour": "crowd"},
     {"count": 2, "speed": float(np.float32(0.25)), "aware": True, "behaviour": "crowd"}),
    ("pose_noise", np.float32(0.1), float(np.float32(0.1))),
    ("pose_noise", {"xy": np.float64(0.05), "heading": np.float16(0.01)}, {"xy": 0.05, "heading": float(np.float16(0.01))}),
    ("comm", {"latency": np.int16(2), "drop": np.float32(0.5), "range": np.float32(np.inf)}, {"latency": 2, "drop": 0.5, "range": float("inf")}),
    ("comm", {"range": np.float64(4.0)}, {"range": 4.0}),
    ("n_robots", np.int64(2), 2),
    ("goal_tolerance", np.float32(0.2), float(np.float32(0.2))),
    ("start_noise", np.float64(0.05), 0.05),
    ("n_obstacle_obs", np.uint8(2), 2),
    ("actuation_delay", np.int64(1), 1),
    ("slip", [np.float32(0.0), np.float64(0.1), np.int64(0)], [0.0, 0.1, 0]),
    ("max_episode_steps", np.int32(50), 50),
]  # fmt: skip


@pytest.mark.parametrize(
    "name, value, python", NUMPY_SCALARS, ids=[f"{n}-{i}" for i, (n, *_) in enumerate(NUMPY_SCALARS)]
)
def test_numpy_scalars_are_taken_wherever_a_python_number_is(
    name: str, value: object, python: object
) -> None:
    """``movers=np.int64(3)`` and ``pose_noise=np.float32(0.1)`` were refused; a numpy scalar now
    gives the env of the Python number, step for step."""
    from koopman_envs.fronts.gym_env import TargetReachingEnv

    if isinstance(python, dict) and python.get("behaviour") == "crowd":
        pytest.importorskip("pyrvo", reason="the ORCA crowd needs the [crowd] extra")
    runs = []
    for given in (value, python):
        env = TargetReachingEnv(**{name: given})
        observations = [env.reset(seed=3)[0]]
        observations += [env.step(np.full(env.action_space.shape, 0.2))[0] for _ in range(5)]
        runs.append(np.array(observations))
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"map": "random", "random_map": {"spacing": np.float32(0.8), "gap": np.float32(0.5), "clearance": np.float64(0.3),
                                          "border": np.int64(1), "swap_targets": np.float32(0.5), "n_obstacles": np.int8(3),
                                          "travel": (np.float32(3), np.int64(5)), "obstacle_along": (np.float32(0.2), np.float64(0.7))}}, None),
        ({"sensing": "lidar", "lidar": {"beams": np.int32(16), "fov": np.float32(3.0), "range": np.float16(4.0),
                                         "noise": np.float64(0.01), "dropout": np.float32(0.1)}}, None),
    ],
)  # fmt: skip
def test_numpy_scalars_in_the_settings_dicts(kwargs: dict, message: str | None) -> None:
    from koopman_envs.fronts.gym_env import TargetReachingEnv

    env = TargetReachingEnv(**kwargs)
    env.reset(seed=0)
    assert np.isfinite(env.step(np.zeros(6))[0]).all()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"uncertainty": "HARSH"}, r"uncertainty='HARSH' is not one of \['nominal', 'realistic', 'harsh'\] \(did you mean 'harsh'\?\)"),
        ({"uncertainty": "Realistic"}, r"\(did you mean 'realistic'\?\)"),
        ({"sensing": "LIDAR"}, r"sensing='LIDAR' is not one of \['state', 'lidar'\] \(did you mean 'lidar'\?\)"),
        ({"movers": {"count": 2, "behaviour": "Crowd"}}, r"movers.behaviour='Crowd' is not one of .*\(did you mean 'crowd'\?\)"),
        ({"map": "MAP3"}, r"map='MAP3' is not one of .*\(did you mean 'map3'\?\)"),
        ({"slip": "HIGH"}, r"slip='HIGH' is not one of .*\(did you mean 'high'\?\)"),
        ({"formation": "Wedge", "map": "random"}, r"formation='Wedge' is not one of .*\(did you mean 'wedge'\?\)"),
        ({"map": "random", "random_map": {"slip_zone_mode": "ADD"}}, r"slip_zone_mode='ADD' is not one of .*\(did you mean 'add'\?\)"),
        ({"comm": {"Latency": 2}}, r"comm has unknown field 'Latency' \(did you mean 'latency'\?\)"),
    ],
)  # fmt: skip
def test_a_name_in_another_case_gets_a_did_you_mean(kwargs: dict, message: str) -> None:
    """``uncertainty='HARSH'`` got no suggestion: difflib's ratio is case-sensitive."""
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, **kwargs)


def test_the_suggestion_helper_prefers_the_same_name_in_another_case() -> None:
    from koopman_envs.checks import closest, did_you_mean

    assert closest("HARSH", ["nominal", "realistic", "harsh"]) == "harsh"
    assert closest("MaP3", ["map1", "map3", "Map3x"]) == "map3"
    assert closest("realstic", ["nominal", "realistic"]) == "realistic"  # the old matches stay
    assert closest("zzz", ["nominal"]) is None and closest(3, ["nominal"]) is None
    assert did_you_mean("CROWDS", ["constant", "crowd"]) == " (did you mean 'crowd'?)"


@pytest.mark.parametrize(
    "call, message",
    [
        ((("slip", "icy", ["low", "high"]), {}), "slip='icy' is not one of ['low', 'high']"),
        (
            (("slip", "hihg", ["low", "high"], " or lambdas"), {}),
            "slip='hihg' is not one of ['low', 'high'] or lambdas (did you mean 'high'?)",
        ),
        (
            (("--reference", "kn", ["a", "b"]), {"sep": " ", "among": "the run's controllers"}),
            "--reference 'kn' is not one of the run's controllers ['a', 'b']",
        ),
        (
            (("slip", "drft", ["low"]), {"suggest": ["low", "drift"]}),
            "slip='drft' is not one of ['low'] (did you mean 'drift'?)",
        ),
        ((("code", True, [0, 1]), {}), "code=True is not one of [0, 1]"),  # a bool is no number here
    ],
)
def test_check_choice_is_the_one_wording(call: tuple, message: str) -> None:
    """``check_choice`` (and ``choice_message``, its text) words every choice check alike: the
    name, its separator, the value's repr, what the set is, the list, ``also``, a did-you-mean."""
    from koopman_envs.checks import check_choice, choice_message

    args, options = call
    assert choice_message(*args, **options) == message
    with pytest.raises(ValueError) as refused:
        check_choice(*args, **options)
    assert str(refused.value) == message
    assert check_choice(args[0], args[2][0], *args[2:], **options) == args[2][0]


def test_no_choice_message_is_worded_inline() -> None:
    """Issue 61: every "is not one of" message of the packages comes from ``choice_message``; a
    string with the phrase anywhere else (a docstring aside) is a second wording. The one left is
    a run log's reason for a record, which lists no allowed set (a run's episodes)."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    # a run log's reason (no allowed set to list)
    allowed = {" is not one of this run's episodes"}
    found = []
    for path in [
        root / "evaluate.py",
        *(
            p
            for d in ("koopman_envs", "controllers", "baselines", "evaluation")
            for p in (root / d).rglob("*.py")
        ),
    ]:
        name = path.relative_to(root).as_posix()
        if name == "koopman_envs/checks.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        docstrings = {
            id(node.body[0].value)
            for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and node.body
            and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)
        }
        found += [
            f"{name}:{node.lineno}"
            for node in ast.walk(tree)
            if isinstance(node, ast.Constant)
            and isinstance(node.value, str)
            and id(node) not in docstrings
            and node.value not in allowed
            and ("is not one of" in node.value or "must be one of" in node.value)
        ]
    assert found == [], found
