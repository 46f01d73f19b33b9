"""The sim-to-sim protocol (issue 62): ``--plant mujoco`` recorded in a run's identity (a kinematic
log is not resumed on the physics plant), the published runs in data/publish.sh differing by the
plant only, and docs/make_sim2sim_md.py's page on two small real runs: its paired numbers are
the records' own, its verdict sentence says what the data say, and runs that differ by more than
the plant are refused by name."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.reports.publications import pack_split
from evaluation.stats.statistics import paired_comparison
from evaluation.stats.transfer import (
    Ordering,
    kendall_tau_b,
    ordering_verdict,
    planned_episodes,
    rank_agreement,
)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_sim2sim_md import (  # noqa: E402  (docs/ is no package)
    FINE_TUNED,
    SUMMARY,
    Level,
    against_source,
    level_title,
    pairwise_sentence,
    transfer_sentence,
    transfers,
)
from make_sim2sim_md import main as make_page  # noqa: E402

#: a small friction sweep: two cheap controllers, map1, two seeds, 40 periods
SMALL = [
    *("--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--controllers", "consensus-free", "orca"),
    *("--episodes", "2", "--max-episode-steps", "40", "--workers", "1", "--quiet"),
    *("--sweep", "slip=nominal,high"),
]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path]:
    """The small sweep on the kinematic plant and on the physics plant, named as the published
    runs are (the intro template names its runs by their files)."""
    pytest.importorskip("mujoco")  # the physics plant (the [physics] extra)
    root = tmp_path_factory.mktemp("sim2sim")
    kinematic, physics = root / "sim2sim_kinematic", root / "sim2sim_physics"
    assert ev.main([*SMALL, "--out", str(kinematic)]) == 0
    assert ev.main([*SMALL, "--plant", "mujoco", "--out", str(physics)]) == 0
    return kinematic, physics


@pytest.fixture(scope="module")
def published(runs, tmp_path_factory) -> tuple[Path, Path]:
    """The two runs published as data/publish.sh packs them (what the page reads)."""
    data = tmp_path_factory.mktemp("data")
    for run in runs:
        pack_split(run, data / run.name)
    return data / runs[0].name, data / runs[1].name


def _records(run: Path, level: str) -> dict[tuple[str, int], dict]:
    lines = (run / "sweep" / f"slip-{level}" / "episodes.jsonl").read_text().splitlines()[1:]
    return {(r["controller"], r["trial"]): r for r in map(json.loads, lines) if r.get("status") == "ok"}


def _make_page(args: list[str], capsys) -> tuple[int, str, str]:
    """``python docs/make_sim2sim_md.py ARGS``: (exit code, stdout, stderr)."""
    code = make_page(args)
    shown = capsys.readouterr()
    return code, shown.out, shown.err


def test_a_kinematic_log_is_not_resumed_on_the_physics_plant(runs, capsys) -> None:
    kinematic, _ = runs
    level = kinematic / "sweep" / "slip-nominal"
    before = (level / "episodes.jsonl").read_bytes()
    args = [a for a in SMALL if a not in ("--sweep", "slip=nominal,high")]
    code = ev.main([*args, "--slips", "nominal", "--plant", "mujoco", "--out", str(level), "--resume"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "belongs to a run with other settings" in err and "'plant': 'mujoco'" in err
    assert (level / "episodes.jsonl").read_bytes() == before  # nothing appended


def test_the_page_pairs_every_episode_with_its_twin_on_the_other_plant(
    runs, published, tmp_path, capsys
) -> None:
    kinematic, physics = runs
    out = tmp_path / "sim2sim.md"
    intro = ROOT / "docs" / "_intros" / "sim2sim_results.md"
    code, printed, err = _make_page([*map(str, published), "--out", str(out), "--intro", str(intro)], capsys)
    assert code == 0, err
    assert printed.strip() == f"wrote {out}"
    text = out.read_text()
    assert "{{" not in text and "differs by the plant only (2 episodes per" in " ".join(text.split())
    for level in ("nominal", "high"):
        assert f"## {level_title(level)}" in text
        before, after = _records(kinematic, level), _records(physics, level)
        section = text.split(f"## {level_title(level)}")[1].split("\n## ")[0]
        for controller in ("consensus-free", "orca"):
            keys = sorted(k for k in before if k[0] == controller and k in after)
            test = paired_comparison(
                [after[k]["success"] for k in keys], [before[k]["success"] for k in keys]
            )
            row = re.search(
                rf"^\| {controller} \| (\d+) \| (\d+)% .*\| (\d+)% .*\| ([+-]\d+) \[", section, re.M
            )
            assert row is not None, section
            assert int(row[1]) == len(keys) == 2
            assert int(row[2]) == round(100 * test.rate_b) and int(row[3]) == round(100 * test.rate_a)
            assert int(row[4]) == round(100 * test.difference)
        assert "**Which verdicts transfer**: " in section
    # the twins are the same episodes but for the plant: same seed, layout and starts
    twin_a, twin_b = _records(kinematic, "high")[("orca", 1)], _records(physics, "high")[("orca", 1)]
    assert (twin_a["seed"], twin_a["map"]) == (twin_b["seed"], twin_b["map"])
    assert json.loads(twin_b["env_kwargs"])["plant"] == "mujoco" and "plant" not in json.loads(
        twin_a["env_kwargs"]
    )


def test_runs_that_differ_by_more_than_the_plant_are_refused_by_name(runs, tmp_path, capsys) -> None:
    kinematic, physics = runs
    out = tmp_path / "page.md"
    code, _, err = _make_page([str(kinematic), str(kinematic), "--out", str(out)], capsys)
    assert code == 2 and "both runs are on the 'kinematic' plant" in err
    other = tmp_path / "other"
    assert (
        ev.main([*SMALL[:-2], "--sweep", "slip=nominal,high", "--tolerance", "0.2", "--out", str(other)]) == 0
    )
    code, _, err = _make_page([str(other), str(physics), "--out", str(out)], capsys)
    assert code == 2 and "differ in ['env_settings'], not only in the plant" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "first, second, verdict",
    [(1, 1, "holds"), (-1, -1, "holds"), (1, 0, "lost"), (1, -1, "reversed"), (0, -1, "new"), (0, 0, "none")],
)
def test_what_became_of_a_verdict(first: int, second: int, verdict: str) -> None:
    assert ordering_verdict(first, second) == verdict


def test_the_sentence_names_each_verdict_by_its_fate() -> None:
    env = "KoopNav-TargetReaching-v0"
    found = [
        Ordering(env, "a", "b", 1, 1),
        Ordering(env, "a", "c", -1, 0),
        Ordering(env, "b", "c", 1, -1),
        Ordering(env, "a", "d", 0, 1),
        Ordering(env, "b", "d", 0, 0),
    ]
    assert transfer_sentence(found) == (
        "Of the 3 orderings significant on the kinematic plant (of 5 pairs), 1 hold on the physics "
        "plant: `a` > `b` (target reaching); 1 are no longer significant there: `c` > `a` (target "
        "reaching); 1 reverse: `b` > `c` (target reaching) (now `c` > `b` (target reaching)); 1 "
        "appear on the physics plant only: `a` > `d` (target reaching)."
    )
    assert transfer_sentence(found[-1:]).startswith("No ordering of two controllers is significant")
    assert pairwise_sentence(_level(found)) == (
        "1 of the 3 orderings significant on the kinematic plant (of 5 pairs) hold; 1 appear on the "
        "physics plant only"
    )
    assert pairwise_sentence(_level(found[3:])) == (
        "no ordering of two controllers of one task is significant on the kinematic plant (of 2 pairs, "
        "Holm over the pairs), so no pairwise verdict is there to transfer; 1 appear on the physics plant only"
    )


def _level(found: list[Ordering]) -> Level:
    """A level with these orderings and nothing else (what :func:`pairwise_sentence` reads)."""
    return Level("nominal", 0, {}, None, None, [], found, None)


def test_the_fine_tuned_rows_are_the_policies_trained_on_the_physics_plant() -> None:
    """Every row the page sets apart is a registered controller whose shipped policies say they
    were fine-tuned on the physics plant from the controller named beside it."""
    pytest.importorskip("stable_baselines3")
    import controllers

    for name, source in FINE_TUNED.items():
        assert {name, source} <= set(controllers.available())
        tuned, origin = controllers.make(name), controllers.make(source)
        for task in ("target_reaching", "formation"):
            metadata = json.loads((tuned.policy_root / task / "metadata.json").read_text())  # type: ignore[attr-defined]
            assert metadata["plant"] == "mujoco"
            shipped = origin.policy_root / task  # type: ignore[attr-defined]
            assert (ROOT / metadata["initialized_from"]["path"]).resolve() == shipped.resolve()
            assert "plant" not in json.loads((shipped / "metadata.json").read_text())  # kinematic


def test_a_fine_tuned_row_is_no_transfer_and_is_paired_with_its_source() -> None:
    env = "KoopNav-TargetReaching-v0"
    [(tuned, source)] = FINE_TUNED.items()
    found = [
        Ordering(env, "a", "b", 1, 1),
        Ordering(env, tuned, "a", 0, 1),
        Ordering(env, source, tuned, 1, 0),
    ]
    assert transfers(found) == found[:1]
    assert pairwise_sentence(_level(found)).startswith(
        "1 of the 1 orderings significant on the kinematic plant (of 1 pairs) hold"
    )
    records = [
        {"controller": name, "env_id": env, "layout": layout, "map": "suite", "seed": layout, "success": ok}
        for name, outcomes in ((tuned, [1, 1, 0, 1]), (source, [0, 1, 0, 0]), ("orca", [1, 1, 1, 1]))
        for layout, ok in enumerate(outcomes)
    ]
    records.append(
        {"controller": tuned, "env_id": env, "layout": 9, "map": "suite", "seed": 9, "success": True}
    )
    test = against_source(records, tuned)
    assert test is not None and test.n == 4  # layout 9 has no twin of the source
    assert (test.rate_a, test.rate_b, test.only_a, test.only_b) == (0.75, 0.25, 2, 0)
    assert against_source([r for r in records if r["controller"] != source], tuned) is None


def test_the_published_runs_differ_by_the_plant_only() -> None:
    script = (ROOT / "data" / "publish.sh").read_text(encoding="utf-8")
    runs = dict(re.findall(r'^RUNS\[(sim2sim_\w+)\]="(.*)"$', script, re.M))
    assert set(runs) == {"sim2sim_kinematic", "sim2sim_physics"}
    assert runs["sim2sim_physics"] == runs["sim2sim_kinematic"] + " --plant mujoco"
    shared, order = re.search(r'^SIM2SIM="(.*)"$', script, re.M), re.search(r"^ORDER=\((.*)\)$", script, re.M)
    assert shared is not None and order is not None
    assert re.search(r"--sweep slip=nominal,(low,)?high ", shared[1])
    names = order[1].split()
    assert names.index("sim2sim_kinematic") < names.index("sim2sim_physics")


def test_the_difference_is_physics_minus_kinematic_on_the_twins(runs) -> None:
    """The small runs end alike on both plants (40 periods reach no target), so here orca's
    physics episodes are marked successful in a copy: its row must show the gain, the others none."""
    from evaluation.experiments.sweep import load_sweep
    from evaluation.stats.run_data import RunData
    from evaluation.stats.transfer import plant_differences

    (kinematic, _, _), (physics, _, _) = (load_sweep(run) for run in runs)
    before, after = dict(kinematic["slip"])["high"], dict(physics["slip"])["high"]
    assert not any(r["success"] for r in before.records + after.records)
    marked = [{**r, "success": r["controller"] == "orca"} for r in after.records]
    rows = {row.controller: row for row in plant_differences(before, RunData(marked, after.config))}
    assert (rows["orca"].first, rows["orca"].second, rows["orca"].difference) == (0.0, 1.0, 1.0)
    assert rows["orca"].second_interval[0] > 0.3 and rows["orca"].first_interval[1] < 0.7
    assert rows["consensus-free"].difference == 0.0 and rows["orca"].pairs == 2


# --------------------------------------------------------------------------- partial runs
def _trim(run: Path, out: Path, keep) -> Path:
    """A copy of ``run`` whose episode logs keep the records ``keep(level, record)`` accepts."""
    import shutil

    shutil.copytree(run, out)
    for log in out.glob("sweep/slip-*/episodes.jsonl"):
        level = log.parent.name.removeprefix("slip-")
        header, *lines = log.read_text().splitlines()
        kept = [line for line in lines if keep(level, json.loads(line))]
        log.write_text("\n".join([header, *kept]) + "\n")
    return out


def test_a_partial_level_is_named_pending_and_left_out(runs, published, tmp_path, capsys) -> None:
    """The physics run published part way: carpet has no episode yet, and on ice orca has one of
    its two. Carpet is named pending with nothing tested; orca is named pending on ice and has no
    row, no test, no place in the ranking; consensus-free, complete on both, keeps its row."""
    _, physics = runs
    dropped = []

    def keep(level: str, record: dict) -> bool:
        if level == "nominal" or (record["controller"] == "orca" and not dropped):
            dropped.append(record)
            return False
        return True

    trimmed = _trim(physics, tmp_path / "run" / "sim2sim_physics", keep)
    partial = pack_split(trimmed, tmp_path / "data" / "sim2sim_physics")
    out = tmp_path / "page.md"
    code, _, err = _make_page([str(published[0]), str(partial), "--out", str(out)], capsys)
    assert code == 0, err
    text = out.read_text()
    carpet = text.split(f"## {level_title('nominal')}")[1].split("\n## ")[0]
    ice = text.split(f"## {level_title('high')}")[1]
    assert "| controller |" not in carpet and "No controller is complete on both plants yet" in carpet
    assert "every controller (2) is pending: 0 of 2 episodes on the physics plant." in carpet
    assert "`orca` (pending: 1 of 2 episodes on the physics plant)" in ice
    assert re.search(r"^\| consensus-free \| 2 \|", ice, re.M) and not re.search(r"^\| orca \|", ice, re.M)
    assert "Fewer than two controllers are complete" in ice  # orca is out of the ranking too
    assert "No pair of controllers of one task is complete on both plants" in ice  # nor in a pair
    block = text.split(f"<!-- begin {SUMMARY}")[1].split(f"<!-- end {SUMMARY} -->")[0]
    assert f"**{level_title('nominal')}**: no controller is complete on both plants yet" in block
    assert "every controller (2) is pending: 0 of 2 episodes on the physics plant." in block
    assert "`orca` (pending: 1 of 2 episodes on the physics plant)" in block
    assert "0 of 0" not in text


def test_the_planned_count_is_the_runs_own() -> None:
    """Episodes per (task, controller) from a header: a suite's selected layouts x episodes per
    layout (or its whole split), a plain map's episodes, times the slips."""
    env = "KoopNav-TargetReaching-v0"
    suite = {"tasks": {env: {"size": 200}}, "layouts": [0, 10], "episodes_per_layout": 2}
    config = {
        "maps": {env: ["suite:koopnav-bench-v1/test"]},
        "suite": suite,
        "slips": ["high"],
        "episodes": 2,
    }
    assert planned_episodes(config, env) == 20
    assert planned_episodes({**config, "suite": {**suite, "layouts": None}}, env) == 400
    plain = {"maps": {env: ["map1", "map2"]}, "suite": None, "slips": ["nominal", "high"], "episodes": 3}
    assert planned_episodes(plain, env) == 12


# --------------------------------------------------------------------------- rank agreement
def test_kendalls_tau_b_is_one_for_one_order_and_minus_one_reversed() -> None:
    scipy_stats = pytest.importorskip("scipy.stats")
    import numpy as np

    x = [0.1, 0.4, 0.2, 0.9]
    assert kendall_tau_b(x, x) == 1.0 and kendall_tau_b(x, [0.2, 0.4, 0.1, 0.9]) == pytest.approx(2 / 3)
    assert kendall_tau_b(x, [-v for v in x]) == -1.0
    assert np.isnan(kendall_tau_b(x, [0.5] * 4))
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 4, size=(50, 2, 7))  # ties, as success rates have them
    for a, b in rows:
        expected = scipy_stats.kendalltau(a, b).statistic
        assert kendall_tau_b(a, b) == pytest.approx(expected, nan_ok=True)
    assert kendall_tau_b(rows[:, 0], rows[:, 1]) == pytest.approx(
        [scipy_stats.kendalltau(a, b).statistic for a, b in rows], nan_ok=True
    )


def _run(outcomes: dict[str, list[list[bool]]]):
    """Records of a suite-like run: controller -> per layout, the successes of its episodes."""
    from types import SimpleNamespace

    records = [
        {
            "env_id": "KoopNav-TargetReaching-v0",
            "controller": name,
            "map": "suite:koopnav-bench-v1/test",
            "layout": layout,
            "trial": layout + 100 * episode,
            "seed": layout + 100 * episode,
            "status": "ok",
            "success": ok,
        }
        for name, layouts in outcomes.items()
        for layout, episodes in enumerate(layouts)
        for episode, ok in enumerate(episodes)
    ]
    return SimpleNamespace(records=records)


def test_the_rank_agreement_is_one_for_the_same_order_and_minus_one_reversed() -> None:
    ranked = {  # a > b > c on every layout
        "a": [[True, True], [True, True], [True, False]],
        "b": [[True, False], [True, False], [False, False]],
        "c": [[False, False], [False, False], [False, False]],
    }
    reversed_ = {"a": ranked["c"], "b": ranked["b"], "c": ranked["a"]}
    same = rank_agreement(_run(ranked), _run(ranked), ["a", "b", "c"])
    assert (same.tau, same.controllers, same.clusters) == (1.0, 3, 3)
    assert same.low == same.high == 1.0  # every resample keeps the one order on both plants
    flipped = rank_agreement(_run(ranked), _run(reversed_), ["a", "b", "c"])
    assert flipped.tau == -1.0 and flipped.high <= 0
    again = rank_agreement(_run(ranked), _run(reversed_), ["a", "b", "c"])
    assert again == flipped  # seeded: the same data give the same interval
    with pytest.raises(ValueError, match=r"two or more controllers; got \['a'\]"):
        rank_agreement(_run(ranked), _run(ranked), ["a"])


def test_the_rank_interval_resamples_layouts_not_episodes() -> None:
    """All episodes on one layout are one cluster: a resample of one cluster is the data itself,
    so the interval is the point, however the episodes within it disagree; a resample of episodes
    would move it. With two layouts that rank the controllers oppositely it is wide."""
    one_layout = {
        "a": [[True, True, False, True, False, True]],
        "b": [[True, False, False, False, True, False]],
        "c": [[False, False, True, False, False, False]],
    }
    physics = {"a": one_layout["b"], "b": one_layout["a"], "c": one_layout["c"]}
    found = rank_agreement(_run(one_layout), _run(physics), ["a", "b", "c"])
    assert found.clusters == 1 and found.low == found.high == found.tau
    kinematic = {"a": [[True] * 4] * 2, "b": [[False] * 4] * 2, "c": [[True, True, False, False]] * 2}
    physics = {  # layout 0 ranks a > c > b as the kinematic plant does, layout 1 b > c > a
        "a": [[True] * 4, [False] * 4],
        "b": [[False] * 4, [True] * 4],
        "c": [[True, True, False, False]] * 2,
    }
    found = rank_agreement(_run(kinematic), _run(physics), ["a", "b", "c"])
    assert found.clusters == 2 and (found.low, found.high) == (-1.0, 1.0)
