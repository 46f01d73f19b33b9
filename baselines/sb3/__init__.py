"""The stable-baselines3 policies (extra ``[rl]``): the SB3 vector env, the set encoder, training
(``python -m baselines.sb3.train``), checkpoint choice (``python -m baselines.sb3.select``),
fine-tuning, and the ``rl-ppo*`` controllers that play the shipped policies through a compiled
actor."""
