"""The benchmark's layout suites (koopman_envs.suites, docs/benchmark.md): disjoint splits, stable
and verified hashes, data the generator reproduces, measures that read hand-made layouts right,
monotone tiers, the suite map on every front, bad input refused by name, the held-out guard, and
the digest of reference rollouts that pins the test episodes."""

from __future__ import annotations

import gzip
import json
import re
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs
from koopman_envs import formation_v0, target_reaching_v0
from koopman_envs.params import PARAMS
from koopman_envs.suites import FAMILIES, SPLITS, SUITES, TIERS, check_split_allowed, load_suite
from koopman_envs.suites.build import (
    PROTOCOL_ROLLOUT_LAYOUTS,
    build_records,
    main,
    protocol_rollout_digest,
    reference_rollout_digest,
)
from koopman_envs.suites.measures import (
    ARENA,
    TIER_THRESHOLDS,
    difficulty_of,
    measure_layout,
    narrowest_gap,
    obstacle_density,
    tier_of,
)
from koopman_envs.suites.planner import PLANNER_RESOLUTION, path_length, shortest_path
from koopman_envs.suites.suite import read_manifest, read_split_document

NAME = "koopnav-bench-v1"
TASKS = ("target_reaching", "formation")
DATA = Path(koopman_envs.__file__).parent / "suites" / "data"

#: the content hashes of koopnav-bench-v1: a published suite never changes (a new generator
#: output is a new suite version, docs/benchmark.md)
HASHES = {
    "target_reaching/train": "23dc892dbd45bf9b55b686ef42334af92957eab09c33a91b83196ce05ad27a10",
    "target_reaching/validation": "2854d73a6bebd83c9cc8733de8e9d2978f1c14ea26face9799ead97f5cb7df5a",
    "target_reaching/test": "7f6471b2138ea1ca776bec69cad01c5fa65687fa982779d0c95a6c046485574c",
    "formation/train": "c901d7d88b3c3a20bcbc37aaadb8cca4982b8e91f41512c4627aa5ce5bd4c4fc",
    "formation/validation": "77649adb3c4e5d02c4b7ffc75cfb571802cc839a59da71d8f45043aa93383ae9",
    "formation/test": "bf3f80dc2a45a258f82d86d00142378e93d7996ec66907e34694c76f2f500969",
}
#: sha256 of the reference rollouts (koopman_envs.suites.build.reference_rollout_digest)
ROLLOUTS = {
    "target_reaching": "0a0c1fecc4323a132d798b3a3772c590ed0465d05390f6d520b77b6025ddaf17",
    "formation": "0b0078e47e95a354ca3ddf87669cbae74287c60746e1f85867def75a4a2f1935",
}
#: sha256 of rollouts under the benchmark's own keywords, to the episode's end
#: (koopman_envs.suites.build.protocol_rollout_digest): pinned here, not in the suite's data
PROTOCOL_ROLLOUTS = {
    "target_reaching": "6c8d7e97bceff219d30b809c4218d49cc52621e6f7a55fbc58d9168afbc9cc64",
    "formation": "6517756c99c726b8e18c5f0dd0e4b4cb458d4859c7dc49c8e098f5cd17eb25a2",
}
SIZES = {"train": 500, "validation": 100, "test": 200}


def _content(layout: object) -> bytes:
    spec = layout.spec  # type: ignore[attr-defined]
    return spec.obstacles.tobytes() + spec.starts.tobytes() + spec.targets.tobytes()


# ------------------------------------------------------------------------------ splits and data
@pytest.mark.parametrize("task", TASKS)
def test_the_splits_are_disjoint_in_seeds_and_content(task: str) -> None:
    suites = {split: load_suite(NAME, task, split) for split in SPLITS}
    ranges = sorted(suite.seeds for suite in suites.values())
    assert all(a[1] <= b[0] for a, b in zip(ranges, ranges[1:])), ranges
    for suite in suites.values():
        assert all(suite.seeds[0] <= layout.seed < suite.seeds[1] for layout in suite.layouts)
        assert len({layout.seed for layout in suite.layouts}) == len(suite) == SIZES[suite.split]
    for a, b in (("train", "validation"), ("train", "test"), ("validation", "test")):
        assert not {x.seed for x in suites[a].layouts} & {x.seed for x in suites[b].layouts}
        assert not {_content(x) for x in suites[a].layouts} & {_content(x) for x in suites[b].layouts}


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("split", SPLITS)
def test_every_split_balances_the_families_and_holds_valid_layouts(task: str, split: str) -> None:
    suite = load_suite(NAME, task, split)
    counts = Counter(layout.family for layout in suite.layouts)
    assert set(counts) == set(FAMILIES) and max(counts.values()) - min(counts.values()) <= 1
    wedge = np.hypot(PARAMS.formation_spacing, PARAMS.formation_spacing)
    for layout in suite.layouts:
        spec = layout.spec
        assert spec.obstacles.shape == (suite.n_obstacles, 3) and spec.max_robots == 3
        spec.validate(3)  # starts and targets free, inside the workspace, apart
        assert (spec.obstacles[:, :2] - spec.obstacles[:, 2:] >= ARENA[0]).all()
        assert (spec.obstacles[:, :2] + spec.obstacles[:, 2:] <= ARENA[1]).all()
        if task == "formation":  # the wedge's offsets at the targets, to the stored millimetre
            offsets = np.hypot(*spec.formation_offsets[1:].T)
            np.testing.assert_allclose(offsets, wedge, atol=3e-3)


@pytest.mark.parametrize("key", sorted(HASHES))
def test_the_hashes_are_stable_and_recorded_in_the_manifest(key: str) -> None:
    task, split = key.split("/")
    suite = load_suite(NAME, task, split)
    assert suite.sha256 == HASHES[key] == read_manifest(NAME)["splits"][key]["sha256"]
    assert re.fullmatch(rf"{NAME}/{task}/{split}@[0-9a-f]{{12}}", suite.label)
    assert suite.label.endswith(HASHES[key][:12]) and suite.version == SUITES[NAME].version == 1


def _copy_data(tmp_path: Path) -> Path:
    shutil.copytree(DATA / NAME, tmp_path / NAME)
    return tmp_path / NAME / "target_reaching" / "test.json.gz"


def test_an_edited_split_file_is_refused_by_name(tmp_path: Path) -> None:
    path = _copy_data(tmp_path)
    load_suite(NAME, "target_reaching", "test", data=tmp_path)  # the copy loads
    text = gzip.decompress(path.read_bytes()).decode()
    edited = text.replace('"seed":2000000,', '"seed":2000001,', 1)  # one byte of the content
    assert edited != text
    path.write_bytes(gzip.compress(edited.encode()))
    other = tmp_path / "other"
    shutil.copytree(tmp_path / NAME, other / NAME)
    with pytest.raises(
        ValueError,
        match=rf"suite file .*{re.escape(str(Path(NAME, 'target_reaching', 'test.json.gz')))} has sha256 .* but the manifest records",
    ):
        load_suite(NAME, "target_reaching", "test", data=other)


def test_a_torn_split_file_is_refused_by_name(tmp_path: Path) -> None:
    path = _copy_data(tmp_path)
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0x01  # one flipped bit inside the compressed stream
    path.write_bytes(bytes(raw))
    with pytest.raises(ValueError, match=r"suite file .*test\.json\.gz (cannot be read|has sha256)"):
        load_suite(NAME, "target_reaching", "test", data=tmp_path)
    path.write_bytes(bytes(raw[: len(raw) // 3]))  # cut short
    with pytest.raises(ValueError, match=r"suite file .*test\.json\.gz cannot be read"):
        read_split_document(NAME, "target_reaching", "test", data=tmp_path)


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("split", SPLITS)
def test_the_generator_reproduces_the_first_stored_layouts(task: str, split: str) -> None:
    """Bit for bit, in this process, what another process stored (the whole data: the slow test)."""
    stored, _ = read_split_document(NAME, task, split)
    built = build_records(SUITES[NAME], task, split, limit=3)
    assert built == [{k: v for k, v in record.items() if k != "tier"} for record in stored["layouts"][:3]]


def test_the_build_script_refuses_to_rewrite_a_published_suite(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--write", "--suite", NAME]) == 2
    assert "a published suite never changes; add a new version" in capsys.readouterr().err


@pytest.mark.slow
def test_the_build_script_reproduces_every_stored_split_and_digest(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["--check"]) == 0, capsys.readouterr().out


# ------------------------------------------------------------------------------------- measures
def _wall(post: float, end: float, radius: float = 0.3, step: float = 0.7) -> list[list[float]]:
    """Discs on x = 0 from the post at y = ``post`` to ``end``, ``step`` apart (0.1 m gaps)."""
    count = int(abs(end - post) / step) + 1
    return [[0.0, post + np.sign(end - post) * step * k, radius] for k in range(count)]


def test_a_known_gap_is_measured_exactly_and_the_detour_within_grid_tolerance() -> None:
    # two discs 1.0 m apart (surface to surface) straight across the travel
    pair = np.array([[0.0, 1.0, 0.5], [0.0, -1.0, 0.5]])
    starts, targets = np.array([[-3.0, 0.0, 0.0]]), np.array([[3.0, 0.0, 0.0]])
    measures = measure_layout(pair, starts, targets)
    assert measures is not None
    assert measures.gap == pytest.approx(1.0) and measures.tortuosity == pytest.approx(1.0)
    # a long wall with one 0.8 m opening above the straight line: the path bends through it
    walled = np.array(_wall(1.3, -8.0) + _wall(2.7, 8.0))  # posts at 1.3 and 2.7
    path = shortest_path(walled, starts[0], targets[0])
    assert path is not None
    assert narrowest_gap(path, walled) == pytest.approx(0.8)
    # the taut path passes the lower post's inflated disc (centre 1.3, radius 0.3 + 0.25)
    bound = 2.0 * np.hypot(3.0, 1.3 + 0.55)
    assert bound - 1e-9 <= path_length(path) <= bound + 2 * PLANNER_RESOLUTION
    measures = measure_layout(walled, starts, targets)
    assert measures is not None and measures.tortuosity == pytest.approx(bound / 6.0, abs=0.04)


def test_density_counts_the_covered_share_of_the_arena() -> None:
    area = (ARENA[1] - ARENA[0]) * (ARENA[3] - ARENA[2])
    assert obstacle_density(np.array([[0.0, 0.0, 1.0]])) == pytest.approx(np.pi / area, abs=2e-4)
    # overlapping discs count once
    twice = obstacle_density(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]))
    assert twice == pytest.approx(np.pi / area, abs=2e-4)


def test_an_enclosed_target_is_unreachable() -> None:
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    ring = np.column_stack([3.0 + 1.5 * np.cos(angles), 1.5 * np.sin(angles), np.full(24, 0.3)])
    assert measure_layout(ring, np.array([[-3.0, 0.0, 0.0]]), np.array([[3.0, 0.0, 0.0]])) is None


def test_tiers_are_monotone_in_difficulty() -> None:
    grid = np.linspace(0.0, 1.0, 501)
    for task, thresholds in TIER_THRESHOLDS.items():
        tiers = [TIERS.index(tier_of(float(d), thresholds)) for d in grid]
        assert tiers == sorted(tiers) and set(tiers) == {0, 1, 2}
        assert thresholds == tuple(read_manifest(NAME)["tier_thresholds"][task])
        for split in SPLITS:
            layouts = sorted(load_suite(NAME, task, split).layouts, key=lambda x: x.measures["difficulty"])
            ranks = [TIERS.index(layout.tier) for layout in layouts]
            assert ranks == sorted(ranks)
    # the difficulty grows with each measure's hardness
    assert difficulty_of(0.6, 1.2, 0.05) > difficulty_of(1.5, 1.2, 0.05)
    assert difficulty_of(1.0, 1.4, 0.05) > difficulty_of(1.0, 1.1, 0.05)
    assert difficulty_of(1.0, 1.2, 0.07) > difficulty_of(1.0, 1.2, 0.03)


def test_the_train_split_splits_into_thirds_at_the_declared_thresholds() -> None:
    for task in TASKS:
        counts = Counter(layout.tier for layout in load_suite(NAME, task, "train").layouts)
        assert all(abs(counts[tier] - 500 / 3) <= 12 for tier in TIERS), counts


# --------------------------------------------------------------------------------------- fronts
MAP = f"suite:{NAME}/test"


@pytest.mark.parametrize("module", [target_reaching_v0, formation_v0], ids=TASKS)
def test_every_front_takes_the_suite_map_and_draws_the_same_layout_per_seed(module: object) -> None:
    env_id = {"target_reaching_v0": "KoopNav-TargetReaching-v0", "formation_v0": "KoopNav-Formation-v0"}[
        module.__name__.rsplit(".", 1)[1]  # type: ignore[attr-defined]
    ]
    single = gym.make(env_id, map=MAP)
    parallel = module.parallel_env(map=MAP)  # type: ignore[attr-defined]
    vector = gym.make_vec(env_id, num_envs=2, map=MAP)
    names = set()
    for seed in (0, 11):
        single.reset(seed=seed)
        parallel.reset(seed=seed)
        vector.reset(seed=seed)
        name = single.unwrapped.scenario.map_name
        assert re.fullmatch(r"test-\d{3}", name)
        assert parallel.unwrapped.scenario.map_name == name == vector.unwrapped.scenario(0).map_name
        single.reset(seed=seed + 1)
        assert vector.unwrapped.scenario(1).map_name == single.unwrapped.scenario.map_name
        names.add(name)
    assert len(names) == 2
    for env in (single, parallel, vector):
        env.close()


def test_the_layout_option_picks_a_layout_and_leaves_the_seeded_draws_alone() -> None:
    suite = load_suite(NAME, "target_reaching", "test")
    env = gym.make("KoopNav-TargetReaching-v0", map=MAP, slip="random")
    _, info = env.reset(seed=5, options={"layout": 17})
    assert env.unwrapped.scenario.map_name == "test-017"
    np.testing.assert_array_equal(info["poses"], suite.layout(17).spec.starts)
    picked = env.unwrapped.engine.slip.lambdas[0].copy()
    env.reset(seed=5)
    # the layout index is drawn either way, so the slip level drawn after it is the seed's
    np.testing.assert_array_equal(env.unwrapped.engine.slip.lambdas[0], picked)
    assert env.unwrapped.scenario.map_name != "test-017"
    vector = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, map=MAP)
    vector.reset(seed=0, options={"layout": [3, 199]})
    assert [vector.unwrapped.scenario(i).map_name for i in range(2)] == ["test-003", "test-199"]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"map": "suite:koopnav-bench-v1/tset"},
            r"is not a suite split; allowed: \[.*'suite:koopnav-bench-v1/test'\]",
        ),
        ({"map": "suite:koopnav-bench-v9/test"}, r"map='suite:koopnav-bench-v9/test' is not a suite split"),
        ({"map": MAP, "n_robots": 4}, r"n_robots=4 is larger than map 'test-000' supports"),
        (
            {"map": MAP, "formation": "line"},
            r"formation='line' does not apply to map='suite:.*allowed: formation=None",
        ),
    ],
)
def test_bad_suite_maps_are_refused_by_name(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make("KoopNav-TargetReaching-v0", **kwargs)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            {"layout": 200},
            r"layout=200 is not a layout of koopnav-bench-v1/target_reaching/test@.*\[0, 199\]",
        ),
        ({"layout": -1}, r"options\['layout'\]=-1 is not allowed; allowed: an integer >= 0"),
        ({"layout": True}, r"options\['layout'\]=True is not allowed"),
        ({"layout": 1.5}, r"options\['layout'\]=1.5 is not allowed"),
    ],
)
def test_bad_layout_options_are_refused_by_name(options: dict[str, object], message: str) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=MAP)
    with pytest.raises(ValueError, match=message):
        env.reset(seed=0, options=options)


def test_the_layout_option_needs_a_suite_map_and_the_vector_env_one_per_sub_env() -> None:
    with pytest.raises(
        ValueError, match=r"options\['layout'\]=1 needs a suite map; this env's map is 'map1'"
    ):
        gym.make("KoopNav-TargetReaching-v0").reset(seed=0, options={"layout": 1})
    vector = gym.make_vec("KoopNav-TargetReaching-v0", num_envs=2, map=MAP)
    with pytest.raises(ValueError, match=r"or a sequence of 2 of them \(one per sub-env\)"):
        vector.reset(seed=0, options={"layout": [1, 2, 3]})


def test_load_suite_refuses_unknown_names_by_name() -> None:
    with pytest.raises(ValueError, match=r"suite='koopnav-bench' is not one of \['koopnav-bench-v1'\]"):
        load_suite("koopnav-bench", "target_reaching", "test")
    with pytest.raises(ValueError, match=r"task='target' is not one of \['target_reaching', 'formation'\]"):
        load_suite(NAME, "target", "test")
    with pytest.raises(ValueError, match=r"split='tests' is not one of \['train', 'validation', 'test'\]"):
        load_suite(NAME, "formation", "tests")


# ------------------------------------------------------------------------------- held-out guard
@pytest.mark.parametrize("purpose", ["tuning", "training", "calibration", "checkpoint selection"])
def test_the_test_split_is_refused_for_tuning_training_calibration_and_selection(purpose: str) -> None:
    with pytest.raises(ValueError, match=rf"split='test' is held out: .* may not be used for {purpose}"):
        check_split_allowed("test", purpose)
    suite = load_suite(NAME, "formation", "test")
    with pytest.raises(ValueError, match=rf"{re.escape(suite.label)} may not be used for {purpose}"):
        suite.require_split_for(purpose)
    check_split_allowed("validation", purpose)
    load_suite(NAME, "formation", "train").require_split_for(purpose)


def test_the_test_split_serves_evaluation_and_unknown_purposes_are_refused() -> None:
    check_split_allowed("test", "evaluation")
    check_split_allowed("test", "reporting")
    with pytest.raises(
        ValueError, match=r"purpose='tune' is not one of \[.*'tuning'.*\] \(did you mean 'tuning'\?\)"
    ):
        check_split_allowed("validation", "tune")
    assert koopman_envs.check_split_allowed is check_split_allowed and koopman_envs.load_suite is load_suite


# ----------------------------------------------------------------------- reference rollouts
@pytest.mark.parametrize("task", TASKS)
def test_the_reference_rollouts_of_the_test_split_are_unchanged(task: str) -> None:
    digest = reference_rollout_digest(NAME, task)
    assert read_manifest(NAME)["reference_rollouts"]["sha256"][task] == ROLLOUTS[task]
    assert digest == ROLLOUTS[task], (
        f"the reference rollouts on {NAME}'s {task} test layouts changed (sha256 {digest}): the dynamics, "
        "the tasks or the layouts now give other test episodes. A published suite's episodes never change: "
        "bump the suite version (koopman_envs.suites.suite.SUITES, e.g. koopnav-bench-v2) and build its data "
        "with python -m koopman_envs.suites.build --write (docs/benchmark.md)"
    )


def _benchmark_episodes(task: str) -> list[Any]:
    """The first episodes of the benchmark's test-suite run of ``task`` on layouts 0, 1, ...: the
    run's own plan (evaluation.experiments.protocols.suite_protocol, where the protocol is
    defined), so the digest below follows its slip, start noise and time limit."""
    from evaluation.experiments.protocols import suite_protocol

    spec = suite_protocol(NAME, "test").resolved(["consensus"])  # any controller: the env keywords
    env_id = koopman_envs.TASKS[task].env_id
    return [e for e in spec.episodes_plan() if e.env_id == env_id][:PROTOCOL_ROLLOUT_LAYOUTS]


@pytest.mark.parametrize("task", TASKS)
def test_the_rollouts_under_the_benchmarks_own_protocol_are_unchanged(task: str) -> None:
    episodes = _benchmark_episodes(task)
    # the digest's episode i is the benchmark's first episode on layout i: same seed, same layout,
    # the same gym.make keywords
    assert [(e.seed, e.reset_options()) for e in episodes] == [
        (i, {"layout": i}) for i in range(len(episodes))
    ]
    assert len({json.dumps(e.make_kwargs(), sort_keys=True) for e in episodes}) == 1
    digest = protocol_rollout_digest(episodes[0].env_id, episodes[0].make_kwargs())
    assert digest == PROTOCOL_ROLLOUTS[task], (
        f"the rollouts under the benchmark's protocol ({episodes[0].make_kwargs()}) on {NAME}'s {task} "
        f"test layouts changed (sha256 {digest}): the slip draws, the start perturbation, the time "
        "limit or the dynamics now give other test episodes. Bump the suite version "
        "(koopman_envs.suites.suite.SUITES) as for the reference rollouts (docs/benchmark.md)"
    )


@pytest.mark.parametrize(
    "change", [{"slip": "low"}, {"slip": "nominal"}, {"start_noise": 0.0}, {"max_episode_steps": 599}]
)
def test_the_protocol_digest_sees_the_slip_the_start_noise_and_the_time_limit(change: dict[str, Any]) -> None:
    # what reference_rollout_digest (default keywords, 40 steps) cannot see; 599 steps: the
    # open-loop episode runs to the time limit
    episode = _benchmark_episodes("target_reaching")[0]
    kwargs = episode.make_kwargs()
    assert {**kwargs, **change} != kwargs
    changed = protocol_rollout_digest(episode.env_id, {**kwargs, **change}, layouts=1)
    assert changed != protocol_rollout_digest(episode.env_id, kwargs, layouts=1)


def test_the_build_writes_every_file_whole_or_not_at_all(tmp_path, monkeypatch) -> None:
    """--write writes its splits and the manifest through koopman_envs.files.write_atomic (the
    manifest is read back between its two writes: a torn one would be read as a published
    suite). The reference rollouts, which load the suite the build wrote, are stood in for."""
    import json
    from types import SimpleNamespace

    from koopman_envs.files import write_atomic
    from koopman_envs.suites import build

    written: list[Path] = []

    def recording(path, content, **options):
        written.append(Path(path))
        return write_atomic(path, content, **options)

    monkeypatch.setattr(build, "write_atomic", recording)
    monkeypatch.setattr(build, "_DATA", tmp_path)
    monkeypatch.setattr(build, "reference_rollout_digest", lambda name, task: f"digest of {name}/{task}")
    definition = SimpleNamespace(name="tiny", tasks=("target_reaching",))
    documents: dict[str, dict[str, Any]] = {"test": {"layouts": [1, 2]}, "train": {"layouts": []}}
    manifest: dict[str, Any] = {"splits": {}, "reference_rollouts": {"sha256": {}}}
    build._write(definition, documents, manifest)  # type: ignore[arg-type]  # a stand-in definition
    root = tmp_path / "tiny"
    assert sorted(p.name for p in root.iterdir()) == ["manifest.json", "test.json.gz", "train.json.gz"]
    assert written == [
        root / "test.json.gz",
        root / "train.json.gz",
        root / "manifest.json",
        root / "manifest.json",
    ]
    assert json.loads(gzip.decompress((root / "test.json.gz").read_bytes())) == {"layouts": [1, 2]}
    stored = json.loads((root / "manifest.json").read_text())
    assert stored["reference_rollouts"]["sha256"] == {"target_reaching": "digest of tiny/target_reaching"}
