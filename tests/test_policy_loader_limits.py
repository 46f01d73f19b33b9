"""The policy zip loader checks before it reads (issue 41, item 8): declared entry sizes, their total
and the compression ratio are refused before anything is unpacked, entries are read in bounded
chunks, and every failure is one :class:`baselines.safe_load.PolicyLoadError` naming the file.

Memory is measured with ``tracemalloc`` (Python's allocations: the bytes a zip read would hold),
never time. The zip bombs are built here with streaming writes, so the test itself stays small.
"""

from __future__ import annotations

import io
import json
import shutil
import struct
import tracemalloc
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO  # noqa: E402

from baselines import safe_load  # noqa: E402
from baselines.sb3.policy import SHIPPED, load_policy  # noqa: E402

SOURCE = SHIPPED / "formation"
MIB = 2**20
#: what a refused load may allocate (Python's count): the file itself and a few read chunks
MEMORY_BOUND = 32 * MIB


def _error() -> type[Exception]:
    # looked up at call time: before the fix the class does not exist, and the tests fail on that
    return getattr(safe_load, "PolicyLoadError", LookupError)


def _peak(load: Callable[[], object]) -> tuple[BaseException | None, int]:
    """Run ``load``; what it raised and the peak of Python's allocations meanwhile."""
    tracemalloc.start()
    try:
        load()
    except BaseException as exc:  # noqa: BLE001 - returned to the test, which checks its class
        raised: BaseException | None = exc
    else:
        raised = None
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    return raised, peak


def _refused(path: Path, match: str, **kwargs) -> None:
    raised, peak = _peak(lambda: safe_load.load_model(path, PPO, **kwargs))
    assert isinstance(raised, _error()), f"{type(raised).__name__}: {raised}"
    assert isinstance(raised, ValueError)
    assert str(path) in str(raised)
    assert match in str(raised), str(raised)
    assert peak < MEMORY_BOUND, f"peak {peak / MIB:.0f} MiB"


def _copy(tmp_path: Path, change: Callable[[str, bytes], bytes | None]) -> Path:
    """The shipped policy.zip with each entry passed through ``change`` (None: left out)."""
    target = tmp_path / "policy.zip"
    with zipfile.ZipFile(SOURCE / "policy.zip") as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            payload = change(item.filename, old.read(item.filename))
            if payload is not None:
                new.writestr(item, payload)
    return target


def _bomb(path: Path, entry: str, size: int, others: bool = True) -> Path:
    """A policy.zip whose ``entry`` unpacks to ``size`` zero bytes (deflated: about size / 1000)."""
    chunk = bytes(MIB)
    with (
        zipfile.ZipFile(SOURCE / "policy.zip") as old,
        zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as new,
    ):
        if others:
            for item in old.infolist():
                if item.filename != entry:
                    new.writestr(item, old.read(item.filename))
        with new.open(entry, "w", force_zip64=True) as fh:
            for _ in range(size // MIB):
                fh.write(chunk)
    return path


# ------------------------------------------------------------------------------------ zip bombs


def test_a_zip_bomb_is_refused_before_it_is_unpacked(tmp_path) -> None:
    """The issue's case: a small zip whose 'data' unpacks to 300 MB."""
    path = _bomb(tmp_path / "policy.zip", "data", 300 * MIB)
    assert path.stat().st_size < 2 * MIB
    _refused(path, "entry 'data' unpacks to 314572800 bytes")
    _refused(path, "entry 'data' unpacks to 314572800 bytes", allow_pickle=True)  # trusted or not


def test_a_bomb_within_the_size_limit_is_refused_by_its_ratio(tmp_path) -> None:
    path = _bomb(tmp_path / "policy.zip", "policy.pth", 64 * MIB)
    _refused(path, "entry 'policy.pth' is compressed")


def test_many_entries_add_up(tmp_path) -> None:
    """Each entry under the per-entry limit, their total above the limit of the whole zip."""
    path = tmp_path / "policy.zip"
    size = safe_load.MAX_ENTRY_BYTES
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as new:
        for name in ("data", "policy.pth"):
            # declared sizes only: a stored entry written through a header that is patched below
            new.writestr(zipfile.ZipInfo(name), b"x")
    blob = bytearray(path.read_bytes())
    at = 0
    while (at := blob.find(b"PK\x01\x02", at)) >= 0:  # central directory: uncompressed size field
        struct.pack_into("<L", blob, at + 24, size)
        struct.pack_into("<L", blob, at + 20, size)  # and compressed, so that the ratio is 1:1
        at += 4
    path.write_bytes(bytes(blob))
    _refused(path, "unpack to")


def test_a_declared_size_that_lies_is_caught_by_the_bounded_read(tmp_path) -> None:
    """'data' declares 1000 bytes and holds 20 MB: the read stops at the declared size and fails."""
    path = _bomb(tmp_path / "policy.zip", "data", 20 * MIB)
    blob = bytearray(path.read_bytes())
    at = 0
    while (at := blob.find(b"PK\x01\x02", at)) >= 0:
        (name_length,) = struct.unpack_from("<H", blob, at + 28)
        if bytes(blob[at + 46 : at + 46 + name_length]) == b"data":
            (compressed,) = struct.unpack_from("<L", blob, at + 20)
            if compressed == 0xFFFFFFFF:  # zip64: the sizes sit in the extra field
                extra = at + 46 + name_length
                struct.pack_into("<QQ", blob, extra + 4, 1000, struct.unpack_from("<Q", blob, extra + 12)[0])
            else:
                struct.pack_into("<L", blob, at + 24, 1000)
        at += 4
    path.write_bytes(bytes(blob))
    _refused(path, "entry 'data'")


def test_a_huge_central_directory_is_refused_before_it_is_parsed(tmp_path) -> None:
    """Thousands of empty entries: zipfile would build an object for each before any check."""
    path = tmp_path / "policy.zip"
    with zipfile.ZipFile(path, "w") as new:
        for i in range(5000):
            new.writestr(f"e{i}", b"")
    _refused(path, "entries")


# ------------------------------------------------------------------------- broken or foreign files


def test_a_truncated_zip(tmp_path) -> None:
    path = tmp_path / "policy.zip"
    path.write_bytes((SOURCE / "policy.zip").read_bytes()[:300_000])
    _refused(path, "not a zip file")


def test_a_damaged_entry(tmp_path) -> None:
    """The directory is whole, the bytes of an entry are not: the CRC check names it."""
    path = tmp_path / "policy.zip"
    shutil.copyfile(SOURCE / "policy.zip", path)
    blob = bytearray(path.read_bytes())
    with zipfile.ZipFile(io.BytesIO(bytes(blob))) as archive:
        info = archive.getinfo("policy.pth")
    blob[info.header_offset + 30 + len(info.filename) + 5000] ^= 0xFF
    path.write_bytes(bytes(blob))
    _refused(path, "entry 'policy.pth'")


@pytest.mark.parametrize(
    "content", [b"", b"not a zip at all\n" * 100, bytes(range(256)) * 40], ids=["empty", "text", "binary"]
)
def test_a_file_that_is_not_a_zip(tmp_path, content) -> None:
    path = tmp_path / "policy.zip"
    path.write_bytes(content)
    _refused(path, "not a zip file")


def test_a_missing_file(tmp_path) -> None:
    _refused(tmp_path / "nowhere.zip", "cannot be read")


def test_a_directory_instead_of_a_file(tmp_path) -> None:
    _refused(tmp_path, "cannot be read")


def test_invalid_utf8_where_text_is_expected(tmp_path) -> None:
    path = _copy(tmp_path, lambda name, payload: b'{"a": "\xff\xfe"}' if name == "data" else payload)
    _refused(path, "entry 'data' is not UTF-8 text")


def test_data_that_is_not_json(tmp_path) -> None:
    path = _copy(tmp_path, lambda name, payload: payload[:1000] if name == "data" else payload)
    _refused(path, "entry 'data' is not JSON")
    path = _copy(tmp_path, lambda name, payload: b"[1, 2]" if name == "data" else payload)
    _refused(path, "entry 'data' is not a JSON object")


@pytest.mark.parametrize("entry", ["data", "policy.pth"])
def test_a_missing_entry(tmp_path, entry) -> None:
    path = _copy(tmp_path, lambda name, payload: None if name == entry else payload)
    _refused(path, f"has no entry {entry!r}")


def test_weights_that_torch_cannot_read(tmp_path) -> None:
    path = _copy(tmp_path, lambda name, payload: b"garbage" * 10 if name == "policy.pth" else payload)
    _refused(path, "stable-baselines3 could not load it")


def test_a_malformed_field(tmp_path) -> None:
    def change(name: str, payload: bytes) -> bytes:
        if name != "data":
            return payload
        data = json.loads(payload)
        del data["observation_space"]["_shape"]
        return json.dumps(data).encode()

    _refused(_copy(tmp_path, change), "observation_space")


def test_the_foreign_pickle_is_still_its_own_class(tmp_path) -> None:
    def change(name: str, payload: bytes) -> bytes:
        if name != "data":
            return payload
        data = json.loads(payload)
        data["surprise"] = {":type:": "<class 'function'>", ":serialized:": "gAR9lC4="}
        return json.dumps(data).encode()

    path = _copy(tmp_path, change)
    with pytest.raises(safe_load.UnsafePolicyFile, match="allow_pickle=True") as caught:
        safe_load.load_model(path, PPO)
    assert isinstance(caught.value, _error()) and str(path) in str(caught.value)


# ---------------------------------------------------------------------------- the policy directory


@pytest.fixture
def policy_copy(tmp_path) -> Path:
    directory = tmp_path / "formation"
    shutil.copytree(SOURCE, directory)
    return directory


def test_load_policy_names_the_bad_file(policy_copy) -> None:
    _bomb(policy_copy / "policy.zip", "data", 300 * MIB)
    raised, peak = _peak(lambda: load_policy(policy_copy))
    assert isinstance(raised, _error()) and peak < MEMORY_BOUND
    assert str(policy_copy / "policy.zip") in str(raised) and "python -m baselines.sb3.train" in str(raised)


def test_an_obs_norm_bomb_is_refused(policy_copy) -> None:
    path = policy_copy / "obs_norm.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for key in ("var", "clip", "epsilon"):
            with archive.open(f"{key}.npy", "w") as fh:
                np.lib.format.write_array(fh, np.ones(1))
        with archive.open("mean.npy", "w", force_zip64=True) as fh:
            header = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                header, {"descr": "<f8", "fortran_order": False, "shape": (2**25,)}
            )
            fh.write(header.getvalue())
            for _ in range(2**28 // MIB):
                fh.write(bytes(MIB))
    raised, peak = _peak(lambda: load_policy(policy_copy))
    assert isinstance(raised, _error()), repr(raised)
    assert str(path) in str(raised) and peak < MEMORY_BOUND


def test_a_huge_metadata_file_is_refused(policy_copy) -> None:
    path = policy_copy / "metadata.json"
    with path.open("w") as fh:
        fh.write('{"pad": "')
        for _ in range(2 * safe_load.MAX_TEXT_BYTES // MIB):
            fh.write(" " * MIB)
        fh.write('"}')
    raised, peak = _peak(lambda: load_policy(policy_copy))
    assert isinstance(raised, _error()) and str(path) in str(raised) and peak < MEMORY_BOUND


def test_metadata_that_is_not_utf8(policy_copy) -> None:
    (policy_copy / "metadata.json").write_bytes(b'{"algo": "\xff"}')
    with pytest.raises(_error(), match="metadata.json"):
        load_policy(policy_copy)


def test_the_shipped_policies_pass_the_checks_and_act_as_before() -> None:
    """The checks refuse nothing that ships, and the loaded model is the plain load's."""
    for path in sorted(SHIPPED.glob("**/policy.zip")):
        model, norm, metadata = load_policy(path.parent)
        plain = PPO.load(path, device="cpu")
        obs = np.random.default_rng(0).normal(size=(64, *plain.observation_space.shape)).astype(np.float32)
        np.testing.assert_array_equal(
            model.predict(obs, deterministic=True)[0], plain.predict(obs, deterministic=True)[0]
        )
