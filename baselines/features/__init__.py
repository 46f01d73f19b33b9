"""What a learned policy reads, for both families (numpy only, no learning library): the per-robot
features beside the env's block (:mod:`~baselines.features.robot_features`), the set observation
of the set policies (:mod:`~baselines.features.set_features`) and, under lidar, the perceived
obstacles and movers listed as a state-sensing env lists the true ones
(:mod:`~baselines.features.perceived`)."""
