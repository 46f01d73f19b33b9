"""The physics plant (``plant="mujoco"``, extra ``[physics]``): TurtleBot3-class robots in MuJoCo.

:mod:`.surfaces` (surface names, friction checks and draws; plain numpy), :mod:`.model` (the
MJCF), :mod:`.world` (the batch of worlds the engine steps; imports MuJoCo when built).
docs/physics.md describes the model.
"""
