"""koopman_envs.Observed.from_info field by field and value by value (issue 41, mutation testing;
issue 61: the typed contract): which keys pass, which never do, the aliases a controller of the
earlier API reads, and the perfect-information view of a hand-written info, each compared exactly.

tests/test_observed_view.py shows that no controller's action changes with a poisoned truth;
these pin the value itself, so that a key let through or an alias computed from the wrong pose
fails here directly.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from koopman_envs import Observed
from koopman_envs.observed import DERIVED_KEYS, OBSERVED_KEYS, SENSED_KEYS, observed_view

#: fields of an env's info that hold the truth (or the env's bookkeeping): never in the view
TRUTH = {
    "poses": np.full((2, 3), np.nan),
    "distances": np.full(2, np.nan),
    "collision": np.array([True, False]),
    "movers": np.full((1, 4), np.nan),
    "slip": np.full(2, np.nan),
    "success": True,
}
#: the field no info key fills: whether the perception ran (read from ``mover_radii``)
STAGE_FIELDS = ("perceived",)


def test_the_observed_keys_are_the_beliefs_the_targets_and_the_tracked_movers() -> None:
    assert OBSERVED_KEYS == (
        "observed_poses",
        "known_poses",
        "message_age",
        "lidar_ranges",
        "targets",
        "observed_movers",
        "mover_tracked",
        "pose_covariance",
        "mover_covariance",
        "mover_radii",
        "perceived_obstacles",
        "obstacle_covariance",
        "pose_age",
    )
    # every observed key is a field of the typed value, and every field is a key or a stage's
    fields = {f.name for f in dataclasses.fields(Observed)}
    assert fields == {*OBSERVED_KEYS, *STAGE_FIELDS}
    assert set(SENSED_KEYS) | set(DERIVED_KEYS) == set(OBSERVED_KEYS)


def test_an_env_info_passes_its_observed_keys_as_they_are_and_aliases_the_estimates() -> None:
    observed = np.array([[0.0, 0.0, 0.1], [1.0, 2.0, -0.2]])
    beliefs = {
        "observed_poses": observed,
        "known_poses": np.arange(12.0).reshape(2, 2, 3),
        "message_age": np.array([[0, 3], [-1, 0]]),
        "lidar_ranges": np.ones((2, 8)),
        "targets": np.array([[3.0, 4.0, 0.0], [-5.0, 14.0, 1.0]]),
        "observed_movers": np.zeros((1, 4)),
        "mover_tracked": np.ones(1, dtype=bool),
        "pose_covariance": np.tile(np.eye(3), (2, 1, 1)),  # what an estimator in front hands on
    }
    view = Observed.from_info({**TRUTH, **beliefs})
    for key, value in beliefs.items():
        assert getattr(view, key) is value  # passed as they are, not copied or converted
    for key in ("mover_covariance", "mover_radii", "perceived_obstacles", "obstacle_covariance", "pose_age"):
        assert getattr(view, key) is None
    assert view.perceived is False and view.n_robots == 2
    np.testing.assert_array_equal(view.poses, observed, strict=True)
    # from the estimates to the targets: (3, 4) -> 5 and (-6, 12) -> sqrt(180)
    np.testing.assert_array_equal(view.distances, np.array([5.0, np.sqrt(180.0)]), strict=True)
    # the dict of the earlier API: the keys set, in order, then the aliases
    assert list(view.to_info()) == [*OBSERVED_KEYS[:8], "poses", "distances"]


def test_a_partial_info_passes_only_what_it_has() -> None:
    view = Observed.from_info({"observed_poses": [[1, 2, 3]], "lidar_ranges": [[2.0]], "collision": [True]})
    np.testing.assert_array_equal(view.observed_poses, np.array([[1.0, 2.0, 3.0]]), strict=True)
    np.testing.assert_array_equal(view.lidar_ranges, np.array([[2.0]]), strict=True)
    assert view.targets is None and view.distances is None  # no targets: no distances
    assert list(view.to_info()) == ["observed_poses", "known_poses", "message_age", "lidar_ranges", "poses"]
    with pytest.raises(
        ValueError, match=r"needs 'observed_poses'.*'poses'; this one has \['slip', 'targets'\]"
    ):
        Observed.from_info({"targets": [[1.0, 1.0, 0.0]], "slip": 1})
    with pytest.raises(ValueError, match=r"this one has \[\]"):
        Observed.from_info({})
    assert Observed.from_info({"poses": np.zeros((0, 3))}).message_age.shape == (0, 0)  # no robots


def test_poses_messages_and_ages_of_the_wrong_shape_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"observed_poses has shape \(3, 2\); expected \(N, 3\)"):
        Observed.from_info({"observed_poses": np.zeros((3, 2))})
    with pytest.raises(
        ValueError, match=r"known_poses has shape \(3, 3\); expected \(3, 3, 3\) for 3 robots"
    ):
        Observed.from_info({"observed_poses": np.zeros((3, 3)), "known_poses": np.zeros((3, 3))})
    with pytest.raises(ValueError, match=r"message_age has shape \(2, 2\); expected \(3, 3\) for 3 robots"):
        Observed.from_info({"poses": np.zeros((3, 3)), "message_age": np.zeros((2, 2))})


def _team(n: int = 3) -> dict:
    """The three fields every Observed has, for ``n`` robots, of the right dtypes."""
    return {
        "observed_poses": np.zeros((n, 3)),
        "known_poses": np.zeros((n, n, 3)),
        "message_age": np.zeros((n, n), dtype=np.int64),
    }


@pytest.mark.parametrize(
    ("fields", "error", "message"),
    [
        (
            {"observed_poses": np.zeros((3, 2))},
            ValueError,
            r"observed_poses has shape \(3, 2\); expected \(N, 3\)",
        ),
        (
            {"observed_poses": [[0.0, 0.0, 0.0]] * 3},
            TypeError,
            r"observed_poses is a list; expected an ndarray",
        ),
        (
            {"known_poses": np.zeros((3, 3, 2))},
            ValueError,
            r"known_poses has shape \(3, 3, 2\); expected \(3, 3, 3\)",
        ),
        ({"message_age": np.zeros((3, 3))}, TypeError, r"message_age has dtype float64; expected int64"),
        (
            {"targets": np.zeros((2, 3))},
            ValueError,
            r"targets has shape \(2, 3\); expected \(3, 3\) for 3 robots",
        ),
        ({"lidar_ranges": np.ones(3)}, ValueError, r"lidar_ranges has shape \(3,\); expected \(3, \*\)"),
        (
            {"observed_movers": np.zeros((2, 3))},
            ValueError,
            r"observed_movers has shape \(2, 3\); expected \(\*, 4\)",
        ),
        ({"mover_tracked": np.ones(2)}, TypeError, r"mover_tracked has dtype float64; expected bool"),
        (
            {"pose_age": np.zeros(2, dtype=np.int64)},
            ValueError,
            r"pose_age has shape \(2,\); expected \(3,\)",
        ),
        ({"pose_age": np.zeros(3, dtype=np.int32)}, TypeError, r"pose_age has dtype int32; expected int64"),
        (
            {"pose_covariance": np.zeros((3, 3))},
            ValueError,
            r"pose_covariance has shape \(3, 3\); expected \(3, 3, 3\)",
        ),
        (
            {"mover_covariance": np.zeros((2, 4, 4), dtype=np.float32)},
            TypeError,
            r"mover_covariance has dtype float32",
        ),
        ({"mover_radii": np.zeros((2, 1))}, ValueError, r"mover_radii has shape \(2, 1\); expected \(\*,\)"),
        ({"perceived_obstacles": np.zeros((4, 2))}, ValueError, r"perceived_obstacles has shape \(4, 2\)"),
        ({"obstacle_covariance": np.zeros((4, 2))}, ValueError, r"obstacle_covariance has shape \(4, 2\)"),
        ({"perceived": 1}, TypeError, r"perceived=1; expected True or False"),
    ],
)
def test_a_value_built_directly_is_held_to_the_same_shapes_and_dtypes(fields, error, message) -> None:
    """The one check of Observed.__post_init__, whether the value came from from_info, from the
    constructor or from a stage's dataclasses.replace."""
    with pytest.raises(error, match=message):
        Observed(**{**_team(), **fields})
    with pytest.raises(error, match=message):
        dataclasses.replace(Observed(**_team()), **fields)


def test_the_radios_pose_age_round_trips_through_the_dict_as_int64() -> None:
    observed = Observed(**_team(), pose_age=np.array([0, 2, -1], dtype=np.int64))
    info = observed.to_info()
    assert list(info)[:4] == ["observed_poses", "known_poses", "message_age", "pose_age"]
    back = Observed.from_info(info)
    assert back.pose_age is observed.pose_age  # an int64 array passes as it is
    # as an info written by hand, or read back from JSON: whole numbers become int64 ages
    read = Observed.from_info({**info, "pose_age": [0.0, 2.0, -1.0]})
    np.testing.assert_array_equal(read.pose_age, np.array([0, 2, -1], dtype=np.int64), strict=True)
    with pytest.raises(ValueError, match=r"pose_age\[1\]=nan is not a whole number of periods"):
        Observed.from_info({**info, "pose_age": [0.0, np.nan, -1.0]})


def test_a_hand_written_info_of_poses_is_one_of_perfect_information() -> None:
    poses = [[0, 0, 0], [3, -4, 1], [1, 1, 2]]  # integers: converted to float
    targets = [[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
    view = Observed.from_info({"poses": poses, "targets": targets, "collision": [False] * 3})
    expected = np.array(poses, dtype=np.float64)
    np.testing.assert_array_equal(view.observed_poses, expected, strict=True)
    np.testing.assert_array_equal(view.poses, expected, strict=True)
    # every robot hears every team-mate at once: each row of known_poses is the team, of age 0
    np.testing.assert_array_equal(view.known_poses, np.stack([expected] * 3), strict=True)
    np.testing.assert_array_equal(view.message_age, np.zeros((3, 3), dtype=np.int64), strict=True)
    np.testing.assert_array_equal(view.distances, np.array([5.0, 5.0, 0.0]), strict=True)


def test_given_messages_are_kept_beside_hand_written_poses() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    known = np.full((2, 2, 3), 7.0)
    age = np.array([[0, 5], [2, 0]])
    view = Observed.from_info({"poses": poses, "known_poses": known, "message_age": age})
    assert view.known_poses is known and view.message_age is age
    np.testing.assert_array_equal(view.observed_poses, poses, strict=True)


def test_observed_poses_win_over_true_poses() -> None:
    view = Observed.from_info({"poses": np.full((2, 3), 9.0), "observed_poses": np.zeros((2, 3))})
    np.testing.assert_array_equal(view.poses, np.zeros((2, 3)), strict=True)
    # no messages given: every robot hears its team-mates' estimates at once
    np.testing.assert_array_equal(view.known_poses, np.zeros((2, 2, 3)), strict=True)
    np.testing.assert_array_equal(view.message_age, np.zeros((2, 2), dtype=np.int64), strict=True)


def test_an_info_with_the_perceptions_radii_counts_as_perceived() -> None:
    base = {"observed_poses": np.zeros((1, 3)), "lidar_ranges": np.ones((1, 4))}
    assert not Observed.from_info(base).perceived
    view = Observed.from_info({**base, "observed_movers": np.zeros((1, 4)), "mover_radii": [0.3]})
    assert view.perceived
    np.testing.assert_array_equal(view.mover_radii, np.array([0.3]), strict=True)


def test_distances_are_each_robots_from_its_estimate_and_a_batch_is_refused() -> None:
    rng = np.random.default_rng(0)
    observed = rng.normal(size=(5, 3))
    targets = rng.normal(size=(5, 3))
    view = Observed(observed, np.zeros((5, 5, 3)), np.zeros((5, 5), dtype=np.int64), targets=targets)
    dx, dy = targets[..., 0] - observed[..., 0], targets[..., 1] - observed[..., 1]
    np.testing.assert_array_equal(view.distances, np.sqrt(dx * dx + dy * dy), strict=True)
    assert view.distances.shape == (5,)
    # one team per value: a batch of teams is refused as from_info refuses it
    with pytest.raises(ValueError, match=r"observed_poses has shape \(4, 5, 3\); expected \(N, 3\)"):
        Observed(rng.normal(size=(4, 5, 3)), np.zeros((5, 5, 3)), np.zeros((5, 5), dtype=np.int64))


def test_the_dict_view_of_the_earlier_api_still_reads_with_a_deprecation_warning() -> None:
    info = {**TRUTH, "observed_poses": np.zeros((2, 3)), "targets": np.ones((2, 3))}
    with pytest.warns(DeprecationWarning, match=r"observed_view is deprecated.*Observed.from_info"):
        view = observed_view(info)
    assert list(view) == ["observed_poses", "known_poses", "message_age", "targets", "poses", "distances"]
    observed = Observed.from_info(info)
    with pytest.warns(DeprecationWarning, match=r"by key \('poses'\) is deprecated.*observed.poses"):
        assert observed["poses"] is observed.observed_poses
    with pytest.warns(DeprecationWarning):
        assert "targets" in observed and "lidar_ranges" not in observed
    with pytest.warns(DeprecationWarning):
        assert observed.get("lidar_ranges", 5) == 5
    with pytest.warns(DeprecationWarning), pytest.raises(KeyError, match="lidar_ranges"):
        observed["lidar_ranges"]


def test_the_value_is_frozen() -> None:
    observed = Observed.from_info({"poses": np.zeros((2, 3))})
    with pytest.raises(dataclasses.FrozenInstanceError):
        observed.observed_poses = np.ones((2, 3))  # type: ignore[misc]
