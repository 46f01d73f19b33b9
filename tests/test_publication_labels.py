"""A controller label with spaces (the ablation's ``model=learned margins=paper constraints=soft``)
publishes split per controller: its part's file writes the space as ``%20`` and reads back to the
label (evaluation/reports/publications.py). Before, such a run could not be packed at all, so
``bash data/publish.sh pack`` failed on the ablation run."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from evaluation.reports import publications

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_publications import _logs, _sweep  # noqa: E402

LABEL = "model=learned margins=paper constraints=soft"


def test_a_label_with_spaces_is_split_and_read_back(tmp_path: Path) -> None:
    run = _sweep(tmp_path / "made", [LABEL, "orca"])
    split = publications.pack_split(run, tmp_path / "data" / "run")
    names = sorted(p.name for p in (split / publications.PARTS).iterdir())
    assert names == ["model=learned%20margins=paper%20constraints=soft.tar.xz", "orca.tar.xz"]
    back = publications.extract_split(split, tmp_path / "back")
    assert _logs(back) == _logs(run)


def test_a_part_whose_file_name_holds_a_space_or_a_stray_percent_is_refused(tmp_path: Path) -> None:
    run = _sweep(tmp_path / "made", [LABEL, "orca"])
    split = publications.pack_split(run, tmp_path / "data" / "run")
    parts = split / publications.PARTS
    encoded = parts / "model=learned%20margins=paper%20constraints=soft.tar.xz"
    for name in (f"{LABEL}.tar.xz", "model=learned%2margins.tar.xz"):
        moved = encoded.rename(parts / name)
        with pytest.raises(ValueError, match=r"not a controller's part \(a regular file LABEL\.tar\.xz\)"):
            publications.extract_split(split, tmp_path / "into")
        moved.rename(encoded)
    assert publications.extract_split(split, tmp_path / "into").is_dir()


def test_labels_without_spaces_keep_their_file_names(tmp_path: Path) -> None:
    run = _sweep(tmp_path / "made", ["a", "nominal-nmpc-v0"])
    split = publications.pack_split(run, tmp_path / "data" / "run")
    assert sorted(p.name for p in (split / publications.PARTS).iterdir()) == [
        "a.tar.xz",
        "nominal-nmpc-v0.tar.xz",
    ]
