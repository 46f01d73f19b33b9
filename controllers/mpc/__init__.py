"""Model predictive control of the team in CasADi (SPEC section 3), one job per module:

- :mod:`~controllers.mpc.config`: :class:`NMPCConfig`, the options of every NMPC, and the solver tables;
- :mod:`~controllers.mpc.layout`: the parameter vector as named blocks, read by the problem and the controller;
- :mod:`~controllers.mpc.models`: the prediction-model protocol, state coding, the nominal unicycle;
- :mod:`~controllers.mpc.problem`: the NLP (cost, collision rows, formation rows), its solvers, the warm start;
- :mod:`~controllers.mpc.rti`: the real-time iteration (one structured QP per period);
- :mod:`~controllers.mpc.slots`: obstacle and pair slots, refilled before every solve;
- :mod:`~controllers.mpc.controller`: :class:`NMPCController`, the closed loop with its fallbacks;
- :mod:`~controllers.mpc.variants`: the nominal, Koopman and adaptive Koopman NMPCs;
- :mod:`~controllers.mpc.distributed`: the distributed NMPC (every robot its own problem).
"""
