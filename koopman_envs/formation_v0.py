"""PettingZoo KoopNav leader-follower formation, version 0.

| Import             | ``from koopman_envs import formation_v0``                  |
|--------------------|------------------------------------------------------------|
| Actions            | Continuous, per agent ``(v [m/s], omega [rad/s])``          |
| Parallel API       | Yes (native); AEC through ``env()``                         |
| Agents             | ``robot_0`` (leader) .. ``robot_{N-1}`` (followers)        |
| Action shape       | (2,), within (+-{v_max} m/s, +-{omega_max} rad/s), saturated           |
| Observation shape  | (11 + 3 (N - 1) + 3 n_obstacle_obs,) = ({features},) by default    |
| State shape        | (N * {features},)                                               |

```python
{make_call}
```
``max_cycles`` (PettingZoo MPE's name) is accepted for ``max_episode_steps``; the keywords are
those of :data:`koopman_envs.engine.keywords.ENV_KEYWORDS` (see the Gymnasium env's Arguments table).
History: v0 initial release.
"""

from koopman_envs.fronts.parallel_env import make_constructors, module_doc

__doc__ = module_doc("formation", __doc__)  # the keywords and values, from their one place

parallel_env, env, raw_env = make_constructors("formation")

__all__ = ["env", "parallel_env", "raw_env"]
