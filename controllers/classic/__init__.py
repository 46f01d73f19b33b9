"""The classic baselines a robotics reviewer expects beside the paper's controllers (issue 45):
``orca`` (:mod:`controllers.classic.orca`: ORCA per robot through pyrvo, the ``[crowd]`` extra)
and ``dwa`` (:mod:`controllers.classic.dwa`: the dynamic window approach per robot, numpy).

Both are decentralized (each robot plans from its own pose estimate and its team-mates' last
messages), read only the observed info, and take the ``estimator`` front-end of the model-based
controllers, so they run under every uncertainty setting. docs/controllers.md has their settings,
sources and measured results.
"""
