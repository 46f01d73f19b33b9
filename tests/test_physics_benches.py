"""The physics plant's benches (bench/physics_model_error.py, bench/physics_speed.py): what their
rows record, their counts checked by name, their JSON written whole or not at all, and no success
without MuJoCo."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from koopman_envs.params import INSTALL_HINT

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import physics_model_error  # noqa: E402
import physics_speed  # noqa: E402


@pytest.mark.parametrize(
    ("bench", "argv", "message"),
    [
        (physics_model_error, ["--episodes", "0"], r"--episodes=0 must be an integer >= 1"),
        (physics_model_error, ["--repetitions", "-3"], r"--repetitions=-3 must be an integer >= 1"),
        (physics_model_error, ["--horizon", "0"], r"--horizon=0 must be an integer >= 1"),
        (physics_model_error, ["--held-out-budget", "0"], r"--held-out-budget=0 must be an integer >= 1"),
        (physics_model_error, ["--controller", "nominal-nmcp"], r"--controller: controller 'nominal-nmcp'"),
        (physics_speed, ["--repeats", "0"], r"--repeats=0 must be an integer >= 1"),
        (physics_speed, ["--envs", "1"], r"--envs=1 must be an integer >= 2"),
        (physics_speed, ["--seconds", "0"], r"--seconds=0.0 must be a number > 0"),
    ],
)
def test_a_bad_count_is_refused_by_name_before_any_work(bench, argv, message, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        bench.main(argv)
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err or pytest.fail(capsys.readouterr().err)


def test_the_speed_bench_without_mujoco_fails_naming_the_install_command(monkeypatch, capsys) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a)
    )
    with pytest.raises(SystemExit) as exit_info:
        physics_speed.main(["--seconds", "0.01", "--repeats", "1"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert INSTALL_HINT in err and "nothing timed" in err


def test_the_speed_bench_leaves_the_old_json_whole_when_the_new_one_cannot_be_written(
    monkeypatch, tmp_path
) -> None:
    """A figure that does not serialize: the file given to --json keeps its old content (an
    ``open(path, "w")`` would have emptied it before ``json.dump`` failed)."""
    pytest.importorskip("mujoco")
    out = tmp_path / "speed.json"
    out.write_text('{"old": 1}')
    monkeypatch.setattr(physics_speed, "single", lambda *a: (1.0, np.float32(1.5)))
    monkeypatch.setattr(physics_speed, "vector", lambda *a: (2.0, 2.0))
    with pytest.raises(TypeError, match="not JSON serializable"):
        physics_speed.main(["--seconds", "0.01", "--repeats", "1", "--json", str(out)])
    assert out.read_text() == '{"old": 1}'
    assert [p.name for p in tmp_path.iterdir()] == ["speed.json"]  # no temporary file left
    monkeypatch.setattr(physics_speed, "single", lambda *a: (1.0, 1.5))
    physics_speed.main(["--seconds", "0.01", "--repeats", "1", "--json", str(out)])
    assert json.loads(out.read_text())["physics single env"] == [1.0, 1.5]


def test_the_model_error_bench_leaves_the_old_json_whole_when_interrupted_while_writing(
    monkeypatch, tmp_path
) -> None:
    """Interrupted while the JSON file is serialized (the printed rows before it are not): the
    old file stays whole (an ``open(path, "w")`` would have emptied it first)."""

    class Interrupted(Exception):
        pass

    class JsonStoppedWhileWriting:
        """``json`` as the bench uses it, interrupted when it serializes the file (indent=1)."""

        @staticmethod
        def dumps(obj: object, indent: int | None = None) -> str:
            if indent is not None:
                raise Interrupted
            return json.dumps(obj)

        @staticmethod
        def dump(obj: object, fp: object, indent: int | None = None) -> None:
            raise Interrupted

    out = tmp_path / "rows.json"
    out.write_text("[]")
    monkeypatch.setattr(physics_model_error, "measure", lambda level, args: {"level": level})
    monkeypatch.setattr(physics_model_error, "tables", lambda rows, args: "")
    monkeypatch.setattr(physics_model_error, "json", JsonStoppedWhileWriting)
    with pytest.raises(Interrupted):
        physics_model_error.main(["--levels", "high", "--json", str(out)])
    assert out.read_text() == "[]"
    monkeypatch.setattr(physics_model_error, "json", json)
    physics_model_error.main(["--levels", "high", "--json", str(out)])
    assert json.loads(out.read_text()) == [{"level": "high"}]


def test_every_row_records_what_it_was_measured_with() -> None:
    """The default controller is the hand-set nominal NMPC (the committed figures'), recorded
    with its options, the seeds, horizon, episodes, budgets and the checkout's commit."""
    args = physics_model_error.build_parser().parse_args(
        ["--seed", "4", "--episodes", "2", "--budget", "500"]
    )
    assert args.controller == physics_model_error.CONTROLLER == "nominal-nmpc-v0"
    record = physics_model_error.provenance(args)
    assert record["controller"] == "nominal-nmpc-v0"
    assert record["controller_options"]["horizon"] == 20  # the hand-set horizon, not the tuned 34
    assert record["seed"] == 4 and record["held_out_seed"] == 1004 and record["episode_seeds"] == [1004, 1005]
    assert (record["horizon"], record["episodes"], record["budget"]) == (20, 2, 500)
    assert record["held_out_budget"] == 20_000 and record["repetitions"] == 30
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    assert record["commit"] == (head.stdout.strip() if head.returncode == 0 else None)
    json.dumps(record)  # it serializes
    tuned = physics_model_error.provenance(
        physics_model_error.build_parser().parse_args(["--controller", "nominal-nmpc"])
    )
    assert tuned["controller_options"]["horizon"] != 20  # the tuned preset: another controller


def test_the_sim2sim_section_counts_every_controller_of_a_default_run() -> None:
    """The protocol's commands name no --controllers, so it runs every controller a default run
    takes (the registered ones but the -v0 variants, which run only when named): the page's count,
    its episodes (10 layouts x 2 tasks x 2 floors each) and the fine-tuned row's "one of N" follow
    controllers.available(variants=False)."""
    import re

    import controllers

    page = (ROOT / "docs" / "physics.md").read_text(encoding="utf-8")
    section = page[page.index("## The sim-to-sim protocol") : page.index("## Speed")]
    n = len(controllers.available(variants=False))
    assert "--controllers" not in section.split("```bash")[1].split("```")[0]
    assert re.findall(r"Every controller a default run takes \((\d+):", section) == [str(n)]
    assert re.findall(r"One of the (\d+) is not a transfer", section) == [str(n)]
    episodes = re.findall(r"(\d+) physics episodes \((\d+) controllers", section)
    assert episodes == [(str(n * 10 * 2 * 2), str(n))]
    assert "--layouts 0:10" in section and "slip=nominal,high" in section
