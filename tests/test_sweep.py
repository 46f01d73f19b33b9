"""``--sweep`` and the robustness profiles: axes parsed and checked before any episode, every level a
paired, resumable run, and the profile's statistics (Wilson, bootstrap, paired, AUC, tail)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import evaluate as ev
from evaluation.experiments.sweep import SweepAxis, parse_sweep
from evaluation.run.spec import RunSpec
from evaluation.stats.statistics import bootstrap_tail_interval, tail_mean

TINY = [
    "--env",
    "KoopNav-TargetReaching-v0",
    "--maps",
    "map1",
    "--episodes",
    "2",
    "--max-episode-steps",
    "25",
    "--workers",
    "1",
    "--quiet",
]


def test_axes_are_parsed_as_json_levels() -> None:
    axis = parse_sweep("comm.drop=0,0.1,0.3")
    assert axis == SweepAxis("comm.drop", (0, 0.1, 0.3))
    assert parse_sweep("uncertainty=nominal,realistic,harsh").levels == ("nominal", "realistic", "harsh")
    assert parse_sweep("actuation_delay=0, 1,2").levels == (0, 1, 2)


@pytest.mark.parametrize(
    "text, message",
    [
        ("comm.drop", r"is not KEY=v1,v2"),
        ("comms.drop=0,1", r"'comms' is not an env keyword \(did you mean 'comm'\?\)"),
        ("map=map1,map2", r"'map' is not an env keyword"),
        ("actuation_delay=1", r"give at least two levels"),
        ("actuation_delay=1,1", r"level '1' is given twice"),
    ],
)
def test_bad_axes_are_refused_by_name(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_sweep(text)


def test_a_nested_level_goes_over_the_runs_own_settings() -> None:
    spec = RunSpec(env_kwargs={"comm": {"latency": 2}, "start_noise": 0.05})
    changed = parse_sweep("comm.drop=0,0.5").apply(spec, 0.5)
    assert changed.env_kwargs == {"comm": {"latency": 2, "drop": 0.5}, "start_noise": 0.05}
    assert spec.env_kwargs["comm"] == {"latency": 2}  # the spec itself is unchanged
    assert parse_sweep("slip=low,high").apply(spec, "high").slips == ("high",)


def test_a_bad_level_stops_the_sweep_before_any_episode(tmp_path, capsys) -> None:
    code = ev.main(
        [*TINY, "--controllers", "consensus", "--sweep", "comm.drop=0,2", "--out", str(tmp_path / "o")]
    )
    assert code == 2
    assert "--sweep comm.drop=2: comm.drop=2 must be a finite number >= 0 <= 1" in capsys.readouterr().err
    assert not (tmp_path / "o" / "sweep").exists()


# slow: a sweep of three levels and the plain run beside it, about 3 CPU-s (issue 61); the other
# sweep tests keep a sweep run in the default run
@pytest.mark.slow
def test_a_sweep_writes_paired_profiles_and_level_zero_is_the_plain_run(tmp_path) -> None:
    out = tmp_path / "sweep"
    code = ev.main(
        [
            *TINY,
            "--controllers",
            "consensus",
            "consensus-free",
            "--sweep",
            "pose_noise.xy=0,0.3",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    profile = json.loads((out / "robustness.json").read_text())[0]
    assert profile["key"] == "pose_noise.xy" and profile["levels"] == [0, 0.3]
    assert profile["reference"] == "consensus"
    rows = {(r["controller"], r["level"]): r for r in profile["rows"]}
    assert rows[("consensus-free", 0.3)]["paired"]["pairs"] == 2
    assert rows[("consensus", 0)]["paired"] is None
    assert set(profile["summary"]) == {"consensus", "consensus-free"}
    assert (out / "figures" / "robustness_pose_noise_xy.png").stat().st_size > 1000
    html = (out / "robustness.html").read_text()
    assert "Robustness: pose_noise.xy" in html and "data:image/png;base64" in html
    # the level 0 run equals a run without the setting, outcome for outcome
    plain = tmp_path / "plain"
    assert ev.main([*TINY, "--controllers", "consensus", "consensus-free", "--out", str(plain)]) == 0
    first = json.loads((out / "sweep" / "pose_noise.xy-0" / "results.json").read_text())["episodes"]
    again = json.loads((plain / "results.json").read_text())["episodes"]
    assert len(first) == len(again) > 0
    for a, b in zip(first, again, strict=True):
        assert (a["controller"], a["seed"]) == (b["controller"], b["seed"])
        assert a["final_distance"] == b["final_distance"] and a["success"] == b["success"]
    # noise changes what the robots do, but not the episode units: same seeds, same starts
    noisy = json.loads((out / "sweep" / "pose_noise.xy-0.3" / "results.json").read_text())["episodes"]
    assert [r["seed"] for r in noisy] == [r["seed"] for r in first]
    assert any(a["final_distance"] != b["final_distance"] for a, b in zip(noisy, first, strict=True))
    # a second call without --resume refuses to overwrite; with --resume it reruns nothing
    assert (
        ev.main(
            [
                *TINY,
                "--controllers",
                "consensus",
                "consensus-free",
                "--sweep",
                "pose_noise.xy=0,0.3",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    again_code = ev.main(
        [
            *TINY,
            "--controllers",
            "consensus",
            "consensus-free",
            "--sweep",
            "pose_noise.xy=0,0.3",
            "--out",
            str(out),
            "--resume",
        ]
    )
    assert again_code == 0
    assert json.loads((out / "robustness.json").read_text())[0]["rows"] == profile["rows"]


def test_the_tail_is_the_mean_of_the_worst_tenth() -> None:
    values = list(range(1, 21))  # worst 10% of 20 values: 19 and 20
    assert tail_mean(values, 0.1) == 19.5
    assert tail_mean([3.0], 0.1) == 3.0 and math.isnan(tail_mean([], 0.1))
    low, high = bootstrap_tail_interval(values, 0.1, resamples=500)
    assert low <= 19.5 <= high <= 20
    assert bootstrap_tail_interval(values, 0.1, resamples=500) == (low, high)  # seeded
    assert np.isnan(bootstrap_tail_interval([], 0.1)).all()


def test_a_level_that_is_the_same_run_as_another_runs_once(tmp_path) -> None:
    from evaluation.experiments.sweep import level_aliases

    axes = [
        parse_sweep("pose_noise.xy=0,0.2"),
        parse_sweep("comm.drop=0.0,0.5"),
        parse_sweep("actuation_delay=0,1"),
    ]
    aliases = level_aliases(RunSpec(slips=["nominal"]), axes)
    assert aliases == {"comm.drop=0.0": "pose_noise.xy=0", "actuation_delay=0": "pose_noise.xy=0"}
    out = tmp_path / "o"
    args = [
        *TINY,
        "--controllers",
        "consensus-free",
        "--sweep",
        "pose_noise.xy=0,0.2",
        "--sweep",
        "comm.drop=0,0.5",
    ]
    assert ev.main([*args, "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "sweep").iterdir()) == [
        "comm.drop-0.5",
        "pose_noise.xy-0",
        "pose_noise.xy-0.2",
    ]
    profiles = {p["key"]: p for p in json.loads((out / "robustness.json").read_text())}
    zero = {r["level"]: r for r in profiles["comm.drop"]["rows"]}[0]
    assert zero == {**{r["level"]: r for r in profiles["pose_noise.xy"]["rows"]}[0], "level": 0}


def test_the_report_of_a_sweep_is_read_back_checked(tmp_path, capsys) -> None:
    def report(argv: list[str]) -> int:  # python evaluate.py --sweep-report OUT
        return ev.main(["--sweep-report", *argv])

    out = tmp_path / "o"
    args = [*TINY, "--controllers", "consensus-free", "--sweep", "actuation_delay=0,2"]
    assert ev.main([*args, "--out", str(out)]) == 0
    first = (out / "robustness.json").read_text()
    assert report([str(out)]) == 0 and (out / "robustness.json").read_text() == first
    # a level not finished is named and left out, never dropped silently
    (out / "sweep" / "actuation_delay-2" / "results.json").unlink()
    assert report([str(out)]) == 0
    assert "levels not finished, left out: actuation_delay=2" in capsys.readouterr().err
    assert report([str(out), "--reference", "nobody"]) == 2
    assert "--reference 'nobody' is not one of the run's controllers" in capsys.readouterr().err
    # a level's results of another run, a torn one, a foreign manifest: refused by name
    other = json.loads((out / "sweep" / "actuation_delay-0" / "results.json").read_text())
    other["config"]["env_settings"]["actuation_delay"] = 3
    (out / "sweep" / "actuation_delay-2" / "results.json").write_text(json.dumps(other))
    assert report([str(out)]) == 2
    assert "records actuation_delay=3, not 2: it belongs to another run" in capsys.readouterr().err
    (out / "sweep" / "actuation_delay-2" / "results.json").write_text('{"schema_version": 3, "conf')
    assert (
        report([str(out)]) == 2 and "actuation_delay-2/results.json' is not JSON" in capsys.readouterr().err
    )
    (out / "sweep.json").write_text("[1, 2]")
    assert report([str(out)]) == 2 and "is not a KoopNav sweep manifest" in capsys.readouterr().err


def _records(controller: str, successes: list[bool], distances: list[float]) -> list[dict]:
    return [
        {
            "key": f"e|{controller}|m|s|{t}",
            "env_id": "e",
            "controller": controller,
            "map": "m",
            "slip": "s",
            "trial": t,
            "status": "ok",
            "success": ok,
            "final_distance": [d, d],
            "final_poses": [[float(t), 0.0, 0.0]] * 2,  # a distinct episode per trial
        }
        for t, (ok, d) in enumerate(zip(successes, distances, strict=True))
    ]


def test_the_profile_statistics_on_a_hand_made_sweep() -> None:
    from types import SimpleNamespace as Results  # profiles read a run's records and config only

    from evaluation.stats.robustness import profiles

    config = {"controllers": ["ref", "other"]}
    level_0 = Results(
        records=_records("ref", [True] * 4, [0.01] * 4)
        + _records("other", [True, True, False, True], [0.02, 0.02, 1.0, 0.02]),
        config=config,
    )
    level_1 = Results(
        records=_records("ref", [True, True, True, False], [0.01, 0.01, 0.01, 0.5])
        + _records("other", [False, False, False, True], [0.3, 0.4, 2.0, 0.02]),
        config=config,
    )
    (profile,) = profiles({"comm.drop": [(0, level_0), (0.5, level_1)]})
    assert profile.reference == "ref" and profile.levels == [0, 0.5]
    other = {row.level: row for row in profile.curve("other")}
    assert (other[0].successes, other[0.5].successes) == (3, 1)
    assert other[0.5].distance == pytest.approx(100 * np.mean([0.3, 0.4, 2.0, 0.02]))
    paired = other[0.5].paired
    assert paired["pairs"] == 4 and paired["success_difference"] == pytest.approx(1 / 4 - 3 / 4)
    assert paired["distance_difference"] == pytest.approx(100 * np.mean([0.29, 0.39, 1.99, -0.48]))
    # AUC: per unit (trial) the mean success over the levels, then the mean over units
    assert profile.summary["other"]["auc"] == pytest.approx(np.mean([0.5, 0.5, 0.0, 1.0]))
    assert profile.summary["ref"]["auc"] == pytest.approx(np.mean([1.0, 1.0, 1.0, 0.5]))
    # tail: the worst ceil(10% of 8) = 1 episode of the sweep
    assert profile.summary["other"]["tail"] == pytest.approx(200.0)
    low, high = profile.summary["other"]["auc_low"], profile.summary["other"]["auc_high"]
    assert 0.0 <= low <= profile.summary["other"]["auc"] <= high <= 1.0
    with pytest.raises(ValueError, match=r"--reference 'nobody' is not one of the run's controllers"):
        profiles({"comm.drop": [(0, level_0)]}, reference="nobody")

    # the overview: every axis's AUC per controller, and the axis with the largest drop
    from evaluation.reports.sections import overview_section, robustness_sections

    assert overview_section([profile]) is None  # one axis: its own summary says it all
    both = profiles(
        {"comm.drop": [(0, level_0), (0.5, level_1)], "pose_noise.xy": [(0, level_0), (0.1, level_0)]}
    )
    overview = overview_section(both)
    assert overview is not None and robustness_sections(both)[0] == overview
    header, rows = overview.blocks[1].table
    assert header[1:3] == ["comm.drop AUC [%]", "pose_noise.xy AUC [%]"]
    by_controller = {row[0]: row for row in rows}
    assert by_controller["other"][1].startswith("50 [") and by_controller["other"][2].startswith("75 [")
    assert by_controller["other"][3] == "comm.drop (75% -> 25% at 0.5)"
    assert by_controller["ref"][3] == "comm.drop (100% -> 75% at 0.5)"


def test_a_sweep_prints_its_overview_to_the_terminal(tmp_path, capsys) -> None:
    words = [w for w in TINY if w != "--quiet"]
    args = [*words, "--controllers", "consensus", "consensus-free", "--sweep", "actuation_delay=0,2"]
    assert ev.main([*args, "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "| Controller | actuation_delay=0 | actuation_delay=2 | AUC |" in out
    assert "| consensus-free | 0% (2) | 0% (2) | 0% |" in out  # never succeeds, every episode distinct


def test_what_each_level_costs_each_controller_against_its_own_first_level() -> None:
    from types import SimpleNamespace as Results

    from evaluation.reports.sections import level_cost_section, markdown
    from evaluation.stats.robustness import level_costs
    from evaluation.stats.statistics import paired_comparison

    config = {"controllers": ["ref", "other"]}
    level_0 = Results(
        records=_records("ref", [True] * 4, [0.01] * 4)
        + _records("other", [True, True, False, True], [0.02] * 4),
        config=config,
    )
    level_1 = Results(
        records=_records("ref", [True, True, True, False], [0.01] * 4)
        + _records("other", [False, False, False, True], [0.3] * 4),
        config=config,
    )
    costs = level_costs({"sensing": [("state", level_0), ("lidar", level_1)]})
    assert [(c.controller, c.level, c.first, c.pairs) for c in costs] == [
        ("ref", "lidar", "state", 4),
        ("other", "lidar", "state", 4),
    ]
    other = costs[1]
    expected = paired_comparison([False, False, False, True], [True, True, False, True])
    assert (other.success, other.first_success) == (0.25, 0.75)
    assert (other.difference, other.p_value) == (expected.difference, expected.p_value)
    assert all(c.p_holm >= c.p_value for c in costs)  # Holm never lowers a p-value
    text = markdown([level_cost_section(costs)])
    assert "| other | sensing | lidar (state) | 4 | 25 (75) |" in text
    assert level_cost_section([]) is None
    # a bit-identical twin of `other` (a -robust variant at nominal slip): its test is other's,
    # counted once in the family, so the Holm values do not move
    twin_config = {"controllers": ["ref", "other", "twin"]}
    with_twin = [
        Results(
            records=run.records
            + [{**r, "controller": "twin"} for r in run.records if r["controller"] == "other"],
            config=twin_config,
        )
        for run in (level_0, level_1)
    ]
    twinned = level_costs({"sensing": [("state", with_twin[0]), ("lidar", with_twin[1])]})
    assert [c.p_holm for c in twinned] == [costs[0].p_holm, costs[1].p_holm, costs[1].p_holm]
