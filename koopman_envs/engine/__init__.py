"""The simulator core: the keyword table, the validated configuration, the batched engine with its
episode resets, and the calibration plant (one layer above the simulator and the tasks, below the
env fronts). Internal: the package exports what others use of it."""
