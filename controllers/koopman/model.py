"""The learned bilinear Koopman model of a robot team: prediction, CasADi export, files."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from controllers.koopman.dictionary import (
    Dictionary,
    check_memory,
    check_velocity,
    lift_memory_casadi,
    lift_state,
    lift_velocity_casadi,
    lifted_size,
    shift_memory,
)
from controllers.koopman.model_file import (
    FORMAT_VERSION,
    ModelFileError,
    model_file_hint,
    read_model_file,
    write_model_file,
)
from controllers.mpc.models import coding_size

__all__ = ["KoopmanModel", "ModelFileError", "FORMAT_VERSION"]


def _sparse_dm(matrix: NDArray) -> ca.DM:
    """A CasADi matrix without the entries that are zero up to rounding.

    The projection C is a selector up to ~1e-16 noise, for instance; keeping such entries would
    make every symbolic product dense and the NMPC's derivatives several times costlier.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    scale = np.abs(matrix).max() if matrix.size else 0.0
    return ca.sparsify(ca.DM(np.where(np.abs(matrix) > 1e-13 * scale, matrix, 0.0)))


def _normalized(block) -> tuple:
    """(x, y, cos, sin) of a CasADi (x, y, cos, sin) block with (cos, sin) scaled to unit length:
    the NLP's predicted heading vector drifts off the circle, the data's never does."""
    c, s = block[2], block[3]
    norm = ca.sqrt(c * c + s * s)
    return block[0], block[1], c / norm, s / norm


@dataclass(eq=False)
class KoopmanModel:
    """z+ = A z + N (u kron z) + B u on z = phi(x); the state is read back through C.

    C projects onto (x, y, cos theta, sin theta) of every robot and the heading is recovered as
    atan2(sin, cos). Predicting several steps re-lifts the projected state every step, as the
    NMPC does (SPEC section 2): lift, advance, project, re-lift.

    With ``memory`` = L > 0 the lift is phi(x) followed by observables of the robots' last L
    commands (:func:`~controllers.koopman.dictionary.lift_memory`), so that the model can carry
    the robots' lag; a prediction then needs the commands applied before its first period
    (``previous``), and every later step re-lifts with the commands it was given.

    With ``velocity`` the lift also holds the robots' measured velocity: the last period's move
    in the body frame (:func:`~controllers.koopman.dictionary.lift_velocity`); a prediction
    needs the poses one period before its first (``before``; None: the robots stand), and every
    later step takes the pose it predicted before.

    Attributes
    ----------
    A, N, B, C : ndarray
        Shapes (D, D), (D, 2N D), (D, 2N), (4N, D).
    dictionary : Dictionary
        Observables phi.
    n_robots : int
        Team size N.
    dt : float
        Sampling period of the data [s].
    metadata : dict
        Provenance: data spec (slip setting, size, seed), fit residual, package version.
    memory : int
        Previous commands in the lift (0: the paper's pose-only lift, at most
        :data:`~controllers.koopman.dictionary.MAX_MEMORY`).
    velocity : bool
        The last period's move in the lift (False: without it).
    """

    A: NDArray[np.float64]
    N: NDArray[np.float64]
    B: NDArray[np.float64]
    C: NDArray[np.float64]
    dictionary: Dictionary
    n_robots: int
    dt: float
    metadata: dict[str, Any] = field(default_factory=dict)
    memory: int = 0
    velocity: bool = False

    def __post_init__(self) -> None:
        self.memory = check_memory(self.memory)
        self.velocity = check_velocity(self.velocity)
        d = self.size
        m = 2 * self.n_robots
        expected = {"A": (d, d), "N": (d, m * d), "B": (d, m), "C": (4 * self.n_robots, d)}
        for name, shape in expected.items():
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != shape:
                raise ModelFileError(
                    f"{name} has shape {value.shape}; a {self.dictionary.name!r} model of "
                    f"{self.n_robots} robots needs {shape}"
                )
            if not np.all(np.isfinite(value)):
                raise ModelFileError(f"{name} contains NaN or inf")
            setattr(self, name, value)
        # N reshaped so that N (u kron z) = sum_i u_i N_i z is one einsum
        self._n_blocks = self.N.reshape(d, m, d).transpose(1, 0, 2)  # (m, D, D)
        self._nlp_index: list | None = None  # (rows, cols) of each NLP constant's nonzeros

    @property
    def size(self) -> int:
        """Dimension D of the lifted state (the dictionary's observables, the memory's, then the
        velocity's)."""
        return lifted_size(self.dictionary, self.n_robots, self.memory, self.velocity)

    def no_memory(self) -> NDArray[np.float64]:
        """Previous commands of a team at rest, shape (memory, N, 2): what a prediction from a
        standing start passes as ``previous``."""
        return np.zeros((self.memory, self.n_robots, 2))

    # ------------------------------------------------------------ prediction
    def robot_block(self, robot: int) -> KoopmanModel:
        """Robot ``robot``'s own one-robot model, cut out of a team model whose robots do not
        couple (the ``"per-robot"`` structure: :func:`controllers.koopman.fit.fit_per_robot`
        places each robot's fit block-diagonally; this takes it out again, exactly).

        Raises
        ------
        ValueError
            ``robot`` outside 0..N-1, or the team model couples robots (a stacked fit).
        """
        n, p = self.n_robots, self.dictionary.per_robot
        if self.memory or self.velocity:
            raise ValueError(
                "robot_block needs a model without memory or velocity (this one has "
                f"memory={self.memory}, velocity={self.velocity})"
            )
        if not 0 <= robot < n:
            raise ValueError(f"robot={robot!r} must be an integer in [0, {n - 1}]")
        d = self.dictionary.size(n)
        index = np.concatenate([[0], 1 + p * robot + np.arange(p)])
        others = np.setdiff1d(np.arange(1, d), index)
        inputs = np.array([2 * robot, 2 * robot + 1])
        coupled = np.abs(self.A[np.ix_(index[1:], others)]).max(initial=0.0) > 0 or any(
            np.abs(self.N[np.ix_(index[1:], k * d + others)]).max(initial=0.0) > 0 for k in range(2 * n)
        )
        if coupled:
            raise ValueError(
                "robot_block needs a team model without cross-robot terms (structure='per-robot')"
            )
        d1 = 1 + p
        bilinear = np.zeros((d1, 2 * d1))
        for k, column in enumerate(inputs):
            bilinear[:, k * d1 : (k + 1) * d1] = self.N[np.ix_(index, column * d + index)]
        c = np.zeros((4, d1))
        c[np.arange(4), self.dictionary.state_rows(1).reshape(-1)] = 1.0
        return KoopmanModel(
            A=self.A[np.ix_(index, index)].copy(),
            N=bilinear,
            B=self.B[np.ix_(index, inputs)].copy(),
            C=c,
            dictionary=self.dictionary,
            n_robots=1,
            dt=self.dt,
            metadata={**self.metadata, "robot": robot},
        )

    def lift(
        self, poses: NDArray, previous: NDArray | None = None, before: NDArray | None = None
    ) -> NDArray[np.float64]:
        """phi(x) for poses (..., N, 3) -> (..., D).

        ``previous`` (..., L, N, 2): the commands of the last L >= ``memory`` periods, the most
        recent first (None: a team at rest); unused without memory. ``before`` (..., N, 3): the
        poses one period earlier (None: the robots stand); unused without velocity.
        """
        return lift_state(
            self.dictionary,
            poses,
            self.memory,
            self.no_memory() if previous is None else previous,
            self.velocity,
            poses if before is None else before,
        )

    def advance(self, z: NDArray, commands: NDArray) -> NDArray[np.float64]:
        """One step in the lifted space: (..., D) and commands (..., N, 2) -> (..., D)."""
        u = np.asarray(commands, dtype=np.float64).reshape(z.shape[:-1] + (2 * self.n_robots,))
        bilinear = np.einsum("...i,idk,...k->...d", u, self._n_blocks, z)
        return z @ self.A.T + bilinear + u @ self.B.T

    def project(self, z: NDArray) -> NDArray[np.float64]:
        """Poses (..., N, 3) read from lifted states (..., D)."""
        xycs = (z @ self.C.T).reshape(z.shape[:-1] + (self.n_robots, 4))
        theta = np.arctan2(xycs[..., 3], xycs[..., 2])
        return np.concatenate([xycs[..., :2], theta[..., None]], axis=-1)

    def step(
        self,
        poses: NDArray,
        commands: NDArray,
        previous: NDArray | None = None,
        before: NDArray | None = None,
    ) -> NDArray[np.float64]:
        """f_b(x, u): predicted poses one period later, batched over leading axes.

        Parameters
        ----------
        poses : ndarray, shape (..., N, 3)
        commands : ndarray, shape (..., N, 2)
        previous : ndarray, shape (..., L, N, 2), optional
            With memory: the commands applied before ``commands``, the most recent first
            (None: a team at rest). Unused without memory.
        before : ndarray, shape (..., N, 3), optional
            With velocity: the poses one period before ``poses`` (None: the robots stand).

        Returns
        -------
        ndarray, shape (..., N, 3)
        """
        return self.project(self.advance(self.lift(poses, previous, before), commands))

    def rollout(
        self,
        start: NDArray,
        commands: NDArray,
        previous: NDArray | None = None,
        before: NDArray | None = None,
    ) -> NDArray[np.float64]:
        """Open-loop prediction with re-lifting every step.

        Parameters
        ----------
        start : ndarray, shape (..., N, 3)
            Initial poses.
        commands : ndarray, shape (T, ..., N, 2)
            Command sequence.
        previous : ndarray, shape (..., L, N, 2), optional
            With memory: the commands applied before the first one, the most recent first
            (None: a team at rest); later steps remember the sequence's own commands.
        before : ndarray, shape (..., N, 3), optional
            With velocity: the poses one period before ``start`` (None: the robots stand); later
            steps take the poses predicted before.

        Returns
        -------
        ndarray, shape (T + 1, ..., N, 3)
            Predicted poses including the start.
        """
        commands = np.asarray(commands, dtype=np.float64)
        out = np.empty((commands.shape[0] + 1,) + np.shape(start))
        out[0] = start
        # a team at rest before the first command; without memory nothing is remembered
        sent = (
            np.zeros(np.shape(start)[:-2] + (self.memory, self.n_robots, 2)) if previous is None else previous
        )
        for t in range(commands.shape[0]):
            out[t + 1] = self.step(out[t], commands[t], sent, before if t == 0 else out[t - 1])
            if self.memory:
                sent = shift_memory(sent, commands[t])
        return out

    @property
    def coding(self) -> str:
        """The NMPC state of this model: (x, y, cos theta, sin theta) per robot (``"cs"``), with
        memory followed by the robot's last ``memory`` commands, most recent first (``"cs+uL"``),
        with velocity then by its (x, y, cos theta, sin theta) one period before (``"+v"``)."""
        return "cs" + (f"+u{self.memory}" if self.memory else "") + ("+v" if self.velocity else "")

    def casadi_nlp_step(self, name: str = "koopman_cs_step") -> ca.Function:
        """f_b on the (x, y, cos theta, sin theta) coding used inside the NMPC.

        Input ``s`` (4N) and ``u`` (2N), output ``s_next`` (4N) = C (A phi + N (u kron phi) + B u)
        with phi evaluated from (x, y) and the normalized (cos, sin). This is the same
        lift-advance-project map as :meth:`casadi_step` without the atan2 round trip: re-lifting
        through the heading only renormalizes (cos, sin), and the normalization matters. Without
        it a bilinear model lets the heading vector grow under alternating turn commands and
        with it the predicted speed, which an optimizer exploits with bang-bang steering.

        With memory the state per robot also holds its last ``memory`` commands (:attr:`coding`):
        the next state's are ``u`` and the older ones shifted, so the first step of a horizon
        remembers the commands applied before it (in the measured state) and later steps the
        horizon's own. With velocity it holds the robot's (x, y, cos, sin) one period before: the
        next state's is this state's.
        """
        state, u, z = self._nlp_lift()
        matrices = self._constant_matrices()
        z_next = self._casadi_advance(z, u, matrices)
        s_next = self._nlp_next(state, u, ca.mtimes(matrices[3], z_next))
        return ca.Function(name, [state, u], [s_next], ["s", "u"], ["s_next"])

    def _nlp_next(self, state, u, xycs):
        """The next NLP state from the projected (x, y, cos, sin) of every robot (4N): with
        memory, each robot's block followed by its command and its older remembered ones; with
        velocity, then by its (x, y, cos, sin) in ``state`` (the pose one period before)."""
        if not (self.memory or self.velocity):
            return xycs
        n, size, lags = self.n_robots, coding_size(self.coding), self.memory
        parts = []
        for i in range(n):
            parts.append(xycs[4 * i : 4 * i + 4])
            if lags:
                parts += [u[2 * i : 2 * i + 2], state[size * i + 4 : size * i + 4 + 2 * (lags - 1)]]
            if self.velocity:
                parts.append(state[size * i : size * i + 4])
        return ca.vertcat(*parts)

    def _casadi_advance(self, z, u, matrices=None):
        """A z + B u + sum_i u_i N_i z, with the model's matrices as constants or as given."""
        A, B, N_blocks, _ = matrices if matrices is not None else self._constant_matrices()
        z_next = ca.mtimes(A, z) + ca.mtimes(B, u)
        for i in range(2 * self.n_robots):
            z_next += u[i] * ca.mtimes(N_blocks[i], z)
        return z_next

    def _constant_matrices(self) -> tuple:
        A, B, blocks, C = self._nlp_matrices(self.A, self.N, self.B)
        return _sparse_dm(A), _sparse_dm(B), [_sparse_dm(block) for block in blocks], _sparse_dm(C)

    def _nlp_matrices(self, A: NDArray, N: NDArray, B: NDArray) -> tuple:
        """(A, B, [N_i], C) as the NLP takes them. With memory C is folded in (C A, C B, C N_i and
        the identity): the NLP re-lifts every step and reads only the projected poses, so the
        rows of the remembered observables' own prediction would be dead weight, most of a memory
        model's coefficients (their derivatives made each real-time iteration several times
        costlier). Without memory the paper's form, as it always was."""
        d = self.size
        blocks = [N[:, i * d : (i + 1) * d] for i in range(2 * self.n_robots)]
        if not (self.memory or self.velocity):
            return A, B, blocks, self.C
        c = self.C
        return c @ A, c @ B, [c @ block for block in blocks], np.eye(c.shape[0])

    # ------------------------------------------------------- the NMPC's parametric form
    # The NMPC takes the model's coefficients as NLP parameters, not constants: its problem (and
    # the compiled solver, cached on disk) then depends only on the structure below, so a model
    # fitted for another slip setting or calibration reuses it instead of compiling anew.
    def nlp_structure(self) -> tuple:
        """What fixes the NMPC's problem: dictionary, team size and the matrices' sparsity."""
        patterns = hashlib.sha256()
        for dm in self._flat_constants():
            patterns.update(np.asarray(dm.sparsity().get_triplet(), dtype=np.int64).tobytes())
            patterns.update(np.asarray(dm.shape, dtype=np.int64).tobytes())
        key: tuple = ("koopman", self.dictionary.name, self.n_robots, patterns.hexdigest())
        # the memory-free key is the one it had before memory existed (compiled solvers on disk)
        key = key if not self.memory else (*key, "memory", self.memory)
        return key if not self.velocity else (*key, "velocity")

    def _flat_constants(self) -> list:
        A, B, blocks, C = self._constant_matrices()
        return [A, B, *blocks, C]

    def nlp_parameters(self) -> NDArray[np.float64]:
        """The coefficients that :meth:`casadi_nlp_step_parametric` takes, in its order."""
        return np.concatenate([np.asarray(dm.nonzeros(), dtype=np.float64) for dm in self._flat_constants()])

    def nlp_parameters_of(self, A: NDArray, N: NDArray, B: NDArray) -> NDArray[np.float64]:
        """:meth:`nlp_parameters` of other matrices (same shapes) on this model's sparsity pattern.

        What an online update passes to the NMPC's problem, which was built for this model's
        structure: entries outside the pattern are dropped (keep them zero).
        """
        if self._nlp_index is None:
            self._nlp_index = [dm.sparsity().get_triplet() for dm in self._flat_constants()]
        A_nlp, B_nlp, blocks, C_nlp = self._nlp_matrices(A, N, B)
        sources = [A_nlp, B_nlp, *blocks, C_nlp]
        return np.concatenate(
            [np.asarray(m, dtype=np.float64)[rows, cols] for m, (rows, cols) in zip(sources, self._nlp_index)]
        )

    def casadi_nlp_step_parametric(self, name: str = "koopman_cs_step") -> ca.Function:
        """:meth:`casadi_nlp_step` with the coefficients as a third input ``theta``
        (:meth:`nlp_parameters`); structural zeros stay zeros."""
        constants = self._flat_constants()
        theta = ca.SX.sym("theta", sum(dm.nnz() for dm in constants))
        symbolic, offset = [], 0
        for dm in constants:
            symbolic.append(ca.SX(dm.sparsity(), theta[offset : offset + dm.nnz()]))
            offset += dm.nnz()
        A, B, C = symbolic[0], symbolic[1], symbolic[-1]
        matrices = (A, B, symbolic[2:-1], C)
        state, u, z = self._nlp_lift()
        z_next = self._casadi_advance(z, u, matrices)
        s_next = self._nlp_next(state, u, ca.mtimes(C, z_next))
        return ca.Function(name, [state, u, theta], [s_next], ["s", "u", "theta"], ["s_next"])

    def _nlp_lift(self) -> tuple:
        """Symbols (s, u) of the NLP coding and the lifted z of s with normalized (cos, sin)."""
        n, size = self.n_robots, coding_size(self.coding)
        state = ca.SX.sym("s", size * n)
        u = ca.SX.sym("u", 2 * n)
        terms: list = [1]
        now, before = [], []
        for i in range(n):
            now.append(_normalized(state[size * i : size * i + 4]))
            terms += self.dictionary._robot_terms_casadi(*now[-1])
            if self.velocity:  # the pose one period before, last in the robot's block
                before.append(_normalized(state[size * (i + 1) - 4 : size * (i + 1)]))
        previous = [
            [(state[size * i + 4 + 2 * lag], state[size * i + 5 + 2 * lag]) for i in range(n)]
            for lag in range(self.memory)
        ]
        terms += lift_memory_casadi([(c, s) for _, _, c, s in now], previous)
        if self.velocity:
            terms += lift_velocity_casadi(now, before)
        return state, u, ca.vertcat(*terms)

    def casadi_step(self, name: str = "koopman_step") -> ca.Function:
        """f_b as a CasADi SX function ``x+ = f(x, u)`` on stacked vectors.

        Inputs ``x`` (3N: x_1, y_1, theta_1, x_2, ...) and ``u`` (2N: v_1, omega_1, ...),
        output ``x_next`` (3N). Without memory only (a model with memory: :meth:`casadi_nlp_step`).
        """
        if self.memory or self.velocity:
            raise ValueError(
                f"casadi_step is the pose-only map; this model has memory={self.memory}, "
                f"velocity={self.velocity}: use casadi_nlp_step"
            )
        n = self.n_robots
        x = ca.SX.sym("x", 3 * n)
        u = ca.SX.sym("u", 2 * n)
        z_next = self._casadi_advance(self.dictionary.lift_casadi(x), u)
        xycs = ca.mtimes(_sparse_dm(self.C), z_next)
        parts = []
        for i in range(n):
            parts += [xycs[4 * i], xycs[4 * i + 1], ca.atan2(xycs[4 * i + 3], xycs[4 * i + 2])]
        return ca.Function(name, [x, u], [ca.vertcat(*parts)], ["x", "u"], ["x_next"])

    # ----------------------------------------------------------------- files
    def save(self, path: str | os.PathLike) -> None:
        """Write the model to a small ``.npz`` (matrices plus JSON metadata)."""
        own = {
            "dictionary": self.dictionary.name,
            "n_robots": self.n_robots,
            "dt": self.dt,
            "memory": self.memory,
            "velocity": self.velocity,
        }
        arrays = {"A": self.A, "N": self.N, "B": self.B, "C": self.C}
        write_model_file(path, arrays, own, self.metadata)

    @classmethod
    def load(
        cls,
        path: str | os.PathLike,
        n_robots: int | None = None,
        dt: float | None = None,
    ) -> KoopmanModel:
        """Read a model written by :meth:`save`.

        Parameters
        ----------
        path : str or path
            The ``.npz`` file.
        n_robots, dt : optional
            When given, the file must match them.

        Raises
        ------
        ModelFileError
            Missing, truncated or corrupt file, unknown format, or a mismatch with ``n_robots``
            or ``dt``. The message says how to regenerate the file.
        """
        fields = read_model_file(path, n_robots, dt)
        try:
            return cls(**fields)
        except ValueError as exc:  # shapes that do not fit the dictionary and team size
            raise ModelFileError(
                f"Koopman model file {os.fspath(path)!r}: {exc}; {model_file_hint()}"
            ) from None
