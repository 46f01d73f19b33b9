"""The env fronts on the engine: the Gymnasium env (gym_env.py), the native vector env
(vector_env.py), the PettingZoo env (parallel_env.py) and the opt-in ``Dict`` observation wrapper
(dict_observation.py). Internal: the package exports the env classes."""
