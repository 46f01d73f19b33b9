"""NumPy's PCG64 streams drawn inside compiled code, bit for bit.

The noise of the sensors, the radio and the people tracker is drawn per environment, each from
its own generator (a child of the env's, see
:func:`koopman_envs.sim.perception.child_generator`), in blocks. Through NumPy that is one
Python call per environment and block, and NumPy's Gaussian sampler itself takes 11-14 ns a
number on our 2-core machines. Here the generator's state is copied once into six 64-bit words
(:func:`generator_words`) and the blocks of every environment that needs one are drawn in one
compiled call, with NumPy's own algorithms: PCG64's 128-bit LCG and XSL-RR output, its buffered
32-bit half-words, and the ziggurat samplers of ``numpy/random/src/distributions``
(tables from ``numba.np.random._constants``, numba's copy of NumPy's). The numbers are the ones
``Generator.standard_normal`` / ``Generator.random`` give for the same state, in the same order
(``tests/test_pcg64.py`` compares millions of them, the samplers' rare slow paths included), so
no published stream changes; the compiled Gaussian takes about 3 ns.

Why not numba's own ``Generator`` support: it calls the bit generator through a function
pointer per number (no faster than NumPy here) and unboxes a ``Generator`` object per call and
environment (about 11 us). Only :class:`numpy.random.PCG64` is reproduced, the bit generator of
``numpy.random.default_rng`` and Gymnasium's seeding; for any other (a user's ``Philox``,
``PCG64DXSM``), :func:`generator_words` returns None and the caller keeps NumPy's path.

A state is ``words[0:2]`` the LCG state (high, low), ``words[2:4]`` its increment (high, low),
``words[4]`` whether a 32-bit half is held and ``words[5]`` that half.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np
from llvmlite import ir
from numba import float32, njit, types, uint32, uint64
from numba.extending import intrinsic
from numpy.typing import NDArray

try:  # numba's copy of NumPy's ziggurat tables (a private module: guarded)
    from numba.np.random._constants import (
        fi_double,
        fi_float,
        ki_double,
        ki_float,
        wi_double,
        wi_float,
        ziggurat_nor_inv_r,
        ziggurat_nor_inv_r_f,
        ziggurat_nor_r,
        ziggurat_nor_r_f,
    )

    #: whether the compiled draws are available; without the tables every generator takes
    #: NumPy's path (:func:`generator_words` returns None), with the same numbers, only slower
    COMPILED_DRAWS = True
except ImportError:  # pragma: no cover - a numba release without the module
    COMPILED_DRAWS = False

__all__ = [
    "COMPILED_DRAWS",
    "STATE_WORDS",
    "Streams",
    "generator_words",
    "normals_f32",
    "normals_f64",
    "refill_f32",
    "refill_normals_f64",
    "store_words",
    "uniforms_f32",
]

#: 64-bit words of one generator's state
STATE_WORDS = 6
#: PCG64's 128-bit multiplier (``PCG_DEFAULT_MULTIPLIER_128``)
_MULTIPLIER = (2549297995355413924 << 64) | 4865540595714422341
_LOW64 = (1 << 64) - 1
_SIGN = np.array([1.0, -1.0], dtype=np.float32)  # x * _SIGN[bit] is -x or x exactly, branch-free
_SIGN64 = np.array([1.0, -1.0])


def generator_words(rng: np.random.Generator) -> NDArray[np.uint64] | None:
    """``rng``'s PCG64 state as :data:`STATE_WORDS` words, or None for another bit generator
    (or an object that only draws like a ``Generator``, as a test's scripted one), or None for
    every generator when the compiled draws are unavailable (:data:`COMPILED_DRAWS`)."""
    if not COMPILED_DRAWS:
        return None
    bit_generator = getattr(rng, "bit_generator", None)
    if type(bit_generator) is not np.random.PCG64:
        return None
    state = bit_generator.state
    value, increment = state["state"]["state"], state["state"]["inc"]
    return np.array(
        [
            value >> 64,
            value & _LOW64,
            increment >> 64,
            increment & _LOW64,
            state["has_uint32"],
            state["uinteger"],
        ],
        dtype=np.uint64,
    )


def store_words(rng: np.random.Generator, words: NDArray[np.uint64]) -> None:
    """Write ``words`` back into ``rng`` (a PCG64 generator), so NumPy continues the stream."""
    state = dict(rng.bit_generator.state)
    state["state"] = {
        "state": (int(words[0]) << 64) | int(words[1]),
        "inc": (int(words[2]) << 64) | int(words[3]),
    }
    state["has_uint32"], state["uinteger"] = int(words[4]), int(words[5])
    rng.bit_generator.state = state


def _lcg_intrinsic(typingctx: Any, high: Any, low: Any, inc_high: Any, inc_low: Any) -> Any:
    """``_lcg(high, low, inc_high, inc_low)``: PCG64's step ``state * multiplier + inc`` modulo
    2**128, as (high, low) words, in LLVM's 128-bit integers (numba has none); compiled code only."""
    pair = cast(Any, types.UniTuple)(types.uint64, 2)
    signature = pair(types.uint64, types.uint64, types.uint64, types.uint64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        wide, narrow = ir.IntType(128), ir.IntType(64)
        shift = ir.Constant(wide, 64)

        def join(high_word: Any, low_word: Any) -> Any:
            return builder.or_(
                builder.shl(builder.zext(high_word, wide), shift), builder.zext(low_word, wide)
            )

        stepped = builder.add(
            builder.mul(join(args[0], args[1]), ir.Constant(wide, _MULTIPLIER)), join(args[2], args[3])
        )
        words = [builder.trunc(builder.lshr(stepped, shift), narrow), builder.trunc(stepped, narrow)]
        return context.make_tuple(builder, sig.return_type, words)

    return signature, codegen


_lcg = cast(Any, intrinsic(_lcg_intrinsic))


@njit(inline="always")
def _next64(words: NDArray[np.uint64]) -> Any:  # pragma: no cover - compiled
    """PCG64's next 64-bit output (``pcg64_next64``): step, then XSL-RR of the new state."""
    high, low = _lcg(words[0], words[1], words[2], words[3])
    words[0], words[1] = high, low
    return _xsl_rr(high, low)


@njit(inline="always")
def _xsl_rr(high: Any, low: Any) -> Any:  # pragma: no cover - compiled
    """PCG64's output of the state (high, low): the halves' XOR rotated right by the top 6 bits."""
    mixed = high ^ low
    rotation = high >> uint64(58)
    return (mixed >> rotation) | (mixed << ((uint64(64) - rotation) & uint64(63)))


@njit(inline="always")
def _next32(words: NDArray[np.uint64]) -> Any:  # pragma: no cover - compiled
    """``pcg64_next32``: the held high half if any, else the low half of a new output."""
    if words[4]:
        words[4] = uint64(0)
        return uint32(words[5])
    value = _next64(words)
    words[4], words[5] = uint64(1), value >> uint64(32)
    return uint32(value & uint64(0xFFFFFFFF))


@njit(inline="always")
def _next_float(words: NDArray[np.uint64]) -> Any:  # pragma: no cover - compiled
    """``next_float``: a float32 in [0, 1) from the top 24 bits of a 32-bit output."""
    return float32(float32(_next32(words) >> uint32(8)) * float32(1.0) / float32(16777216.0))


@njit(inline="always")
def _next_double(words: NDArray[np.uint64]) -> Any:  # pragma: no cover - compiled
    """``next_double``: a float64 in [0, 1) from the top 53 bits of a 64-bit output."""
    return float(_next64(words) >> uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def uniforms_f32(words: NDArray[np.uint64], out: NDArray[np.float32]) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (1-D) as ``Generator.random(dtype=np.float32, out=out)`` would."""
    for i in range(out.shape[0]):
        out[i] = _next_float(words)


@njit(cache=True)
def normals_f32(words: NDArray[np.uint64], out: NDArray[np.float32]) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (1-D) as ``Generator.standard_normal(dtype=np.float32, out=out)`` would
    (``random_standard_normal_f``). The fast path (99.3% of draws) keeps the state in registers;
    the rest runs NumPy's loop as written, on the state words."""
    high, low, held_flag, held = words[0], words[1], words[4], words[5]
    for i in range(out.shape[0]):
        if held_flag:
            r = uint32(held)
            held_flag = uint64(0)
        else:
            high, low = _lcg(high, low, words[2], words[3])
            value = _xsl_rr(high, low)
            held_flag, held = uint64(1), value >> uint64(32)
            r = uint32(value & uint64(0xFFFFFFFF))
        idx = r & 0xFF
        rabs = (r >> 9) & 0x0007FFFFF
        x = float32(float32(rabs) * wi_float[idx]) * _SIGN[(r >> 8) & 0x1]
        if rabs < ki_float[idx]:
            out[i] = x
            continue
        words[0], words[1], words[4], words[5] = high, low, held_flag, held
        out[i] = _normal_f32_tail(words, idx, rabs, x)
        high, low, held_flag, held = words[0], words[1], words[4], words[5]
    words[0], words[1], words[4], words[5] = high, low, held_flag, held


@njit(inline="always")
def _normal_f32_tail(
    words: NDArray[np.uint64], idx: Any, rabs: Any, x: Any
) -> Any:  # pragma: no cover - compiled
    """The rest of ``random_standard_normal_f`` after a first draw (``idx``, ``rabs``, ``x``)
    left the fast path: the tail or wedge test, and fresh draws until one is accepted."""
    while True:
        if idx == 0:
            while True:
                xx = float32(-ziggurat_nor_inv_r_f * np.log1p(-_next_float(words)))
                yy = float32(-np.log1p(-_next_float(words)))
                if float32(yy + yy) > float32(xx * xx):
                    if (rabs >> 8) & 0x1:
                        return -float32(ziggurat_nor_r_f + xx)
                    return float32(ziggurat_nor_r_f + xx)
        elif ((fi_float[idx - 1] - fi_float[idx]) * _next_float(words) + fi_float[idx]) < float32(
            np.exp(-float32(0.5) * x * x)
        ):
            return x
        r = _next32(words)
        idx = r & 0xFF
        rabs = (r >> 9) & 0x0007FFFFF
        x = float32(float32(rabs) * wi_float[idx]) * _SIGN[(r >> 8) & 0x1]
        if rabs < ki_float[idx]:
            return x


@njit(cache=True)
def normals_f64(words: NDArray[np.uint64], out: NDArray[np.float64]) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (1-D) as ``Generator.standard_normal(out=out)`` would (``random_standard_normal``)."""
    for i in range(out.shape[0]):
        while True:
            r = _next64(words)
            idx = r & uint64(0xFF)
            r >>= uint64(8)
            rabs = (r >> uint64(1)) & uint64(0x000FFFFFFFFFFFFF)
            x = float(rabs) * wi_double[idx] * _SIGN64[r & uint64(0x1)]
            if rabs < ki_double[idx]:
                out[i] = x
                break
            if idx == 0:
                while True:
                    xx = -ziggurat_nor_inv_r * np.log1p(-_next_double(words))
                    yy = -np.log1p(-_next_double(words))
                    if yy + yy > xx * xx:
                        out[i] = (
                            -(ziggurat_nor_r + xx)
                            if (rabs >> uint64(8)) & uint64(0x1)
                            else ziggurat_nor_r + xx
                        )
                        break
                break
            if ((fi_double[idx - 1] - fi_double[idx]) * _next_double(words) + fi_double[idx]) < np.exp(
                -0.5 * x * x
            ):
                out[i] = x
                break


#: environments drawn into scratch before their columns are written: a period's row of that many
#: neighbouring environments is then one contiguous write (the buffers are period-major)
REFILL_CHUNK = 16


@njit(cache=True)
def refill_f32(
    words: NDArray[np.uint64],
    rows: NDArray[np.int64],
    normal: NDArray[np.float32],
    uniform: NDArray[np.float32],
    cursor: NDArray[np.int64],
) -> None:  # pragma: no cover - compiled
    """For every environment k of ``rows``: draw its block of standard normals, then its block
    of uniforms, from the state ``words[k]`` into ``normal[:, k]`` and ``uniform[:, k]``
    (period-major buffers, (periods, K, width)), and rewind ``cursor[k]`` to 0."""
    periods, width_n, width_u = normal.shape[0], normal.shape[2], uniform.shape[2]
    normals = np.empty((REFILL_CHUNK, periods, width_n), dtype=np.float32)
    uniforms = np.empty((REFILL_CHUNK, periods, width_u), dtype=np.float32)
    for start in range(0, rows.shape[0], REFILL_CHUNK):
        chunk = rows[start : start + REFILL_CHUNK]
        for c in range(chunk.shape[0]):
            k = chunk[c]
            normals_f32(words[k], normals[c].reshape(periods * width_n))
            uniforms_f32(words[k], uniforms[c].reshape(periods * width_u))
            cursor[k] = 0
        for p in range(periods):
            for c in range(chunk.shape[0]):
                k = chunk[c]
                for j in range(width_n):
                    normal[p, k, j] = normals[c, p, j]
                for j in range(width_u):
                    uniform[p, k, j] = uniforms[c, p, j]


@njit(cache=True)
def refill_normals_f64(
    words: NDArray[np.uint64], rows: NDArray[np.int64], pool: NDArray[np.float64], cursor: NDArray[np.int64]
) -> None:  # pragma: no cover - compiled
    """For every environment k of ``rows``: fill ``pool[k]`` ((K, width)) with standard normals
    from ``words[k]`` and rewind ``cursor[k]`` to 0."""
    for k in rows:
        normals_f64(words[k], pool[k])
        cursor[k] = 0


class Streams:
    """One generator per environment, drawn in compiled code where it is a PCG64.

    Parameters
    ----------
    num_envs : int
        Environments K.

    Attributes
    ----------
    words : ndarray of uint64, shape (K, STATE_WORDS)
        The state of every compiled environment's generator; it advances as the compiled
        kernels draw (the ``Generator`` object itself is not advanced).
    compiled : ndarray of bool, shape (K,)
        Whether environment k's generator is a PCG64 drawn through :attr:`words`.
    generators : list of Generator or None
        Each environment's generator (None before :meth:`attach`); drawn through NumPy where
        not :attr:`compiled`.
    """

    def __init__(self, num_envs: int) -> None:
        self.words = np.zeros((num_envs, STATE_WORDS), dtype=np.uint64)
        self.compiled = np.zeros(num_envs, dtype=bool)
        self.generators: list[np.random.Generator | None] = [None] * num_envs

    def attach(self, index: int, rng: np.random.Generator) -> None:
        """Draw environment ``index``'s numbers from ``rng`` from now on (its current state)."""
        words = generator_words(rng)
        self.generators[index] = rng
        self.compiled[index] = words is not None
        if words is not None:
            self.words[index] = words

    def split(
        self, rows: NDArray[np.int64], owner: str
    ) -> tuple[NDArray[np.int64], list[tuple[int, np.random.Generator]]]:
        """Of the environments ``rows``: those drawn in compiled code, and the others with their
        generators (in ``rows``' order).

        Raises
        ------
        RuntimeError
            An environment of ``rows`` has no generator yet (stepped before its reset); the
            message names ``owner``.
        """
        compiled = self.compiled[rows]
        others = []
        for k in rows[~compiled].tolist():
            rng = self.generators[k]
            if rng is None:
                raise RuntimeError(f"{owner}: environment {k} was stepped before reset()")
            others.append((k, rng))
        return rows[compiled], others
