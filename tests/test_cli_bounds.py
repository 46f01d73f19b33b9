"""The command line refuses what would hang, exhaust memory or silently drop a setting (issue 41,
items 4 and 9): episode counts beyond the stated bound, an env keyword given twice with different
values, an empty sweep level; each named before any episode."""

from __future__ import annotations

import pytest

import evaluate as ev
from koopman_envs.params import MAX_EPISODES_PER_CELL

ARGS = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
ARGS += ["--workers", "1", "--quiet"]


@pytest.mark.parametrize(
    "extra, message",
    [
        (
            ["--episodes", "99999999999999999999999"],
            f"episodes=99999999999999999999999 must be an integer >= 1 and <= {MAX_EPISODES_PER_CELL} (trials per cell)",
        ),
        (
            ["--episodes", str(MAX_EPISODES_PER_CELL + 1)],
            f"episodes={MAX_EPISODES_PER_CELL + 1} must be an integer >= 1 and <= {MAX_EPISODES_PER_CELL}",
        ),
        (
            ["--random-maps", "10000000000"],
            f"random_maps=10000000000 must be an integer >= 1 and <= {MAX_EPISODES_PER_CELL} (layouts per cell)",
        ),
        (
            ["--env-kwargs", "max_episode_steps=5", "--max-episode-steps", "20"],
            "--max-episode-steps 20 and --env-kwargs max_episode_steps=5 set the same env keyword to "
            "different values; give it once",
        ),
        (
            ["--tolerance", "0.1", "--env-kwargs", "goal_tolerance=0.2"],
            "--tolerance 0.1 and --env-kwargs goal_tolerance=0.2 set the same env keyword",
        ),
        (
            ["--sweep", "comm.drop=0,,0.5"],
            "--sweep 'comm.drop=0,,0.5': level 2 is empty (two commas in a row, or a comma at an end)",
        ),
        (["--sweep", "comm.drop=0,0.5,"], "level 3 is empty"),
        (["--workers", "10000000"], "workers=10000000 must be an integer >= 1 and <= 1024"),
        (
            ["--calibration-budget", "10000000000"],
            "calibration budget=10000000000 must be an integer >= 1 and <= 10000000",
        ),
        (["--sweep", "comm.drop=0"], "give at least two levels"),
        (["--env-kwargs", "comm.latency=1000000000"], "comm.latency=1000000000 must be an integer"),
        (["--env-kwargs", "actuation_delay=1000000000"], "actuation_delay=1000000000 must be an integer"),
        (
            ["--env-kwargs", "lidar.beams=10000000", "sensing=lidar"],
            "lidar.beams=10000000 must be an integer",
        ),
    ],
)
def test_bad_sizes_and_conflicts_exit_2_before_any_episode(tmp_path, capsys, extra, message) -> None:
    out = tmp_path / "run"
    code = ev.main(
        [*ARGS, "--episodes", "1", *extra, "--out", str(out)]
        if "--episodes" not in extra
        else [*ARGS, *extra, "--out", str(out)]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err and "Traceback" not in err
    assert not (out / "episodes.jsonl").exists()


def test_the_same_value_given_both_ways_is_accepted(tmp_path) -> None:
    code = ev.main(
        [
            *ARGS,
            "--episodes",
            "1",
            "--max-episode-steps",
            "5",
            "--env-kwargs",
            "max_episode_steps=5",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
