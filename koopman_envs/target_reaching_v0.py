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
target_reaching_v0.parallel_env(map="map1", slip="nominal", n_robots=3, goal_tolerance=0.1,
                                max_episode_steps=600, render_mode=None, robot_radius=0.2,
                                n_obstacle_obs=4, random_map=None, start_noise=0.0)
```
``max_cycles`` (PettingZoo MPE's name) is accepted for ``max_episode_steps``.
History: v0 initial release.
"""

from koopman_envs.fronts.parallel_env import make_constructors

parallel_env, env, raw_env = make_constructors("target_reaching")

__all__ = ["env", "parallel_env", "raw_env"]
