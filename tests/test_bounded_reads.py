"""Issue 59, items 2, 3, 4, 6, 9, 11 and 13: nothing is read without a bound (a FIFO, a device or an
oversized file is refused by name, never read), a published archive is unpacked under limits
checked while it streams and into a directory removed after use, ``publish.sh unpack`` keeps a
longer local log, and every report is written whole or not at all.

The FIFO cases run the command line in a subprocess with a timeout: only a guard against the
hang they used to be, never a measure of speed."""

from __future__ import annotations

import errno
import io
import json
import lzma
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.archive import main as archive_command
from evaluation.experiments.sweep import load_sweep
from evaluation.reports import publications, published
from evaluation.reports.baseline import load_baseline

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
#: a subprocess that used to hang on a FIFO is stopped after this [s] (a hang guard, not a timing)
HANG_GUARD = 120
ARGS = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
ARGS += ["--episodes", "1", "--max-episode-steps", "5", "--workers", "1", "--quiet"]


def _cli(*argv: str) -> subprocess.CompletedProcess[str]:
    """``python evaluate.py ARGV`` from the repository root; a hang fails the test instead of stalling
    the suite. Every path in ARGV is absolute; the root as working directory lets the command run
    under mutmut too (its trampolines find their configuration in the working directory)."""
    try:
        return subprocess.run(
            [sys.executable, str(ROOT / "evaluate.py"), *argv],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=HANG_GUARD,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"evaluate.py {' '.join(argv)} hung (killed after {HANG_GUARD} s)")


# ------------------------------------------------------------------------------ item 2: FIFOs


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_as_the_baseline_is_refused_by_name(tmp_path) -> None:
    fifo = tmp_path / "base.json"
    os.mkfifo(fifo)
    done = _cli(*ARGS, "--out", str(tmp_path / "out"), "--baseline", str(fifo))
    assert done.returncode == 2, done.stderr
    assert (
        f"baseline {str(fifo)!r} cannot be read: it is a FIFO (named pipe), not a regular file" in done.stderr
    )
    assert "Traceback" not in done.stderr


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_as_the_resumed_episode_log_is_refused_by_name(tmp_path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / "episodes.jsonl")
    done = _cli(*ARGS, "--out", str(out), "--resume")
    assert done.returncode == 2, done.stderr
    assert f"episode log '{out / 'episodes.jsonl'}' cannot be read: it is a FIFO" in done.stderr


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_as_the_sweep_manifest_is_refused_by_name(tmp_path) -> None:
    out = tmp_path / "sweep"
    out.mkdir()
    os.mkfifo(out / "sweep.json")
    done = _cli("--sweep-report", str(out))
    assert done.returncode == 2, done.stderr
    assert f"sweep manifest '{out / 'sweep.json'}' cannot be read: it is a FIFO" in done.stderr


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_as_the_thresholds_file_is_refused_by_name(tmp_path) -> None:
    # the command line reads --check after the run: the reader itself, in a subprocess (hang guard)
    fifo = tmp_path / "floors.toml"
    os.mkfifo(fifo)
    code = (
        f"from evaluation.reports.thresholds import check_thresholds; check_thresholds(None, {str(fifo)!r})"
    )
    try:
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=HANG_GUARD
        )
    except subprocess.TimeoutExpired:
        pytest.fail("check_thresholds hung on a FIFO")
    assert f"thresholds file {str(fifo)!r} cannot be read: it is a FIFO" in done.stderr, done.stderr


def test_dev_zero_as_the_baseline_is_refused_unread(tmp_path) -> None:
    """It was read until MemoryError: the reader runs under a 1 GiB data limit (a guard for the
    machine), and the refusal must come without reading."""
    code = (
        "import resource; resource.setrlimit(resource.RLIMIT_DATA, (2**30, 2**30)); "
        "from evaluation.reports.baseline import load_baseline; load_baseline('/dev/zero')"
    )
    try:
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=HANG_GUARD
        )
    except subprocess.TimeoutExpired:
        pytest.fail("load_baseline('/dev/zero') did not return")
    assert "baseline '/dev/zero' cannot be read: it is a character device, not a regular file" in done.stderr
    assert "MemoryError" not in done.stderr


def test_an_oversized_log_is_refused_with_its_cap(tmp_path, monkeypatch) -> None:
    from evaluation.episodes import runlog

    log = tmp_path / "episodes.jsonl"
    log.write_text('{"kind": "koopnav-run", "config": {}}\n' + "x" * 200)
    monkeypatch.setattr(runlog, "MAX_LOG_BYTES", 100)
    with pytest.raises(
        ValueError, match=r"episode log .* cannot be read: it is 2\d\d bytes; at most 100 bytes"
    ):
        runlog.read_log(log, {})


# ------------------------------------------------------------ item 11: a file of the wrong kind


def test_a_published_archive_as_the_baseline_says_how_to_use_it() -> None:
    archive = DATA / "scale_n3.tar.xz"
    with pytest.raises(ValueError, match=r"baseline '.*scale_n3\.tar\.xz' is a published archive") as raised:
        load_baseline(archive)
    assert "tar -xJf" in str(raised.value)


def test_a_binary_baseline_names_the_file_and_what_was_expected(tmp_path) -> None:
    blob = tmp_path / "results.json"
    blob.write_bytes(b'{"a": "\xff"}')
    with pytest.raises(
        ValueError, match=r"baseline '.*results\.json' is not UTF-8 text .*expected a KoopNav results"
    ):
        load_baseline(blob)


# --------------------------------------------------------------------- items 3 and 9: archives


def _tar_xz(path: Path, members: Sequence[tarfile.TarInfo | tuple[str, bytes]], preset: int = 6) -> Path:
    """An xz tar of ``members``: (name, bytes) for a regular file, or a ready TarInfo (no data)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for member in members:
            if isinstance(member, tarfile.TarInfo):
                tar.addfile(member)
            else:
                info = tarfile.TarInfo(member[0])
                info.size = len(member[1])
                tar.addfile(info, io.BytesIO(member[1]))
    path.write_bytes(lzma.compress(buffer.getvalue(), format=lzma.FORMAT_XZ, preset=preset))
    return path


def test_a_decompression_bomb_is_stopped_while_it_streams(tmp_path, monkeypatch) -> None:
    """64 MiB of zeros in 10 KB: refused by its ratio within the first megabytes unpacked."""
    bomb = _tar_xz(tmp_path / "bomb.tar.xz", [("run/episodes.jsonl", bytes(64 * 2**20))], preset=0)
    unpacked = []
    read = lzma.LZMAFile.read

    def counted(self, size=-1):  # every byte the reader takes out of the xz stream
        data = read(self, size)
        unpacked.append(len(data))
        return data

    monkeypatch.setattr(lzma.LZMAFile, "read", counted)
    with pytest.raises(ValueError, match=r"bomb\.tar\.xz: .*beyond 100:1 .*decompression bomb"):
        published.extract_archive(bomb, tmp_path / "x")
    assert sum(unpacked) <= 4 * 2**20  # not unpacked in full and checked after
    assert not (tmp_path / "x").exists()  # nothing of it left


@pytest.mark.parametrize(
    ("limit", "value", "message"),
    [
        ("MAX_MEMBERS", 2, r"holds more than 2 members"),
        (
            "MAX_MEMBER_BYTES",
            1000,
            r"member 'run/sweep/a/episodes\.jsonl' unpacks to 2000 bytes; at most 1000",
        ),
        ("MAX_TOTAL_BYTES", 5000, r"unpacks to more than 5000 bytes"),
    ],
)
def test_member_count_size_and_total_are_bounded(tmp_path, monkeypatch, limit, value, message) -> None:
    members = [(f"run/sweep/{name}/episodes.jsonl", os.urandom(1000).hex().encode()) for name in "abc"]
    archive = _tar_xz(tmp_path / "many.tar.xz", members)
    monkeypatch.setattr(published, limit, value)
    with pytest.raises(ValueError, match=message):
        published.extract_archive(archive, tmp_path / "x")
    assert not (tmp_path / "x").exists()


def _special(name: str, kind: bytes, link: str = "") -> tarfile.TarInfo:
    info = tarfile.TarInfo(name)
    info.type, info.linkname = kind, link
    return info


@pytest.mark.parametrize(
    ("member", "message"),
    [
        (("/etc/run/episodes.jsonl", b"{}\n"), "would land outside the extraction directory"),
        (("run/../../episodes.jsonl", b"{}\n"), "would land outside the extraction directory"),
        (_special("run/episodes.jsonl", tarfile.SYMTYPE, "/etc/passwd"), "is a symbolic link"),
        (_special("run/episodes.jsonl", tarfile.LNKTYPE, "/etc/passwd"), "is a hard link"),
        (_special("run/episodes.jsonl", tarfile.CHRTYPE), "is a device"),
    ],
    ids=["absolute", "dot-dot", "symlink", "hardlink", "device"],
)
def test_a_member_outside_or_not_a_file_is_refused_by_name(tmp_path, member, message) -> None:
    archive = _tar_xz(tmp_path / "evil.tar.xz", [member])
    name = member.name if isinstance(member, tarfile.TarInfo) else member[0]
    with pytest.raises(ValueError, match=rf"evil\.tar\.xz: member {name!r} {message}"):
        published.extract_archive(archive, tmp_path / "x")


def test_a_truncated_archive_is_named(tmp_path) -> None:
    cut = tmp_path / "cut.tar.xz"
    cut.write_bytes((DATA / "scale_n3.tar.xz").read_bytes()[:30_000])
    with pytest.raises(ValueError, match=r"cut\.tar\.xz: is truncated"):
        published.extract_archive(cut, tmp_path / "x")


def test_a_published_archive_given_to_sweep_report_is_a_clear_error(tmp_path, capsys) -> None:
    archive = shutil.copy(DATA / "realistic_classic.tar.xz", tmp_path)
    assert ev.main(["--sweep-report", str(archive)]) == 2
    assert f"--sweep-report {str(archive)!r} is a published archive" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["realistic_classic.tar.xz"]


# --------------------------------------------------------------------- item 4: no leftover dirs


def test_reading_an_archive_leaves_no_temporary_directory(tmp_path, monkeypatch) -> None:
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))  # this test's own system temp dir
    done, missing, _ = load_sweep(DATA / "realistic_classic.tar.xz")
    assert done and not missing
    bad = _tar_xz(tmp_path / "bad.tar.xz", [("run/sweep.json", b"{}"), ("run/evil.sh", b"")])
    with pytest.raises(ValueError, match="not an episode log"):
        load_sweep(bad)
    with pytest.raises(RuntimeError), publications.extracted_archive(DATA / "scale_n3.tar.xz") as run:
        assert (run / "episodes.jsonl").is_file()
        raise RuntimeError("the caller fails")
    assert list(scratch.iterdir()) == []


# ----------------------------------------------------------------- item 6: publish.sh unpack


def test_unpack_keeps_a_local_log_with_more_records_unless_forced(tmp_path) -> None:
    (tmp_path / "data").mkdir()
    (tmp_path / ".ci").mkdir()
    shutil.copy(DATA / "publish.sh", tmp_path / "data")
    shutil.copy(DATA.parent / ".ci" / "blas_pin.sh", tmp_path / ".ci")  # the script sources it
    shutil.copy(DATA / "scale_n3.tar.xz", tmp_path / "data")
    with publications.extracted_archive(DATA / "scale_n3.tar.xz") as run:
        log = (run / "episodes.jsonl").read_text()
    packed = len(log.splitlines()) - 1
    local = tmp_path / "data" / "runs" / "scale_n3" / "episodes.jsonl"
    local.parent.mkdir(parents=True)
    local.write_text(log + log.splitlines()[-1] + "\n")  # one record more than the archive
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}

    def unpack(*extra: str) -> subprocess.CompletedProcess[str]:
        command = ["bash", str(tmp_path / "data" / "publish.sh"), "unpack", *extra]
        return subprocess.run(command, capture_output=True, text=True, env=env, timeout=HANG_GUARD)

    refused = unpack()
    assert refused.returncode != 0
    assert f"data/runs/scale_n3/episodes.jsonl holds {packed + 1} records, the archive" in refused.stderr
    assert f"scale_n3.tar.xz {packed}" in refused.stderr
    assert len(local.read_text().splitlines()) == packed + 2  # kept as it was
    forced = unpack("--force")
    assert forced.returncode == 0, forced.stderr
    assert local.read_text() == log


def test_unpack_run_in_process_refuses_to_lose_records_and_forced_replaces_the_log(tmp_path, capsys) -> None:
    # the same rule as publish.sh's, called in this process (the command line's exit code and
    # message too), so that mutation testing reaches it: under `mutmut run` a child process
    # started in publish.sh's working directory cannot find mutmut's configuration
    archive = DATA / "scale_n3.tar.xz"
    with publications.extracted_archive(archive) as run:
        log = (run / "episodes.jsonl").read_text()
    packed = len(log.splitlines()) - 1
    local = tmp_path / "scale_n3" / "episodes.jsonl"
    local.parent.mkdir()
    local.write_text(log + log.splitlines()[-1] + "\n")  # one record more than the archive
    with pytest.raises(ValueError) as caught:
        publications.unpack_run(archive, tmp_path)
    assert str(caught.value) == (
        f"{local} holds {packed + 1} records, the archive {archive} {packed}: unpacking would lose the "
        "records added since it was packed; pack them first (bash data/publish.sh pack), or unpack with "
        "--force to replace the log"
    )
    assert len(local.read_text().splitlines()) == packed + 2  # kept as it was
    assert archive_command(["unpack", str(archive), str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith(f"error: {local} holds {packed + 1} records")
    assert archive_command(["unpack", str(archive), str(tmp_path), "--force"]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'scale_n3'}\n"
    assert local.read_text() == log
    # a local log with as many records (or fewer) is replaced without --force
    local.write_text(log)
    assert publications.unpack_run(archive, tmp_path) == tmp_path / "scale_n3"


# -------------------------------------------------------------- item 13: atomic report writes


def test_a_full_disk_leaves_the_previous_report_whole_and_names_the_file(
    tmp_path, monkeypatch, capsys
) -> None:
    out = tmp_path / "out"
    assert ev.main([*ARGS, "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != "episodes.jsonl"}
    capsys.readouterr()
    real = os.write

    def full(fd: int, data) -> int:  # the disk fills after the first bytes of a file
        real(fd, bytes(data[:10]))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", full)  # the os.write koopman_envs.files calls
    code = ev.main([*ARGS, "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert code == ev.UNWRITABLE_OUT_EXIT, err
    assert "No space left on device" in err and str(out / "results.md") in err
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != "episodes.jsonl"}
    assert after == before  # every report whole, and no temporary file left beside them
    json.loads(before["results.json"])


def test_write_atomic_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch) -> None:
    from koopman_envs import files

    target = tmp_path / "results.json"
    target.write_text('{"old": true}\n')

    def full(fd: int, data) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", full)  # the os.write koopman_envs.files calls
    with pytest.raises(
        OSError, match=r"No space left on device; .*results\.json was left as it was"
    ) as raised:
        files.write_atomic(target, '{"new": true}\n')
    assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(target)
    assert target.read_text() == '{"old": true}\n' and list(tmp_path.iterdir()) == [target]


def test_write_atomic_gives_the_mode_of_a_plain_open_under_the_umask_of_the_process(tmp_path) -> None:
    """0o666 less the umask (here 0o027, set before anything is written), as ``open(path, "w")``
    gives, for text and for a writer of its own; the umask left as it was."""
    script = (
        "import os, stat, sys\n"
        "from pathlib import Path\n"
        "os.umask(0o027)\n"
        "from koopman_envs.files import write_atomic\n"
        "folder = Path(sys.argv[1])\n"
        "write_atomic(folder / 'a.json', '{}')\n"
        "write_atomic(folder / 'b.txt', lambda tmp: Path(tmp).write_text('x'))\n"
        "open(folder / 'plain.txt', 'w').close()\n"
        "modes = [stat.S_IMODE((folder / n).stat().st_mode) for n in ('a.json', 'b.txt', 'plain.txt')]\n"
        "print(*(oct(m) for m in modes), oct(os.umask(0)))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, check=True, timeout=120
    )
    assert done.stdout.split() == ["0o640", "0o640", "0o640", "0o27"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.txt", "plain.txt"]


@pytest.mark.skipif(not hasattr(os, "umask") or sys.platform == "win32", reason="POSIX file modes")
def test_write_atomic_never_sets_the_umask(tmp_path, monkeypatch) -> None:
    """Reading the umask means setting it and setting it back; another thread that makes a file in
    between makes it with the wrong mode. write_atomic lets the kernel apply the umask instead."""
    import stat

    from koopman_envs import files

    umask = os.umask(0o022)
    os.umask(umask)

    def refused(mask: int) -> int:
        raise AssertionError(f"os.umask({mask:#o}) called: it changes the umask of every thread")

    monkeypatch.setattr(os, "umask", refused)
    target = files.write_atomic(tmp_path / "report.md", "# report\n")
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    assert target.read_text() == "# report\n" and list(tmp_path.iterdir()) == [target]


def test_write_atomic_tries_another_temporary_name_when_one_is_taken(tmp_path, monkeypatch) -> None:
    """The temporary file is made with O_EXCL: a name already taken (another writer's) is never
    opened; the next random name is."""
    from koopman_envs import files

    names = iter(["taken", "taken", "free"])
    monkeypatch.setattr(files.secrets, "token_hex", lambda n: next(names))
    taken = tmp_path / ".out.txt.taken.txt"
    taken.write_text("another writer's")
    files.write_atomic(tmp_path / "out.txt", "mine")
    assert (tmp_path / "out.txt").read_text() == "mine" and taken.read_text() == "another writer's"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.txt.taken.txt", "out.txt"]


def test_the_archive_command_exits_103_naming_the_file_when_the_disk_is_full(
    tmp_path, monkeypatch, capsys
) -> None:
    """evaluation.archive caught ValueError only: a full disk was a traceback (exit 1)."""
    run = tmp_path / "run"
    assert ev.main([*ARGS, "--out", str(run)]) == 0
    capsys.readouterr()

    def full(fd: int, data) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", full)  # the os.write koopman_envs.files calls
    assert archive_command([str(run), str(tmp_path / "data" / "run")]) == ev.UNWRITABLE_OUT_EXIT
    assert "No space left on device" in capsys.readouterr().err
