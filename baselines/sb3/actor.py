"""A trained PPO actor's deterministic forward pass in compiled code, equal for one robot or many.

torch's matrix products pick their kernels (and so their summation order) by the batch size:
the same robot's command differs in the last bits when it is computed alone or beside 63 other
teams' robots. An evaluation that acts on a whole batch of episodes at once (issue 47) must give
each episode the commands it gets alone, so the shipped policies' actors run here instead: every
weight matrix is applied row by row in compiled loops whose order does not depend on the batch
(each output accumulates its inputs in index order; the vectorised loop runs across outputs,
which reorders nothing, and the compiler is not allowed to contract or reassociate), so a row's
result is the same bit for bit whatever else is in the batch. It is also faster than torch for
the small batches of one team (no dispatch, no autograd bookkeeping; ``bench/policy_speed.py``).

Supported: stable-baselines3's ``ActorCriticPolicy`` with a Gaussian head (PPO), its
``FlattenExtractor`` or KoopNav's :class:`~baselines.sb3.set_encoder.SetEncoder`, an MLP of
``Linear`` layers with ``Tanh`` or ``ReLU``. Anything else (SAC's squashed head, another
extractor) is refused by :func:`compile_actor`, and the caller falls back to torch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["ActorNetwork", "Dense", "SetPool", "compile_actor"]

#: activation codes of the compiled layer
IDENTITY, TANH, RELU = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def _dense(x: NDArray[np.float32], weight_t: NDArray[np.float32], bias: NDArray[np.float32], activation: int):
    """``activation(x @ weight_t + bias)`` row by row; each output sums its inputs in index order."""
    rows, n_in = x.shape
    n_out = weight_t.shape[1]
    out = np.empty((rows, n_out), dtype=np.float32)
    acc = np.empty(n_out, dtype=np.float32)
    for r in range(rows):
        acc[:] = 0.0
        for i in range(n_in):
            xi = x[r, i]
            for o in range(n_out):
                acc[o] += xi * weight_t[i, o]
        for o in range(n_out):
            v = acc[o] + bias[o]
            if activation == 1:
                v = np.tanh(v)
            elif activation == 2:
                v = max(v, np.float32(0.0))
            out[r, o] = v
    return out


@numba.njit(cache=True, nogil=True)
def _layer_into(x, weight_t, bias, out):
    """``out = relu(x @ weight_t + bias)`` for one row, each output summing in index order."""
    out[:] = 0.0
    for i in range(x.shape[0]):
        xi = x[i]
        for o in range(out.shape[0]):
            out[o] += xi * weight_t[i, o]
    for o in range(out.shape[0]):
        out[o] = max(out[o] + bias[o], np.float32(0.0))


@numba.njit(cache=True, nogil=True)
def _set_pool(x, start, slots, slot_size, w1_t, b1, w2_t, b2):
    """A set's pooled features for every row of ``x``: each slot's values (``slot_size`` entries
    and a mask entry, from column ``start``) through the two-layer ReLU encoder, then the mean
    and the maximum of the masked encodings and the occupied fraction.

    An absent slot (mask 0) is not encoded: its masked encoding is exactly zero (the encodings
    are finite and non-negative), which adds nothing to the sum and never exceeds the maximum
    (which starts at zero for the same reason), so skipping it changes no bit. Slots are summed
    in index order.
    """
    rows = x.shape[0]
    width = w2_t.shape[1]
    out = np.zeros((rows, 2 * width + 1), dtype=np.float32)
    hidden = np.empty(w1_t.shape[1], dtype=np.float32)
    encoded = np.empty(width, dtype=np.float32)
    for r in range(rows):
        count = np.float32(0.0)
        for k in range(slots):
            column = start + k * (slot_size + 1)
            m = x[r, column + slot_size]
            count += m
            if m == 0.0:
                continue
            _layer_into(x[r, column : column + slot_size], w1_t, b1, hidden)
            _layer_into(hidden, w2_t, b2, encoded)
            for w in range(width):
                v = encoded[w] * m
                out[r, w] += v
                if v > out[r, width + w]:
                    out[r, width + w] = v
        divisor = max(count, np.float32(1.0))
        for w in range(width):
            out[r, w] = out[r, w] / divisor
        out[r, 2 * width] = count / np.float32(slots)
    return out


@dataclass(frozen=True)
class Dense:
    """One ``Linear`` layer and the activation after it."""

    weight_t: NDArray[np.float32]  # (in, out), contiguous
    bias: NDArray[np.float32]
    activation: int

    def __call__(self, x: NDArray[np.float32]) -> NDArray[np.float32]:
        return _dense(np.ascontiguousarray(x, dtype=np.float32), self.weight_t, self.bias, self.activation)


def _run(layers: tuple[Dense, ...], x: NDArray[np.float32]) -> NDArray[np.float32]:
    for layer in layers:
        x = layer(x)
    return x


@dataclass(frozen=True)
class SetPool:
    """One set of :class:`~baselines.sb3.set_encoder.SetEncoder`: its columns, slot size and its
    two-layer ReLU slot encoder."""

    columns: slice
    slot_size: int
    phi: tuple[Dense, Dense]

    def __call__(self, observations: NDArray[np.float32]) -> NDArray[np.float32]:
        first, second = self.phi
        slots = (self.columns.stop - self.columns.start) // (self.slot_size + 1)
        return _set_pool(
            observations,
            self.columns.start,
            slots,
            self.slot_size,
            first.weight_t,
            first.bias,
            second.weight_t,
            second.bias,
        )


@dataclass(frozen=True)
class ActorNetwork:
    """A PPO actor's deterministic action (the Gaussian's mean, clipped to the action space).

    ``ego`` and ``sets`` are a set encoder's parts (empty ``sets`` and ``ego`` None: the
    observation is flattened as it is); ``head`` is the actor MLP and its action layer.
    """

    ego: tuple[slice, tuple[Dense, ...]] | None
    sets: tuple[SetPool, ...]
    head: tuple[Dense, ...]
    low: NDArray[np.float32]
    high: NDArray[np.float32]

    def __call__(self, observations: NDArray[np.float32]) -> NDArray[np.float32]:
        """(B, F) float32 normalized observations -> (B, A) actions in the action space."""
        x = np.ascontiguousarray(observations, dtype=np.float32)
        if x.ndim != 2:
            raise ValueError(f"the actor takes a (batch, features) array, not one of shape {x.shape}")
        if self.ego is not None:
            columns, layers = self.ego
            x = np.concatenate([_run(layers, x[:, columns])] + [pool(x) for pool in self.sets], axis=1)
        return np.clip(_run(self.head, x), self.low, self.high)


def _dense_layers(module: Any) -> tuple[Dense, ...]:
    """The ``Linear``/activation sequence of a torch module as compiled layers (ValueError if other)."""
    from torch import nn

    modules = list(module) if isinstance(module, nn.Sequential) else [module]
    layers: list[Dense] = []
    for item in modules:
        if isinstance(item, nn.Linear):
            weight = item.weight.detach().cpu().numpy().astype(np.float32)
            bias = item.bias.detach().cpu().numpy().astype(np.float32) if item.bias is not None else None
            layers.append(
                Dense(
                    np.ascontiguousarray(weight.T),
                    bias if bias is not None else np.zeros(weight.shape[0], np.float32),
                    IDENTITY,
                )
            )
        elif isinstance(item, (nn.Tanh, nn.ReLU)) and layers and layers[-1].activation == IDENTITY:
            code = TANH if isinstance(item, nn.Tanh) else RELU
            layers[-1] = Dense(layers[-1].weight_t, layers[-1].bias, code)
        else:
            raise ValueError(f"a {type(item).__name__} layer is not compiled")
    return tuple(layers)


def compile_actor(model: Any) -> ActorNetwork | None:
    """The compiled deterministic actor of a stable-baselines3 PPO model, or None when its
    policy has a part this module does not compile (the caller then uses ``predict``)."""
    from stable_baselines3.common.torch_layers import FlattenExtractor

    from baselines.sb3.set_encoder import SetEncoder, _SetPool

    policy = getattr(model, "policy", None)
    if policy is None or not (hasattr(policy, "mlp_extractor") and hasattr(policy, "action_net")):
        return None
    if getattr(policy, "squash_output", False):
        return None
    extractor = policy.pi_features_extractor
    try:
        head = _dense_layers(policy.mlp_extractor.policy_net) + _dense_layers(policy.action_net)
        ego = None
        sets: list[SetPool] = []
        if isinstance(extractor, SetEncoder):
            ego_columns, neighbours, obstacles, movers = extractor._slices
            ego = (ego_columns, _dense_layers(extractor.ego))
            for pool, columns in (
                (extractor.neighbours, neighbours),
                (extractor.obstacles, obstacles),
                (extractor.movers, movers),
            ):
                if isinstance(pool, _SetPool):
                    phi = _dense_layers(pool.phi)
                    if len(phi) != 2 or any(layer.activation != RELU for layer in phi):
                        return None  # the compiled pool is the two-layer ReLU encoder of _SetPool
                    sets.append(SetPool(columns, pool.slot_size, (phi[0], phi[1])))
        elif not isinstance(extractor, FlattenExtractor):
            return None
    except ValueError:
        return None
    space = model.action_space
    return ActorNetwork(
        ego,
        tuple(sets),
        head,
        np.asarray(space.low, dtype=np.float32),
        np.asarray(space.high, dtype=np.float32),
    )
