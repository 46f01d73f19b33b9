"""Solver plumbing shared by the controllers: compiled ``nlpsol`` solvers cached per machine
(:mod:`~controllers.solvers.compiled`, with the caching compiler wrapper
:mod:`~controllers.solvers.cached_cc`) and the exact two-variable QP of the safety filter
(:mod:`~controllers.solvers.two_variable_qp`)."""
