"""The evaluator as a research harness: configurations, user controllers, env settings, lists."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import evaluate as ev
from controllers.base import BaseController
from controllers.consensus import ConsensusController
from evaluation.run.configs import controller_configs, split_controller_list

TARGET = "KoopNav-TargetReaching-v0"


class StandStill(BaseController):
    """A controller of the user's own script: never moves (module level, so workers can import it)."""

    name = "stand-still"

    def __init__(self, speed: float = 0.0) -> None:
        super().__init__()
        self.speed = speed

    def _reset(self, scenario, seed):
        pass

    def _act(self, observation, info):
        return np.tile([self.speed, 0.0], self.scenario.n_robots)


def _one_consensus_episode_on(path: Path, steps: int) -> ev.RunSpec:
    """The run of one consensus episode of ``steps`` steps on the map file at ``path``, nominal slip."""
    return ev.RunSpec(
        TARGET,
        ["consensus"],
        maps=[str(path)],
        slips=["nominal"],
        episodes=1,
        env_kwargs={"max_episode_steps": steps},
    )


# slow: seven rows of episodes, about 3 CPU-s (issue 61); test_cli_runs_comma_lists_env_kwargs_and_random_maps
# keeps a harness run in the default run
@pytest.mark.slow
def test_options_and_a_script_local_class_are_their_own_rows() -> None:
    spec = ev.RunSpec(
        TARGET,
        {
            "mine": StandStill,
            "mine-moving": (StandStill, {"speed": 0.05}),
            "gentle": ("consensus", {"goal_gain": 0.01}),
            "default": "consensus",
            "text": "consensus:goal_gain=2.0",
        },
        maps=["map1"],
        slips=["nominal"],
        episodes=1,
        env_kwargs={"max_episode_steps": 40},
    )
    results = ev.evaluate(spec, workers=2)
    rows = {row["controller"] for row in results.leaderboard()}
    assert rows == {"mine", "mine-moving", "gentle", "default", "text"}
    by_label = {r["controller"]: r for r in results.records}
    assert all(r["status"] == "ok" for r in results.records), [r.get("error") for r in results.records]
    assert by_label["mine"]["controller_name"].endswith("test_research_harness.StandStill")
    # the options reached the controllers: different configurations, different motion
    still = np.asarray(by_label["mine"]["path_length"])
    moving = np.asarray(by_label["mine-moving"]["path_length"])
    assert np.all(still == 0) and np.all(moving > 0.05)
    assert by_label["gentle"]["final_poses"] != by_label["default"]["final_poses"]
    assert json.loads(by_label["gentle"]["controller_options"]) == {"goal_gain": 0.01}
    configs = {c["label"]: c for c in results.config["controller_configs"]}
    assert configs["text"] == {"label": "text", "name": "consensus", "options": {"goal_gain": 2.0}}


def test_env_kwargs_reach_the_env_and_the_record() -> None:
    spec = ev.RunSpec(
        TARGET,
        ["consensus"],
        maps=["random"],
        slips=["high"],
        episodes=1,
        env_kwargs={"max_episode_steps": 30, "n_robots": 5, "goal_tolerance": 0.08},
    )
    results = ev.evaluate(spec, workers=1)
    (rec,) = results.records
    assert rec["status"] == "ok", rec.get("error")
    assert np.asarray(rec["final_poses"]).shape == (5, 3)
    assert results.config["env_settings"]["n_robots"] == 5
    assert results.config["env_settings"]["goal_tolerance"] == 0.08 and rec["tolerance"] == 0.08


def test_random_maps_are_one_row_of_k_shared_layouts() -> None:
    spec = ev.RunSpec(
        TARGET,
        ["consensus", "consensus-free"],
        maps=["map1"],
        slips=["nominal"],
        episodes=1,
        random_maps=3,
        env_kwargs={"max_episode_steps": 20},
    )
    results = ev.evaluate(spec, workers=1)
    random_cells = [c for c in results.cells if c.map == "random"]
    assert len(random_cells) == 2 and all(c.episodes == 3 for c in random_cells)
    first = [r for r in results.records if r["map"] == "random" and r["trial"] == 0]
    # trial 0 of both controllers drove on one layout; the three trials have three layouts
    assert first[0]["obstacles"] == first[1]["obstacles"]
    targets = {
        json.dumps(r["targets"])
        for r in results.records
        if r["map"] == "random" and r["controller"] == "consensus"
    }
    assert len(targets) == 3


def test_a_user_map_file_is_fingerprinted_and_checked_on_resume(tmp_path) -> None:
    from koopman_envs.sim.maps.map_spec import load_map

    path = tmp_path / "mine.json"
    load_map("map1").save(path)
    out = tmp_path / "run"
    spec = _one_consensus_episode_on(path, 20)
    results = ev.evaluate(spec, workers=1, out=out)
    assert results.records[0]["status"] == "ok" and results.records[0]["map"] == str(path)
    assert str(path) in results.config["map_files"]
    layout = json.loads(path.read_text())
    layout["obstacles"][0][2] += 0.01  # the file changes between the run and its resume
    path.write_text(json.dumps(layout))
    with pytest.raises(ValueError, match="map_files"):
        ev.evaluate(spec, workers=1, out=out, resume=True)


@pytest.mark.parametrize("edit", ["obstacle moved", "not a map"])
def test_a_map_file_edited_after_its_fingerprint_does_not_change_the_run(tmp_path, edit) -> None:
    """The bytes fingerprinted are the bytes run: a map file replaced after the run read it (here
    between the plan and the first episode) changes neither the recorded fingerprint nor the map
    the episodes run on (they ran on the file read again, the edited one: other obstacles, or an
    error record for every episode)."""
    import hashlib

    from koopman_envs.sim.maps.map_spec import load_map

    path = tmp_path / "mine.json"
    load_map("map1").save(path)
    original = path.read_bytes()
    layout = json.loads(original)

    def replace_the_file(plan) -> None:
        if edit == "obstacle moved":
            edited = json.loads(original)
            edited["obstacles"][0][0] += 0.5
            path.write_text(json.dumps(edited))
        else:
            path.write_text("{not json")

    spec = _one_consensus_episode_on(path, 5)
    results = ev.evaluate(spec, workers=1, plan_check=replace_the_file)
    (record,) = results.records
    assert record["status"] == "ok", record.get("error")
    assert record["obstacles"] == layout["obstacles"]
    assert results.config["map_files"] == {str(path): hashlib.sha256(original).hexdigest()}


def test_a_run_reads_each_map_file_once_its_checks_included(tmp_path, monkeypatch) -> None:
    """The run's checks build every (env, map) from the text read for the run: a whole
    evaluate() reads a user map file once (it read it twice when RunSpec.validate built the
    map from the file), and validate given that text needs no file."""
    import koopman_envs.files
    import koopman_envs.sim.maps.map_spec as map_spec_module
    from evaluation.run import plan as plan_module
    from evaluation.run.plan import read_map_files
    from koopman_envs.sim.maps.map_spec import load_map

    path = tmp_path / "mine.json"
    load_map("map2").save(path)
    reads: list[str] = []
    real = koopman_envs.files.read_text

    def counting(name, *args, **kwargs):
        reads.append(str(name))
        return real(name, *args, **kwargs)

    for module in (plan_module, map_spec_module):  # the run's reader and the loader's
        monkeypatch.setattr(module, "read_text", counting)
    spec = ev.RunSpec(
        TARGET,
        ["consensus"],
        maps=[str(path)],
        slips=["nominal"],
        episodes=2,
        env_kwargs={"max_episode_steps": 3},
    )
    results = ev.evaluate(spec, workers=1)
    assert [r["status"] for r in results.records] == ["ok", "ok"]
    assert reads == [str(path)]
    files = read_map_files(spec.maps)
    path.unlink()
    spec.validate(1, files)  # built from the text: the file is gone
    with pytest.raises(Exception, match="mine.json"):
        spec.validate(1)


def test_an_episode_of_a_map_file_builds_its_map_from_the_text_read(tmp_path) -> None:
    """The plan's episodes carry the map file's text: the file itself is not read again."""
    from evaluation.run.plan import read_map_files
    from koopman_envs.sim.maps.map_spec import load_map

    path = tmp_path / "mine.json"
    load_map("map2").save(path)
    spec = ev.RunSpec(TARGET, ["consensus"], maps=[str(path)], slips=["nominal"], episodes=2).resolved()
    files = read_map_files(spec.maps)
    path.unlink()
    plan = spec.episodes_plan(map_files=files)
    assert [episode.map for episode in plan] == [str(path)] * 2
    built = plan[0].make_kwargs()["map"]
    assert built.name == "map2" and built.obstacles.tolist() == load_map("map2").obstacles.tolist()
    assert "map_text" not in plan[0].record_fields()


def test_gifs_record_one_animation_per_cell(tmp_path) -> None:
    spec = ev.RunSpec(
        TARGET,
        ["consensus"],
        maps=["map1"],
        slips=["nominal"],
        episodes=2,
        gifs=True,
        env_kwargs={"max_episode_steps": 5},
    )
    results = ev.evaluate(spec, workers=1, out=tmp_path)
    first, second = results.records
    assert first["animation"] and not second["animation"]
    gif = tmp_path / first["animation"]
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")


def test_comma_separated_lists_work_like_spaced_ones() -> None:
    assert split_controller_list(
        ["nominal-nmpc,koopman-nmpc:horizon=30,uncertainty_margin=0", "consensus"]
    ) == ["nominal-nmpc", "koopman-nmpc:horizon=30,uncertainty_margin=0", "consensus"]
    assert ev.split_slips(["nominal,high", "0,0.1,0.2", "low,0,0,0.3"]) == [
        "nominal",
        "high",
        "0,0.1,0.2",
        "low",
        "0,0,0.3",
    ]
    assert ev.split_words(["map1,map2", "map3"]) == ["map1", "map2", "map3"]
    assert ev.parse_env_kwargs(["n_robots=5", 'random_map={"n_obstacles": 2}', "x=text"]) == {
        "n_robots": 5,
        "random_map": {"n_obstacles": 2},
        "x": "text",
    }
    # a dotted key sets one field of a dict keyword, over the fields given before
    given = {"pose_noise": {"xy": 0.5, "heading": 0.1}}
    assert ev.parse_env_kwargs(["pose_noise.xy=0.1", "comm.drop=0.2"], into=given) == {
        "pose_noise": {"xy": 0.1, "heading": 0.1},
        "comm": {"drop": 0.2},
    }
    assert given == {"pose_noise": {"xy": 0.5, "heading": 0.1}}  # not changed
    with pytest.raises(ValueError, match=r"n_robots is already 3, not a dict of fields"):
        ev.parse_env_kwargs(["n_robots.x=1"], into={"n_robots": 3})
    with pytest.raises(ValueError, match=r"actuation_delay is already 0, not a dict of fields"):
        ev.parse_env_kwargs(["actuation_delay=0", "actuation_delay.x=1"])
    with pytest.raises(ValueError, match=r"keyword.field for one field of a dict keyword"):
        ev.parse_env_kwargs(["pose_noise.=1"])


def test_cli_runs_comma_lists_env_kwargs_and_random_maps(tmp_path) -> None:
    cmd = [
        sys.executable,
        "evaluate.py",
        "--env",
        TARGET,
        "--controllers",
        "consensus,consensus:goal_gain=0.5",
        "--maps",
        "random",
        "--random-maps",
        "2",
        "--slips",
        "nominal,high",
        "--env-kwargs",
        "n_robots=4",
        "--max-episode-steps",
        "20",
        "--workers",
        "1",
        "--out",
        str(tmp_path),
        "--quiet",
    ]
    proc = subprocess.run(cmd, cwd=Path(ev.__file__).parent, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc["config"]["controllers"] == ["consensus", "consensus:goal_gain=0.5"]
    assert doc["config"]["slips"] == ["nominal", "high"] and doc["config"]["env_settings"]["n_robots"] == 4
    assert len(doc["episodes"]) == 2 * 2 * 2


def _lambda_factory_config():
    return {"inline": lambda: ConsensusController()}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (
            dict(env_kwargs={"n_robotz": 5}),
            "env_kwargs: 'n_robotz' is not one the environments take .did you mean "
            "'n_robots'.*; allowed: .*n_robots",
        ),
        (dict(env_kwargs={"map": "map2"}), "env_kwargs: 'map' is a cell axis"),
        (dict(env_kwargs={"n_robots": 5}), "map 'map1'.*n_robots"),
        (dict(env_kwargs={"goal_tolerance": -1}), "goal_tolerance=-1"),
        (dict(controllers=["consensus:goal_gain=-1"]), "goal_gain=-1"),
        (dict(controllers=["consensus:gain"]), "'gain' is not key=value"),
        (dict(controllers=["consensus:nope=1"]), "unknown option .nope."),
        (dict(controllers={"x": 42}), "'x': 42 is not a registered name"),
        (dict(controllers={"x": ("consensus", {"goal_gain": object()})}), "must be plain JSON"),
        (dict(controllers=_lambda_factory_config(), workers=2), "cannot be sent to worker processes"),
        (dict(random_maps=0), "random_maps=0 must be an integer >= 1"),
        (dict(gifs=True), "gifs=True needs an output directory"),
    ],
)
def test_bad_research_input_is_named_before_any_episode(kwargs, message) -> None:
    base = dict(
        envs=TARGET,
        controllers=["consensus"],
        maps=["map1"],
        slips=["nominal"],
        episodes=1,
        env_kwargs={"max_episode_steps": 10},
    )
    options = {"workers": kwargs.pop("workers", 1)}
    with pytest.raises(ValueError, match=message):
        ev.evaluate(ev.RunSpec(**{**base, **kwargs}), **options)


def test_mapping_forms_give_the_same_configuration() -> None:
    a, b, c = controller_configs(
        {"g": "consensus:goal_gain=0.4", "h": ("consensus", {"goal_gain": 0.4}), "k": ConsensusController}
    )
    assert (a.name, a.options) == (b.name, b.options) == ("consensus", (("goal_gain", 0.4),))
    assert c.factory is ConsensusController and c.name == "controllers.consensus.ConsensusController"
