"""``unpack_run`` reads each file of one archive again under the member bound before it writes it
out (a file grown or swapped between the extraction and the read): the refusal names it an
unpacked member, with the bound, and nothing is written (issue 59). A split publication is refused
earlier, by ``extract_split``'s own read (tests/test_publications.py)."""

from __future__ import annotations

import io
import lzma
import tarfile
from pathlib import Path

import pytest

from evaluation.reports import publications


def _archive(path: Path, name: str, data: bytes) -> Path:
    """One xz-compressed tar archive holding ``name`` (built here, not by the module under test)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        info = tarfile.TarInfo(name)
        info.size = len(data)
        tar.addfile(info, io.BytesIO(data))
    path.write_bytes(lzma.compress(buffer.getvalue()))
    return path


def test_one_archives_unpacked_member_past_the_bound_is_refused_by_what_it_is(tmp_path, monkeypatch) -> None:
    archive = _archive(tmp_path / "run.tar.xz", "run/episodes.jsonl", b"x" * 100)
    # the extraction's own member bound stays; only the read before the write is made tighter
    monkeypatch.setattr(publications, "MAX_MEMBER_BYTES", 16)
    into = tmp_path / "runs"
    refused = r"^unpacked member '[^']+episodes\.jsonl' cannot be read: it is 100 bytes; at most 16 bytes are allowed$"
    with pytest.raises(ValueError, match=refused):
        publications.unpack_run(archive, into)
    assert not list(into.rglob("episodes.jsonl"))


def test_one_archive_within_the_bound_is_unpacked_whole(tmp_path) -> None:
    archive = _archive(tmp_path / "run.tar.xz", "run/episodes.jsonl", b"x" * 100)
    run = publications.unpack_run(archive, tmp_path / "runs")
    assert run == tmp_path / "runs" / "run"
    assert (run / "episodes.jsonl").read_bytes() == b"x" * 100
