"""The Koopman model's file: a small ``.npz`` of the matrices and JSON metadata, byte for byte
a function of its content (:class:`~controllers.koopman.model.KoopmanModel`'s save and load)."""

from __future__ import annotations

import io
import json
import os
import zipfile
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.calibration import check_position_residual
from controllers.koopman.dictionary import check_memory, check_velocity, get_dictionary
from koopman_envs.checks import parse_json
from koopman_envs.files import MAX_LOG_BYTES, FileRefused, read_bounded, write_atomic

__all__ = ["FORMAT_VERSION", "ModelFileError", "read_model_file", "write_model_file"]

FORMAT_VERSION = 1
#: the metadata keys the model's own fields fill (the rest is provenance)
_OWN = ("format_version", "dictionary", "n_robots", "dt", "memory", "velocity")
_HINT = "regenerate it with `python -m controllers.koopman fit --slip SETTING --out PATH`"


class ModelFileError(ValueError):
    """A model file is missing, corrupt, truncated or does not match what was asked for."""


def write_model_file(
    path: str | os.PathLike, arrays: dict[str, NDArray], own: dict[str, Any], metadata: dict[str, Any]
) -> None:
    """Write the matrices ``arrays`` and the metadata (``own`` fields after the provenance
    ``metadata``) to ``path``.

    ``own`` holds the dictionary, team size and period, and the lift's options only where they
    differ from the paper's lift (no memory, no velocity): such a model writes the file it wrote
    before the options existed.
    """
    meta = {"format_version": FORMAT_VERSION, **{k: own[k] for k in ("dictionary", "n_robots", "dt")}}
    meta.update(metadata)
    meta.update({k: v for k, v in own.items() if k in ("memory", "velocity") and v})
    entries = {**arrays, "metadata": np.array(json.dumps(meta, sort_keys=True))}

    # np.savez stamps the current time into the archive; fixed timestamps make the file a
    # pure function of its content, so a refit can be compared byte for byte
    def write(temporary: str) -> None:
        with zipfile.ZipFile(temporary, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for key, value in entries.items():
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                with archive.open(info, "w") as fh:
                    np.lib.format.write_array(fh, np.asarray(value), allow_pickle=False)

    # whole or not at all (a temporary file renamed over the path): a model file is read back by
    # every later run, and a kill mid-write would otherwise leave a truncated one in its place
    write_atomic(path, write)


def read_model_file(
    path: str | os.PathLike, n_robots: int | None = None, dt: float | None = None
) -> dict[str, Any]:
    """The keyword arguments of the model written to ``path``: A, N, B, C, dictionary,
    n_robots, dt, metadata, memory and velocity.

    Raises
    ------
    ModelFileError
        Missing, truncated or corrupt file, unknown format, bad metadata, or a mismatch with
        ``n_robots`` or ``dt`` (when given). The message says how to regenerate the file.
    """
    path = os.fspath(path)
    if not os.path.lexists(path):
        raise ModelFileError(f"Koopman model file {path!r} does not exist; {_HINT}")
    try:
        # a regular file within the cap, read once (a FIFO in the cache would block an open)
        blob = io.BytesIO(read_bounded(path, MAX_LOG_BYTES, what="Koopman model file"))
        with np.load(blob, allow_pickle=False) as data:
            arrays = {key: data[key] for key in ("A", "N", "B", "C")}
            meta = parse_json(str(data["metadata"]), f"Koopman model file {path!r}, metadata")
    except FileRefused as exc:  # not a regular file, or over the cap: named by the reader
        raise ModelFileError(f"{exc}; {_HINT}") from None
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise ModelFileError(
            f"Koopman model file {path!r} is corrupt or truncated ({type(exc).__name__}: {exc}); {_HINT}"
        ) from exc
    if meta.get("format_version") != FORMAT_VERSION:
        raise ModelFileError(
            f"Koopman model file {path!r} has format_version={meta.get('format_version')!r}; "
            f"this package reads {FORMAT_VERSION}; {_HINT}"
        )
    try:
        own: dict[str, Any] = {
            "dictionary": get_dictionary(meta["dictionary"]),
            "n_robots": int(meta["n_robots"]),
            "dt": float(meta["dt"]),
            "memory": check_memory(meta.get("memory", 0)),
            "velocity": check_velocity(meta.get("velocity", False)),
        }
    except (KeyError, ValueError) as exc:
        raise ModelFileError(f"Koopman model file {path!r} has bad metadata ({exc}); {_HINT}") from exc
    if n_robots is not None and own["n_robots"] != n_robots:
        raise ModelFileError(
            f"Koopman model file {path!r} models {own['n_robots']} robots, but {n_robots} were "
            f"asked for; fit a model for this team size ({_HINT})"
        )
    if dt is not None and not np.isclose(own["dt"], dt):
        raise ModelFileError(f"Koopman model file {path!r} was fitted at dt={own['dt']}, not dt={dt}")
    bad = [key for key, value in arrays.items() if not np.all(np.isfinite(value))]
    if bad:
        raise ModelFileError(f"Koopman model file {path!r} has non-finite entries in {bad}; {_HINT}")
    if "position_residual" in meta:
        try:
            check_position_residual(
                meta["position_residual"], own["n_robots"], f"Koopman model file {path!r}"
            )
        except ValueError as exc:
            raise ModelFileError(f"{exc}; {_HINT}") from None
    extra = {k: v for k, v in meta.items() if k not in _OWN}
    return {**arrays, **own, "metadata": extra}


def model_file_hint() -> str:
    """How to regenerate a model file (the end of every :class:`ModelFileError`'s message)."""
    return _HINT
