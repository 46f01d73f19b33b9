"""Perception between each robot's lidar and its planner: scans to discs and wall segments
(:mod:`~controllers.perception.scan`), discs to tracked movers (:mod:`~controllers.perception.tracker`),
and the front that hands a controller what its team sees (docs/perception.md)."""
