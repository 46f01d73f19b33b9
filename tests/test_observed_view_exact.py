"""koopman_envs.observed.observed_view key by key and value by value (issue 41, mutation testing):
which keys pass, which never do, the aliases a controller of the earlier API reads, and the
perfect-information view of a hand-written info, each compared exactly.

tests/test_observed_view.py shows that no controller's action changes with a poisoned truth;
these pin the view itself, so that a key let through or an alias computed from the wrong pose
fails here directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from koopman_envs.observed import OBSERVED_KEYS, observed_view

#: fields of an env's info that hold the truth (or the env's bookkeeping): never in the view
TRUTH = {
    "poses": np.full((2, 3), np.nan),
    "distances": np.full(2, np.nan),
    "collision": np.array([True, False]),
    "movers": np.full((1, 4), np.nan),
    "slip": np.full(2, np.nan),
    "success": True,
}


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
    )


def test_an_env_info_passes_its_observed_keys_as_they_are_and_aliases_the_estimates() -> None:
    observed = np.array([[0.0, 0.0, 0.1], [1.0, 2.0, -0.2]])
    beliefs = {
        "observed_poses": observed,
        "known_poses": np.arange(12.0).reshape(2, 2, 3),
        "message_age": np.array([[0, 3], [-1, 0]]),
        "lidar_ranges": np.ones((2, 8)),
        "targets": np.array([[3.0, 4.0, 0.0], [-5.0, 14.0, 1.0]]),
        "observed_movers": np.zeros((2, 1, 4)),
        "mover_tracked": np.ones((2, 1), dtype=bool),
        "pose_covariance": np.tile(np.eye(3), (2, 1, 1)),  # what an estimator in front hands on
    }
    view = observed_view({**TRUTH, **beliefs})
    assert list(view) == [*OBSERVED_KEYS[:8], "poses", "distances"]
    for key, value in beliefs.items():
        assert view[key] is value  # passed as they are, not copied or converted
    np.testing.assert_array_equal(view["poses"], observed, strict=True)
    # from the estimates to the targets: (3, 4) -> 5 and (-6, 12) -> sqrt(180)
    np.testing.assert_array_equal(view["distances"], np.array([5.0, np.sqrt(180.0)]), strict=True)


def test_a_partial_info_passes_only_what_it_has() -> None:
    view = observed_view({"observed_poses": [[1, 2, 3]], "lidar_ranges": [[2.0]], "collision": [True]})
    assert list(view) == ["observed_poses", "lidar_ranges", "poses"]  # no targets: no distances
    np.testing.assert_array_equal(view["poses"], np.array([[1.0, 2.0, 3.0]]), strict=True)
    assert view["observed_poses"] == [[1, 2, 3]]
    assert observed_view({"targets": [[1.0, 1.0, 0.0]], "slip": 1}) == {"targets": [[1.0, 1.0, 0.0]]}
    assert observed_view({}) == {}
    assert observed_view({"poses": np.zeros((0, 3))})["message_age"].shape == (0, 0)  # no robots


def test_a_hand_written_info_of_poses_is_one_of_perfect_information() -> None:
    poses = [[0, 0, 0], [3, -4, 1], [1, 1, 2]]  # integers: converted to float
    targets = [[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
    view = observed_view({"poses": poses, "targets": targets, "collision": [False] * 3})
    assert list(view) == ["targets", "observed_poses", "known_poses", "message_age", "poses", "distances"]
    expected = np.array(poses, dtype=np.float64)
    np.testing.assert_array_equal(view["observed_poses"], expected, strict=True)
    np.testing.assert_array_equal(view["poses"], expected, strict=True)
    # every robot hears every team-mate at once: each row of known_poses is the team, of age 0
    np.testing.assert_array_equal(view["known_poses"], np.stack([expected] * 3), strict=True)
    np.testing.assert_array_equal(view["message_age"], np.zeros((3, 3), dtype=np.int64), strict=True)
    np.testing.assert_array_equal(view["distances"], np.array([5.0, 5.0, 0.0]), strict=True)


def test_given_messages_are_kept_beside_hand_written_poses() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    known = np.full((2, 2, 3), 7.0)
    age = np.array([[0, 5], [2, 0]])
    view = observed_view({"poses": poses, "known_poses": known, "message_age": age})
    assert view["known_poses"] is known and view["message_age"] is age
    np.testing.assert_array_equal(view["observed_poses"], poses, strict=True)


def test_observed_poses_win_over_true_poses() -> None:
    view = observed_view({"poses": np.full((2, 3), 9.0), "observed_poses": np.zeros((2, 3))})
    np.testing.assert_array_equal(view["poses"], np.zeros((2, 3)), strict=True)
    assert "known_poses" not in view and "message_age" not in view  # no perfect-information fill-in


@pytest.mark.parametrize("batch", [(), (4,), (2, 3)])
def test_batched_estimates_and_targets_give_batched_distances(batch) -> None:
    rng = np.random.default_rng(0)
    observed = rng.normal(size=(*batch, 5, 3))
    targets = rng.normal(size=(*batch, 5, 3))
    view = observed_view({"observed_poses": observed, "targets": targets})
    dx, dy = targets[..., 0] - observed[..., 0], targets[..., 1] - observed[..., 1]
    np.testing.assert_array_equal(view["distances"], np.sqrt(dx * dx + dy * dy), strict=True)
    assert view["distances"].shape == (*batch, 5)
