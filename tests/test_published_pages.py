"""Published data (evaluation/reports/published.py, data/*.tar.xz): every page listed in data/pages.json
is rebuilt by its generator from the committed episode logs, byte for byte; an archive that is
not what KoopNav packs is refused by name."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

from evaluation.reports.publications import FRAME
from evaluation.reports.published import extract_archive, results_from_log

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_pages import PAGES, page_command, page_digest, read_digests  # noqa: E402  (docs/ is no package)


# 25-100 s per page (each reads its archives and draws its figures): run by -m slow; the generators run
# in the default run on a small evaluator run (tests/test_scripts.py), and the archive reader on
# data/scale_n3.tar.xz (test_packing_is_reproducible_and_reads_back below)
@pytest.mark.slow
@pytest.mark.parametrize("entry", PAGES, ids=[p["page"] for p in PAGES])
def test_the_page_is_rebuilt_from_the_committed_data_byte_for_byte(entry, tmp_path) -> None:
    page = tmp_path / Path(entry["page"]).name
    subprocess.run(
        page_command(entry, page, tmp_path / "_static"), cwd=ROOT, check=True, capture_output=True, text=True
    )
    committed = (ROOT / entry["page"]).read_text(encoding="utf-8")
    assert page.read_text(encoding="utf-8") == committed
    # the digest the fast check of hand edits compares with (tests/test_prose_checks.py)
    assert read_digests()[entry["page"]] == page_digest(page.read_bytes())
    if "_static/" in committed:  # its figures too (docs/paper.md draws none)
        assert list((tmp_path / "_static").glob("*.png"))


def _publications_on_pages(pages: list[dict] = PAGES) -> set[str]:
    """The publications the pages read: an argument ``data/NAME.tar.xz`` or ``data/NAME`` (split),
    alone or as ``RUN=PATH``."""
    paths = {a.partition("=")[2] or a for p in pages for a in p["args"]}
    return {a for a in paths if a.startswith("data/") and (a.endswith(".tar.xz") or not Path(a).suffix)}


def test_every_published_archive_is_on_a_page_and_reads_back_checked() -> None:
    archives = {f"data/{p.name}" for p in (ROOT / "data").glob("*.tar.xz")}
    split = {f"data/{p.parent.name}" for p in (ROOT / "data").glob(f"*/{FRAME}")}
    assert archives and not {a.removesuffix(".tar.xz") for a in archives} & split  # one form per run
    # a page may name a publication not made yet (docs/bench_results.md, docs/ablation.md) only
    # while the committed page says so, naming it as pending
    for entry in PAGES:
        text = (ROOT / entry["page"]).read_text(encoding="utf-8")
        for path in _publications_on_pages([entry]) - archives - split:
            assert f"`{path}`" in text and "pending" in text.lower(), (entry["page"], path)
    assert "data/paper.tar.xz" in _publications_on_pages()  # RUN=PATH arguments are read too


def _archive(tmp_path: Path, members: dict[str, bytes]) -> Path:
    path = tmp_path / "bad.tar.xz"
    with tarfile.open(path, "w:xz") as tar:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return path


def test_a_foreign_archive_or_log_is_refused_by_name(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"member 'run/evil.sh' is not an episode log"):
        extract_archive(_archive(tmp_path, {"run/evil.sh": b"rm -rf /"}), tmp_path / "x")
    with pytest.raises(ValueError, match=r"not one run's directory"):
        extract_archive(
            _archive(tmp_path, {"a/episodes.jsonl": b"", "b/episodes.jsonl": b""}), tmp_path / "y"
        )
    log = tmp_path / "episodes.jsonl"
    log.write_text('{"kind": "something else"}\n')
    with pytest.raises(ValueError, match=r"is not a KoopNav episode log"):
        results_from_log(log)
    header = json.dumps({"kind": "koopnav-run", "config": {"env_ids": ["E"]}})
    log.write_text(header + "\n" + json.dumps({"key": "k", "status": "ok", "success": "yes"}) + "\n")
    with pytest.raises(ValueError, match=r"line 2: "):
        results_from_log(log)


def test_an_archive_of_another_name_or_compression_is_refused_by_name(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"old\.tar\.gz: a published archive's name ends in '\.tar\.xz'"):
        extract_archive(tmp_path / "old.tar.gz", tmp_path / "x")
    gzipped = tmp_path / "gzipped.tar.xz"
    with tarfile.open(gzipped, "w:gz") as tar:
        tar.addfile(tarfile.TarInfo("run/episodes.jsonl"), io.BytesIO(b""))
    with pytest.raises(ValueError, match=r"gzipped\.tar\.xz: not an xz-compressed tar archive"):
        extract_archive(gzipped, tmp_path / "y")


def test_packing_is_reproducible_and_reads_back(tmp_path) -> None:
    from evaluation.reports.published import pack_run

    run = extract_archive(ROOT / "data" / "scale_n3.tar.xz", tmp_path / "run")
    again = pack_run(run, tmp_path / "again.tar.xz")
    assert again.read_bytes() == (ROOT / "data" / "scale_n3.tar.xz").read_bytes()
    with pytest.raises(ValueError, match=r"name ends in '\.tar\.xz'"):
        pack_run(run, tmp_path / "again.tar.gz")
