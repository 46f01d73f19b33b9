"""The robustness figures a reader can read (evaluation/reports/figures.py): families, one colour
per controller in every figure, identical twins drawn once, units on the axes."""

from __future__ import annotations

from evaluation.reports.figures import FAMILIES, axis_label, colour_of, family_of, save_profile_figures, twins
from evaluation.stats.robustness import AxisProfile, LevelRow


def _row(controller: str, level, successes: int, distance: float) -> LevelRow:
    return LevelRow(controller, level, 10, successes, 0.1, 0.9, distance, distance - 1, distance + 1)


def _profile() -> AxisProfile:
    profile = AxisProfile("actuation_delay", [0, 2], "koopman-nmpc")
    for name, curve in {
        "koopman-nmpc": [(9, 3.0), (5, 9.0)],
        "koopman-nmpc-robust": [(9, 3.0), (5, 9.0)],  # the twin: the same at every level
        "dmpc-nominal": [(10, 2.0), (8, 4.0)],
        "rl-ppo-set": [(9, 2.5), (9, 2.5)],
    }.items():
        for level, (wins, distance) in zip(profile.levels, curve, strict=True):
            profile.rows.append(_row(name, level, wins, distance))
        profile.summary[name] = {"auc": 0.5}
    return profile


def test_families_twins_colours_and_units() -> None:
    assert [family_of(n) for n in ("koopman-nmpc", "dmpc-koopman", "safe:nominal-nmpc", "consensus", "rl-ppo-set")] == [
        FAMILIES[0], FAMILIES[1], FAMILIES[2], FAMILIES[2], FAMILIES[3]
    ]  # fmt: skip
    assert sorted(map(sorted, twins(_profile()))) == [
        ["dmpc-nominal"],
        ["koopman-nmpc", "koopman-nmpc-robust"],
        ["rl-ppo-set"],
    ]
    # the same colour wherever a controller appears; different controllers, different colours
    assert colour_of("koopman-nmpc") == colour_of("koopman-nmpc")
    assert len({colour_of(n) for n in ("koopman-nmpc", "nominal-nmpc", "dmpc-koopman", "consensus")}) == 4
    assert colour_of("my-plugin:label") == colour_of("my-plugin:label")
    assert axis_label("actuation_delay") == "actuation delay [periods of 0.1 s]"
    assert axis_label("pose_noise.xy").endswith("[m]") and axis_label("unknown.key") == "unknown.key"


def test_a_figure_is_written_per_axis(tmp_path) -> None:
    categorical = AxisProfile("uncertainty", ["nominal", "realistic"], "koopman-nmpc")
    for level in categorical.levels:
        categorical.rows.append(_row("koopman-nmpc", level, 5, 4.0))
    categorical.summary["koopman-nmpc"] = {"auc": 0.5}
    paths = save_profile_figures([_profile(), categorical], tmp_path)
    assert [p.name for p in paths] == ["robustness_actuation_delay.png", "robustness_uncertainty.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
