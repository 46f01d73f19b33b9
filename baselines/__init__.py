"""Learned baselines: stable-baselines3 policies for the KoopNav environments (extra ``[rl]``).

``python -m baselines.sb3.train --env KoopNav-Formation-v0 --policy set --out runs/formation``
trains PPO with one set-encoder policy shared by every robot (:mod:`baselines.features.set_features`,
:mod:`baselines.sb3.set_encoder`) on the random-layout curriculum of :mod:`baselines.curriculum`
(teams of 2 to 12); ``--policy mlp`` (the default) trains the first, 3-robot MLP.
``python -m baselines.sb3.select`` keeps the best checkpoint on held-out random layouts. Two
controllers play the shipped policies through the common controller protocol (entry point
``koopnav.controllers``): ``rl-ppo-set`` (``baselines/policies/set/``, any team size) and
``rl-ppo`` (``baselines/policies/``). :mod:`baselines.marl.benchmarl_task` runs both tasks in
BenchMARL (extra ``[benchmarl]``).
"""
