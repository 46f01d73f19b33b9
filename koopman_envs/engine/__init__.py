"""The builders: the keyword table, the validated configuration, the batched engine and the
calibration plant (one layer above the simulator and the tasks, below the env fronts)."""
