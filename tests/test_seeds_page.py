"""docs/seeds_results.md (docs/make_seeds_md.py) from a real seeds publication: the committed
finished seeds of data/training run by ``python -m evaluation.experiments.seeds --split validation
--layouts 3`` (tests/data/seeds_validation_layouts0-2.tar.xz, 9 episodes: never the test split),
packed as ``bash data/publish.sh pack`` packs it (``python -m evaluation.archive``, split per seed).
The page's numbers are the data's, its progress statement names every planned seed not on it, the
committed page is rebuilt byte for byte, and a torn or foreign publication is refused by name."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

from evaluation.experiments.seeds import FINISHED_FILE, TRAINING_ROOT, chosen_seed, finished_seeds
from evaluation.experiments.seeds_published import planned_seeds, read_publication

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "seeds_validation_layouts0-2.tar.xz"
GENERATOR = ROOT / "docs" / "make_seeds_md.py"
TRAINING = ROOT / TRAINING_ROOT
sys.path.insert(0, str(ROOT / "docs"))
from make_pages import PAGES, page_command, page_digest, read_digests  # noqa: E402  (docs/ is no package)


def _run_dir(tmp_path: Path) -> Path:
    """The fixture's run unpacked (``seeds/target_reaching/episodes.jsonl``), with tarfile: the
    publication readers are what is tested."""
    with tarfile.open(FIXTURE) as tar:
        tar.extractall(tmp_path / "unpacked", filter="data")
    return tmp_path / "unpacked" / "seeds"


def _pack(run: Path, dest: Path) -> Path:
    """``bash data/publish.sh pack``'s command for one run: split per controller."""
    subprocess.run([sys.executable, "-m", "evaluation.archive", str(run), str(dest)], cwd=ROOT, check=True)
    return dest


def _page(publication: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(GENERATOR), str(publication), "--out", str(out), *extra],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )


def _records(run: Path) -> list[dict]:
    lines = (run / "target_reaching" / "episodes.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines[1:]]


def test_the_page_states_the_publications_seeds_and_their_validation_records(tmp_path) -> None:
    publication = _pack(_run_dir(tmp_path), tmp_path / "seeds")
    assert sorted(p.name for p in (publication / "controllers").iterdir()) == [
        f"rl-ppo-set@seed{k}.tar.xz" for k in range(3)
    ]
    done = _page(publication, tmp_path / "page.md")
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "page.md").read_text()
    assert "ran on the validation split, not on test" in text
    records = _records(_run_dir(tmp_path / "again"))
    runs = finished_seeds(TRAINING, "rl-ppo-set", "target_reaching")
    assert [r.seed for r in runs] == [0, 1, 2]
    rates = {}
    for run in runs:
        mine = [r for r in records if r["controller"] == run.label]
        rates[run.seed] = sum(r["success"] is True for r in mine) / len(mine)
        # each seed's row: its kept checkpoint's validation record (data/training) beside its rate
        row = next(
            line
            for line in text.splitlines()
            if line.startswith(f"| `rl-ppo-set` | target_reaching | {run.seed} |")
        )
        assert f"| {100 * run.validation['success_rate']:.1f}% (step {run.validation['step']:,}) |" in row
        assert f"| {100 * rates[run.seed]:.1f}% [" in row
        assert ("chosen on validation" in row) == (run.seed == chosen_seed(runs).seed)
    mean = sum(rates.values()) / len(rates)
    assert f"mean {100 * mean:.1f}% [" in text and "3 seeds: fewer than 4, the IQM trims nothing" in text
    low, high = min(rates.values()), max(rates.values())
    chosen = chosen_seed(runs)
    spread = (
        f"| `rl-ppo-set` | target_reaching | 3 | {100 * low:.1f}% | {100 * high:.1f}% | "
        f"{100 * (high - low):.1f} points | seed {chosen.seed} "
        f"({chosen.validation['successes']}/{chosen.validation['episodes']}) |"
    )
    assert spread in text
    assert "koopnav-bench-v1/target_reaching/validation@" in text
    # the same publication as one archive gives the same page, byte for byte, but for its name
    archive = tmp_path / "one" / "seeds.tar.xz"
    archive.parent.mkdir()
    shutil.copy(FIXTURE, archive)
    assert _page(archive, tmp_path / "page2.md").returncode == 0
    assert (tmp_path / "page2.md").read_text() == text.replace(str(publication), str(archive))


def _training_root(tmp_path: Path, finished: list[tuple[str, str, int]]) -> Path:
    """A training root whose seeds ``finished`` hold the records the page reads (each a copy of
    rl-ppo-set target_reaching seed 0's, renamed), and nothing else."""
    root = tmp_path / "training"
    source = TRAINING / "rl-ppo-set" / "target_reaching" / "seed0"
    for policy, task, seed in finished:
        folder = root / policy / task / f"seed{seed}"
        folder.mkdir(parents=True)
        for name in (FINISHED_FILE, "selection.json"):
            shutil.copy(source / name, folder / name)
    return root


def test_the_progress_statement_names_every_planned_seed_not_on_the_page(tmp_path) -> None:
    run = _run_dir(tmp_path)
    # seed 1 published partial: one of its three episodes dropped from the log
    log = run / "target_reaching" / "episodes.jsonl"
    lines = log.read_text().splitlines(keepends=True)
    dropped = next(i for i, line in enumerate(lines) if '"controller": "rl-ppo-set@seed1"' in line)
    log.write_text("".join(lines[:dropped] + lines[dropped + 1 :]))
    publication = _pack(run, tmp_path / "seeds")
    published = [("rl-ppo-set", "target_reaching", k) for k in range(3)]
    root = _training_root(tmp_path, [*published, ("ippo", "formation", 1)])
    done = _page(publication, tmp_path / "page.md", "--training", str(root))
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "page.md").read_text()
    progress = text[text.index("## Progress") :]
    assert "On this page: 2 of the 12 planned seed runs" in progress
    assert "Not on it yet (10):" in progress
    assert (
        "- `rl-ppo-set` target_reaching seed 1: evaluation in progress (2 of 3 episodes published), "
        "left out of the tables" in progress
    )
    assert "- `ippo` formation seed 1: finished training, not evaluated yet" in progress
    unfinished = [s for s in planned_seeds() if s not in published and s != ("ippo", "formation", 1)]
    assert len(unfinished) == 8
    for policy, task, seed in unfinished:
        assert f"- `{policy}` {task} seed {seed}: training not finished" in progress
    # the partial seed is in no table: two seeds aggregated
    assert "| `rl-ppo-set` | target_reaching | 1 |" not in text
    assert "| `rl-ppo-set` | target_reaching | 2 | " in text and "(2 seeds: fewer than 4" in text


def test_the_plan_is_the_drivers_defaults(tmp_path) -> None:
    plan = planned_seeds()
    assert len(plan) == 12 and plan[0] == ("rl-ppo-set", "target_reaching", 0)
    assert plan[-1] == ("ippo", "formation", 2)
    script = (ROOT / "data" / "training" / "run.sh").read_text()
    five = tmp_path / "five.sh"
    five.write_text(script.replace('SEEDS="${SEEDS:-3}"', 'SEEDS="${SEEDS:-5}"'))
    assert len(planned_seeds(five)) == 20
    bad = tmp_path / "bad.sh"
    bad.write_text(script.replace("policies=(rl-ppo-set ippo)", "policies=(rl-ppo-set mappo)"))
    with pytest.raises(ValueError, match=r"default policy.*'mappo'"):
        planned_seeds(bad)
    bad.write_text(script.replace('SEEDS="${SEEDS:-3}"', "SEEDS=3"))
    with pytest.raises(ValueError, match=rf"{bad} states no default SEEDS"):
        planned_seeds(bad)


def test_the_committed_page_is_rebuilt_byte_for_byte(tmp_path) -> None:
    entry = next(e for e in PAGES if e["page"] == "docs/seeds_results.md")
    assert entry["generator"] == "docs/make_seeds_md.py" and entry["args"][0] == "data/seeds"
    page = tmp_path / "seeds_results.md"
    subprocess.run(page_command(entry, page), cwd=ROOT, check=True, capture_output=True)
    assert page.read_bytes() == (ROOT / entry["page"]).read_bytes()
    assert read_digests()[entry["page"]] == page_digest(page.read_bytes())
    text = page.read_text()
    if not (ROOT / "data" / "seeds").exists():  # pending: no number of a test episode, the plan stated
        assert "**Pending: the seeds are not published yet** (`data/seeds` is missing)" in text
        assert "%" not in text
        for policy, task, seed in planned_seeds():
            assert f"- `{policy}` {task} seed {seed}: " in text


def test_a_torn_publication_is_refused_by_name(tmp_path) -> None:
    publication = _pack(_run_dir(tmp_path), tmp_path / "seeds")
    part = publication / "controllers" / "rl-ppo-set@seed1.tar.xz"
    with tarfile.open(part) as tar:
        member = tar.getmembers()[0]
        data = tar.extractfile(member).read()  # type: ignore[union-attr]
    torn = data[: len(data) - 40]  # the last record cut by a kill
    scratch = tmp_path / "torn"
    (scratch / Path(member.name).parent).mkdir(parents=True)
    (scratch / member.name).write_bytes(torn)
    with tarfile.open(part, "w:xz") as tar:
        tar.add(scratch / member.name, arcname=member.name)
    done = _page(publication, tmp_path / "page.md")
    assert done.returncode == 2
    assert f"{part}: target_reaching/episodes.jsonl, line 4 is not a JSON record (torn?)" in done.stderr
    assert not (tmp_path / "page.md").exists()
    # a run directory whose log was cut mid-line, read directly
    run = _run_dir(tmp_path / "direct")
    log = run / "target_reaching" / "episodes.jsonl"
    log.write_bytes(log.read_bytes()[:-40])
    with pytest.raises(ValueError, match=rf"{log}, line 10: not JSON"):
        read_publication(run, TRAINING)


def test_a_foreign_publication_is_refused_by_name(tmp_path) -> None:
    # another run of data/ (the 3-robot team-size run, one log at its top)
    done = _page(ROOT / "data" / "scale_n3.tar.xz", tmp_path / "page.md")
    assert done.returncode == 2
    assert "data/scale_n3.tar.xz: not a seeds publication" in done.stderr
    assert "holds ['episodes.jsonl']" in done.stderr
    assert not (tmp_path / "page.md").exists()
    # a seeds run whose controller is not a training seed's
    run = _run_dir(tmp_path)
    log = run / "target_reaching" / "episodes.jsonl"
    log.write_text(log.read_text().replace("rl-ppo-set@seed2", "rl-ppo-set-seed2"))
    with pytest.raises(ValueError, match=r"controller 'rl-ppo-set-seed2' is not a training seed's"):
        read_publication(run, TRAINING)
    # a seed whose folder is not a finished seed under the training root
    run = _run_dir(tmp_path / "other")
    root = _training_root(tmp_path, [("rl-ppo-set", "target_reaching", k) for k in (0, 1)])
    with pytest.raises(
        ValueError, match=r"rl-ppo-set@seed2 is published, but .*seed2 is not a finished seed"
    ):
        read_publication(run, root)


def test_a_seed_finished_later_joins_the_published_log(tmp_path) -> None:
    """``bash data/publish.sh seeds`` resumes each task's log: a run with one more seed adds its
    controller (evaluation/episodes/runlog.py's rule), the logged seeds' records kept; a run
    without a logged seed is refused."""
    from evaluation.episodes.runlog import LogError, read_log

    run = _run_dir(tmp_path)
    log = run / "target_reaching" / "episodes.jsonl"
    header, *lines = log.read_text().splitlines(keepends=True)
    config = json.loads(header)["config"]  # three seeds: the run that resumes
    earlier = json.loads(header)
    earlier["config"]["controller_configs"] = config["controller_configs"][:2]
    log.write_text(json.dumps(earlier) + "\n" + "".join(l for l in lines if "@seed2" not in l))
    done, notes = read_log(log, config)
    assert len(done) == 6
    assert any("adds rl-ppo-set@seed2 to the logged run's controllers" in note for note in notes)
    assert json.loads(log.read_text().splitlines()[0])["config"] == config  # the header now names it
    fewer = dict(config, controller_configs=config["controller_configs"][:1])
    with pytest.raises(LogError, match=r"belongs to a run with other settings"):
        read_log(log, fewer)


def test_the_pending_page_does_not_change_when_a_seed_finishes_training(tmp_path) -> None:
    """While data/seeds is missing, a training session that commits a finished seed leaves the
    page as it is (docs/benchmark.md's seed paragraph states the training progress)."""
    missing = tmp_path / "seeds"
    before = _training_root(tmp_path / "a", [("rl-ppo-set", "target_reaching", 0)])
    after = _training_root(tmp_path / "b", [("rl-ppo-set", "target_reaching", 0), ("ippo", "formation", 2)])
    for root, out in ((before, "before.md"), (after, "after.md")):
        assert _page(missing, tmp_path / out, "--training", str(root)).returncode == 0
    text = (tmp_path / "before.md").read_text()
    assert text == (tmp_path / "after.md").read_text()
    assert "On this page: 0 of the 12 planned seed runs" in text and "Not on it yet (12):" in text
