"""The compiled PCG64 draws (koopman_envs.sim.pcg64) are NumPy's, number for number."""

from __future__ import annotations

import numpy as np
import pytest

from koopman_envs.settings import CommConfig, PoseNoise
from koopman_envs.sim.movers.tracking import MoverTracker
from koopman_envs.sim.pcg64 import (
    Streams,
    generator_words,
    normals_f32,
    normals_f64,
    refill_f32,
    refill_normals_f64,
    store_words,
    uniforms_f32,
)
from koopman_envs.sim.perception import Perception

DT, WORKSPACE = 0.1, (-5.0, 5.0, -5.0, 5.0)


def _child(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed).spawn(1)[0]


@pytest.mark.parametrize("seed", [0, 1, 20261128])
def test_interleaved_draws_equal_numpys_and_leave_the_same_state(seed: int) -> None:
    """Odd lengths interleave the 32-bit half-words; a million Gaussians reach the samplers'
    slow paths (the tail and the wedges, about 0.7% of draws) thousands of times."""
    compiled, reference = _child(seed), _child(seed)
    words = generator_words(compiled)
    assert words is not None
    plan = [
        ("n32", 1_000_001),
        ("u32", 7),
        ("n64", 300_001),
        ("n32", 5),
        ("u32", 12_345),
        ("n64", 3),
        ("n32", 2),
    ]
    for kind, size in plan:
        if kind == "n32":
            ours, theirs = np.empty(size, np.float32), reference.standard_normal(size, dtype=np.float32)
            normals_f32(words, ours)
        elif kind == "u32":
            ours, theirs = np.empty(size, np.float32), reference.random(size, dtype=np.float32)
            uniforms_f32(words, ours)
        else:
            ours, theirs = np.empty(size), reference.standard_normal(size)
            normals_f64(words, ours)
        np.testing.assert_array_equal(ours, theirs, strict=True, err_msg=f"{kind} x {size}")
    np.testing.assert_array_equal(generator_words(reference), words)
    # and NumPy continues the stream from the words
    store_words(compiled, words)
    np.testing.assert_array_equal(compiled.standard_normal(9), reference.standard_normal(9))


def test_the_slow_paths_are_exercised() -> None:
    """Guard of the test above: its draws include values only the tail sampler returns."""
    reference = _child(1).standard_normal(1_000_001, dtype=np.float32)
    assert np.abs(reference).max() > 3.6541528  # beyond the ziggurat's last layer (r)


@pytest.mark.parametrize(
    "rng",
    [
        np.random.Generator(np.random.Philox(1)),
        np.random.Generator(np.random.PCG64DXSM(1)),
        np.random.Generator(np.random.MT19937(1)),
        object(),
    ],
    ids=["Philox", "PCG64DXSM", "MT19937", "not-a-generator"],
)
def test_other_bit_generators_are_left_to_numpy(rng) -> None:
    assert generator_words(rng) is None
    streams = Streams(2)
    streams.attach(1, rng)
    compiled, others = streams.split(np.array([1]), "Owner")
    assert compiled.tolist() == [] and others == [(1, rng)]


def test_an_environment_without_a_generator_is_refused_by_owner_and_index() -> None:
    streams = Streams(3)
    streams.attach(0, _child(0))
    with pytest.raises(RuntimeError, match=r"^Owner: environment 2 was stepped before reset\(\)$"):
        streams.split(np.array([0, 2]), "Owner")


def test_batched_refills_write_each_environments_own_stream() -> None:
    """refill_f32 (period-major buffers) and refill_normals_f64 give every environment of the
    batch what its generator gives alone; environments not listed are untouched."""
    periods, k = 5, 40  # more environments than a refill's chunk
    rows = np.array([0, 3, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 39])
    words = np.stack([generator_words(_child(s)) for s in range(k)])
    normal, uniform = np.full((periods, k, 6), -7.0, np.float32), np.full((periods, k, 3), -7.0, np.float32)
    cursor = np.full(k, periods)
    refill_f32(words, rows, normal, uniform, cursor)
    pool, pool_cursor = np.full((k, 4, 2), -7.0), np.full(k, 4)
    refill_normals_f64(words, rows, pool.reshape(k, -1), pool_cursor)
    for e in range(k):
        if e not in rows:
            assert (normal[:, e] == -7).all() and (uniform[:, e] == -7).all() and (pool[e] == -7).all()
            assert cursor[e] == periods and pool_cursor[e] == 4
            continue
        reference = _child(e)
        np.testing.assert_array_equal(normal[:, e], reference.standard_normal((periods, 6), dtype=np.float32))
        np.testing.assert_array_equal(uniform[:, e], reference.random((periods, 3), dtype=np.float32))
        np.testing.assert_array_equal(pool[e], reference.standard_normal((4, 2)))
        assert cursor[e] == 0 and pool_cursor[e] == 0


def _philox_parent(seed: int) -> np.random.Generator:
    return np.random.Generator(np.random.Philox(np.random.SeedSequence(seed)))


def test_perception_blocks_are_numpys_draws_compiled_or_not() -> None:
    """Env 0's parent is a PCG64 (compiled draws), env 1's a Philox (NumPy's path): each block,
    the first and the one after it is used up, is its child's normals then uniforms."""
    perception = Perception(2, 3, PoseNoise(0.05), CommConfig(drop=0.2), None, 0, DT, WORKSPACE)
    parents = [np.random.default_rng(5), _philox_parent(6)]
    for k in range(2):
        perception.reset_env(k, parents[k])
    assert perception.streams.compiled.tolist() == [True, False]
    references = [np.random.default_rng(5).spawn(1)[0], _philox_parent(6).spawn(1)[0]]
    block, width_n, width_u = perception.block, perception._normals, perception._uniforms
    state = np.zeros((2, 3, 3))
    state[:, 0] = np.arange(3)
    for _ in range(2):
        perception.cursor[:] = block  # used up: the next update draws a block
        perception.update(state, (np.zeros((2, 0)),) * 3, np.full(3, 0.2), np.arange(2))
        for k in range(2):
            expected_n = references[k].standard_normal((block, width_n), dtype=np.float32)
            expected_u = references[k].random((block, width_u), dtype=np.float32)
            np.testing.assert_array_equal(perception.normal[:, k], expected_n)
            np.testing.assert_array_equal(perception.uniform[:, k], expected_u)


def test_tracker_pools_are_numpys_draws_compiled_or_not() -> None:
    tracker = MoverTracker(2, 3, DT, detection_range=5.0, detection_noise=0.05)
    parents = [np.random.default_rng(8), _philox_parent(9)]
    for k in range(2):
        tracker.reset_env(k, parents[k])
    references = [np.random.default_rng(8).spawn(1)[0], _philox_parent(9).spawn(1)[0]]
    periods = tracker._pool.shape[1]
    movers = np.zeros((2, 3, 4))
    movers[..., 0] = np.arange(3)
    poses = np.zeros((2, 3, 2))
    for _ in range(2):
        tracker._cursor[:] = periods
        tracker.step(movers, poses, poses)
        for k in range(2):
            np.testing.assert_array_equal(tracker._pool[k], references[k].standard_normal((periods, 3, 2)))


def test_without_the_compiled_draws_every_generator_takes_numpys_path(monkeypatch) -> None:
    """If numba's copy of the tables is missing, the same numbers come through NumPy."""
    import koopman_envs.sim.pcg64 as pcg64

    monkeypatch.setattr(pcg64, "COMPILED_DRAWS", False)
    assert generator_words(np.random.default_rng(0)) is None
    perception = Perception(1, 3, PoseNoise(0.05), CommConfig(drop=0.2), None, 0, DT, WORKSPACE)
    perception.reset_env(0, np.random.default_rng(5))
    assert perception.streams.compiled.tolist() == [False]
    state = np.zeros((1, 3, 3))
    perception.update(state, (np.zeros((1, 0)),) * 3, np.full(3, 0.2), np.arange(1))
    reference = np.random.default_rng(5).spawn(1)[0]
    block, width_n, width_u = perception.block, perception._normals, perception._uniforms
    np.testing.assert_array_equal(
        perception.normal[:, 0], reference.standard_normal((block, width_n), dtype=np.float32)
    )
    np.testing.assert_array_equal(
        perception.uniform[:, 0], reference.random((block, width_u), dtype=np.float32)
    )
