"""docs/crowd_results.md's collisions split by fault (issue 60; evaluation/reports/sections/fault_split.py,
docs/make_robustness_md.py ``--fault-split``): on a tiny real run among an oblivious ORCA crowd the
section shows the split and its counts add up to the records' own; a record written before the
fault rule is refused by name; an absent publication is said to be pending with the command that
makes it; and data/publish.sh's crowd_faults run plans crowd_crowd's episodes. The whole page,
this section included, is rebuilt byte for byte by tests/test_published_pages.py (-m slow)."""

from __future__ import annotations

import json
import shlex
import shutil
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest

from evaluation.cli.options import build_parser
from evaluation.cli.run_args import run_from_args
from evaluation.reports.sections.fault_split import FAULT_FIELDS, MissingFaultFields, fault_rows

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
import make_robustness_md  # noqa: E402  (docs/ is no package)
from make_pages import PAGES, page_digest, read_digests  # noqa: E402

from helpers.extras import skip_without_extra  # noqa: E402

LEVELS = (8, 16)
#: 2 episodes per controller and level (map1's trial 0 and one random layout) among 8 and 16 ORCA
#: pedestrians that do not see the robots: 8 episodes, 6 ended by a collision, 3 of them not at
#: the robot's fault (measured on the code of this commit; the test needs at least one of each)
TINY_RUN = (
    "--crowd crowd --controllers orca dwa --env KoopNav-TargetReaching-v0 --maps map1 "
    f"--random-maps 1 --episodes 1 --sweep movers.count={','.join(map(str, LEVELS))}"
)
HEADER = "| Controller | movers.count | Episodes | Success [%] | Success excusing unavoidable [%]"


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    skip_without_extra("pyrvo")  # the oblivious ORCA crowd and orca
    out = tmp_path_factory.mktemp("crowd") / "run"
    subprocess.run(
        [sys.executable, "evaluate.py", *shlex.split(TINY_RUN), "--out", str(out), "--quiet"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    )
    return out


def _log(run: Path, level: int) -> Path:
    return run / "sweep" / f"movers.count-{level}" / "episodes.jsonl"


def _records(run: Path, level: int) -> list[dict]:
    lines = [json.loads(line) for line in _log(run, level).read_text(encoding="utf-8").splitlines()]
    return [r for r in lines if "key" in r]


def _page(run: Path, out: Path, split: str) -> tuple[int, str]:
    code = make_robustness_md.main(
        [str(run), "--out", str(out), "--figures", str(out.parent / "figures"), "--fault-split", split]
    )
    return code, out.read_text(encoding="utf-8") if out.exists() else ""


def _section_rows(page: str) -> dict[tuple[str, str], list[str]]:
    """(Controller, level) -> the cells of its row in the section's table."""
    section = page[page.index("## Collisions by fault") :]
    table = section[section.index(HEADER) :].splitlines()[2:]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in table if line.startswith("|")]
    return {(row[0], row[1]): row for row in rows}


def test_the_section_splits_the_collisions_and_they_add_up(tiny_run, tmp_path) -> None:
    code, page = _page(tiny_run, tmp_path / "page.md", str(tiny_run))
    assert code == 0
    rows = _section_rows(page)
    assert list(rows) == [(c, str(level)) for c in ("dwa", "orca") for level in LEVELS]
    split = {"all": 0, "at": 0, "not": 0}
    for (controller, level), row in rows.items():
        mine = [r for r in _records(tiny_run, int(level)) if r["controller"] == controller]
        assert row[2] == str(len(mine)) == "2"
        collided = [r for r in mine if r["collision"] is not None]
        at_fault = sum(r["collision_at_fault"] for r in collided)
        # the page's counts are the records' own, and all = at fault + not at fault
        assert row[6:9] == [str(len(collided)), str(at_fault), str(len(collided) - at_fault)]
        assert int(row[6]) == int(row[7]) + int(row[8])
        success = sum(r["success"] for r in mine)
        excused = sum(r["success_excusing_unavoidable"] for r in mine)
        assert row[3].split(" [")[0] == f"{100 * success / 2:.0f}"
        assert row[4].split(" [")[0] == f"{100 * excused / 2:.0f}"
        assert row[5].split(" [")[0] == f"{100 * (excused - success) / 2:.0f}"
        split["all"] += len(collided)
        split["at"] += at_fault
        split["not"] += len(collided) - at_fault
    # the run holds both kinds, so the split is shown, not only a column of zeros
    assert split["at"] >= 1 and split["not"] >= 1
    assert "Pending" not in page


def _without(run: Path, tmp_path: Path, field: str) -> tuple[Path, str]:
    """A copy of ``run`` whose first record lacks ``field`` (as a record written before the
    fault rule), and that record's key."""
    copy = tmp_path / "old"
    shutil.copytree(run, copy)
    lines = _log(copy, LEVELS[-1]).read_text(encoding="utf-8").splitlines()
    index = next(i for i, line in enumerate(lines) if '"key"' in line)
    record = json.loads(lines[index])
    del record[field]
    lines[index] = json.dumps(record)
    _log(copy, LEVELS[-1]).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return copy, record["key"]


@pytest.mark.parametrize("field", FAULT_FIELDS)
def test_a_record_without_the_fields_is_refused_by_name(tiny_run, tmp_path, capsys, field) -> None:
    old, key = _without(tiny_run, tmp_path, field)
    code, _ = _page(old, tmp_path / "page.md", str(old))
    assert code == 2
    message = capsys.readouterr().err
    assert f"episode {key!r} has no field {field!r}" in message and str(old) in message
    assert not (tmp_path / "page.md").exists()  # no page with an "excusing" rate that was not measured
    records = _records(old, LEVELS[-1])
    with pytest.raises(MissingFaultFields, match=f"the publication: episode {key!r} has no field {field!r}"):
        fault_rows([(LEVELS[-1], _Run(records))], "the publication")


class _Run:
    """What fault_rows reads of a level's results: its records."""

    def __init__(self, records: list[dict]) -> None:
        self.records = records


def test_an_absent_publication_is_pending_and_names_the_command(tiny_run, tmp_path) -> None:
    code, page = _page(tiny_run, tmp_path / "page.md", str(tmp_path / "crowd_faults"))
    assert code == 0
    section = page[page.index("## Collisions by fault") :]
    assert "Pending" in section and f"`{tmp_path / 'crowd_faults'}`" in section
    assert "`bash data/publish.sh crowd_faults`" in section
    assert HEADER not in section  # no excusing column without the data


def test_the_section_rebuilds_byte_for_byte(tiny_run, tmp_path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _, first = _page(tiny_run, tmp_path / "a" / "page.md", str(tiny_run))
    _, second = _page(tiny_run, tmp_path / "b" / "page.md", str(tiny_run))
    assert first == second and "## Collisions by fault" in first


def test_the_packed_publication_gives_the_run_directorys_section(tiny_run, tmp_path) -> None:
    """What `bash data/publish.sh pack` makes of the run (data/NAME/, split per controller) is
    read alike: the section from the publication is the run directory's, command included."""
    publication = tmp_path / "crowd_faults"
    subprocess.run(
        [sys.executable, "-m", "evaluation.archive", str(tiny_run), str(publication)],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    assert (publication / "controllers" / "orca.tar.xz").is_file()
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _, from_run = _page(tiny_run, tmp_path / "a" / "page.md", str(tiny_run))
    _, packed = _page(tiny_run, tmp_path / "b" / "page.md", str(publication))
    section = from_run[from_run.index("## Collisions by fault") :]
    assert HEADER in section and packed.endswith(section)


def test_the_committed_page_names_the_pending_publication() -> None:
    """docs/crowd_results.md reads --fault-split data/crowd_faults (data/pages.json), and while
    that publication is absent the committed page says so; its digest is the generator's."""
    entry = next(e for e in PAGES if e["page"] == "docs/crowd_results.md")
    publication = entry["args"][entry["args"].index("--fault-split") + 1]
    assert publication == "data/crowd_faults"
    page = (ROOT / entry["page"]).read_text(encoding="utf-8")
    assert "## Collisions by fault" in page
    if not (ROOT / publication).exists():
        assert "Pending: the publication `data/crowd_faults`" in page
        assert "`bash data/publish.sh crowd_faults`" in page
    assert read_digests()[entry["page"]] == page_digest((ROOT / entry["page"]).read_bytes())


def _published_runs() -> dict[str, str]:
    """data/publish.sh's runs as bash expands them (its definitions only; nothing is run)."""
    script = (ROOT / "data" / "publish.sh").read_text(encoding="utf-8")
    definitions = script[: script.index("\nrun() {")]
    show = 'for name in "${!RUNS[@]}"; do printf "%s\\t%s\\n" "$name" "${RUNS[$name]}"; done'
    printed = subprocess.run(
        ["bash", "-c", f"{definitions}\n{show}", str(ROOT / "data" / "publish.sh")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return dict(line.split("\t", 1) for line in printed.splitlines())


def test_crowd_faults_plans_crowd_crowds_episodes() -> None:
    """The publication differs from crowd_crowd by its controllers only: the same tasks, maps,
    random layouts, trials, seed, env settings (the ORCA crowd, start noise), solver and mover
    counts, so that its records pair with crowd_crowd's by key."""
    runs = _published_runs()
    crowd, faults = (
        run_from_args(build_parser().parse_args(shlex.split(runs[n])))
        for n in ("crowd_crowd", "crowd_faults")
    )
    assert faults.sweep == crowd.sweep == ("movers.count=0,4,8,16",)
    assert faults.reference == crowd.reference == "koopman-nmpc"
    labels = [c.label for c in faults.spec.controllers or ()]
    assert labels == "koopman-nmpc nominal-nmpc consensus orca dwa mpc-cbf rl-ppo-set-movers".split()
    assert crowd.spec.controllers is None  # every registered controller, these among them
    assert faults.spec.solver == crowd.spec.solver == "rti"
    differ = [
        f.name for f in fields(crowd.spec) if getattr(crowd.spec, f.name) != getattr(faults.spec, f.name)
    ]
    assert differ == ["controllers"]
    assert (
        "crowd_faults" in runs
        and "crowd_faults" in (ROOT / "data" / "publish.sh").read_text().split("ORDER=(")[1]
    )
