"""A run published split per controller (evaluation/reports/publications.py, issue 61): it reads
back as the same run as one archive of it, a rerun of one controller rewrites that controller's
file only, and a publication that is not what KoopNav packs (a file added, missing, renamed,
truncated, of another run or another controller) is refused, naming it, with nothing left behind."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tarfile
import tempfile
from pathlib import Path
from typing import Any

import pytest
from test_published_archive import HEADER, _record

from evaluation.archive import main as archive_command
from evaluation.experiments.sweep import load_sweep
from evaluation.reports import publications, published
from evaluation.reports.baseline import load_baseline

LEVELS = ("lvl-0", "lvl-1")


def _config(labels: list[str]) -> dict[str, Any]:
    return {"controller_configs": [{"label": label, "name": label, "options": {}} for label in labels]}


def _records(labels: list[str], steps: int = 10) -> list[dict[str, Any]]:
    """Two episodes of each controller, interleaved as workers finish them."""
    return [_record("E", label, "m", "s", trial, steps=steps) for trial in range(2) for label in labels]


def _write_log(path: Path, labels: list[str], records: list[dict[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    level = int(path.parent.name.removeprefix("lvl-"))  # the sweep's axis, as a level's run records it
    header = {**HEADER, "config": {**_config(labels), "env_settings": {"lvl": level}}}
    path.write_text("".join(json.dumps(line) + "\n" for line in [header, *records]))


def _sweep(root: Path, labels: list[str] = ["a", "b"], name: str = "run", steps: int = 10) -> Path:  # noqa: B006
    """A two-level sweep's directory of the controllers ``labels`` (records with ``steps``)."""
    run = root / name
    for level in LEVELS:
        _write_log(run / "sweep" / level / "episodes.jsonl", labels, _records(labels, steps))
    (run / "sweep.json").write_text(
        json.dumps({"kind": "koopnav-sweep", "axes": [{"key": "lvl", "levels": [0, 1]}]}) + "\n"
    )
    return run


def _logs(run: Path) -> dict[str, list[str]]:
    """Each log's header and its sorted record lines (a split keeps records, not their order)."""
    out = {}
    for log in sorted(run.rglob("episodes.jsonl")):
        lines = log.read_text().splitlines()
        out[str(log.relative_to(run))] = [lines[0], *sorted(lines[1:])]
    return out


def test_a_split_publication_reads_back_as_the_run_and_as_its_single_archive(tmp_path) -> None:
    run = _sweep(tmp_path / "made")
    split = publications.pack_split(run, tmp_path / "data" / "run")
    assert sorted(str(p.relative_to(split)) for p in split.rglob("*") if p.is_file()) == [
        "controllers/a.tar.xz",
        "controllers/b.tar.xz",
        "run.tar.xz",
    ]
    archive = published.pack_run(run, tmp_path / "data" / "run.tar.xz")
    with publications.extracted_archive(split) as back, publications.extracted_archive(archive) as whole:
        assert back.name == "run"
        assert _logs(back) == _logs(whole)
        assert (back / "sweep.json").read_bytes() == (run / "sweep.json").read_bytes()
        for log in _logs(back):  # the same results, in the run's planned order
            assert (
                published.results_from_log(back / log).to_json()
                == published.results_from_log(whole / log).to_json()
            )
    for form in (split, archive):
        done, missing, manifest = load_sweep(form)
        assert missing == [] and manifest["kind"] == "koopnav-sweep"
    assert publications.is_split(split) and publications.is_published(split)
    assert not publications.is_split(run) and not publications.is_published(run)


def test_a_rerun_of_one_controller_rewrites_its_file_only(tmp_path) -> None:
    dest = tmp_path / "data" / "run"
    publications.pack_split(_sweep(tmp_path / "first"), dest)
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in dest.rglob("*.tar.xz")}
    rerun = _sweep(tmp_path / "second")
    for level in LEVELS:  # b's episodes run again (forget, resume): appended after a's, other steps
        log = rerun / "sweep" / level / "episodes.jsonl"
        lines = log.read_text().splitlines(keepends=True)
        kept = [line for line in lines[1:] if json.loads(line)["controller"] == "a"]
        again = [json.dumps(r) + "\n" for r in _records(["b"], steps=11)]
        log.write_text(lines[0] + "".join(kept + again))
    publications.pack_split(rerun, dest)
    changed = sorted(str(p.relative_to(dest)) for p, (data, _) in before.items() if p.read_bytes() != data)
    assert changed == ["controllers/b.tar.xz"]
    assert all(p.stat().st_mtime_ns == mtime for p, (data, mtime) in before.items() if p.read_bytes() == data)
    with publications.extracted_archive(dest) as back:
        steps = {
            (r["controller"], r["steps"])
            for r in map(json.loads, (back / "sweep/lvl-0/episodes.jsonl").read_text().splitlines()[1:])
        }
    assert ("b", 11) in steps and ("b", 10) not in steps and ("a", 10) in steps
    # a controller dropped from the run: its part goes, the frame names the others only
    publications.pack_split(_sweep(tmp_path / "third", ["a"]), dest)
    assert sorted(p.name for p in (dest / publications.PARTS).iterdir()) == ["a.tar.xz"]


def test_the_command_publishes_split_or_whole_by_the_name_and_unpacks_both(tmp_path, capsys) -> None:
    run = _sweep(tmp_path / "made")
    assert archive_command([str(run), str(tmp_path / "split")]) == 0
    assert archive_command([str(run), str(tmp_path / "whole.tar.xz")]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'split'}\n{tmp_path / 'whole.tar.xz'}\n"
    for form, into in ((tmp_path / "split", tmp_path / "a"), (tmp_path / "whole.tar.xz", tmp_path / "b")):
        assert archive_command(["unpack", str(form), str(into)]) == 0
    assert _logs(tmp_path / "a" / "run") == _logs(tmp_path / "b" / "run") == _logs(run)
    assert archive_command([str(run), str(tmp_path / "run.tar.gz")]) == 2  # neither form
    assert "without a suffix (data/NAME)" in capsys.readouterr().err
    assert not (tmp_path / "run.tar.gz").exists()


def test_packing_refuses_what_cannot_be_split_and_writes_nothing(tmp_path) -> None:
    run = _sweep(tmp_path / "made", ["a", "b/c"])
    with pytest.raises(ValueError, match=r"controller label 'b/c' cannot name its part's file"):
        publications.pack_split(run, tmp_path / "out")
    log = _sweep(tmp_path / "other", ["a"]) / "sweep" / "lvl-0" / "episodes.jsonl"
    with log.open("a") as handle:
        handle.write(json.dumps(_record("E", "z", "m", "s", 0)) + "\n")
    with pytest.raises(
        ValueError,
        match=r"lvl-0/episodes.jsonl, line 4: a record of controller 'z', not one of the run's \['a'\]",
    ):
        publications.pack_split(log.parents[2], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_packing_refuses_a_record_nested_past_the_bound_by_its_line(tmp_path) -> None:
    """A line nested 100,000 deep raised RecursionError (a traceback) from json.loads."""
    log = _sweep(tmp_path / "made", ["a"]) / "sweep" / "lvl-0" / "episodes.jsonl"
    with log.open("a") as handle:
        handle.write("[" * 100_000 + "]" * 100_000 + "\n")
    with pytest.raises(ValueError, match=r"lvl-0/episodes.jsonl, line 4: JSON nested 100000 levels deep"):
        publications.pack_split(log.parents[2], tmp_path / "out")
    assert not (tmp_path / "out").exists()
    log.write_text(log.read_text().splitlines(keepends=True)[0] + "[1]\n")  # JSON, but no record
    with pytest.raises(ValueError, match=r"lvl-0/episodes.jsonl, line 2: a JSON list, not an episode record"):
        publications.pack_split(log.parents[2], tmp_path / "out")


@pytest.fixture()
def split(tmp_path) -> Path:
    return publications.pack_split(_sweep(tmp_path / "made"), tmp_path / "data" / "run")


def _refused(split: Path, tmp_path: Path, message: str) -> None:
    into = tmp_path / "into"
    with pytest.raises(ValueError, match=message):
        publications.extract_split(split, into)
    assert not into.exists() or list(into.iterdir()) == []


def test_a_file_added_or_a_part_missing_or_foreign_is_refused(split, tmp_path) -> None:
    (split / "notes.txt").write_text("x")
    _refused(
        split, tmp_path, r"holds \['notes.txt'\]; a split publication holds run.tar.xz and controllers/ only"
    )
    (split / "notes.txt").unlink()
    (split / "controllers" / "README").write_text("x")
    _refused(split, tmp_path, r"controllers/README: not a controller's part")
    (split / "controllers" / "README").unlink()
    shutil.copy(split / "controllers" / "a.tar.xz", split / "controllers" / "c.tar.xz")
    _refused(
        split,
        tmp_path,
        r"parts \['a', 'b', 'c'\], the run's controllers \['a', 'b'\]: missing \[\], foreign \['c'\]",
    )
    (split / "controllers" / "c.tar.xz").unlink()
    (split / "controllers" / "b.tar.xz").unlink()
    _refused(split, tmp_path, r"missing \['b'\], foreign \[\]")
    shutil.rmtree(split / "controllers")
    _refused(split, tmp_path, r"no controllers/ folder of parts beside run.tar.xz")


def test_a_renamed_torn_or_foreign_part_is_refused_by_name(split, tmp_path) -> None:
    parts = split / "controllers"
    a, b = (parts / "a.tar.xz").read_bytes(), (parts / "b.tar.xz").read_bytes()
    (parts / "a.tar.xz").write_bytes(b)
    (parts / "b.tar.xz").write_bytes(a)
    _refused(
        split,
        tmp_path,
        r"a.tar.xz: sweep/lvl-0/episodes.jsonl, line 1 is not the part header of controller 'a'",
    )
    (parts / "b.tar.xz").write_bytes(b)
    (parts / "a.tar.xz").write_bytes(a[: len(a) // 2])
    _refused(split, tmp_path, r"a.tar.xz: is truncated")
    # a part whose header is right but holds b's record (a file put together by hand)
    header = publications._part_header("a")
    members = [
        (
            f"run/sweep/{level}/episodes.jsonl",
            header + json.dumps(_record("E", "b", "m", "s", 0)).encode() + b"\n",
        )
        for level in LEVELS
    ]
    (parts / "a.tar.xz").write_bytes(published.tar_xz(members))
    _refused(
        split,
        tmp_path,
        r"a.tar.xz: sweep/lvl-0/episodes.jsonl, line 2 is a record of 'b', not of its part's controller 'a'",
    )
    (parts / "a.tar.xz").write_bytes(published.tar_xz(members[:1]))
    _refused(split, tmp_path, r"a.tar.xz: holds the logs \['sweep/lvl-0/episodes.jsonl'\], the run's frame")
    other = publications.pack_split(_sweep(tmp_path / "o", name="other"), tmp_path / "data" / "other")
    shutil.copy(other / "controllers" / "a.tar.xz", parts / "a.tar.xz")
    _refused(split, tmp_path, r"a.tar.xz: a part of run 'other', not of 'run'")


def test_a_frame_holding_records_is_refused(split, tmp_path) -> None:
    header = (
        json.dumps({**HEADER, "config": {**_config(["a", "b"]), "env_settings": {"lvl": 0}}}).encode() + b"\n"
    )
    record = json.dumps(_record("E", "a", "m", "s", 0)).encode() + b"\n"
    members = [(f"run/sweep/{level}/episodes.jsonl", header + record) for level in LEVELS]
    (split / "run.tar.xz").write_bytes(published.tar_xz(members))
    _refused(split, tmp_path, r"run.tar.xz: sweep/lvl-0/episodes.jsonl is not one run header line")


def test_a_split_publication_given_as_a_baseline_is_refused_with_how_to_unpack_it(split) -> None:
    with pytest.raises(
        ValueError, match=r"is a published archive .* \(python -m evaluation.archive unpack .*/run DIR\)"
    ):
        load_baseline(split, what="baseline")


# 40 s (four fresh interpreters, xz at preset 9): run by -m slow (.ci/run)
@pytest.mark.slow
def test_publish_sh_pack_keeps_an_unchanged_whole_archive_and_splits_a_republished_run(tmp_path) -> None:
    """``bash data/publish.sh pack`` on a run published whole (data/NAME.tar.xz): unchanged logs
    leave it as it is (no split, nothing added to the history); a rerun controller's records
    replace it with data/NAME/, which ``unpack`` restores."""
    root = Path(__file__).resolve().parents[1]
    data = tmp_path / "data"
    data.mkdir()
    (tmp_path / ".ci").mkdir()
    shutil.copy(root / "data" / "publish.sh", data)
    shutil.copy(root / ".ci" / "blas_pin.sh", tmp_path / ".ci")  # the script sources it
    shutil.copy(root / "data" / "scale_n3.tar.xz", data)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}

    def publish(*words: str) -> None:
        done = subprocess.run(
            ["bash", str(data / "publish.sh"), *words], capture_output=True, text=True, env=env
        )
        assert done.returncode == 0, done.stderr

    publish("unpack")
    whole = (data / "scale_n3.tar.xz").read_bytes()
    publish("pack")
    assert (data / "scale_n3.tar.xz").read_bytes() == whole and not (data / "scale_n3").exists()
    log = data / "runs" / "scale_n3" / "episodes.jsonl"
    lines = log.read_text().splitlines(keepends=True)
    rerun = [json.loads(line) for line in lines[1:] if json.loads(line)["controller"] == "orca"]
    kept = [line for line in lines[1:] if json.loads(line)["controller"] != "orca"]
    log.write_text(
        lines[0] + "".join(kept) + "".join(json.dumps({**r, "steps": r["steps"] + 1}) + "\n" for r in rerun)
    )
    publish("pack")
    assert not (data / "scale_n3.tar.xz").exists() and publications.is_split(data / "scale_n3")
    shutil.rmtree(data / "runs")
    publish("unpack")
    back = [json.loads(line) for line in log.read_text().splitlines()[1:]]
    assert sorted((r["controller"], r["key"], r["steps"]) for r in back) == sorted(
        [(r["controller"], r["key"], r["steps"]) for r in map(json.loads, kept)]
        + [(r["controller"], r["key"], r["steps"] + 1) for r in rerun]
    )


@pytest.mark.parametrize("name", ["extracted_archive", "unpack_run"])
def test_the_moved_names_warn_at_their_old_path_for_one_release(name) -> None:
    with pytest.warns(
        DeprecationWarning,
        match=rf"published\.{name} is deprecated and will be removed in KoopNav 0\.2\.0; import it from evaluation\.reports\.publications",
    ) as caught:
        assert getattr(published, name) is getattr(publications, name)
    # the warning points past the module's __getattr__ to who read the old name (here; under a
    # mutation run's trampoline, at the trampoline: one frame more), never into published.py
    assert len(caught) == 1 and Path(caught[0].filename).name != Path(published.__file__).name
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        published.nothing  # noqa: B018


def test_a_part_whose_last_line_has_no_newline_keeps_its_records_apart(split, tmp_path) -> None:
    header = publications._part_header("a")
    records = [json.dumps(_record("E", "a", "m", "s", trial)).encode() for trial in range(2)]
    members = [(f"run/sweep/{level}/episodes.jsonl", header + b"\n".join(records)) for level in LEVELS]
    (split / "controllers" / "a.tar.xz").write_bytes(published.tar_xz(members))
    run = publications.extract_split(split, tmp_path / "into")
    lines = (run / "sweep" / "lvl-0" / "episodes.jsonl").read_text().splitlines()
    assert [json.loads(line)["controller"] for line in lines[1:]] == ["a", "a", "b", "b"]


# ------------------------------------------- issue 59: what the reader's mutation run left untested


def _part(split: Path, label: str, body: bytes) -> Path:
    """Replace ``label``'s part by one whose two logs hold its part header, then ``body``."""
    path = split / publications.PARTS / f"{label}.tar.xz"
    header = publications._part_header(label)
    path.write_bytes(
        published.tar_xz((f"run/sweep/{level}/episodes.jsonl", header + body) for level in LEVELS)
    )
    return path


def _line(label: str, trial: int = 0) -> bytes:
    return json.dumps(_record("E", label, "m", "s", trial)).encode() + b"\n"


def _message(split: Path, tmp_path: Path) -> str:
    """The refusal of ``split``, with nothing left in the directory it was unpacked into."""
    into = tmp_path / "into"
    with pytest.raises(ValueError) as raised:
        publications.extract_split(split, into)
    assert not into.exists() or list(into.iterdir()) == []
    return str(raised.value)


def test_a_parts_line_that_is_torn_or_not_an_object_is_refused_by_its_number(split, tmp_path) -> None:
    log = "sweep/lvl-0/episodes.jsonl"
    part = _part(split, "a", _line("a") + b'{"key": "E|a|m\n')
    assert _message(split, tmp_path) == f"{part}: {log}, line 3 is not a JSON record (torn?)"
    _part(split, "a", _line("a") + b"[" * 100 + b"]" * 100 + b"\n")  # past the nesting bound, not torn
    assert (
        _message(split, tmp_path)
        == f"{part}: {log}, line 3: JSON nested 100 levels deep; allowed: at most 64"
    )
    _part(split, "a", b"[1, 2]\n")  # JSON, but no record: it has no controller
    assert _message(split, tmp_path) == (
        f"{part}: {log}, line 2 is a record of None, not of its part's controller 'a' among the log's ['a', 'b']"
    )
    _part(split, "a", _line("a") + b"\n" + _line("b"))  # a blank line does not end the part
    assert _message(split, tmp_path) == (
        f"{part}: {log}, line 4 is a record of 'b', not of its part's controller 'a' among the log's ['a', 'b']"
    )


def test_a_part_missing_a_log_is_refused_naming_both_sets(split, tmp_path) -> None:
    part = split / publications.PARTS / "a.tar.xz"
    members = [("run/sweep/lvl-0/episodes.jsonl", publications._part_header("a") + _line("a"))]
    part.write_bytes(published.tar_xz(members))
    assert _message(split, tmp_path) == (
        f"{part}: holds the logs ['sweep/lvl-0/episodes.jsonl'], the run's frame "
        "['sweep/lvl-0/episodes.jsonl', 'sweep/lvl-1/episodes.jsonl']; a part holds every log of its run"
    )


def test_a_symlinked_part_or_a_folder_named_as_one_is_refused(split, tmp_path) -> None:
    parts = split / publications.PARTS
    (parts / "a.tar.xz").rename(tmp_path / "a.tar.xz")
    (parts / "a.tar.xz").symlink_to(tmp_path / "a.tar.xz")  # the bytes are a's part, but elsewhere
    expected = "{}: not a controller's part (a regular file LABEL.tar.xz)"
    assert _message(split, tmp_path) == expected.format(parts / "a.tar.xz")
    (parts / "a.tar.xz").unlink()
    (tmp_path / "a.tar.xz").rename(parts / "a.tar.xz")
    (parts / "c.tar.xz").mkdir()
    assert _message(split, tmp_path) == expected.format(parts / "c.tar.xz")


def test_the_number_of_parts_is_bounded_at_max_parts(split, tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(publications, "MAX_PARTS", 2)  # the run's two controllers: at the bound
    assert publications.extract_split(split, tmp_path / "at").name == "run"
    monkeypatch.setattr(publications, "MAX_PARTS", 1)
    assert _message(split, tmp_path) == (
        f"{split}: holds 2 parts, more than 1, the most allowed (evaluation.reports.publications.MAX_PARTS)"
    )


def test_what_is_not_a_directory_or_whose_run_is_there_already_is_refused(split, tmp_path) -> None:
    with pytest.raises(ValueError) as raised:
        publications.extract_split(split / publications.FRAME, tmp_path)
    assert str(raised.value) == (
        f"{split / publications.FRAME}: not a directory, so not a split publication (data/NAME/run.tar.xz, ...)"
    )
    (tmp_path / "into" / "run").mkdir(parents=True)
    with pytest.raises(ValueError) as raised:
        publications.extract_split(split, tmp_path / "into")
    assert str(raised.value) == (
        f"{tmp_path / 'into' / 'run'} exists; a publication is unpacked into a directory without its run"
    )
    assert list((tmp_path / "into" / "run").iterdir()) == []


def test_a_frame_log_that_is_not_text_or_not_a_run_header_is_refused_by_name(split, tmp_path) -> None:
    frame = split / publications.FRAME
    log = "sweep/lvl-0/episodes.jsonl"
    frame.write_bytes(published.tar_xz([(f"run/{log}", b"\xff\n")]))
    # the unpacked path is what says which file of the publication it was: the frame, or a part
    assert re.fullmatch(
        rf"episode log '.*/koopnav-split-\w+/frame/run/{log}' is not UTF-8 text \(byte 0 is b'\\xff'\); expected a run header line",
        _message(split, tmp_path),
    )
    frame.write_bytes(published.tar_xz([(f"run/{log}", json.dumps({"kind": "other"}).encode() + b"\n")]))
    assert _message(split, tmp_path) == (
        f"{frame}: {log}: line 1 is not a KoopNav run header naming its controllers"
    )


def test_a_parts_log_and_a_log_put_together_are_bounded_by_the_log_cap(split, tmp_path, monkeypatch) -> None:
    """The cap of an episode log (MAX_LOG_BYTES) holds for each part's log as read and for the
    log put together, inclusive, and a refusal in the middle of writing leaves nothing behind."""
    log = "sweep/lvl-0/episodes.jsonl"
    whole = (publications.extract_split(split, tmp_path / "whole") / log).read_bytes()
    _part(split, "b", _line("b") + _line("b", 1) + _line("b", 2))  # longer than a's: read last
    longest = len(publications._part_header("b") + _line("b") * 3)  # trials 0-2: lines of one length
    monkeypatch.setattr(publications, "MAX_LOG_BYTES", longest - 1)
    assert re.fullmatch(
        rf"episode log '.*/koopnav-split-\w+/parts/b/run/{log}' cannot be read: it is {longest} bytes; "
        rf"at most {longest - 1} bytes are allowed",
        _message(split, tmp_path),
    )
    # the logs put together: lvl-0 is written before lvl-1, which is longer
    _part(split, "b", _line("b") + _line("b", 1))
    lvl1 = published.tar_xz(
        (f"run/sweep/{level}/episodes.jsonl", publications._part_header("b") + body)
        for level, body in (("lvl-0", _line("b") + _line("b", 1)), ("lvl-1", _line("b") * 3))
    )
    (split / publications.PARTS / "b.tar.xz").write_bytes(lvl1)
    second = len(whole) + len(_line("b"))
    for limit in (len(whole) - 1, second - 1):  # the first log refused, then the second
        monkeypatch.setattr(publications, "MAX_LOG_BYTES", limit)
        name = log if limit < len(whole) else "sweep/lvl-1/episodes.jsonl"
        size = len(whole) if limit < len(whole) else second
        assert _message(split, tmp_path) == f"{split}: {name} is {size} bytes put together, beyond {limit}"
    monkeypatch.setattr(publications, "MAX_LOG_BYTES", second)
    assert (
        len((publications.extract_split(split, tmp_path / "at") / "sweep/lvl-1/episodes.jsonl").read_bytes())
        == second
    )


def test_the_scratch_directory_is_named_for_koopnav_and_removed(split, tmp_path, monkeypatch) -> None:
    """A process killed while unpacking leaves a ``koopnav-split-*`` directory, which says whose it
    is (issue 59's leaked directories were found by their name)."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    seen = []
    extract = publications.extract_archive

    def spied(archive: Path, into: Path) -> Path:
        seen.append(sorted(p.name for p in scratch.iterdir()))
        return extract(archive, into)

    monkeypatch.setattr(publications, "extract_archive", spied)
    publications.extract_split(split, tmp_path / "into")
    assert len(seen) == 3 and all(len(names) == 1 for names in seen)
    assert seen[0][0].startswith("koopnav-split-") and seen[0] == seen[1] == seen[2]
    assert list(scratch.iterdir()) == []


def test_a_parts_line_1_is_the_documented_part_header(split) -> None:
    """The published format (module docstring): what older publications hold must read back."""
    with tarfile.open(split / publications.PARTS / "b.tar.xz") as tar:
        names = tar.getnames()
        first = [tar.extractfile(name).readline() for name in names]  # type: ignore[union-attr]
    assert names == [f"run/sweep/{level}/episodes.jsonl" for level in LEVELS]
    assert first == [b'{"kind": "koopnav-part", "controller": "b"}\n'] * 2


BAD_HEADERS = {
    "not JSON": b"koopnav-run",
    "a list": b'[{"kind": "koopnav-run"}]',
    "another kind": json.dumps({"kind": "koopnav-sweep", "config": _config(["a", "b"])}).encode(),
    "no config": json.dumps({"kind": "koopnav-run"}).encode(),
    "a config without controllers": json.dumps({"kind": "koopnav-run", "config": {}}).encode(),
    "controllers not a list": json.dumps(
        {"kind": "koopnav-run", "config": {"controller_configs": {}}}
    ).encode(),
    "a controller without a label": json.dumps(
        {"kind": "koopnav-run", "config": {"controller_configs": [{"name": "a"}]}}
    ).encode(),
    "a controller not a table": json.dumps(
        {"kind": "koopnav-run", "config": {"controller_configs": ["a"]}}
    ).encode(),
}


@pytest.mark.parametrize("header", BAD_HEADERS.values(), ids=BAD_HEADERS.keys())
def test_a_log_whose_line_1_is_not_a_run_header_naming_its_controllers_is_refused(
    header: bytes, split: Path, tmp_path: Path
) -> None:
    frame = split / publications.FRAME
    log = "sweep/lvl-0/episodes.jsonl"
    frame.write_bytes(published.tar_xz([(f"run/{log}", header + b"\n")]))
    assert (
        _message(split, tmp_path)
        == f"{frame}: {log}: line 1 is not a KoopNav run header naming its controllers"
    )
    run = _sweep(tmp_path / "made")
    (run / log).write_bytes(header + b"\n" + (run / log).read_bytes().partition(b"\n")[2])
    with pytest.raises(ValueError) as raised:
        publications.pack_split(run, tmp_path / "out")
    assert str(raised.value) == f"{run / log}: line 1 is not a KoopNav run header naming its controllers"
    assert not (tmp_path / "out").exists()


def test_packing_names_the_publication_it_did_not_write(tmp_path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError) as raised:
        publications.pack_split(empty, tmp_path / "out")
    assert str(raised.value) == (
        f"{empty}: no episode log (episodes.jsonl) in it or below it, so not a run's directory; "
        f"{tmp_path / 'out'} was not written"
    )
    with pytest.raises(ValueError) as raised:
        publications.pack_split(_sweep(tmp_path / "made", ["a", ".b"]), tmp_path / "out")
    assert str(raised.value) == (
        "controller label '.b' cannot name its part's file (letters, digits and . _ + = -, at most 100, "
        f"not starting with a dot or a sign); {tmp_path / 'out'} was not written"
    )
    assert not (tmp_path / "out").exists()


def test_logs_of_other_controllers_and_several_sweeps_read_back_whole(tmp_path) -> None:
    """A run directory holding two sweeps (one's manifest sorted before the other's logs), whose
    levels ran other controllers: each part holds every log, the header alone where its
    controller did not run, and the run reads back as packed."""
    run = tmp_path / "made" / "run"
    _sweep(run, ["a", "b"], name="first")
    _sweep(run, ["b", "c"], name="second")
    split = publications.pack_split(run, tmp_path / "data" / "run")
    assert sorted(p.name for p in (split / publications.PARTS).iterdir()) == [
        "a.tar.xz",
        "b.tar.xz",
        "c.tar.xz",
    ]
    back = publications.extract_split(split, tmp_path / "into")
    assert _logs(back) == _logs(run) and len(_logs(back)) == 4
    assert (back / "second" / "sweep.json").read_bytes() == (run / "second" / "sweep.json").read_bytes()


def test_an_unpacked_member_past_the_bound_is_refused_by_what_it_is(split, tmp_path, monkeypatch) -> None:
    """Each file unpacked is read again under the member bound before it is joined or written out
    (a file grown or swapped between the extraction and the read): the refusal names it an
    unpacked member, with the bound, and nothing is left in ``into``."""
    monkeypatch.setattr(publications, "MAX_MEMBER_BYTES", 16)
    refused = r"^unpacked member '[^']+' cannot be read: it is \d+ bytes; at most 16 bytes are allowed$"
    into = tmp_path / "into"
    with pytest.raises(ValueError, match=refused):
        publications.extract_split(split, into)
    assert not into.exists() or list(into.iterdir()) == []
    with pytest.raises(ValueError, match=refused):
        publications.unpack_run(split, tmp_path / "runs")
    assert not (tmp_path / "runs").exists() or list((tmp_path / "runs").rglob("*.jsonl")) == []
