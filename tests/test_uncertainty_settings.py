"""The uncertainty settings (koopman_envs/settings/uncertainty.py) field by field at their bounds (issue 41,
mutation testing): what each dataclass accepts, the normal form it stores (0 and 0.0, NumPy and
Python numbers are one setting), what it refuses with the field's name, and how ``parse_setting``
reads an instance, a dict merged over a preset, one number, or None.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from koopman_envs.checks import MAX_NUMBER
from koopman_envs.params import LIMITS
from koopman_envs.settings.uncertainty import MIN_LIDAR_FOV, CommConfig, LidarConfig, PoseNoise, parse_setting

POSE_FIELDS = ["xy", "heading", "drift_xy", "drift_heading"]


def _refused(make, prefix: str) -> None:
    with pytest.raises(ValueError) as caught:
        make()
    assert str(caught.value).startswith(prefix), str(caught.value)


# ------------------------------------------------------------------------------- pose noise
@pytest.mark.parametrize("field", POSE_FIELDS)
def test_each_pose_noise_field_is_a_number_of_at_least_zero_stored_as_float(field) -> None:
    assert getattr(PoseNoise(**{field: 0}), field) == 0.0
    assert type(getattr(PoseNoise(**{field: 0}), field)) is float
    value = PoseNoise(**{field: np.float32(0.25)})
    assert getattr(value, field) == 0.25 and type(getattr(value, field)) is float
    assert PoseNoise(**{field: 2}) == PoseNoise(**{field: 2.0})
    for bad in (-0.01, math.nan, math.inf, True, "0.1", None):
        _refused(
            lambda bad=bad: PoseNoise(**{field: bad}),
            f"pose_noise.{field}={bad!r} must be a finite number >= 0",
        )
    others = [f for f in POSE_FIELDS if f != field]
    assert all(getattr(value, f) == 0.0 for f in others)


def test_pose_noise_is_active_when_any_field_is_positive() -> None:
    assert not PoseNoise().active
    assert [PoseNoise(**{f: 1e-9}).active for f in POSE_FIELDS] == [True] * 4


# ------------------------------------------------------------------------------------ lidar
def test_lidar_defaults_and_normal_form() -> None:
    lidar = LidarConfig()
    assert (lidar.beams, lidar.fov, lidar.range, lidar.noise, lidar.dropout) == (
        32,
        2 * math.pi,
        5.0,
        0.0,
        0.0,
    )
    same = LidarConfig(beams=np.int64(32), fov=2 * math.pi, range=5, noise=0, dropout=np.float64(0))
    assert same == lidar and hash(same) == hash(lidar)
    assert type(same.beams) is int and all(
        type(getattr(same, f)) is float for f in ("fov", "range", "noise", "dropout")
    )
    assert not lidar.random and LidarConfig(noise=0.01).random and LidarConfig(dropout=0.01).random


@pytest.mark.parametrize(
    ("kwargs", "prefix"),
    [
        ({"beams": 0}, f"lidar.beams=0 must be an integer >= 1 and <= {LIMITS.lidar_beams}"),
        ({"beams": LIMITS.lidar_beams + 1}, f"lidar.beams={LIMITS.lidar_beams + 1} must be an integer >= 1"),
        ({"beams": 8.0}, "lidar.beams=8.0 must be an integer"),
        ({"beams": True}, "lidar.beams=True must be an integer"),
        ({"fov": 0.0}, "lidar.fov=0.0 must be a finite number > 0"),
        ({"fov": -1.0}, "lidar.fov=-1.0 must be a finite number > 0"),
        ({"fov": 2 * math.pi + 1e-9}, f"lidar.fov={2 * math.pi + 1e-9!r} must be a finite number > 0"),
        ({"range": 0}, "lidar.range=0 must be a finite number > 0"),
        (
            {"range": LIMITS.lidar_range + 0.5},
            f"lidar.range={LIMITS.lidar_range + 0.5!r} must be a finite number > 0",
        ),
        ({"range": math.inf}, "lidar.range=inf must be a finite number > 0"),
        ({"noise": -0.1}, "lidar.noise=-0.1 must be a finite number >= 0"),
        ({"dropout": -0.1}, "lidar.dropout=-0.1 must be a finite number >= 0 <= 1"),
        ({"dropout": 1.01}, "lidar.dropout=1.01 must be a finite number >= 0 <= 1"),
    ],
)
def test_lidar_settings_out_of_range_are_refused_by_name(kwargs, prefix) -> None:
    _refused(lambda: LidarConfig(**kwargs), prefix)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"fov": 0.0}, f"lidar.fov=0.0 must be a finite number > 0 <= {2 * math.pi} ((0, 2 pi] rad)"),
        ({"fov": 7.0}, f"lidar.fov=7.0 must be a finite number > 0 <= {2 * math.pi} ((0, 2 pi] rad)"),
        ({"range": 0}, f"lidar.range=0 must be a finite number > 0 <= {float(LIMITS.lidar_range)} (metres)"),
        (
            {"range": 101},
            f"lidar.range=101 must be a finite number > 0 <= {float(LIMITS.lidar_range)} (metres)",
        ),
        (
            {"fov": MIN_LIDAR_FOV * 0.99},
            f"lidar.fov={MIN_LIDAR_FOV * 0.99!r} is narrower than 0.001 rad; allowed: [0.001, 2 pi] rad",
        ),
    ],
)
def test_the_lidar_field_of_view_and_range_messages_state_the_unit(kwargs, message) -> None:
    with pytest.raises(ValueError) as caught:
        LidarConfig(**kwargs)
    assert str(caught.value) == message


def test_the_narrowest_field_of_view_is_a_milliradian() -> None:
    assert MIN_LIDAR_FOV == 1e-3
    assert LidarConfig(fov=MIN_LIDAR_FOV).fov == MIN_LIDAR_FOV  # the bound itself is allowed


def test_pose_noise_is_bounded_by_the_workspace_side() -> None:
    bound = LIMITS.pose_noise
    for field in POSE_FIELDS:
        assert getattr(PoseNoise(**{field: bound}), field) == bound
        with pytest.raises(ValueError) as caught:
            PoseNoise(**{field: bound * 1.5})
        assert (
            str(caught.value) == f"pose_noise.{field}={bound * 1.5!r} must be a finite number >= 0 <= {bound}"
        )
    # one number names the keyword itself
    assert parse_setting("pose_noise", bound, PoseNoise) == PoseNoise(xy=bound)
    with pytest.raises(ValueError) as caught:
        parse_setting("pose_noise", bound * 2, PoseNoise)
    assert str(caught.value) == f"pose_noise={bound * 2!r} must be a finite number >= 0 <= {bound}"


def test_lidar_settings_at_their_bounds_are_accepted() -> None:
    edge = LidarConfig(beams=LIMITS.lidar_beams, fov=2 * math.pi, range=LIMITS.lidar_range, dropout=1)
    assert (edge.beams, edge.range, edge.dropout) == (LIMITS.lidar_beams, float(LIMITS.lidar_range), 1.0)
    one = LidarConfig(beams=1, fov=0.5, range=0.01, noise=3, dropout=0)
    assert (one.beams, one.fov, one.range, one.noise, one.dropout) == (1, 0.5, 0.01, 3.0, 0.0)


# ------------------------------------------------------------------------------------ radio
def test_comm_defaults_are_perfect_and_stored_in_normal_form() -> None:
    comm = CommConfig()
    assert (comm.latency, comm.drop, comm.range) == (0, 0.0, math.inf) and comm.perfect
    same = CommConfig(latency=np.int64(0), drop=0, range=np.float32(np.inf))
    assert same == comm and hash(same) == hash(comm)
    assert type(same.latency) is int and type(same.drop) is float and type(same.range) is float
    assert CommConfig(range=np.float64(np.inf)).range is math.inf
    assert not CommConfig(latency=1).perfect and not CommConfig(drop=0.1).perfect
    assert not CommConfig(range=10).perfect


def test_comm_settings_at_their_bounds_are_accepted() -> None:
    comm = CommConfig(latency=LIMITS.latency, drop=1, range=1e-6)
    assert (comm.latency, comm.drop, comm.range) == (LIMITS.latency, 1.0, 1e-6)
    assert type(CommConfig(range=5).range) is float and CommConfig(range=5).range == 5.0
    assert CommConfig(latency=np.int32(3)).latency == 3


@pytest.mark.parametrize(
    ("kwargs", "prefix"),
    [
        (
            {"latency": -1},
            f"comm.latency=-1 must be an integer >= 0 and <= {LIMITS.latency} (control periods)",
        ),
        ({"latency": LIMITS.latency + 1}, f"comm.latency={LIMITS.latency + 1} must be an integer >= 0"),
        ({"latency": 1.0}, "comm.latency=1.0 must be an integer"),
        ({"drop": -0.1}, "comm.drop=-0.1 must be a finite number >= 0 <= 1"),
        ({"drop": 1.5}, "comm.drop=1.5 must be a finite number >= 0 <= 1"),
        ({"drop": math.nan}, "comm.drop=nan must be a finite number"),
        ({"range": 0}, f"comm.range=0 must be a finite number > 0 <= {MAX_NUMBER} (metres, or inf)"),
        (
            {"range": -math.inf},
            f"comm.range=-inf must be a finite number > 0 <= {MAX_NUMBER} (metres, or inf)",
        ),
        ({"range": True}, f"comm.range=True must be a finite number > 0 <= {MAX_NUMBER} (metres, or inf)"),
        ({"range": "inf"}, f"comm.range='inf' must be a finite number > 0 <= {MAX_NUMBER} (metres, or inf)"),
        ({"range": None}, f"comm.range=None must be a finite number > 0 <= {MAX_NUMBER} (metres, or inf)"),
    ],
)
def test_comm_settings_out_of_range_are_refused_by_name(kwargs, prefix) -> None:
    _refused(lambda: CommConfig(**kwargs), prefix)


# ---------------------------------------------------------------------------- parse_setting
def test_none_is_the_base_or_the_perfect_default_and_an_instance_is_taken_as_it_is() -> None:
    base = CommConfig(latency=2)
    assert parse_setting("comm", None, CommConfig) == CommConfig()
    assert parse_setting("comm", None, CommConfig, base) is base
    given = CommConfig(drop=0.5)
    assert parse_setting("comm", given, CommConfig, base) is given


def test_a_dict_is_merged_over_the_base() -> None:
    base = CommConfig(latency=2, drop=0.1, range=5.0)
    assert parse_setting("comm", {"drop": 0.3}, CommConfig, base) == CommConfig(
        latency=2, drop=0.3, range=5.0
    )
    assert parse_setting("comm", {"drop": 0.3}, CommConfig) == CommConfig(drop=0.3)
    assert parse_setting("comm", {}, CommConfig, base) == base
    lidar = parse_setting("lidar", {"beams": 8}, LidarConfig, LidarConfig(noise=0.02))
    assert lidar == LidarConfig(beams=8, noise=0.02)
    _refused(
        lambda: parse_setting("comm", {"drop": 2}, CommConfig, base), "comm.drop=2 must be a finite number"
    )


def test_one_number_is_the_pose_noise_std_of_x_and_y() -> None:
    assert parse_setting("pose_noise", 0.05, PoseNoise) == PoseNoise(xy=0.05)
    assert parse_setting("pose_noise", np.float64(0.05), PoseNoise, PoseNoise(heading=1.0)) == PoseNoise(
        xy=0.05
    )
    assert parse_setting("pose_noise", 0, PoseNoise) == PoseNoise()
    _refused(
        lambda: parse_setting("pose_noise", -0.1, PoseNoise), "pose_noise=-0.1 must be a finite number >= 0"
    )


@pytest.mark.parametrize(
    ("name", "value", "kind", "message"),
    [
        (
            "pose_noise",
            True,
            PoseNoise,
            "pose_noise=True must be a dict of ['xy', 'heading', 'drift_xy', 'drift_heading'], a PoseNoise or "
            "one number (the x and y std [m]), or None",
        ),
        (
            "pose_noise",
            "0.1",
            PoseNoise,
            "pose_noise='0.1' must be a dict of ['xy', 'heading', 'drift_xy', 'drift_heading'], a PoseNoise or "
            "one number (the x and y std [m]), or None",
        ),
        (
            "comm",
            3,
            CommConfig,
            "comm=3 must be a dict of ['latency', 'drop', 'range'], a CommConfig, or None",
        ),
        (
            "lidar",
            [8],
            LidarConfig,
            "lidar=[8] must be a dict of ['beams', 'fov', 'range', 'noise', 'dropout', 'map_known'], a LidarConfig, or None",
        ),
        (
            "comm",
            {"dorp": 0.1},
            CommConfig,
            "comm has unknown field 'dorp' (did you mean 'drop'?); allowed: ['latency', 'drop', 'range']",
        ),
        (
            "comm",
            {"drop": 0.1, "zzz": 1, "yyy": 2},
            CommConfig,
            "comm has unknown field 'zzz'; allowed: ['latency', 'drop', 'range']",
        ),
        (
            "pose_noise",
            {"heding": 0.1},
            PoseNoise,
            "pose_noise has unknown field 'heding' (did you mean 'heading'?); allowed: "
            "['xy', 'heading', 'drift_xy', 'drift_heading']",
        ),
    ],
)
def test_other_values_are_refused_naming_what_is_allowed(name, value, kind, message) -> None:
    with pytest.raises(ValueError) as caught:
        parse_setting(name, value, kind, kind())
    assert str(caught.value) == message


def test_the_settings_are_frozen() -> None:
    for setting in (PoseNoise(), LidarConfig(), CommConfig()):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setting.range = 1.0  # type: ignore[misc]
