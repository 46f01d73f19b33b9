"""Learned baselines: stable-baselines3 policies for the KoopNav environments (extra ``[rl]``).

``python -m baselines.train --env KoopNav-Formation-v0 --out runs/formation`` trains PPO (one
policy shared by the robots) on random maps and random slip levels with the native vector env;
``python -m baselines.select`` keeps the best checkpoint on held-out random layouts; ``rl-ppo``
(registered through the ``koopnav.controllers`` entry point) plays a policy through the common
controller protocol. Policies for both tasks ship in ``baselines/policies/``.
"""
