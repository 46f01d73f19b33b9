"""Episodes run on the env fronts: the one episode runner (single.py: reset, the act/step loop, the
compute charge), many episodes at once on the vector env (batch.py), the per-episode metrics
(metrics.py) and ``python -m koopman_envs.episodes.demo``, one short episode (a smoke test). The
top layer of the environments: it drives the fronts and imports no controller. Internal: the
package exports ``run_episode``, ``run_episodes_in_batch``, ``EpisodeResult`` and the rest."""
