"""A permutation-invariant set encoder as a stable-baselines3 features extractor (deep sets).

Each robot's set observation (:mod:`baselines.features.set_features`) is split into its ego entries and
two sets, team-mates and obstacles, and a third, movers, for a policy that reads them. Every element of a set goes through the same small MLP;
the encodings are multiplied by the element's mask and pooled by their mean and their maximum
(both ignore the order of the elements, and a masked element contributes zero to both since
the encodings are non-negative after a ReLU), plus the fraction of occupied slots. The pooled
sets and the encoded ego vector form the features that PPO's actor and critic heads read.

One network therefore serves every team size and every obstacle count: the input has a fixed
number of slots, and which of them are filled changes nothing in the weights (Zaheer et al.,
"Deep Sets", 2017). Mean-and-max pooling rather than attention: it is exact about masks,
order-free by construction and cheap enough for 1 ms inference at 16 robots on one core.
"""

from __future__ import annotations

from typing import Any

import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from baselines.features.set_features import (
    MOVER_SIZE,
    NEIGHBOUR_SIZE,
    OBSTACLE_SIZE,
    SetFeatureConfig,
    split_set_observation,
)

__all__ = ["SetEncoder"]


def _mlp(inputs: int, width: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(inputs, width), nn.ReLU(), nn.Linear(width, width), nn.ReLU())


class _SetPool(nn.Module):
    """Encode each slot, mask, pool by mean and max (and the occupied fraction)."""

    def __init__(self, slot_size: int, width: int) -> None:
        super().__init__()
        self.slot_size = slot_size
        self.phi = _mlp(slot_size, width)

    def forward(self, slots: torch.Tensor) -> torch.Tensor:
        # slots: (B, K * (slot_size + 1)) with the mask as each slot's last entry
        batch = slots.shape[0]
        slots = slots.reshape(batch, -1, self.slot_size + 1)
        values, mask = slots[..., : self.slot_size], slots[..., self.slot_size :]
        encoded = self.phi(values) * mask  # (B, K, width), zero in absent slots
        count = mask.sum(dim=1)  # (B, 1)
        mean = encoded.sum(dim=1) / count.clamp(min=1.0)
        maximum = encoded.max(dim=1).values  # encodings are >= 0, absent ones exactly 0
        return torch.cat([mean, maximum, count / slots.shape[1]], dim=1)


class SetEncoder(BaseFeaturesExtractor):
    """Deep-sets features of a robot's ego entries, team-mates and obstacles.

    Parameters
    ----------
    observation_space : gymnasium.spaces.Box
        Of shape (``SetFeatureConfig(**set_config).size``,).
    set_config : dict
        The :class:`~baselines.features.set_features.SetFeatureConfig` fields the observations
        were built with.
    width : int
        Width of every encoder layer.
    """

    def __init__(self, observation_space: spaces.Box, set_config: dict[str, Any], width: int = 64) -> None:
        config = SetFeatureConfig(**set_config)
        ego, neighbours, obstacles, movers = split_set_observation(int(observation_space.shape[0]), config)
        sets = 3 if config.movers else 2
        super().__init__(observation_space, features_dim=width + sets * (2 * width + 1))
        self._slices = (ego, neighbours, obstacles, movers)
        self.ego = nn.Sequential(nn.Linear(ego.stop - ego.start, width), nn.ReLU())
        self.neighbours = _SetPool(NEIGHBOUR_SIZE, width)
        self.obstacles = _SetPool(OBSTACLE_SIZE, width)
        # the third set only for a policy with mover slots: the earlier policies' networks unchanged
        self.movers = _SetPool(MOVER_SIZE, width) if config.movers else None

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        ego, neighbours, obstacles, movers = self._slices
        parts = [
            self.ego(observations[:, ego]),
            self.neighbours(observations[:, neighbours]),
            self.obstacles(observations[:, obstacles]),
        ]
        if self.movers is not None:  # appended last: a fine-tune from a policy without keeps its columns
            parts.append(self.movers(observations[:, movers]))
        return torch.cat(parts, dim=1)
