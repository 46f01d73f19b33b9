"""The published-archive reader (evaluation/reports/published.py) on small archives built here, each in
tmp_path with the module's own pack_run or with tarfile (issue 59: the cases its mutation run
left untested): the planned order of a log's records, a log's bad lines named by number, every
limit exact at its bound, every refusal's message in full, directory members, the clean-up of a
refused archive, packing and unpacking, and its command (evaluation/archive.py)."""

from __future__ import annotations

import json
import lzma
import os
import random
import re
import tarfile
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest
from test_bounded_reads import _special, _tar_xz

from evaluation.archive import main as archive_command
from evaluation.reports import publications, published

HEADER = {"kind": "koopnav-run", "config": {}}


def _record(env: str, controller: str, map_name: str, slip: str, trial: int, **extra: Any) -> dict[str, Any]:
    """A record as KoopNav logs one (evaluation.records.record_problem accepts it)."""
    return {
        "key": f"{env}|{controller}|{map_name}|{slip}|{trial}",
        "status": "ok",
        "env_id": env,
        "controller": controller,
        "map": map_name,
        "slip": slip,
        "trial": trial,
        "seed": trial,
        "success": True,
        "collision": None,
        "steps": 10,
        "final_distance": [0.1],
        "solver_failures": 0,
        "time_to_goal": 1.0,
        "path_length": [1.0],
        "control_effort": [1.0],
        "formation_rms": None,
        "solve_ms_median": 1.0,
        "solve_ms_p95": 2.0,
        **extra,
    }


def _log(path: Path, records: list[dict[str, Any]], config: dict[str, Any] | None = None) -> Path:
    """An episode log: the run header, then one record a line."""
    header = {**HEADER, "config": config or {}}
    path.write_text("".join(json.dumps(line) + "\n" for line in [header, *records]))
    return path


def _run(root: Path, records: int = 2, name: str = "run") -> Path:
    """A run's directory with an episode log of ``records`` records."""
    run = root / name
    run.mkdir(parents=True)
    _log(run / "episodes.jsonl", [_record("E", "c", "m", "s", t) for t in range(records)])
    return run


def _unpacked_bytes(monkeypatch: pytest.MonkeyPatch, archive: Path, into: Path) -> int:
    """Extract ``archive`` and return the bytes taken out of its xz stream, counted apart from the
    reader's own count (every read of lzma.LZMAFile)."""
    taken = []
    read = lzma.LZMAFile.read

    def counted(self: lzma.LZMAFile, size: int = -1) -> bytes:
        data = read(self, size)
        taken.append(len(data))
        return data

    with monkeypatch.context() as patch:
        patch.setattr(lzma.LZMAFile, "read", counted)
        published.extract_archive(archive, into)
    return sum(taken)


# ------------------------------------------------------------------------ results_from_log


def test_records_come_back_in_the_planned_order_whatever_order_they_were_logged_in(tmp_path) -> None:
    """Env, controller, map (the env's own list), slip, trial, each in the header's order (not
    alphabetical), and a value the header does not list after the listed ones."""
    config = {
        "env_ids": ["E2", "E1"],
        "controller_configs": [{"label": "c2"}, {"label": "c1"}],
        "maps": {"E2": ["m2", "m1"], "E1": ["m1"]},  # E3 has no list of maps
        "slips": ["s2", "s1"],
    }
    maps = {"E2": ["m2", "m1", "m3"], "E1": ["m1", "m3"], "E3": ["m1"]}
    planned = [
        (env, controller, map_name, slip, trial)
        for env in ("E2", "E1", "E3")
        for controller in ("c2", "c1", "c3")
        for map_name in maps[env]
        for slip in ("s2", "s1", "s3")
        for trial in (0, 1)
    ]
    logged = [_record(*cell) for cell in planned]
    random.Random(0).shuffle(logged)
    results = published.results_from_log(_log(tmp_path / "episodes.jsonl", logged, config))
    order = [(r["env_id"], r["controller"], r["map"], r["slip"], r["trial"]) for r in results.records]
    assert order == planned
    assert results.config["controllers"] == ["c2", "c1"]
    assert results.config["env_ids"] == ["E2", "E1"]


def test_a_log_without_its_last_newline_keeps_its_last_record(tmp_path) -> None:
    log = _log(tmp_path / "episodes.jsonl", [_record("E", "c", "m", "s", t) for t in range(3)])
    log.write_text(log.read_text().rstrip("\n"))
    assert [r["trial"] for r in published.results_from_log(log).records] == [0, 1, 2]


def test_an_empty_log_is_not_a_run_log(tmp_path) -> None:
    log = tmp_path / "episodes.jsonl"
    log.write_text("")
    with pytest.raises(ValueError) as raised:
        published.results_from_log(log)
    assert str(raised.value) == f"{log} is not a KoopNav episode log (line 1 is not a run header)"


def test_a_log_that_is_not_utf8_names_itself_and_what_was_expected(tmp_path) -> None:
    log = tmp_path / "episodes.jsonl"
    log.write_bytes(json.dumps(HEADER).encode() + b"\n\xff\n")
    with pytest.raises(ValueError) as raised:
        published.results_from_log(log)
    assert str(raised.value) == (
        f"episode log {str(log)!r} is not UTF-8 text (byte {log.stat().st_size - 2} is b'\\xff'); "
        "expected a KoopNav episode log (JSON lines)"
    )


def test_a_bad_line_is_named_by_its_number(tmp_path) -> None:
    log = _log(tmp_path / "episodes.jsonl", [_record("E", "c", "m", "s", 0)])
    text = log.read_text()
    log.write_text(text + "{not json\n")
    with pytest.raises(ValueError) as raised:
        published.results_from_log(log)
    assert str(raised.value) == f"{log}, line 3: not JSON (Expecting property name enclosed in double quotes)"
    log.write_text(text + "[" * 100 + "]" * 100 + "\n")  # deeper than parse_json reads
    with pytest.raises(ValueError) as raised:
        published.results_from_log(log)
    assert str(raised.value).startswith(f"{log}, line 3: JSON nested 100 levels deep")


def test_an_episode_logged_twice_with_two_outcomes_names_both_lines(tmp_path) -> None:
    records = [_record("E", "c", "m", "s", t) for t in range(2)]
    records.append(_record("E", "c", "m", "s", 0, success=False))  # line 4 contradicts line 2
    log = _log(tmp_path / "episodes.jsonl", records)
    with pytest.raises(ValueError) as raised:
        published.results_from_log(log)
    assert str(raised.value).startswith(
        f"{log}: episode 'E|c|m|s|0' (seed 0) is recorded twice with different outcomes, at line 2 and line 4,"
    )


# ----------------------------------------------------------------------- the bounded stream


def test_the_stream_hands_out_at_most_a_chunk_and_exactly_what_is_asked(tmp_path) -> None:
    """tarfile asks for a record at a time; asked for everything (size -1), the stream still hands
    out one chunk, so no single read unpacks a bomb whole; asked for nothing, it gives nothing."""
    # a random block repeated: it compresses about 20:1, below MAX_RATIO, and fast
    payload = (random.Random(0).randbytes(2**16) * 32)[: published._CHUNK + published._CHUNK // 4]
    stream = published._Bounded(lzma.compress(payload, preset=0), tmp_path / "a.tar.xz")
    assert stream.read(0) == b""
    assert stream.read(10) == payload[:10]
    assert stream.read() == payload[10 : 10 + published._CHUNK]
    assert stream.count == 10 + published._CHUNK


@pytest.fixture
def small(tmp_path) -> Path:
    """A small, very compressible archive of three members (well below every limit)."""
    members = [(f"run/sweep/{name}/episodes.jsonl", b"{}\n" * 200) for name in "abc"]
    return _tar_xz(tmp_path / "small.tar.xz", members)


def test_every_limit_holds_its_own_value(small, tmp_path, monkeypatch) -> None:
    """A limit is the most allowed: an archive exactly at it is read, one byte (or member) past
    it is refused, with the numbers counted apart from the reader."""
    total = _unpacked_bytes(monkeypatch, small, tmp_path / "counted")
    packed = small.stat().st_size  # read whole at the first read: it is far below xz's buffer
    cases: list[tuple[str, Any, str | None]] = [
        ("MAX_TOTAL_BYTES", total, None),
        (
            "MAX_TOTAL_BYTES",
            total - 1,
            f"{small}: unpacks to more than {total - 1} bytes, the most allowed "
            "(evaluation.reports.published.MAX_TOTAL_BYTES); nothing more was unpacked",
        ),
        ("MAX_MEMBERS", 3, None),
        (
            "MAX_MEMBERS",
            2,
            f"{small}: holds more than 2 members, the most allowed (evaluation.reports.published.MAX_MEMBERS)",
        ),
        ("MAX_MEMBER_BYTES", 600, None),
        ("MAX_RATIO", Fraction(total, packed), None),  # exactly MAX_RATIO:1 is allowed
    ]
    for number, (limit, value, refusal) in enumerate(cases):
        with monkeypatch.context() as patch:
            patch.setattr(published, limit, value)
            if limit == "MAX_RATIO":
                patch.setattr(published, "RATIO_FLOOR", 0)
            into = tmp_path / f"case{number}"
            if refusal is None:
                assert published.extract_archive(small, into) == into / "run", (limit, value)
            else:
                with pytest.raises(ValueError) as raised:
                    published.extract_archive(small, into)
                assert str(raised.value) == refusal
                assert not into.exists()


def test_the_ratio_floor_holds_its_own_value_and_the_refusal_names_both_counts(
    small, tmp_path, monkeypatch
) -> None:
    total = _unpacked_bytes(monkeypatch, small, tmp_path / "counted")
    packed = small.stat().st_size
    monkeypatch.setattr(published, "MAX_RATIO", 1)
    monkeypatch.setattr(published, "RATIO_FLOOR", total)  # never passed: read
    assert published.extract_archive(small, tmp_path / "x") == tmp_path / "x" / "run"
    monkeypatch.setattr(published, "RATIO_FLOOR", total - 1)  # passed at the last read
    with pytest.raises(ValueError) as raised:
        published.extract_archive(small, tmp_path / "y")
    assert str(raised.value) == (
        f"{small}: {packed} compressed bytes unpack to {total} and more, beyond 1:1 "
        "(evaluation.reports.published.MAX_RATIO): the mark of a decompression bomb; nothing more was unpacked"
    )


def test_the_ratio_is_of_the_compressed_bytes_read_so_far(tmp_path) -> None:
    """2 MiB of zeros, then 64 KiB that do not compress: refused while the zeros stream, by the
    compressed bytes read until then, not the whole archive's (which would let them through)."""
    noise = random.Random(0).randbytes(64 * 1024)
    members = [("run/episodes.jsonl", bytes(2 * 2**20)), ("run/sweep.json", noise)]
    archive = _tar_xz(tmp_path / "front.tar.xz", members, preset=0)
    with pytest.raises(ValueError, match=r"beyond 100:1") as raised:
        published.extract_archive(archive, tmp_path / "x")
    read = re.search(r": (\d+) compressed bytes unpack to", str(raised.value))
    assert read is not None and int(read.group(1)) < archive.stat().st_size // 2


# -------------------------------------------------------------------------------- members


@pytest.mark.parametrize(
    ("member", "why"),
    [
        (
            ("run/..\\..\\x/episodes.jsonl", b"{}\n"),
            "would land outside the extraction directory (an absolute path or '..'); a published "
            "archive holds relative paths only",
        ),
        (
            _special("run/episodes.jsonl", b"Z"),  # a type tarfile does not know
            "is not a regular file; a published archive holds regular files only",
        ),
        (
            _special("run/episodes.jsonl", tarfile.SYMTYPE, "x"),
            "is a symbolic link; a published archive holds regular files only",
        ),
        (
            ("episodes.jsonl", b"{}\n"),
            "is not inside a run's directory; a published archive holds one run's directory "
            "(RUN/episodes.jsonl, RUN/sweep.json, RUN/sweep/LEVEL/...)",
        ),
    ],
    ids=["backslash", "unknown-type", "symlink", "top-level-file"],
)
def test_a_refused_member_is_named_with_why(tmp_path, member, why) -> None:
    archive = _tar_xz(tmp_path / "evil.tar.xz", [member])
    name = member.name if isinstance(member, tarfile.TarInfo) else member[0]
    with pytest.raises(ValueError) as raised:
        published.extract_archive(archive, tmp_path / "x")
    assert str(raised.value) == f"{archive}: member {name!r} {why}"
    assert not (tmp_path / "x").exists()


def test_an_archive_of_a_top_level_log_restores_nothing_and_says_so(tmp_path, capsys) -> None:
    """It used to be taken for a run whose directory is the log: unpack_run wrote nothing and
    reported the run restored."""
    archive = _tar_xz(tmp_path / "top.tar.xz", [("episodes.jsonl", json.dumps(HEADER).encode() + b"\n")])
    assert archive_command(["unpack", str(archive), str(tmp_path / "into")]) == 2
    assert "is not inside a run's directory" in capsys.readouterr().err
    assert not (tmp_path / "into").exists()


def test_an_empty_directory_beside_the_run_is_a_second_top_directory(tmp_path) -> None:
    archive = _tar_xz(
        tmp_path / "two.tar.xz", [_special("junk", tarfile.DIRTYPE), ("run/episodes.jsonl", b"{}\n")]
    )
    with pytest.raises(ValueError) as raised:
        published.extract_archive(archive, tmp_path / "x")
    assert str(raised.value) == f"{archive}: holds ['junk', 'run'], not one run's directory"
    assert not (tmp_path / "x").exists()


def test_directory_members_in_any_order_and_files_after_them(tmp_path) -> None:
    """tar lists a directory before its files, but need not list its parents, and may list one
    twice; every file after a directory is still unpacked."""
    archive = _tar_xz(
        tmp_path / "dirs.tar.xz",
        [
            _special("run/sweep/a", tarfile.DIRTYPE),  # its parents are not listed
            ("run/sweep/a/episodes.jsonl", b"a\n"),
            _special("run/sweep", tarfile.DIRTYPE),  # already made
            ("run/sweep.json", b"{}\n"),
        ],
    )
    run = published.extract_archive(archive, tmp_path / "x")
    assert run == tmp_path / "x" / "run"
    assert (run / "sweep" / "a" / "episodes.jsonl").read_bytes() == b"a\n"
    assert (run / "sweep.json").read_bytes() == b"{}\n"


def test_a_member_twice_is_named(tmp_path) -> None:
    archive = _tar_xz(tmp_path / "twice.tar.xz", [("run/episodes.jsonl", b"a"), ("run/episodes.jsonl", b"b")])
    with pytest.raises(ValueError) as raised:
        published.extract_archive(archive, tmp_path / "x")
    assert str(raised.value) == f"{archive}: member 'run/episodes.jsonl' appears twice"


class _Chunks:
    """A member's stream that hands out fixed chunks whatever it is asked: a tar reader that
    does not stop at the declared size."""

    def __init__(self, chunks: list[bytes]) -> None:
        self.chunks: Iterator[bytes] = iter(chunks)

    def read(self, size: int = -1) -> bytes:
        return next(self.chunks, b"")


def test_a_member_holding_more_than_it_declares_is_refused_across_chunks(tmp_path, monkeypatch) -> None:
    archive = _tar_xz(tmp_path / "long.tar.xz", [("run/episodes.jsonl", b"0123456789")])
    monkeypatch.setattr(tarfile.TarFile, "extractfile", lambda self, member: _Chunks([b"x" * 8, b"y" * 8]))
    with pytest.raises(ValueError) as raised:
        published.extract_archive(archive, tmp_path / "x")
    assert str(raised.value) == f"{archive}: member 'run/episodes.jsonl' holds more than it declares"
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------------ extract_archive


def test_a_directory_as_the_archive_is_named(tmp_path) -> None:
    folder = tmp_path / "folder.tar.xz"
    folder.mkdir()
    with pytest.raises(ValueError) as raised:
        published.extract_archive(folder, tmp_path / "x")
    assert str(raised.value).startswith(
        f"published archive {str(folder)!r} cannot be read: it is a directory, not a regular file"
    )


def test_extracting_into_a_new_nested_directory_and_beside_other_files(small, tmp_path) -> None:
    nested = tmp_path / "a" / "b" / "c"
    assert published.extract_archive(small, nested) == nested / "run"
    into = tmp_path / "into"
    into.mkdir()
    (into / "keep.txt").write_text("mine")
    bad = _tar_xz(tmp_path / "bad.tar.xz", [("run/episodes.jsonl", b"{}\n"), ("run/evil.sh", b"")])
    with pytest.raises(ValueError, match="is not an episode log"):
        published.extract_archive(bad, into)
    assert [p.name for p in into.iterdir()] == ["keep.txt"]  # its run/ removed, the rest kept


def test_a_damaged_tar_inside_good_xz_is_named_with_tarfiles_reason(tmp_path) -> None:
    archive = tmp_path / "damaged.tar.xz"
    archive.write_bytes(lzma.compress(b"not a tar archive " * 100))
    with pytest.raises(ValueError) as raised:
        published.extract_archive(archive, tmp_path / "x")
    assert str(raised.value).startswith(f"{archive}: is damaged or not a tar archive (ReadError: ")
    assert not (tmp_path / "x").exists()


def test_remove_takes_files_trees_and_links_and_passes_over_what_is_gone(tmp_path) -> None:
    kept = tmp_path / "kept"
    (kept / "inner").mkdir(parents=True)
    tree, file, link, gone = tmp_path / "tree", tmp_path / "file", tmp_path / "link", tmp_path / "gone"
    (tree / "sub").mkdir(parents=True)
    (tree / "sub" / "f").write_text("x")
    file.write_text("x")
    link.symlink_to(kept, target_is_directory=True)
    published._remove([tree, file, link, gone])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"]
    assert (kept / "inner").is_dir()  # a link is removed, never what it points to


def test_a_failed_clean_up_does_not_hide_why_the_archive_was_refused(tmp_path, monkeypatch) -> None:
    bad = _tar_xz(tmp_path / "bad.tar.xz", [("run/episodes.jsonl", b"{}\n"), ("run/evil.sh", b"")])

    def refused(*args: Any, **kwargs: Any) -> None:
        raise PermissionError("rmdir refused")

    monkeypatch.setattr(os, "rmdir", refused)
    with pytest.raises(ValueError, match=r"member 'run/evil\.sh' is not an episode log"):
        published.extract_archive(bad, tmp_path / "x")


# ------------------------------------------------------------------- pack_run, unpack_run


def test_pack_keeps_only_the_logs_and_manifests_and_drops_solve_times(tmp_path) -> None:
    run = tmp_path / "run"
    (run / "sweep" / "lvl").mkdir(parents=True)
    record = _record("E", "c", "m", "s", 0, solve_ms=[1.5, 2.5])
    _log(run / "episodes.jsonl", [record])
    _log(run / "sweep" / "lvl" / "episodes.jsonl", [record])
    manifest = json.dumps({"levels": ["lvl"]}, indent=2) + "\n"  # several lines: not a log
    (run / "sweep.json").write_text(manifest)
    (run / "notes.txt").write_text("not published")
    archive = published.pack_run(run, tmp_path / "run.tar.xz")
    with tarfile.open(archive) as tar:
        assert tar.getnames() == ["run/episodes.jsonl", "run/sweep/lvl/episodes.jsonl", "run/sweep.json"]
        packed = {name: tar.extractfile(name).read().decode() for name in tar.getnames()}  # type: ignore[union-attr]
    assert packed["run/sweep.json"] == manifest
    del record["solve_ms"]
    log = json.dumps(HEADER) + "\n" + json.dumps(record) + "\n"
    assert packed["run/episodes.jsonl"] == packed["run/sweep/lvl/episodes.jsonl"] == log


def test_pack_refuses_a_directory_without_a_log_and_leaves_the_archive(tmp_path) -> None:
    archive = published.pack_run(_run(tmp_path / "made"), tmp_path / "run.tar.xz")
    packed = archive.read_bytes()
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "sweep.json").write_text("{}\n")
    for missing in (tmp_path / "empty", tmp_path / "absent"):
        with pytest.raises(ValueError) as raised:
            published.pack_run(missing, archive)
        assert str(raised.value) == (
            f"{missing}: no episode log (episodes.jsonl) in it or below it, so not a run's directory; "
            f"{archive} was not written"
        )
    assert archive.read_bytes() == packed


def test_pack_names_an_oversized_log(tmp_path, monkeypatch) -> None:
    run = _run(tmp_path)
    monkeypatch.setattr(published, "MAX_MEMBER_BYTES", 10)
    with pytest.raises(ValueError) as raised:
        published.pack_run(run, tmp_path / "run.tar.xz")
    assert str(raised.value).startswith(
        f"episode log or sweep manifest {str(run / 'episodes.jsonl')!r} cannot be read: it is "
    )


def test_unpack_names_a_local_log_that_is_not_text(tmp_path) -> None:
    archive = published.pack_run(_run(tmp_path / "made"), tmp_path / "run.tar.xz")
    local = tmp_path / "into" / "run" / "episodes.jsonl"
    local.parent.mkdir(parents=True)
    local.write_bytes(b"\xff\n")
    with pytest.raises(ValueError) as raised:
        publications.unpack_run(archive, tmp_path / "into")
    assert str(raised.value) == (
        f"episode log {str(local)!r} is not UTF-8 text (byte 0 is b'\\xff'); "
        "expected a KoopNav episode log (JSON lines)"
    )


def test_unpack_counts_an_archive_log_of_no_records_as_none(tmp_path) -> None:
    archive = published.pack_run(_run(tmp_path / "made", records=0), tmp_path / "run.tar.xz")
    local = _run(tmp_path / "into", records=1) / "episodes.jsonl"
    with pytest.raises(ValueError, match=rf"holds 1 records, the archive {re.escape(str(archive))} 0: "):
        publications.unpack_run(archive, tmp_path / "into")
    assert len(local.read_text().splitlines()) == 2  # kept


def test_unpack_replaces_a_longer_local_sweep_manifest(tmp_path) -> None:
    """Only an episode log's records are counted: a manifest is replaced whatever its length."""
    made = _run(tmp_path / "made")
    (made / "sweep.json").write_text('{"levels": []}\n')
    archive = published.pack_run(made, tmp_path / "run.tar.xz")
    local = tmp_path / "into" / "run" / "sweep.json"
    local.parent.mkdir(parents=True)
    local.write_text(json.dumps({"levels": ["a", "b"]}, indent=2) + "\n")
    assert publications.unpack_run(archive, tmp_path / "into") == tmp_path / "into" / "run"
    assert local.read_text() == '{"levels": []}\n'


# ------------------------------------------------------------------------- the command line


def test_the_command_line_packs_unpacks_and_refuses_other_words(tmp_path, capsys) -> None:
    run, archive, into = _run(tmp_path / "made"), tmp_path / "run.tar.xz", tmp_path / "into"
    assert archive_command([str(run), str(archive)]) == 0
    assert capsys.readouterr().out == f"{archive}\n"
    with tarfile.open(archive) as tar:
        assert tar.getnames() == ["run/episodes.jsonl"]
    usage = f"{archive_command.__doc__}\n"
    for wrong in (
        ["unpack", str(archive), str(into), "--bogus"],
        ["unpack", str(archive), str(into), "--force", "more"],
        [str(run)],
    ):
        assert archive_command(wrong) == 2, wrong
        assert capsys.readouterr() == ("", usage)
    assert not into.exists()
    assert archive_command(["unpack", str(archive), str(into)]) == 0
    assert capsys.readouterr().out == f"{into / 'run'}\n"
    assert (into / "run" / "episodes.jsonl").read_bytes() == (run / "episodes.jsonl").read_bytes()


def test_unpack_without_a_directory_is_a_usage_error_and_leaves_the_archive(tmp_path, capsys) -> None:
    """``unpack ARCHIVE`` (DIR forgotten) once packed a run named "unpack", which is none, over
    ARCHIVE: "unpack" is always the command."""
    archive = published.pack_run(_run(tmp_path / "made"), tmp_path / "run.tar.xz")
    packed = archive.read_bytes()
    assert archive_command(["unpack", str(archive)]) == 2
    assert capsys.readouterr() == ("", f"{archive_command.__doc__}\n")
    assert archive.read_bytes() == packed
