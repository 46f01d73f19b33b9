"""The movers of K environments, simulated: the setting is :mod:`koopman_envs.settings.moving_obstacles`'s.

One module per concept (internal: the package exports nothing; import from its modules):

* :mod:`.field`: :class:`~koopman_envs.sim.movers.field.MoverField`, the movers' state in a
  batch, its reset, its step, the robots' contacts with movers and the observation's mover items.
* :mod:`.placement`: where the movers may go (the arena: the map's region grown by
  :data:`~koopman_envs.sim.movers.placement.ARENA_MARGIN`, clipped to the workspace) and where
  they start (drawn clear of the obstacles, of each other and of every start and target).
* :mod:`.motion`: the compiled motion of ``"constant"`` and ``"waypoints"`` movers, and the
  crowd's goals.
* :mod:`.crowd`: the ``"crowd"`` movers' velocities, ORCA (RVO2 through ``pyrvo``) per
  environment.
* :mod:`.tracking`: the movers as a robot's people tracker reports them under
  ``sensing="state"`` (compiled constant-velocity Kalman filters).

Each environment draws from children of its generator
(:func:`~koopman_envs.sim.perception.child_generator`): the env's own stream (map, starts,
slip) is untouched, so an episode with movers pairs with the same episode without.
"""
