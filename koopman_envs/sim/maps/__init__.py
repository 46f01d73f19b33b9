"""The maps of the workspace (internal: the package exports ``MapSpec``, ``load_map``,
``generate_random_map`` and the rest; import from the modules):

* :mod:`.map_spec`: :class:`~koopman_envs.sim.maps.map_spec.MapSpec`, the built-in maps (the data
  files of ``koopman_envs/maps/``) and user map files, read and checked.
* :mod:`.generator`: the seeded random-map generator (``map="random"``), compiled.
* :mod:`.generator_config`: its settings and which team shapes fit its layouts.
"""
