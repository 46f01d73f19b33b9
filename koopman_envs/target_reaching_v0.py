"""PettingZoo KoopNav target reaching, version 0.

| Import             | ``from koopman_envs import target_reaching_v0``            |
|--------------------|------------------------------------------------------------|
| Actions            | Continuous, per agent ``(v [m/s], omega [rad/s])``          |
| Parallel API       | Yes (native); AEC through ``env()``                         |
| Agents             | ``robot_0 .. robot_{N-1}`` (N = 3 by default)              |
| Action shape       | (2,), within (+-0.6 m/s, +-pi/4 rad/s), saturated           |
| Observation shape  | (9 + 3 (N - 1) + 3 n_obstacle_obs,) = (27,) by default       |
| State shape        | (N * 27,)                                                  |

```python
{make_call}
```
``max_cycles`` (PettingZoo MPE's name) is accepted for ``max_episode_steps``; the keywords are
those of :data:`koopman_envs.keywords.ENV_KEYWORDS` (see the Gymnasium env's Arguments table).
History: v0 initial release.
"""

from koopman_envs.fronts.parallel_env import make_call, make_constructors

__doc__ = __doc__.replace("{make_call}", make_call("target_reaching"))  # the keywords, from the one table

parallel_env, env, raw_env = make_constructors("target_reaching")

__all__ = ["env", "parallel_env", "raw_env"]
