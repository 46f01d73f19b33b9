"""A sweep whose episodes raise: exit 3 (episodes raised) as a run without ``--sweep``, the count
printed per level, and the robustness report says which controller raised where (issue 41, item 5)."""

from __future__ import annotations

from test_sweep import TINY as SWEEP_TINY

import evaluate as ev

# the sweep tests' tiny run, with shorter episodes: every episode of a raising controller raises
# at once anyway
TINY = [
    *SWEEP_TINY[: SWEEP_TINY.index("--max-episode-steps") + 1],
    "10",
    *SWEEP_TINY[SWEEP_TINY.index("--max-episode-steps") + 2 :],
]


def test_a_level_where_every_episode_raised_fails_the_sweep(tmp_path, capsys) -> None:
    out = tmp_path / "sweep"
    code = ev.main(
        [
            *TINY,
            "--controllers",
            "consensus",
            "plugin_controllers:AlwaysRaising:label=raising",
            "--sweep",
            "comm.drop=0,0.5",
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert code == ev.EPISODES_RAISED_EXIT == 3, err  # the count is printed, not encoded
    assert "4 episode(s) raised in the sweep" in err  # 2 of the raising controller at each of 2 levels
    assert "2 episode(s) raised at comm.drop=0;" in err and "2 episode(s) raised at comm.drop=0.5;" in err
    report = (out / "robustness.md").read_text()
    assert "| raising | 0 | 0 (2 raised) |" in report and "| raising | 0.5 | 0 (2 raised) |" in report
    assert "**4 episode(s) raised and are not counted**: raising at 0 (2), raising at 0.5 (2)" in report
    assert "| raising | 0 | 0 (2 raised) | - | - | - |" in report  # no pairs: not the reference
    assert "| consensus | 0 | 2 |" in report  # the other controller's episodes count as before


def test_a_sweep_without_errors_still_exits_0(tmp_path) -> None:
    out = tmp_path / "sweep"
    assert (
        ev.main([*TINY, "--controllers", "consensus", "--sweep", "comm.drop=0,0.5", "--out", str(out)]) == 0
    )
    assert "raised" not in (out / "robustness.md").read_text()
