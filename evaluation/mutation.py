"""The committed store of mutation verdicts (issue 59): ``python -m evaluation.mutation``.

``.ci/mutation.sh`` runs for hours, longer than a session, and every session is a new machine, so
mutmut's verdicts (its ``mutants/FILE.meta``) are carried in a committed file,
``data/mutation/MODULE.json``, one per module of the script. Each verdict names what it was decided
against: the SHA-256 of the mutated module's source, of every test file of the module's selection,
mutmut's version and the script's ``[tool.mutmut]`` settings. A verdict is reused when all of
them are unchanged, and a *killed* verdict also when tests were only added: the same module,
mutmut and settings besides the test selection, and every entry of the old selection still
selected with its file unchanged (each test that killed the mutant still runs, as it was; a test
added can kill more mutants, never revive one). Any other verdict is stale and the mutant is
tested again, never trusted. So a survivor can be answered by a test in a new file (or a new
entry of the selection) without rerunning the module's killed mutants. A store that
is torn (not whole JSON) or foreign (another format, another module, a malformed record) is
refused by name.

Commands (the script calls the first three with the clone's paths; ``report`` is for people)::

    python -m evaluation.mutation restore STORE MODULE CLONE TARGET SETTINGS_FILE TEST...
    python -m evaluation.mutation save STORE MODULE CLONE TARGET SETTINGS_FILE TEST...
    python -m evaluation.mutation report [STORE ...]    # default: data/mutation/*.json

``restore`` writes the store's trusted verdicts into the clone's ``mutants/TARGET.meta`` before
``mutmut run`` (mutmut keeps a verdict whose function's hash is unchanged and tests only the
mutants without one); when every mutant has a trusted verdict it writes ``mutants/results.txt``
(``NAME: STATUS`` lines, as ``mutmut results --all true``) and exits 10, so that mutmut is not
started at all. ``save`` writes the clone's final verdicts back into the store, whole (a temporary
file renamed over it). Exit 2: a store refused.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from koopman_envs.checks import parse_json
from koopman_envs.files import FileRefused, read_bounded, write_atomic

FORMAT = "koopnav-mutation-verdicts"
#: the line of the script's ``[tool.mutmut]`` section that lists the test selection
SELECTION_KEY = "pytest_add_cli_args_test_selection"
VERSION = 1
MAX_STORE_BYTES = 16 * 2**20
# mutmut 3's exit codes of the verdicts a rerun would repeat (mutmut.stats.status_by_exit_code);
# any other (pytest interrupted, a worker killed by a signal, "suspicious") may be an
# interruption's and is never stored. Kept here so that a store is read without mutmut.
FINAL_STATUS = {
    0: "survived",
    1: "killed",
    3: "killed",
    5: "no tests",
    33: "no tests",
    34: "skipped",
    36: "timeout",
    -24: "timeout",
    24: "timeout",
    152: "timeout",
    255: "timeout",
    37: "caught by type check",
}
EXIT_ALL_DECIDED = 10


def status_of(code: int | None) -> str:
    """The name of a mutant's exit code (``1`` -> ``"killed"``; not final: ``"not final (CODE)"``)."""
    return FINAL_STATUS.get(code, f"not final ({code})") if isinstance(code, int) else "not checked"


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@dataclass(frozen=True)
class Against:
    """What a module's verdicts were decided against."""

    target: dict[str, str]
    tests: dict[str, str]
    mutmut: str
    settings: str
    #: the settings without the test selection's line (:data:`SELECTION_KEY`)
    rest: str = ""
    #: the selection's entries (test files or test ids), sorted
    selection: tuple[str, ...] = ()

    @classmethod
    def of_tree(
        cls, root: Path, target: str, tests: list[str], settings: str, mutmut: str | None = None
    ) -> Against:
        """The digests of the tree at ``root``: ``target``, the files of ``tests`` (test ids and
        repeats reduced to files), mutmut's version (default: the installed one) and the settings,
        whole and without the selection's line; and the selection's entries."""
        files = sorted({t.split("::")[0] for t in tests})
        rest = "\n".join(
            line for line in settings.splitlines() if not line.lstrip().startswith(SELECTION_KEY)
        )
        return cls(
            target={target: _sha256((root / target).read_bytes())},
            tests={f: _sha256((root / f).read_bytes()) for f in files},
            mutmut=mutmut or metadata.version("mutmut"),
            settings=_sha256(settings.encode("utf-8")),
            rest=_sha256(rest.encode("utf-8")),
            selection=tuple(sorted(set(tests))),
        )

    def as_json(self) -> dict[str, Any]:
        record = {
            "target": self.target,
            "tests": self.tests,
            "mutmut": self.mutmut,
            "settings": self.settings,
        }
        if self.rest:  # a record of before these fields keeps its digest
            record.update(rest=self.rest, selection=list(self.selection))
        return record

    def keeps_killed(self, old: Mapping[str, Any]) -> bool:
        """Whether a mutant killed against ``old`` (an :meth:`as_json` record) is killed against
        this tree too: the same module, mutmut and settings besides the selection, and every entry
        of ``old``'s selection still selected (as itself or by its whole file) with its file's
        digest unchanged. A record without ``rest`` (of before the rule) keeps nothing."""
        selection = old.get("selection")
        if not self.rest or not old.get("rest") or not isinstance(selection, list):
            return False
        if (old.get("target"), old.get("mutmut"), old.get("rest")) != (self.target, self.mutmut, self.rest):
            return False
        tests = old.get("tests")
        if not isinstance(tests, dict):
            return False
        mine = set(self.selection)
        for entry in selection:
            file = str(entry).split("::")[0]
            if (entry not in mine and file not in mine) or tests.get(file) != self.tests.get(file):
                return False
        return True

    @property
    def digest(self) -> str:
        """One digest of all of it, which each verdict carries."""
        return _sha256(json.dumps(self.as_json(), sort_keys=True).encode("utf-8"))


@dataclass
class Store:
    """A module's verdicts: mutant name -> (mutmut's exit code, the digest it was decided against)."""

    module: str
    verdicts: dict[str, tuple[int, str]] = field(default_factory=dict)
    mutants: int = 0
    against: dict[str, Any] = field(default_factory=dict)

    def trusted(self, against: Against) -> dict[str, int]:
        """The exit codes decided against exactly ``against``, and the kills decided against the
        store's own record (:attr:`against`) where ``against`` keeps them (:meth:`Against.keeps_killed`)."""
        kept = bool(self.against) and against.keeps_killed(self.against)
        old = _sha256(json.dumps(self.against, sort_keys=True).encode("utf-8")) if kept else None
        return {
            name: code
            for name, (code, made) in self.verdicts.items()
            if made == against.digest or (made == old and status_of(code) == "killed")
        }

    def to_json(self) -> str:
        records = [
            {"name": name, "exit_code": code, "status": status_of(code), "against": made}
            for name, (code, made) in sorted(self.verdicts.items())
        ]
        body = {
            "format": FORMAT,
            "version": VERSION,
            "module": self.module,
            "mutants": self.mutants,
            "against": self.against,
            "verdicts": records,
        }
        return json.dumps(body, indent=1, sort_keys=True) + "\n"


def _foreign(path: Path, reason: str) -> ValueError:
    return ValueError(f"mutation store {str(path)!r} refused: {reason}")


def read_store(path: Path, module: str | None) -> Store:
    """The store at ``path`` (an empty one when missing), for ``module`` (``None``: any).

    Raises
    ------
    ValueError
        The file is not a regular file of at most 16 MiB, is torn (not whole JSON), or is foreign:
        another format or version, another module, or a record that is not a name, an exit code
        of a final verdict and a digest. The message names the file.
    """
    if not path.exists() and module is not None:
        return Store(module)
    data = read_bounded(path, MAX_STORE_BYTES, what="mutation store")
    try:
        body = parse_json(data, str(path))
    except json.JSONDecodeError as exc:
        raise _foreign(path, f"torn or not JSON ({exc.msg} at character {exc.pos})") from None
    if not isinstance(body, dict) or body.get("format") != FORMAT:
        raise _foreign(path, f"not a {FORMAT} file")
    if body.get("version") != VERSION:
        raise _foreign(path, f"version {body.get('version')!r}; allowed: {VERSION}")
    if module is not None and body.get("module") != module:
        raise _foreign(path, f"made for module {body.get('module')!r}, not {module!r}")
    records, mutants = body.get("verdicts"), body.get("mutants")
    if not isinstance(records, list) or not isinstance(mutants, int) or isinstance(mutants, bool):
        raise _foreign(path, "no list of verdicts and count of mutants")
    store = Store(str(body["module"]), mutants=mutants, against=body.get("against") or {})
    for i, record in enumerate(records):
        ok = isinstance(record, dict) and isinstance(record.get("name"), str)
        code = record.get("exit_code") if ok else None
        ok = (
            ok
            and isinstance(code, int)
            and not isinstance(code, bool)
            and isinstance(record.get("against"), str)
        )
        if not ok or code not in FINAL_STATUS or record.get("status") != status_of(code):
            raise _foreign(
                path, f"verdict {i} is not a mutant's name, final exit code, status and digest: {record!r}"
            )
        store.verdicts[record["name"]] = (code, record["against"])  # type: ignore[assignment]
    return store


def write_store(path: Path, store: Store) -> None:
    """Write ``store`` to ``path`` whole."""
    write_atomic(path, store.to_json())


def _mutants(root: Path, target: str) -> tuple[list[str], dict[str, str]]:
    """mutmut's qualified mutant names of ``target`` and its functions' hashes."""
    from mutmut.mutation.file_mutation import mutate_file_contents
    from mutmut.utils.format_utils import get_mutant_name

    made = mutate_file_contents(target, (root / target).read_text(encoding="utf-8"))
    return [get_mutant_name(Path(target), n) for n in made.mutant_names], dict(made.hash_by_function_name)


def _meta_path(root: Path, target: str) -> Path:
    return root / "mutants" / f"{target}.meta"


def _read_meta(path: Path) -> dict[str, Any]:
    """mutmut's meta file, read bounded; ``ValueError`` naming it when torn or not mutmut's."""
    meta = parse_json(read_bounded(path, 4 * MAX_STORE_BYTES, what="mutmut meta file"), str(path))
    if not isinstance(meta, dict) or not isinstance(meta.get("exit_code_by_key"), dict):
        raise ValueError(f"mutmut meta file {str(path)!r} holds no exit_code_by_key")
    return meta


def restore(path: Path, module: str, root: Path, target: str, against: Against) -> int:
    """Write the trusted verdicts of the store into the clone's meta file; 10 when all are decided."""
    store = read_store(path, module)
    trusted = store.trusted(against)
    names, hashes = _mutants(root, target)
    meta_path = _meta_path(root, target)
    if meta_path.exists():
        meta = _read_meta(meta_path)
    else:
        meta = {
            "exit_code_by_key": {},
            "hash_by_function_name": hashes,
            "type_check_error_by_key": {},
            "durations_by_key": {},
            "estimated_durations_by_key": {},
        }
    codes = meta["exit_code_by_key"]
    restored = 0
    for name in names:
        if codes.get(name) is None and name in trusted:
            codes[name] = trusted[name]
            restored += 1
        codes.setdefault(name, None)
    write_atomic(meta_path, json.dumps(meta, indent=4))
    stale = len(store.verdicts) - len(trusted)
    note = f", {stale} stale verdicts (decided against another tree) to test again" if stale else ""
    print(f"  {restored} verdicts restored from {path}{note}")
    if all(codes[n] is not None for n in names):
        lines = [f"    {n}: {status_of(codes[n])}" for n in names]
        write_atomic(root / "mutants" / "results.txt", "".join(f"{line}\n" for line in lines))
        print(f"  every one of the {len(names)} mutants has a verdict: mutmut is not started")
        return EXIT_ALL_DECIDED
    return 0


def save(path: Path, module: str, root: Path, target: str, against: Against) -> int:
    """Write the clone's final verdicts into the store (with its trusted ones), whole."""
    store = read_store(path, module)
    kept = store.trusted(against)
    meta_path = _meta_path(root, target)
    if not meta_path.exists():
        return 0
    try:
        codes = _read_meta(meta_path)["exit_code_by_key"]
    except ValueError:  # FileRefused and JSONDecodeError too
        print(f"  {meta_path} is torn: nothing saved from it")
        return 0
    for name, code in codes.items():
        if code in FINAL_STATUS:
            kept[name] = code
    digest = against.digest
    new = Store(
        module, {n: (c, digest) for n, c in kept.items() if n in codes}, len(codes), against.as_json()
    )
    text = new.to_json()
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        write_atomic(path, text)
    return 0


def report(paths: list[Path]) -> int:
    """Print each store's score: killed / mutants, the verdicts missing, the mutants not killed."""
    for path in paths:
        store = read_store(path, None)
        statuses = {name: status_of(code) for name, (code, _) in store.verdicts.items()}
        killed = sum(s == "killed" for s in statuses.values())
        total = max(store.mutants, len(statuses))
        share = f"{100.0 * killed / total:.1f}%" if total else "-"
        missing = total - len(statuses)
        todo = f", {missing} without a verdict" if missing else ""
        print(f"{store.module}: {killed}/{total} killed ({share}){todo} [{path}]")
        for name, status in sorted(statuses.items()):
            if status != "killed":
                print(f"  {status}: {name}")
    return 0


def main(argv: list[str]) -> int:
    usage = (
        "usage: python -m evaluation.mutation restore|save STORE MODULE CLONE TARGET SETTINGS_FILE TEST...\n"
        "       python -m evaluation.mutation report [STORE ...]"
    )
    if not argv or argv[0] not in {"restore", "save", "report"}:
        print(
            f"{usage}\ncommand {argv[0] if argv else None!r}; allowed: restore, save, report", file=sys.stderr
        )
        return 2
    try:
        if argv[0] == "report":
            paths = [Path(p) for p in argv[1:]] or sorted(Path("data/mutation").glob("*.json"))
            return report(paths)
        if len(argv) < 6:
            print(usage, file=sys.stderr)
            return 2
        store, module, root, target, settings = Path(argv[1]), argv[2], Path(argv[3]), argv[4], Path(argv[5])
        against = Against.of_tree(root, target, argv[6:], settings.read_text(encoding="utf-8"))
        command = restore if argv[0] == "restore" else save
        return command(store, module, root, target, against)
    except (FileRefused, ValueError) as exc:
        print(exc, file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
