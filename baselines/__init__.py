"""Learned baselines: stable-baselines3 policies for the KoopNav environments (extra ``[rl]``).

``python -m baselines.train --env KoopNav-Formation-v0 --algo ppo --timesteps 2_000_000 --out runs/f``
trains on random maps and random slip levels with the native vector env; ``rl-ppo`` (registered in
:mod:`controllers`) plays a trained policy through the common controller protocol.
"""
