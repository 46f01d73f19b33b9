"""Property test of the evaluator's command line (issue 41): random values of every flag either
make a run that validates and is ready to start, or are refused with exit 2 and a message, never
another exception, never a memory blow-up.

Each example runs ``evaluate.main`` on one small cell (consensus, map1, the drawn flag on top) up
to the moment the first episode would start: a ``plan_check`` stops it there, after every check of
the options, the run's configuration and its plan. Examples: :data:`EXAMPLES` per flag (about
40 flags). Memory: the peak of Python allocations per example stays under :data:`PEAK_BYTES`. No
time limit is asserted (the suite runs on busy machines); Hypothesis' deadline is off.
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import evaluate as ev
import evaluation.execution.runner as runner
from evaluation.cli import (
    build_parser,
    command,  # the command evaluate.py runs: what a test stubs
)

EXAMPLES = 12
PEAK_BYTES = 400 * 2**20

#: flags whose values name files to write (drawn inside the example's directory only)
_PATHS = {"--out", "--ablation-out", "--sweep-report"}
#: one small cell, overridden by the drawn flag (argparse: the last value wins)
BASE = ["--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--controllers", "consensus"]
BASE += ["--episodes", "1", "--workers", "1", "--quiet"]

WORDS = st.sampled_from(
    [
        "consensus",
        "nominal-nmpc",
        "map1",
        "map9",
        "random",
        "high",
        "nominal",
        "0,0.1,0.2",
        "comm.drop=0,0.5",
        "comm.drop=0,,0.5",
        "pose_noise.xy=0,0.1",
        "n_robots=5",
        "n_robots=100000",
        "movers.count=3",
        "lidar.beams=99999999",
        "x=1",
        "=",
        "",
        "os:mkdir:path=/tmp/never",
        "KoopNav-Formation-v0",
        "crowd",
        "model",
        "rti",
        "none",
    ]
)
NUMBERS = st.one_of(
    st.integers(-(10**25), 10**25),
    st.integers(-3, 30),
    st.floats(allow_nan=True, allow_infinity=True),
).map(str)
VALUES = st.one_of(WORDS, NUMBERS, st.text(max_size=12))


class _Ready(BaseException):  # not an Exception: main() reports those as internal errors (exit 1)
    """The run validated and planned: the first episode would start now."""


def _flags() -> list:
    return [a for a in build_parser()._actions if a.option_strings and a.option_strings[0] != "-h"]


FLAGS = _flags()


@pytest.fixture
def stop_before_episodes(monkeypatch):
    real = runner.evaluate

    def evaluate_until_ready(spec, **kwargs):
        def ready(plan):
            if kwargs.get("plan_check") is not None:
                kwargs["plan_check"](plan)
            raise _Ready(len(plan))

        return real(spec, **{**kwargs, "plan_check": ready})

    monkeypatch.setattr(runner, "evaluate", evaluate_until_ready)
    monkeypatch.setattr(command, "evaluate", evaluate_until_ready)


@pytest.mark.parametrize("flag", FLAGS, ids=[a.option_strings[0] for a in FLAGS])
def test_every_flag_validates_or_is_refused_with_exit_2(
    flag, tmp_path_factory, stop_before_episodes, capsys
) -> None:
    name = flag.option_strings[0]

    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )
    @given(values=st.lists(VALUES, min_size=1, max_size=3))
    def check(values: list[str]) -> None:
        work = tmp_path_factory.mktemp("run")
        if name in _PATHS:
            values = [str(work / Path(v).name or "x") for v in values[:1]]
        words = [name] if flag.nargs == 0 else [name, *(values if flag.nargs in ("+", "*") else values[:1])]
        argv = [*BASE, "--out", str(work / "out"), "--ablation-out", str(work / "ablation.md"), *words]
        tracemalloc.start()
        try:
            code = ev.main(argv)
        except _Ready:
            code = None
        except SystemExit as exc:  # argparse refuses a value of the wrong type or choice
            code = exc.code
        finally:
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        err = capsys.readouterr().err
        assert peak < PEAK_BYTES, f"{argv}: {peak / 2**20:.0f} MB"
        assert code in (None, 0, 2), f"{argv} -> exit {code}: {err[-2000:]}"
        if code == 2:
            assert "error:" in err and "Traceback" not in err, err

    check()
