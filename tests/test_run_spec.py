"""RunSpec: the run as data. Validation names the field; presets are the protocols as they were;
the command line builds the spec its options say."""

from __future__ import annotations

import pytest

import evaluate as ev
from evaluation.experiments.protocols import PAPER_EXACT, PROTOCOLS, protocol
from evaluation.run.configs import ControllerConfig
from evaluation.run.spec import RunSpec
from koopman_envs.params import PARAMS

PAPER_MAPS = {"KoopNav-TargetReaching-v0": ("map1", "map2"), "KoopNav-Formation-v0": ("map3", "map4")}
BOTH = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")


@pytest.mark.parametrize(
    "changes, message",
    [
        (
            {"envs": ["KoopNav-Formaton-v0"]},
            r"envs: 'KoopNav-Formaton-v0' is not one of .* \(did you mean 'KoopNav-Formation-v0'",
        ),
        ({"controllers": []}, "controllers: no controller to evaluate"),
        ({"controllers": ["consensus", "consensus"]}, r"controllers: labels \['consensus'\] appear twice"),
        ({"controllers": ["consensus:gain"]}, "controllers: .*'gain' is not key=value"),
        ({"slips": []}, "slips: no slip setting"),
        ({"slips": ["extreme"]}, "slips: 'extreme'"),
        ({"episodes": 0}, "episodes=0 must be an integer >= 1"),
        ({"episodes": 2.5}, "episodes=2.5 must be an integer >= 1"),
        ({"seed": -1}, "seed=-1 must be an integer >= 0"),
        ({"calibration_seed": "a"}, "calibration_seed='a' must be an integer >= 0"),
        ({"random_maps": 0}, r"random_maps=0 must be an integer >= 1 and <= 10000 \(layouts per cell\)"),
        ({"gifs": "yes"}, "gifs='yes' must be True or False"),
        ({"solver": "sqp"}, r"'sqp' is not one of \['ipopt', 'fatrop', 'rti'\]|'sqp' is not one of"),
        (
            {"env_kwargs": {"max_episode_step": 5}},
            r"env_kwargs: 'max_episode_step' .*did you mean 'max_episode_steps'",
        ),
        ({"env_kwargs": {"slip": "high"}}, "env_kwargs: 'slip' is a cell axis"),
        ({"env_kwargs": {"n_robots": float("nan")}}, "env_kwargs: n_robots=nan must be plain JSON"),
        ({"env_kwargs": {"goal_tolerance": 0}}, "goal_tolerance=0 must be a finite number > 0"),
        ({"maps": ["map9"]}, "map 'map9'"),
    ],
)
def test_validation_names_the_field(changes, message) -> None:
    spec = RunSpec(controllers=["consensus"])
    spec.validate()  # the base spec is fine
    with pytest.raises(ValueError, match=message):
        spec.replace(**changes).validate()


def test_workers_are_checked_too() -> None:
    with pytest.raises(ValueError, match="workers=0 must be an integer >= 1"):
        RunSpec(controllers=["consensus"]).validate(workers=0)


def test_evaluate_takes_a_run_spec_only() -> None:
    with pytest.raises(TypeError, match="evaluate\\(\\) takes a RunSpec, got str"):
        ev.evaluate("KoopNav-Formation-v0")  # type: ignore[arg-type]


def test_forms_of_a_field_normalize_to_one_spec() -> None:
    a = RunSpec(
        envs="KoopNav-Formation-v0", controllers=["consensus"], maps=["map3"], slips=[[0.0, 0.1, 0.2]]
    )
    b = RunSpec(
        envs=["KoopNav-Formation-v0"],
        controllers=("consensus",),
        maps={"KoopNav-Formation-v0": "map3"},
        slips=("0.0,0.1,0.2",),
    )
    assert a == b
    assert a.maps == {"KoopNav-Formation-v0": ("map3",)} and a.slips == ("0.0,0.1,0.2",)


def test_env_settings_live_in_the_env_kwargs_only() -> None:
    spec = RunSpec(controllers=["consensus"], env_kwargs={"max_episode_steps": 40, "n_robots": 3})
    assert spec.env_settings() == {
        "goal_tolerance": PARAMS.goal_tolerance,
        "max_episode_steps": 40,
        "n_robots": 3,
        "start_noise": 0.0,
    }
    (episode, *_) = spec.episodes_plan()
    assert episode.make_kwargs() == {**spec.env_settings(), "map": "map1", "slip": "nominal"}
    config = spec.config(workers=1, backend="process")
    assert config["env_settings"] == spec.env_settings()
    assert (config["tolerance"], config["max_episode_steps"]) == (PARAMS.goal_tolerance, 40)


def test_signature_changes_with_what_an_episode_does() -> None:
    spec = RunSpec(controllers=["consensus"])
    assert spec.signature() == RunSpec(controllers=["consensus"]).signature()
    assert spec.signature() != spec.replace(seed=1).signature()
    assert spec.signature() != spec.replace(env_kwargs={"start_noise": 0.05}).signature()
    # spelling out an env default is the same run
    assert spec.signature() == spec.replace(env_kwargs={"goal_tolerance": PARAMS.goal_tolerance}).signature()


def test_presets_equal_the_protocols_field_by_field() -> None:
    """The values of the protocol dicts they replace (evaluation/experiments/protocols.py before RunSpec)."""
    quick = protocol("quick")
    assert (
        quick.envs,
        quick.maps,
        quick.slips,
        quick.episodes,
        quick.env_kwargs,
        quick.solver,
        quick.controllers,
    ) == (BOTH, PAPER_MAPS, ("high",), 2, {"start_noise": 0.05}, "rti", None)
    for name, strict in (("paper", False), ("paper-strict", True)):
        paper = protocol(name)
        assert (paper.envs, paper.maps, paper.slips, paper.episodes, paper.env_kwargs, paper.solver) == (
            BOTH,
            PAPER_MAPS,
            ("nominal", "low", "high"),
            10,
            {"start_noise": 0.05},  # distinct trials (the paper's exact starts: --start-noise 0)
            "ipopt",
        )
        # --paper-strict: the paper's controllers exactly (PAPER_EXACT's options, checked for what
        # they mean by tests/test_fair_comparison.py::test_paper_strict_builds_the_papers_controllers_exactly)
        expected = [
            ControllerConfig(n, n, PAPER_EXACT["nmpc" if n.endswith("nmpc") else n] if strict else ())
            for n in ("koopman-nmpc", "nominal-nmpc", "consensus")
        ]
        assert list(paper.controllers) == expected
    ablation = protocol("ablation")
    assert (ablation.envs, ablation.maps, ablation.slips, ablation.episodes, ablation.solver) == (
        BOTH,
        PAPER_MAPS,
        ("high",),
        20,
        "ipopt",
    )
    assert len(ablation.controllers) > 1
    crowd = protocol("crowd")
    with_random = {env: (*maps, "random") for env, maps in PAPER_MAPS.items()}  # the 20 layouts' row
    assert (crowd.envs, crowd.maps, crowd.slips, crowd.episodes, crowd.solver, crowd.random_maps) == (
        BOTH,
        with_random,
        ("nominal",),
        20,
        "rti",
        20,
    )
    for name in PROTOCOLS:
        spec = protocol(name)
        assert (spec.seed, spec.calibration_budget, spec.calibration_seed, spec.random_maps, spec.gifs) == (
            0,
            PARAMS.calibration_budget,
            0,
            20 if name == "crowd" else None,
            False,
        )


def test_an_unknown_protocol_gets_a_suggestion() -> None:
    with pytest.raises(ValueError, match=r"protocol 'papr' is not one of .* \(did you mean 'paper'\?\)"):
        protocol("papr")


def test_the_command_line_builds_the_spec_its_options_say() -> None:
    args = ev.build_parser().parse_args(
        [
            "--paper",
            "--episodes",
            "3",
            "--maps",
            "map1",
            "--env",
            "KoopNav-TargetReaching-v0",
            "--max-episode-steps",
            "50",
            "--env-kwargs",
            "n_robots=3",
            "--seed",
            "4",
        ]
    )
    spec = ev.spec_from_args(args)
    assert spec == protocol("paper").replace(
        envs=["KoopNav-TargetReaching-v0"],
        maps=["map1"],
        episodes=3,
        seed=4,
        env_kwargs={"start_noise": 0.05, "max_episode_steps": 50, "n_robots": 3},
    )
    # controllers named on the command line keep their own solver; --solver applies to them
    named = ev.spec_from_args(ev.build_parser().parse_args(["--controllers", "nominal-nmpc"]))
    assert named.solver is None and named.env_kwargs == {"start_noise": 0.05}
    assert (
        ev.spec_from_args(
            ev.build_parser().parse_args(["--controllers", "nominal-nmpc", "--solver", "rti"])
        ).solver
        == "rti"
    )

    # --fallback-solver reaches every NMPC configuration whose default it is not (no rescue is
    # the NMPCs' default: --fallback-solver none changes no configuration)
    def rescue(name: str) -> list[dict]:
        args = ["--controllers", "nominal-nmpc", "dmpc-nominal", "consensus", "--fallback-solver", name]
        return [
            dict(c.options)
            for c in ev.spec_from_args(ev.build_parser().parse_args(args)).resolved().controllers
        ]

    assert rescue("none") == [{}, {}, {}]
    assert rescue("ipopt") == [{"fallback_solver": "ipopt"}, {"fallback_solver": "ipopt"}, {}]
    with pytest.raises(SystemExit):  # argparse names the allowed values
        ev.build_parser().parse_args(["--fallback-solver", "rti"])
    # the quick board keeps its solver for its own (all registered) controllers
    assert ev.spec_from_args(ev.build_parser().parse_args([])) == protocol("quick")
