"""The learned policies on the benchmark (issue 60): trained on the suite's train layouts, the
checkpoint chosen on validation, the test split refused by the trainers by name, seeds trained by
a resumable driver, and their test results aggregated (IQM over seeds in rliable's unit, one score per seed)."""

from __future__ import annotations

import json
import os
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

from baselines.suite_training import CheckpointScore, SuiteTraining, choose, refuse_held_out_map
from evaluation.episodes.records import selection_key
from evaluation.experiments.seeds import (
    SeedRun,
    aggregate,
    chosen_seed,
    evaluate_seeds,
    outcomes_by_label,
    report_markdown,
)

from helpers.training import TINY_IPPO_BATCHES, TINY_SB3, one_seed_driver

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[1]
SUITE = "koopnav-bench-v1"
HELD_OUT = r"split='test' is held out"
#: a tiny set-policy run: 2 envs x 3 robots x 64 steps per rollout, 2 validation layouts

#: a tiny IPPO run: 2 envs, 2 iterations of 200 frames
TINY_IPPO = ["--frames", "400", *TINY_IPPO_BATCHES]


# ----------------------------------------------------------------------------- held out by name
def test_the_sb3_trainer_refuses_the_test_split_by_name_before_any_work(tmp_path, capsys) -> None:
    from baselines.sb3.train import main

    out = tmp_path / "run"
    argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, "--out", str(out)]
    argv += [
        "--timesteps",
        "384",
        "--validation-layouts",
        "1",
        *TINY_SB3,
    ]  # a trainer that failed to refuse ends soon
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--split", "test"])
    assert exit_info.value.code == 2
    assert "split='test' is held out: the test split may not be used for training" in capsys.readouterr().err
    assert not out.exists()  # nothing started
    with pytest.raises(SystemExit):
        main([*argv, "--split", "tset"])
    assert "split='tset' is not one of" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # --split without --suite
        main(["--split", "train", "--out", str(out)])
    assert "--split needs --suite NAME" in capsys.readouterr().err


def test_selection_on_the_test_split_and_a_test_map_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=HELD_OUT + r".*checkpoint selection"):
        SuiteTraining(SUITE, "formation", selection_split="test").check()
    with pytest.raises(
        ValueError, match=HELD_OUT + r": map='suite:koopnav-bench-v1/test' may not be used for training"
    ):
        refuse_held_out_map({"map": "suite:koopnav-bench-v1/test"})
    refuse_held_out_map({"map": "suite:koopnav-bench-v1/train"})  # train and validation are fine
    refuse_held_out_map({"map": "random"})
    from evaluation.tune.configuration import evaluate_configuration

    with pytest.raises(ValueError, match=HELD_OUT + r".*checkpoint selection"):
        evaluate_configuration("ippo", {}, "formation", "test", [0], 1, 0, purpose="checkpoint selection")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--suite", SUITE, "--split", "test"], HELD_OUT + ": the test split may not be used for training"),
        (["--env-kwargs", '{"map": "suite:koopnav-bench-v1/test"}'], HELD_OUT + ": map="),
        (["--stages", '[{"share": 1, "env": {"map": "suite:koopnav-bench-v1/test"}}]'], HELD_OUT),
        (["--suite", SUITE, "--algorithm", "mappo"], "--suite trains --algorithm ippo"),
        (["--suite", SUITE, "--curriculum"], "leave out --curriculum and --stages"),
        (["--suite", SUITE, "--env-kwargs", '{"slip": "nominal"}'], "--suite sets slip itself"),
    ],
)
def test_the_benchmarl_trainer_refuses_the_test_split_by_name_before_any_work(
    options: list[str], message: str, tmp_path, capsys
) -> None:
    pytest.importorskip("benchmarl")
    from baselines.marl.benchmarl_train import main

    with pytest.raises(SystemExit) as exit_info:
        main(
            [
                "--task",
                "formation",
                "--algorithm",
                "ippo",
                *TINY_IPPO,
                *options,
                "--out",
                str(tmp_path / "run"),
            ]
        )
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_the_training_envs_are_the_train_layouts_under_the_benchmarks_settings() -> None:
    env = SuiteTraining(SUITE, "target_reaching").env_kwargs()
    assert env == {
        "map": "suite:koopnav-bench-v1/train",
        "slip": "high",
        "goal_tolerance": 0.1,
        "max_episode_steps": 600,
        "start_noise": 0.05,
    }


# ----------------------------------------------------------------------------- checkpoint choice
def _score(step: int, successes: int, distance: float | None) -> CheckpointScore:
    return CheckpointScore(step, f"ck{step}", successes, 10, 0, distance)


def test_the_kept_checkpoint_is_the_best_by_success_then_final_distance_then_the_later() -> None:
    assert choose([_score(1, 3, 0.5), _score(2, 4, 2.0), _score(3, 2, 0.1)]).step == 2
    assert choose([_score(1, 4, 0.5), _score(2, 4, 0.7), _score(3, 4, None)]).step == 1
    assert choose([_score(1, 4, 0.5), _score(2, 4, 0.5)]).step == 2
    with pytest.raises(ValueError, match="no checkpoint was scored"):
        choose([])


def _policy_weights(folder: Path) -> bytes:
    with zipfile.ZipFile(folder / "policy.zip") as archive:
        return archive.read("policy.pth")


@pytest.mark.slow
def test_a_tiny_suite_run_keeps_the_checkpoint_best_on_validation_and_is_deterministic(tmp_path) -> None:
    """A real set-policy run (1,152 robot-steps) on the train layouts, every checkpoint scored on
    2 validation layouts through the evaluator; twice with the same seed, the same weights."""
    from baselines.sb3.train import main

    def run(out: Path) -> None:
        argv = ["--env", "KoopNav-TargetReaching-v0", "--policy", "set", "--suite", SUITE, "--seed", "3"]
        argv += ["--timesteps", "1152", "--eval-freq", "384", "--validation-layouts", "2", "--threads", "1"]
        assert main([*argv, *TINY_SB3, "--out", str(out)]) == 0

    run(tmp_path / "a")
    record = json.loads((tmp_path / "a" / "selection.json").read_text())
    steps = [c["step"] for c in record["checkpoints"]]
    assert steps == [384, 768, 1152]
    assert all(c["episodes"] == 2 and c["errors"] == 0 for c in record["checkpoints"])
    assert record["suite"]["labels"]["selection"].startswith("koopnav-bench-v1/target_reaching/validation@")
    assert record["suite"]["env"]["map"] == "suite:koopnav-bench-v1/train"
    best = max(record["checkpoints"], key=lambda c: (c["success_rate"], -c["mean_final_distance"], c["step"]))
    assert record["chosen"]["step"] == best["step"]
    kept = tmp_path / "a" / "target_reaching"
    metadata = json.loads((kept / "metadata.json").read_text())
    assert metadata["trained_on"].startswith("koopnav-bench-v1/target_reaching/train@")
    assert (
        metadata["selected_timesteps"] == best["step"] and metadata["selection"]["chosen"] == record["chosen"]
    )
    chosen_files = tmp_path / "a" / "checkpoints" / f"step_{best['step']}" / "target_reaching"
    assert (kept / "policy.zip").read_bytes() == (chosen_files / "policy.zip").read_bytes()
    run(tmp_path / "b")
    for step in steps:
        folder = f"checkpoints/step_{step}/target_reaching"
        assert _policy_weights(tmp_path / "a" / folder) == _policy_weights(tmp_path / "b" / folder)


@pytest.mark.slow
def test_a_tiny_ippo_suite_run_exports_scores_and_keeps_a_checkpoint(tmp_path) -> None:
    pytest.importorskip("benchmarl")
    import numpy as np

    from baselines.marl.benchmarl_train import main

    argv = ["--task", "formation", "--algorithm", "ippo", "--suite", SUITE, *TINY_IPPO]
    argv += ["--eval-freq", "200", "--validation-layouts", "2"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    record = json.loads((tmp_path / "a" / "selection.json").read_text())
    assert [c["step"] for c in record["checkpoints"]] == [200, 400]
    assert all(c["episodes"] == 2 for c in record["checkpoints"])
    kept = np.load(tmp_path / "a" / "formation" / "policy.npz")
    chosen = np.load(
        tmp_path / "a" / "checkpoints" / f"frames_{record['chosen']['step']}" / "formation" / "policy.npz"
    )
    assert all(np.array_equal(kept[k], chosen[k]) for k in chosen.files)
    metadata = json.loads((tmp_path / "a" / "formation" / "metadata.json").read_text())
    assert metadata["env"]["map"] == "suite:koopnav-bench-v1/train" and metadata["env"]["max_cycles"] == 600


# ----------------------------------------------------------------------------- the driver
def _driver(root: Path) -> subprocess.CompletedProcess[str]:
    sb3_args = [*TINY_SB3, "--eval-freq", "384"]
    return one_seed_driver(
        "rl-ppo-set", "target_reaching", root, 900, TIMESTEPS="384", SB3_ARGS=" ".join(sb3_args)
    )()


@pytest.mark.slow
def test_the_driver_skips_a_finished_seed_and_restarts_an_unfinished_one(tmp_path) -> None:
    seed_dir = tmp_path / "rl-ppo-set" / "target_reaching" / "seed0"
    first = _driver(tmp_path)
    assert first.returncode == 0, first.stderr
    marker = json.loads((seed_dir / "finished.json").read_text())
    assert marker["policy"] == "rl-ppo-set" and marker["seed"] == 0
    assert (seed_dir / "target_reaching" / "policy.zip").is_file() and (seed_dir / "selection.json").is_file()
    stamp = (seed_dir / "selection.json").stat().st_mtime_ns

    again = _driver(tmp_path)
    assert again.returncode == 0, again.stderr
    assert "seed 0: finished, skipped" in again.stdout
    assert (seed_dir / "selection.json").stat().st_mtime_ns == stamp  # not trained again

    (seed_dir / "finished.json").unlink()  # as an interrupted run leaves it
    (seed_dir / "half-written").write_text("x")
    restarted = _driver(tmp_path)
    assert restarted.returncode == 0, restarted.stderr
    assert "unfinished run" in restarted.stdout and "removed; training again" in restarted.stdout
    assert not (seed_dir / "half-written").exists() and (seed_dir / "finished.json").is_file()

    # the seed, evaluated on 2 test layouts through the evaluator
    [summary] = evaluate_seeds(
        tmp_path, ["rl-ppo-set"], ["target_reaching"], layouts=(0, 2), workers=1, n_boot=200
    )
    assert summary["suite"].startswith("koopnav-bench-v1/target_reaching/test@")
    assert summary["aggregate"].seeds == (0,) and summary["aggregate"].layouts == 2


def test_the_driver_refuses_an_unknown_policy_before_touching_a_folder(tmp_path) -> None:
    result = subprocess.run(
        ["bash", str(ROOT / "data/training/run.sh"), "rl-ppo-sett"],
        env={**os.environ, "TRAINING_ROOT": str(tmp_path / "t")},
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 2 and "unknown policy 'rl-ppo-sett'" in result.stderr
    assert not (tmp_path / "t").exists()


# ----------------------------------------------------------------------------- aggregation
#: outcomes[seed][layout]: two episodes per (layout, seed)
HAND_MADE = {
    0: {0: [1, 1], 1: [1, 1], 2: [0, 0], 3: [1, 1]},
    1: {0: [1, 0], 1: [1, 1], 2: [0, 0], 3: [0, 1]},
    2: {0: [0, 0], 1: [1, 0], 2: [0, 1], 3: [1, 1]},
}


def test_the_aggregate_scores_each_seed_over_the_layouts_as_rliable_scores_each_run() -> None:
    result = aggregate(HAND_MADE, n_boot=500)
    # one score per seed (rliable's (task, run) score): 6/8, 4/8, 4/8; 3 scores, n // 4 = 0 cut:
    # the IQM is their mean, 14/24, and the report leads with the mean
    assert result.iqm[0] == pytest.approx(14 / 24) and result.mean[0] == pytest.approx(14 / 24)
    assert result.lead == "mean" and result.strata == (None,)
    assert {s: r[0] for s, r in result.per_seed.items()} == {0: 0.75, 1: 0.5, 2: 0.5}
    assert result.seeds == (0, 1, 2) and result.layouts == 4
    for low_high in (result.iqm[1:], result.mean[1:], *(r[1:] for r in result.per_seed.values())):
        assert 0.0 <= low_high[0] <= low_high[1] <= 1.0
    assert aggregate(HAND_MADE, n_boot=500) == result  # a function of its arguments
    runs = [SeedRun("ippo", "formation", s, Path("."), {"success_rate": 0.5, "step": 10}) for s in (0, 1, 2)]
    table = report_markdown(
        [
            {
                "policy": "ippo",
                "task": "formation",
                "suite": "s",
                "runs": runs,
                "aggregate": result,
                "chosen": runs[0],
            }
        ]
    )
    assert "| `ippo` | formation | s | 3 | 4 | mean 58.3% [" in table
    assert "(3 seeds: fewer than 4, the IQM trims nothing)" in table
    # by stratum: layouts 0, 1 "easy", 2, 3 "hard": scores (easy, hard) per seed (1, .5), (.75, .25),
    # (.25, .75); 6 scores sorted .25 .25 .5 .75 .75 1, 1 cut at each end: (.25 + .5 + .75 + .75) / 4
    by_tier = aggregate(HAND_MADE, strata={0: "easy", 1: "easy", 2: "hard", 3: "hard"}, n_boot=500)
    assert by_tier.iqm[0] == pytest.approx(0.5625) and by_tier.strata == ("easy", "hard")
    with pytest.raises(ValueError, match=r"seed 1 ran layouts \[0, 1\], seed 0 ran \[0, 1, 2, 3\]"):
        aggregate({0: HAND_MADE[0], 1: {0: [1], 1: [0]}})
    with pytest.raises(ValueError, match=r"strata has no stratum for layouts \[3\]"):
        aggregate(HAND_MADE, strata={0: "a", 1: "a", 2: "b"})


def test_one_episode_per_layout_still_separates_a_78_from_a_97_percent_policy() -> None:
    """The audit's case: at the default ``--episodes 1`` a (layout, seed) score is 0 or 1, and the
    IQM of 0/1 scores was 1.0 for both policies. Scored per seed, the aggregates are distinct, in
    order, near the true rates, and their intervals do not overlap."""
    rng = np.random.default_rng(60)
    results = {
        p: aggregate(
            {s: {lay: [bool(rng.random() < p)] for lay in range(200)} for s in range(5)}, n_boot=1000
        )
        for p in (0.78, 0.97)
    }
    weak, strong = results[0.78], results[0.97]
    assert weak.iqm[0] == pytest.approx(0.78, abs=0.04) and strong.iqm[0] == pytest.approx(0.97, abs=0.02)
    assert weak.iqm[2] < strong.iqm[1]
    assert weak.lead == strong.lead == "iqm"  # 5 seeds: the IQM trims one at each end


def test_records_group_by_variant_and_layout() -> None:
    records = [
        {"controller": "ippo@seed0", "layout": 4, "success": True},
        {"controller": "ippo@seed0", "layout": 4, "success": None, "status": "error"},
        {"controller": "ippo@seed1", "layout": 5, "success": False},
    ]
    assert outcomes_by_label(records) == {"ippo@seed0": {4: [True, False]}, "ippo@seed1": {5: [False]}}


def test_the_shipped_seed_is_chosen_on_validation_never_on_test() -> None:
    def run(seed: int, rate: float, distance: float | None) -> SeedRun:
        return SeedRun(
            "ippo",
            "formation",
            seed,
            Path(f"seed{seed}"),
            {"success_rate": rate, "mean_final_distance": distance},
        )

    assert chosen_seed([run(0, 0.5, 0.1), run(1, 0.7, 0.9), run(2, 0.6, 0.0)]).seed == 1
    assert chosen_seed([run(0, 0.7, 0.3), run(1, 0.7, 0.2)]).seed == 1
    assert chosen_seed([run(0, 0.7, 0.2), run(1, 0.7, 0.2)]).seed == 0
    with pytest.raises(ValueError, match="no finished seed"):
        chosen_seed([])


def test_the_checkpoint_and_the_seed_are_chosen_by_one_rule() -> None:
    # one helper (evaluation.episodes.records.selection_key) orders both, with only the last
    # tie-break their own: the later checkpoint, the lower seed
    rng = np.random.default_rng(0)
    for _ in range(200):
        n = int(rng.integers(1, 6))
        successes = rng.integers(0, 4, size=n)  # few values: ties in success are common
        distances = [None if rng.random() < 0.2 else float(rng.choice([0.1, 0.2, 0.3])) for _ in range(n)]
        scores = [CheckpointScore(k, f"ck{k}", int(successes[k]), 10, 0, distances[k]) for k in range(n)]
        runs = [
            SeedRun("ippo", "formation", k, Path(f"seed{k}"), dict(scores[k].as_dict())) for k in range(n)
        ]
        for score in scores:
            assert score.order() == selection_key(score.success_rate, score.mean_final_distance, score.step)
        # the same validation records: the same pick, but where only the tie-break separates them
        best = max(selection_key(s.success_rate, s.mean_final_distance, 0) for s in scores)
        tied = [s.step for s in scores if selection_key(s.success_rate, s.mean_final_distance, 0) == best]
        assert choose(scores).step == max(tied)
        assert chosen_seed(runs).seed == min(tied)
