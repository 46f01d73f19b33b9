"""Load a stable-baselines3 model from its zip without running any of the pickles inside it.

An SB3 zip stores its weights as tensors (``policy.pth``, read by ``torch.load(weights_only=True)``,
which runs no code) and its settings as JSON, except a dozen fields that it pickles with
cloudpickle (the policy class, the spaces, the schedules, the extractor class...).
``cloudpickle.loads`` runs whatever code the file's author put there, so loading an untrusted zip
the plain way is running an untrusted program.

SB3's ``load(custom_objects=...)`` takes a value for a field instead of unpickling it. This module
rebuilds every pickled field of a policy that KoopNav trains (``python -m baselines.sb3.train``) from
the readable text SB3 writes beside each pickle, against an allow-list of classes, and refuses a
zip that holds any other pickled field. The shipped policies load this way (tested bit-identical
to the pickled load); ``allow_pickle=True`` loads any zip the plain way, for files you trust.

Before any of that, trusted or not, the file is checked as a zip without unpacking anything: its
size, its central directory (entry count and size, before ``zipfile`` builds an object per
entry), each entry's declared uncompressed size, their total and the compression ratio (a zip
bomb: a 0.8 MB zip whose entry unpacks to 800 MB once took 2.6 GB). Every entry is then streamed
in bounded chunks, never more than it declares, with its CRC checked, and SB3 loads the very bytes
that were checked. Every failure is a :class:`PolicyLoadError` naming the file and what is wrong;
the limits are the ``MAX_*`` constants below.
"""

from __future__ import annotations

import io
import json
import os
import re
import struct
import zipfile
import zlib
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs import files

__all__ = [
    "MAX_DIRECTORY_BYTES",
    "MAX_ENTRIES",
    "MAX_ENTRY_BYTES",
    "MAX_FILE_BYTES",
    "MAX_RATIO",
    "MAX_TEXT_BYTES",
    "MAX_TOTAL_BYTES",
    "RATIO_FLOOR",
    "PolicyLoadError",
    "UnsafePolicyFile",
    "load_model",
    "load_npz",
    "read_bounded",
    "read_json",
]

_MIB = 2**20
#: Largest uncompressed size of one entry [bytes]. The shipped policies' largest entry (an Adam
#: state) is 1.3 MB; 256 MiB holds the weights of a network of tens of millions of parameters, far
#: beyond what KoopNav trains, and bounds what reading one entry (SB3 reads each one whole) can take.
MAX_ENTRY_BYTES = 256 * _MIB
#: Largest total of the entries' uncompressed sizes [bytes]: SB3 reads them all.
MAX_TOTAL_BYTES = 256 * _MIB
#: Largest uncompressed-to-compressed ratio of an entry above :data:`RATIO_FLOOR`. Weights and JSON
#: compress about 1-10:1; deflate goes beyond 200:1 only on long runs of one byte, a zip bomb's payload.
MAX_RATIO = 200
#: Entries up to this size [bytes] are not ratio-checked: whatever their ratio they cost little,
#: and a short text (a version string, a run of spaces) may compress beyond :data:`MAX_RATIO`.
RATIO_FLOOR = _MIB
#: Largest number of entries (SB3 writes 6, an ``obs_norm.npz`` 4).
MAX_ENTRIES = 64
#: Largest central directory [bytes], checked before ``zipfile`` parses it into one object per
#: entry (a directory of millions of empty entries would take gigabytes before any other check).
MAX_DIRECTORY_BYTES = _MIB
#: Largest file [bytes]: the entries' total and room for their headers (the file is read whole,
#: so that SB3 loads the very bytes that were checked).
MAX_FILE_BYTES = MAX_TOTAL_BYTES + _MIB
#: Largest text parsed as JSON [bytes] (SB3's ``data`` entry, ``metadata.json``): the parser
#: builds objects several times the size of the text. The shipped ones are 0.6 MB at most.
MAX_TEXT_BYTES = files.MAX_TEXT_BYTES
#: Bytes read from an entry at a time.
_CHUNK = _MIB

# the end of a zip's central directory (see the ZIP application note, 4.3.16 and 4.3.14-15)
_END = struct.Struct("<4s4H2LH")  # signature, disks, entries here and in all, size, offset, comment
_END64_LOCATOR = struct.Struct("<4sLQL")
_END64 = struct.Struct("<4sQ2H2L4Q")  # ..., entries here and in all, size, offset

#: the extractor classes a KoopNav policy may name (by the text SB3 writes beside the pickle): the
#: set encoder under its module path now and under the one it had when the shipped set policies
#: were trained (``baselines.set_encoder``, recorded in their zips; they keep loading after the move)
_EXTRACTORS = {
    f"<class '{module}.SetEncoder'>": ("baselines.sb3.set_encoder", "SetEncoder")
    for module in ("baselines.sb3.set_encoder", "baselines.set_encoder")
}
#: pickled fields that only matter for training (rollout state, episode buffers): left out
_TRAINING_STATE = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
)


class PolicyLoadError(ValueError):
    """A policy file cannot be loaded: the message names the file and what is wrong.

    Every failure of :func:`load_model` (and of :func:`baselines.sb3.policy.load_policy`) is one: a
    file that is missing, not a zip, damaged or beyond the ``MAX_*`` limits, an entry that is
    missing, not UTF-8 or not JSON, a malformed field, weights that torch cannot read.
    """


class UnsafePolicyFile(PolicyLoadError):
    """A policy zip holds a pickled field this loader cannot rebuild without running it."""


def _refuse(path: str | os.PathLike[str], reason: str) -> PolicyLoadError:
    return PolicyLoadError(f"{os.fspath(path)}: {reason}")


def _reason(exc: BaseException) -> str:
    """``Type: message``, first line only (torch's messages run to a page; the cause is chained)."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def _size(n: int) -> str:
    """``n`` bytes, with MiB for the reader."""
    return f"{n} bytes ({n / _MIB:.1f} MiB)" if n >= _MIB else f"{n} bytes"


def read_bounded(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of the file ``path``; one of more than ``limit`` bytes, or one that is not a regular
    file (a FIFO, a device), is refused unread (:func:`koopman_envs.files.read_bounded`).

    Raises
    ------
    PolicyLoadError
        The file cannot be read, is not a regular file, or is larger than ``limit``.
    """
    try:
        return files.read_bounded(path, limit, what="policy file")
    except files.FileRefused as exc:
        raise PolicyLoadError(str(exc)) from None


def _directory_size(blob: bytes, path: str | os.PathLike[str]) -> tuple[int, int]:
    """(entries, bytes) of the central directory, read from its end record as ``zipfile`` reads it."""
    start = blob.rfind(b"PK\x05\x06", max(0, len(blob) - _END.size - 0xFFFF))
    if start < 0 or start + _END.size > len(blob):
        raise _refuse(path, "is not a zip file (no end of central directory: not a zip, or truncated)")
    _, _, _, _, entries, size, _, _ = _END.unpack_from(blob, start)
    # zip64: a locator right before the end record, the zip64 end record right before the locator
    locator = start - _END64_LOCATOR.size
    record = locator - _END64.size
    if (
        record >= 0
        and blob[locator : locator + 4] == b"PK\x06\x07"
        and blob[record : record + 4] == b"PK\x06\x06"
    ):
        fields = _END64.unpack_from(blob, record)
        entries, size = fields[7], fields[8]
    return entries, size


def _open_zip(blob: bytes, path: str | os.PathLike[str]) -> zipfile.ZipFile:
    """``blob`` as a zip whose declared sizes are within the limits; nothing is unpacked."""
    entries, directory = _directory_size(blob, path)
    if entries > MAX_ENTRIES:
        raise _refuse(path, f"has {entries} entries; at most {MAX_ENTRIES} are allowed")
    if directory > MAX_DIRECTORY_BYTES:
        raise _refuse(
            path,
            f"has a central directory of {_size(directory)}; at most {_size(MAX_DIRECTORY_BYTES)} are allowed",
        )
    try:
        archive = zipfile.ZipFile(io.BytesIO(blob))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError, struct.error) as exc:
        raise _refuse(path, f"is not a zip file, or a damaged one ({_reason(exc)})") from exc
    infos = archive.infolist()
    if len(infos) > MAX_ENTRIES:  # more than its end record declared
        archive.close()
        raise _refuse(path, f"has {len(infos)} entries; at most {MAX_ENTRIES} are allowed")
    total = 0
    for info in infos:
        name, size, packed = info.filename, info.file_size, info.compress_size
        problem = None
        if size > MAX_ENTRY_BYTES:
            problem = f"entry {name!r} unpacks to {_size(size)}; at most {_size(MAX_ENTRY_BYTES)} per entry are allowed"
        elif size > RATIO_FLOOR and size > MAX_RATIO * packed:
            problem = (
                f"entry {name!r} is compressed {size / max(packed, 1):.0f}:1 ({packed} bytes unpack to {size}); "
                f"at most {MAX_RATIO}:1 is allowed for entries above {_size(RATIO_FLOOR)}: the mark of a zip bomb"
            )
        total += size
        if problem is None and total > MAX_TOTAL_BYTES:
            problem = f"its entries unpack to more than {_size(MAX_TOTAL_BYTES)} in total, the most allowed"
        if problem is not None:
            archive.close()
            raise _refuse(path, problem)
    return archive


def _read_entry(
    archive: zipfile.ZipFile, name: str, path: str | os.PathLike[str], keep: bool = False
) -> bytes:
    """Stream entry ``name`` in bounded chunks, checking its CRC; its bytes if ``keep``, else b""."""
    info = archive.getinfo(name)
    parts, count = [], 0
    try:
        # zipfile stops at the declared size (checked against the limits): a larger payload
        # fails the CRC check instead of filling memory
        with archive.open(info) as fh:
            while chunk := fh.read(_CHUNK):
                count += len(chunk)
                if count > info.file_size:
                    break
                if keep:
                    parts.append(chunk)
    except (
        zipfile.BadZipFile,
        OSError,
        EOFError,
        ValueError,
        NotImplementedError,
        RuntimeError,
        zlib.error,
    ) as exc:
        raise _refuse(path, f"entry {name!r} is damaged ({_reason(exc)})") from exc
    if count != info.file_size:
        raise _refuse(
            path, f"entry {name!r} holds {count} bytes or more, not the {info.file_size} it declares"
        )
    return b"".join(parts)


def _checked_zip(
    path: str | os.PathLike[str], required: tuple[str, ...] = (), text: tuple[str, ...] = ()
) -> tuple[bytes, dict[str, bytes]]:
    """The file's bytes, checked as a zip with the ``required`` entries, every entry streamed once;
    and the bytes of the ``text`` entries (at most :data:`MAX_TEXT_BYTES` each)."""
    blob = read_bounded(path, MAX_FILE_BYTES)
    texts: dict[str, bytes] = {}
    with _open_zip(blob, path) as archive:
        names = archive.namelist()
        for name in (*required, *text):
            if name not in names:
                raise _refuse(path, f"has no entry {name!r} (it holds {names})")
        for name in names:
            size = archive.getinfo(name).file_size
            if name in text and size > MAX_TEXT_BYTES:
                raise _refuse(
                    path,
                    f"entry {name!r} is {_size(size)} of text; at most {_size(MAX_TEXT_BYTES)} are allowed",
                )
            content = _read_entry(archive, name, path, keep=name in text)
            if name in text:
                texts[name] = content
    return blob, texts


def _json_object(text: bytes, path: str | os.PathLike[str], what: str) -> dict[str, Any]:
    """``text`` parsed as a JSON object, or a :class:`PolicyLoadError` naming ``what`` of ``path``."""
    try:
        value = json.loads(text.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise _refuse(path, f"{what} is not UTF-8 text ({_reason(exc)})") from exc
    except (json.JSONDecodeError, RecursionError) as exc:
        raise _refuse(path, f"{what} is not JSON ({_reason(exc)})") from exc
    if not isinstance(value, dict):
        raise _refuse(path, f"{what} is not a JSON object (a {type(value).__name__})")
    return value


def read_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A JSON object file of at most :data:`MAX_TEXT_BYTES` (a policy's ``metadata.json``).

    Raises
    ------
    PolicyLoadError
        Naming the file: unreadable, too large, not UTF-8, not JSON or not an object.
    """
    return _json_object(read_bounded(path, MAX_TEXT_BYTES), path, "its text")


def load_npz(path: str | os.PathLike[str], keys: tuple[str, ...]) -> dict[str, NDArray[Any]]:
    """The arrays ``keys`` of an ``.npz`` (a policy's ``obs_norm.npz``), checked as a policy zip is.

    Raises
    ------
    PolicyLoadError
        Naming the file: beyond the limits, damaged, without one of ``keys``, or unreadable by numpy.
    """
    blob, _ = _checked_zip(path)
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as data:
            missing = [key for key in keys if key not in data.files]
            if missing:
                raise _refuse(path, f"has no arrays {missing} (it holds {data.files})")
            return {key: data[key] for key in keys}
    except PolicyLoadError:
        raise
    except (ValueError, OSError, EOFError, MemoryError, zipfile.BadZipFile) as exc:
        raise _refuse(path, f"cannot be read by numpy ({_reason(exc)})") from exc


def _box(field: dict[str, Any], name: str) -> Any:
    """A ``Box`` from SB3's readable text of one; the bounds must read as what we rebuild."""
    from gymnasium import spaces

    if field.get(":type:") != "<class 'gymnasium.spaces.box.Box'>":
        raise UnsafePolicyFile(f"{name} is a {field.get(':type:')}, not a Box")
    shape = tuple(int(v) for v in field["_shape"])
    dtype = np.dtype(field["dtype"])
    low, high = (np.array(str(field[k]).strip("[]").split(), dtype=dtype) for k in ("low", "high"))
    if low.size != int(np.prod(shape)) or high.size != int(np.prod(shape)):
        # a long vector is cut short in the text: an unbounded observation box (float32 limits)
        limit = np.finfo(dtype).max
        low, high = np.full(shape, -limit, dtype=dtype), np.full(shape, limit, dtype=dtype)
    return spaces.Box(low.reshape(shape), high.reshape(shape), shape=shape, dtype=dtype)


def _constant(field: dict[str, Any], name: str) -> float:
    match = re.fullmatch(r"ConstantSchedule\(val=([-+0-9.eE]+)\)", str(field.get("value_schedule", "")))
    if match is None:
        raise UnsafePolicyFile(f"{name} is not a constant schedule ({field.get('value_schedule')!r})")
    return float(match.group(1))


def _policy_kwargs(field: dict[str, Any]) -> dict[str, Any]:
    import importlib

    kwargs = {k: v for k, v in field.items() if not k.startswith(":")}
    extractor = kwargs.get("features_extractor_class")
    if extractor is not None:
        if extractor not in _EXTRACTORS:
            raise UnsafePolicyFile(
                f"policy_kwargs names the extractor {extractor}, not one of {list(_EXTRACTORS)}"
            )
        module, attribute = _EXTRACTORS[extractor]
        kwargs["features_extractor_class"] = getattr(importlib.import_module(module), attribute)
    return kwargs


def _replacements(data: dict[str, Any], algorithm: Any) -> dict[str, Any]:
    """A value for every pickled field of ``data`` (SB3's ``data`` JSON of the zip)."""
    from stable_baselines3.common.buffers import RolloutBuffer
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.utils import ConstantSchedule, FloatSchedule

    pickled = [k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v]
    out: dict[str, Any] = {}
    for key in pickled:
        field = data[key]
        try:
            out[key] = _rebuild(key, field, ActorCriticPolicy, RolloutBuffer, ConstantSchedule, FloatSchedule)
        except UnsafePolicyFile:
            raise
        except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
            # the text beside a pickle is SB3's own; a field without the parts it always writes is damaged
            raise PolicyLoadError(f"the field {key!r} of entry 'data' is malformed ({_reason(exc)})") from exc
    return out


def _rebuild(key: str, field: dict[str, Any], *sb3: Any) -> Any:
    """The value of one pickled field, from its text (see :func:`_replacements`)."""
    actor_critic, rollout_buffer, constant_schedule, float_schedule = sb3
    if key in _TRAINING_STATE:
        return None
    if key == "policy_class":
        if field.get("__module__") != "stable_baselines3.common.policies" or "ActorCriticPolicy" not in str(
            field.get("__init__")
        ):
            raise UnsafePolicyFile("policy_class is not stable-baselines3's ActorCriticPolicy")
        return actor_critic
    if key in ("observation_space", "action_space"):
        return _box(field, key)
    if key in ("clip_range", "lr_schedule"):
        return float_schedule(constant_schedule(_constant(field, key)))
    if key == "rollout_buffer_class":
        if "RolloutBuffer.__init__" not in str(field.get("__init__")):
            raise UnsafePolicyFile("rollout_buffer_class is not stable-baselines3's RolloutBuffer")
        return rollout_buffer
    if key == "policy_kwargs":
        return _policy_kwargs(field)
    raise UnsafePolicyFile(f"the pickled field {key!r} cannot be rebuilt without running it")


def load_model(path: str | os.PathLike[str], algorithm: Any, *, allow_pickle: bool = False) -> Any:
    """Load an SB3 model of class ``algorithm`` (e.g. ``PPO``) on the CPU.

    Parameters
    ----------
    path : path
        The ``policy.zip``.
    algorithm : type
        The SB3 algorithm class.
    allow_pickle : bool
        False (default): rebuild every pickled field from its text (see the module docstring) and
        run none of them; a zip with a field that cannot be rebuilt raises
        :class:`UnsafePolicyFile`. True: SB3's plain load, which unpickles them (trusted files only).
        The zip checks (sizes, ratio, damage) apply either way.

    Raises
    ------
    UnsafePolicyFile
        Without ``allow_pickle``, a field that cannot be rebuilt (named).
    PolicyLoadError
        Anything else that keeps the file from loading, naming the file and what is wrong: it
        cannot be read, is not a zip or a damaged one, exceeds a ``MAX_*`` limit (checked before
        anything is unpacked), lacks ``data`` or ``policy.pth``, its ``data`` is not UTF-8 JSON
        or has a malformed field, or SB3 / torch cannot load it.
    """
    # SB3 writes its settings to 'data' and the weights to 'policy.pth'; a zip without them is not a policy
    blob, texts = _checked_zip(path, required=("policy.pth",), text=("data",))
    data = _json_object(texts["data"], path, "entry 'data'")
    replacements = None
    if not allow_pickle:
        try:
            replacements = _replacements(data, algorithm)
        except UnsafePolicyFile as exc:
            raise UnsafePolicyFile(
                f"{os.fspath(path)}: {exc}; loading it would run code stored in the file. If you trust "
                "the file, load it with allow_pickle=True"
            ) from None
        except PolicyLoadError as exc:
            raise _refuse(path, str(exc)) from exc.__cause__
    try:
        # the bytes that were checked, not the file again (it may have changed meanwhile)
        return algorithm.load(io.BytesIO(blob), device="cpu", custom_objects=replacements)
    except Exception as exc:  # noqa: BLE001 - torch, SB3 and the spaces raise many kinds; each is the file's
        raise _refuse(path, f"stable-baselines3 could not load it ({_reason(exc)})") from exc
