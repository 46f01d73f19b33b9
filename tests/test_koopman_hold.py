"""Held (piecewise-constant) identification inputs (issue 62): ``DataSpec.hold`` and
``koopman-nmpc:hold``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from controllers.calibration import MAX_HOLD, DataSpec, collect_data, data_spec_for
from controllers.koopman.store import _model_key, calibrated_model, fit_on_plant
from koopman_envs import make_plant

ENV = "KoopNav-TargetReaching-v0"


def _plant(budget: int, seed: int = 0):
    return make_plant(ENV, slip="high", budget=budget, seed=seed)


@pytest.mark.parametrize("hold", [0, -1, MAX_HOLD + 1, 1.5, "3", True, None])
def test_bad_hold_is_refused_by_name(hold) -> None:
    import controllers

    for make in (
        lambda: DataSpec(2, 100, hold=hold),
        lambda: data_spec_for(200, 0, hold=hold),
        lambda: controllers.make("koopman-nmpc", hold=hold),
        lambda: calibrated_model(_plant(200), 0, hold=hold),
    ):
        with pytest.raises(ValueError, match=rf"hold={hold!r} must be an integer >= 1 and <= {MAX_HOLD}"):
            make()


@pytest.mark.parametrize("hold", [1, 7, 25])
def test_held_inputs_are_constant_over_the_hold_and_change_between_holds(hold) -> None:
    steps, teams = 103, 4  # not a multiple of the holds: the last hold is cut at the end
    spec = DataSpec(teams, steps, seed=3, hold=hold)
    data = collect_data(_plant(spec.transitions), spec)
    commands = data.commands
    assert commands.shape == (steps, teams, 3, 2) and data.states.shape == (steps + 1, teams, 3, 3)
    starts = np.arange(0, steps, hold)
    for start in starts:
        block = commands[start : start + hold]
        np.testing.assert_array_equal(block, np.broadcast_to(block[0], block.shape))
    # a new draw at every hold's start, for every robot and both inputs (continuous draws: never equal)
    assert np.all(commands[starts[1:]] != commands[starts[1:] - 1])
    assert np.abs(commands).max() <= spec.input_bound
    # the draws are the hold=1 stream's first ceil(steps / hold) periods, each held
    paper = collect_data(_plant(teams * steps), DataSpec(teams, steps, seed=3)).commands
    np.testing.assert_array_equal(commands[starts], paper[: len(starts)])


def test_hold_one_is_the_papers_data_set_and_cache_key() -> None:
    spec = data_spec_for(2000, 0)
    assert spec.hold == 1 and "hold" not in spec.to_dict()  # keys of caches and shipped files unchanged
    assert data_spec_for(2000, 0, hold=10).to_dict()["hold"] == 10
    plant = _plant(2000)
    keys = {hold: _model_key(plant, data_spec_for(2000, 0, hold), "minimal", 0.0) for hold in (1, 2, 10)}
    assert len(set(keys.values())) == 3  # the hold is part of the model cache key
    assert keys[1] == _model_key(plant, DataSpec(2, 1000, seed=0), "minimal", 0.0)


def test_calibration_with_a_hold_is_deterministic_to_the_bit() -> None:
    spec = data_spec_for(2000, 0, hold=10)
    first, second = (fit_on_plant(_plant(2000), spec, velocity=True) for _ in range(2))
    for name in ("A", "B", "N", "C"):
        assert np.asarray(getattr(first, name)).tobytes() == np.asarray(getattr(second, name)).tobytes()
    assert first.metadata == second.metadata and first.metadata["data"]["hold"] == 10
    paper = fit_on_plant(_plant(2000), data_spec_for(2000, 0), velocity=True)
    assert not np.array_equal(paper.A, first.A)  # held data are other data


def test_koopman_nmpc_calibrates_on_held_inputs() -> None:
    import controllers
    from controllers.mpc.variants import KoopmanNMPC

    ctrl = KoopmanNMPC(hold=5, velocity=True)
    summary = ctrl.calibrate(_plant(2000), seed=0)
    assert ctrl.model is not None and ctrl.model.metadata["data"]["hold"] == 5
    assert summary["key"] == _model_key(
        _plant(2000), data_spec_for(2000, 0, 5), "minimal", 0.0, velocity=True
    )
    assert controllers.options("koopman-nmpc").option("hold").default == 1


# --------------------------------------------------------------------------- random holds
@pytest.mark.parametrize(("hold", "random_hold"), [(30, 1), (30, "true"), (30, None), (1, True)])
def test_bad_random_hold_is_refused_by_name(hold, random_hold) -> None:
    import controllers

    for make in (
        lambda: DataSpec(2, 100, hold=hold, random_hold=random_hold),
        lambda: data_spec_for(200, 0, hold=hold, random_hold=random_hold),
        lambda: controllers.make("koopman-nmpc", hold=hold, random_hold=random_hold),
        lambda: calibrated_model(_plant(200), 0, hold=hold, random_hold=random_hold),
    ):
        with pytest.raises(ValueError, match=r"random_hold="):
            make()


def _segments(commands: np.ndarray, team: int, robot: int) -> tuple[np.ndarray, np.ndarray]:
    """The periods a robot's command changes at (0 first) and the lengths of its holds."""
    changed = np.any(commands[1:, team, robot] != commands[:-1, team, robot], axis=-1)
    starts = np.r_[0, np.nonzero(changed)[0] + 1]
    return starts, np.diff(np.r_[starts, commands.shape[0]])


def test_random_holds_are_drawn_from_one_to_hold_per_robot() -> None:
    steps, teams, hold = 1000, 3, 30
    spec = DataSpec(teams, steps, seed=4, hold=hold, random_hold=True)
    commands = collect_data(_plant(spec.transitions), spec).commands
    paper = collect_data(_plant(teams * steps), DataSpec(teams, steps, seed=4)).commands
    assert commands.shape == paper.shape and np.abs(commands).max() <= spec.input_bound
    lengths_of_all = []
    for team in range(teams):
        for robot in range(3):
            starts, lengths = _segments(commands, team, robot)
            # the robot's k-th command is the hold=1 stream's period k, held 1..hold periods
            np.testing.assert_array_equal(commands[starts, team, robot], paper[: len(starts), team, robot])
            assert lengths[:-1].min() >= 1 and lengths.max() <= hold  # the last one may be cut
            lengths_of_all.append(lengths[:-1])
    lengths = np.concatenate(lengths_of_all)
    # short and long holds both (a fixed hold would give one length), mean near (1 + hold) / 2
    assert lengths.min() <= 3 and lengths.max() >= hold - 2
    assert abs(lengths.mean() - (1 + hold) / 2) < 2.0
    # robots switch at their own periods, not together
    assert not np.array_equal(_segments(commands, 0, 0)[0], _segments(commands, 0, 1)[0])


def test_random_hold_is_part_of_the_key_and_leaves_the_fixed_holds_alone() -> None:
    assert "random_hold" not in data_spec_for(2000, 0, hold=10).to_dict()
    assert data_spec_for(2000, 0, hold=10, random_hold=True).to_dict()["random_hold"] is True
    plant = _plant(2000)
    fixed = _model_key(plant, data_spec_for(2000, 0, 10), "minimal", 0.0)
    randomly = _model_key(plant, data_spec_for(2000, 0, 10, True), "minimal", 0.0)
    assert fixed != randomly


def test_calibration_with_random_holds_is_deterministic_to_the_bit() -> None:
    spec = data_spec_for(2000, 0, hold=30, random_hold=True)
    first, second = (fit_on_plant(_plant(2000), spec, velocity=True) for _ in range(2))
    for name in ("A", "B", "N", "C"):
        assert np.asarray(getattr(first, name)).tobytes() == np.asarray(getattr(second, name)).tobytes()
    assert first.metadata == second.metadata and first.metadata["data"]["random_hold"] is True
    fixed = fit_on_plant(_plant(2000), data_spec_for(2000, 0, hold=30), velocity=True)
    assert not np.array_equal(fixed.A, first.A)  # other data than a fixed hold of 30


def test_koopman_nmpc_calibrates_on_random_holds() -> None:
    import controllers
    from controllers.mpc.variants import KoopmanNMPC

    ctrl = KoopmanNMPC(hold=20, random_hold=True, velocity=True)
    summary = ctrl.calibrate(_plant(2000), seed=0)
    assert ctrl.model is not None and ctrl.model.metadata["data"]["random_hold"] is True
    assert summary["key"] == _model_key(
        _plant(2000), data_spec_for(2000, 0, 20, True), "minimal", 0.0, velocity=True
    )
    assert controllers.options("koopman-nmpc").option("random_hold").default is False


# --------------------------------------------------------------------------- docs/physics.md's figures
ROOT = Path(__file__).resolve().parents[1]
#: the committed outputs of ``bench/physics_model_error.py --json`` behind docs/physics.md's held-input table
MEASURED = ROOT / "data" / "physics_model_error"
LIFT_NAMES = {
    "koopman": "pose only",
    "koopman-u3": "memory 3",
    "koopman-v": "velocity",
    "koopman-u3v": "memory 3 + velocity",
    "unicycle": "unicycle",
}


def held_rows(row: dict) -> list[str]:
    """The Markdown rows docs/physics.md shows for one level of one bench output (every lift, the
    unicycle last; ratios over the unicycle's)."""
    circle, windows, one_step = row["circle"], row["closed_loop"], row["identification"]["one_step"]
    out = []
    for name, label in LIFT_NAMES.items():
        if name not in windows:
            continue
        c, w = circle[name]["mean"], windows[name]
        ratios = (
            ("", "")
            if name == "unicycle"
            else (
                f"{c / circle['unicycle']['mean']:.2f}",
                f"{w / windows['unicycle']:.2f}",
            )
        )
        # the unicycle fits nothing: one row per floor; random holds are drawn from 1..hold
        hold = "" if name == "unicycle" else f"1..{row['hold']}" if row.get("random_hold") else row["hold"]
        refits = row.get("rollout_refits", 0)  # refits of the fit on its own rollouts
        if refits and name != "unicycle":
            label += f", {refits} refit" + ("s" if refits > 1 else "")
        out.append(
            f"| {row['level']} ({row['surface']}) | {hold} | {label} | {c:.1f} | {ratios[0]} | {w:.1f} "
            f"| {ratios[1]} | {one_step[name]:.2f} | {circle['speed'][name]:.3f} |"
        )
    return out


def test_the_held_input_figures_of_the_physics_page_are_the_committed_measurements() -> None:
    page = (ROOT / "docs" / "physics.md").read_text(encoding="utf-8")
    files = sorted(MEASURED.glob("*.json"))
    assert files, f"no bench output in {MEASURED}"
    for path in files:
        for row in json.loads(path.read_text(encoding="utf-8")):
            for line in held_rows(row):
                assert line in page, f"docs/physics.md lacks the row of {path.name}: {line}"


def page_commands(page: str) -> list:
    """Every ``python bench/physics_model_error.py ...`` command of ``page``, parsed by the
    bench's own parser (so its defaults fill what a command leaves out)."""
    import shlex
    import sys

    sys.path.insert(0, str(ROOT / "bench"))
    try:
        from physics_model_error import build_parser
    finally:
        sys.path.remove(str(ROOT / "bench"))
    prefix = "python bench/physics_model_error.py"
    lines = [line.split("#")[0] for line in page.splitlines() if line.startswith(prefix)]
    return [build_parser().parse_args(shlex.split(line)[2:]) for line in lines]


def made_by(row: dict, command) -> bool:
    """Whether ``command`` (parsed) measures ``row``: its level, hold, random hold, refits and lifts."""
    lifts = {f"koopman-u{memory}" for memory in command.memory}
    if command.velocity:
        lifts |= {"koopman-v"} | {f"koopman-u{memory}v" for memory in command.memory}
    return (
        row["level"] in command.levels
        and row["hold"] == command.hold
        and bool(row.get("random_hold")) == command.random_hold
        and row.get("rollout_refits", 0) == command.rollout_refits
        and set(row["closed_loop"]) == {"koopman", "unicycle"} | lifts
    )


def test_the_physics_pages_commands_name_the_controller_the_committed_measurements_ran() -> None:
    """Every committed row names its closed-loop controller, and the page's commands that make
    the row (the bench's defaults filling what they leave out) drive the same one: the hand-set
    ``nominal-nmpc-v0``, not the tuned ``nominal-nmpc`` (another closed loop)."""
    commands = page_commands((ROOT / "docs" / "physics.md").read_text(encoding="utf-8"))
    assert commands, "docs/physics.md shows no bench/physics_model_error.py command"
    for path in sorted(MEASURED.glob("*.json")):
        for row in json.loads(path.read_text(encoding="utf-8")):
            controller = row["measured_with"]["controller"]
            makers = [command for command in commands if made_by(row, command)]
            assert makers, f"no command on docs/physics.md makes {path.name}'s {row['level']} row"
            for command in makers:
                assert command.controller == controller, (path.name, command.controller, controller)


#: Map 1 closed-loop episodes on the physics plant behind the page's closed-loop table: the
#: evaluator's records (episodes.jsonl) reduced to the fields the table uses (:data:`EPISODE_FIELDS`)
EPISODES = ROOT / "data" / "physics_closed_loop"
EPISODE_FIELDS = ("controller", "slip", "seed", "success", "collision", "steps", "final_distance")


def episode_rows(records: list[dict]) -> list[str]:
    """The page's rows of Map 1 episodes: per controller and floor, successes, every seed's periods
    (and collision), and the robots' final distance to their targets (mean and largest) [cm]."""
    cells: dict[tuple[str, str], list[dict]] = {}
    for record in records:
        cells.setdefault((record["controller"], record["slip"]), []).append(record)
    out = []
    for (controller, slip), cell in cells.items():
        cell.sort(key=lambda r: r["seed"])
        distances = np.array([r["final_distance"] for r in cell]) * 100.0
        periods = ", ".join(
            f"{r['steps']}" + (f" ({r['collision']})" if r["collision"] else "") for r in cell
        )
        out.append(
            f"| `{controller}` | {slip} | {sum(r['success'] for r in cell)}/{len(cell)} | {periods} "
            f"| {distances.mean():.1f} | {distances.max():.1f} |"
        )
    return out


def test_the_closed_loop_figures_of_the_physics_page_are_the_committed_episodes() -> None:
    page = (ROOT / "docs" / "physics.md").read_text(encoding="utf-8")
    for path in sorted(EPISODES.glob("*.jsonl")):
        records = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]
        assert records and all(set(r) == set(EPISODE_FIELDS) for r in records), path.name
        for line in episode_rows(records):
            assert line in page, f"docs/physics.md lacks the row of {path.name}: {line}"


def reduce_episodes(source: Path, target: Path) -> None:
    """Write the evaluator's ``episodes.jsonl`` at ``source`` as the reduced records at ``target``."""
    lines = [json.loads(line) for line in source.read_text(encoding="utf-8").splitlines()]
    kept = [{k: r[k] for k in EPISODE_FIELDS} for r in lines if r.get("status") == "ok"]
    target.write_text("".join(json.dumps(r) + "\n" for r in kept), encoding="utf-8")


if __name__ == "__main__":  # print the rows for the page: python tests/test_koopman_hold.py
    for path in sorted(MEASURED.glob("*.json")):
        for row in json.loads(path.read_text(encoding="utf-8")):
            print("\n".join(held_rows(row)))
    for path in sorted(EPISODES.glob("*.jsonl")):
        print(
            "\n".join(
                episode_rows([json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()])
            )
        )
