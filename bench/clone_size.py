"""What a newcomer's clone weighs, how much of it is ``data/``, and what republishing adds (issue 61).

Usage::

    python bench/clone_size.py [--repo PATH] [--no-clone] [--archives NAME ...]

It clones ``--repo`` (default: this repository) with ``git clone --no-local`` into a temporary
folder, as a newcomer's clone would be made, and prints:

- the clone's size on disk (``du``) and its pack (``git count-objects -v``, ``size-pack``);
- the history's objects on disk (``git rev-list --objects --all | git cat-file --batch-check``
  with ``%(objectsize:disk)``), and the share of them under ``data/``, of which the versions
  that are no longer in the tip (superseded archives);
- for every publication in the tip (``data/NAME.tar.xz`` or ``data/NAME/``): its size now, how
  many versions the history holds and what each added (its size on disk in the pack);
- what republishing one controller adds: for each whole archive (or the ``--archives`` named),
  the archive unpacked and packed split per controller
  (:func:`evaluation.reports.publications.pack_split`) in a temporary folder, with its frame's
  size and its median and largest part: a rerun of one controller rewrites one part, where it
  rewrote the whole archive before.

``--no-clone`` measures ``--repo`` in place (quicker: no copy; its pack may hold more than a
clone's). Nothing in the repository is written.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import tempfile
from collections import defaultdict
from pathlib import Path

from evaluation.reports.publications import FRAME, PARTS, extracted_archive, pack_split

ROOT = Path(__file__).resolve().parents[1]
_MB = 1e6


def git(repo: Path, *args: str, stdin: str | None = None) -> str:
    """The output of ``git -C repo ARGS`` (an error names the command)."""
    done = subprocess.run(
        ["git", "-C", str(repo), *args], input=stdin, capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise RuntimeError(f"git {' '.join(args)} failed in {repo}: {done.stderr.strip()}")
    return done.stdout


def disk_bytes(path: Path) -> int:
    """Bytes of the files under ``path`` (``du -sb``)."""
    return int(
        subprocess.run(["du", "-sb", str(path)], capture_output=True, text=True, check=True).stdout.split()[0]
    )


def file_bytes(path: Path) -> int:
    """Bytes of the files under the directory ``path`` (the files' sizes, as git stores them)."""
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def objects_on_disk(repo: Path) -> dict[str, tuple[int, str]]:
    """Every object of the history: its id -> (its size in the pack [bytes], the first path it is
    seen at, "" for commits and the root trees)."""
    listed = git(repo, "rev-list", "--objects", "--all")
    checked = git(repo, "cat-file", "--batch-check=%(objectname) %(objectsize:disk) %(rest)", stdin=listed)
    out = {}
    for line in checked.splitlines():
        name, size, *path = line.split(" ", 2)
        out[name] = (int(size), path[0] if path else "")
    return out


def versions(repo: Path, path: str) -> list[str]:
    """The blob ids ``path`` has held in the history (every branch), oldest first."""
    raw = git(repo, "log", "--all", "--reverse", "--format=", "--raw", "--no-abbrev", "--", path)
    ids = [line.split()[3] for line in raw.splitlines() if line.startswith(":")]
    return list(dict.fromkeys(i for i in ids if set(i) != {"0"}))


def publications(repo: Path) -> list[str]:
    """The publications in the tip: ``data/NAME.tar.xz`` and the split ``data/NAME/``."""
    files = git(repo, "ls-tree", "-r", "--name-only", "HEAD", "data/").splitlines()
    whole = [f for f in files if f.count("/") == 1 and f.endswith(".tar.xz")]
    split = sorted({f.rsplit("/", 1)[0] for f in files if f.endswith(f"/{FRAME}") and f.count("/") == 2})
    return sorted(whole) + split


def split_sizes(archive: Path, scratch: Path) -> tuple[int, int, list[int]]:
    """The archive packed split per controller: (the split's bytes, its frame's, each part's)."""
    with extracted_archive(archive) as run:
        dest = pack_split(run, scratch / run.name)
    parts = [p.stat().st_size for p in sorted((dest / PARTS).iterdir())]
    return file_bytes(dest), (dest / FRAME).stat().st_size, parts


def report(repo: Path, names: list[str] | None) -> None:
    """Print the figures of the module docstring for the repository ``repo``."""
    objects = objects_on_disk(repo)
    total = sum(size for size, _ in objects.values())
    data = sum(size for size, path in objects.values() if path.startswith("data/"))
    tip = set(git(repo, "rev-parse", "HEAD:data").split()) | {
        line.split()[2] for line in git(repo, "ls-tree", "-r", "HEAD", "data/").splitlines()
    }
    old = sum(size for name, (size, path) in objects.items() if path.startswith("data/") and name not in tip)
    print(
        f"history: {total / _MB:.1f} MB of objects on disk, data/ {data / _MB:.1f} MB ({100 * data / total:.1f}%)"
    )
    print(
        f"  of which versions no longer in the tip: {old / _MB:.1f} MB ({100 * old / total:.1f}% of the history)"
    )
    by_kind: dict[str, int] = defaultdict(int)
    for size, path in objects.values():
        if path.startswith("data/") and path.endswith(".tar.gz"):
            by_kind["data/*.tar.gz (the gzip form, removed)"] += size
    for kind, size in by_kind.items():
        print(f"  {kind}: {size / _MB:.1f} MB")
    print()
    print(
        "| publication | now [KB] | versions | each version added [KB] | parts | frame [KB] | median part [KB] | largest part [KB] | split total [KB] |"
    )
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|")
    rewrites, parts_added, splits = [], [], []
    with tempfile.TemporaryDirectory(prefix="koopnav-clone-size-") as scratch:
        for pub in publications(repo):
            name = Path(pub).name.removesuffix(".tar.xz")
            if names is not None and name not in names:
                continue
            ids = versions(repo, pub) if pub.endswith(".tar.xz") else versions(repo, f"{pub}/{PARTS}")
            added = [objects[i][0] for i in ids if i in objects]
            now = (repo / pub).stat().st_size if pub.endswith(".tar.xz") else file_bytes(repo / pub)
            row = f"| {pub} | {now / 1e3:,.0f} | {len(ids)} | {', '.join(f'{a / 1e3:,.0f}' for a in added)} |"
            if pub.endswith(".tar.xz"):
                whole, frame, parts = split_sizes(repo / pub, Path(scratch))
                rewrites.append(now)
                parts_added.append(statistics.median(parts))
                splits.append(whole)
                row += f" {len(parts)} | {frame / 1e3:.1f} | {statistics.median(parts) / 1e3:,.0f} | {max(parts) / 1e3:,.0f} | {whole / 1e3:,.0f} |"
            else:
                row += " | | | | |"
            print(row)
    if rewrites:
        print()
        print(
            f"republishing one controller of a run adds: its whole archive (old) median {statistics.median(rewrites) / 1e3:,.0f} KB, "
            f"mean {statistics.mean(rewrites) / 1e3:,.0f} KB; one part (split) median {statistics.median(parts_added) / 1e3:,.0f} KB, "
            f"mean {statistics.mean(parts_added) / 1e3:,.0f} KB"
        )
        print(
            f"one controller rerun in each of the {len(rewrites)} runs adds: {sum(rewrites) / _MB:.1f} MB whole (old), "
            f"{sum(parts_added) / _MB:.1f} MB split ({sum(rewrites) / sum(parts_added):.1f}x less); "
            f"the first split publication of all of them adds {sum(splits) / _MB:.1f} MB once "
            f"({sum(splits) / sum(rewrites):.2f}x their whole archives: the parts are compressed apart)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", type=Path, default=ROOT, help="the repository (default: this one)")
    parser.add_argument(
        "--no-clone", action="store_true", help="measure --repo in place instead of a fresh clone"
    )
    parser.add_argument(
        "--archives", nargs="+", metavar="NAME", help="split only these runs (default: every whole archive)"
    )
    args = parser.parse_args()
    if args.no_clone:
        report(args.repo, args.archives)
        return
    with tempfile.TemporaryDirectory(prefix="koopnav-clone-") as scratch:
        clone = Path(scratch) / "clone"
        subprocess.run(["git", "clone", "--quiet", "--no-local", str(args.repo), str(clone)], check=True)
        pack = dict(line.split(": ") for line in git(clone, "count-objects", "-v").splitlines())
        print(
            f"clone (git clone --no-local): {disk_bytes(clone) / _MB:.1f} MB on disk, .git {disk_bytes(clone / '.git') / _MB:.1f} MB, "
            f"pack {int(pack['size-pack']) / 1024:.1f} MiB in {pack['in-pack']} objects"
        )
        report(clone, args.archives)


if __name__ == "__main__":
    main()
