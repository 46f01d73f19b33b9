"""What the lidar perception costs a team decision, and how its clustering compares with DBSCAN.

Usage::

    python bench/perception_speed.py [--periods 200] [--json out.json]

Random layouts with 8 constant movers, 32 beams of 2 cm noise, the robots driven by consensus so
that the scans change as in an episode; the scans are recorded first, then the perception
(``controllers.perception.front.LidarPerception``: known returns removed, clusters and fits,
tracks) runs over them, once with the map known and once unknown:

* per team decision, median and 95th percentile [ms], at 3 robots (target: median < 1 ms) and at
  16 robots (target: median < 5 ms);
* the clustering alone against scikit-learn's DBSCAN on the same returns (``eps`` the scan
  clustering's break distance at 2 m, ``min_samples=1``: every return in a cluster, as the scan
  clustering), when scikit-learn is installed (the ``[bench]`` extra).

Each figure comes from one process, the competitor measured in the same run.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from typing import Any

import gymnasium as gym
import numpy as np

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.perception.front import LidarPerception
from controllers.perception.scan import ScanSettings, cluster_scan, scan_points
from koopman_envs import Observed, beam_angles

ENV = "KoopNav-TargetReaching-v0"


def _views(robots: int, periods: int, map_known: bool, seed: int = 0) -> tuple[list[Observed], Any]:
    """``periods`` observed views of one episode on a random layout (consensus drives)."""
    env = gym.make(
        ENV,
        map="random",
        n_robots=robots,
        sensing="lidar",
        lidar={"noise": 0.02, "map_known": map_known},
        movers={"count": 8},
        max_episode_steps=periods + 1,
    )
    obs, info = env.reset(seed=seed)
    driver = controllers.make("consensus")
    driver.reset(env, seed=seed)
    views = []
    for _ in range(periods):
        views.append(Observed.from_info(info))
        obs, _, terminated, truncated, info = env.step(driver.act(obs, info))
        if terminated or truncated:
            obs, info = env.reset(seed=seed + len(views))
            driver.reset(env, seed=seed + len(views))
    return views, env.unwrapped.scenario.planner_view()


def perception_times(robots: int, periods: int, map_known: bool) -> dict[str, float]:
    """Median and 95th percentile of one team decision's perception [ms]."""
    views, scenario = _views(robots, periods, map_known)
    perception = LidarPerception()
    perception.reset(scenario)
    for view in views[:10]:  # warm the caches of numpy and scipy
        perception.view(view)
    perception.reset(scenario)
    for view in views:
        perception.view(view)
    times = 1e3 * np.asarray(perception.times)
    return {"median_ms": float(np.median(times)), "p95_ms": float(np.percentile(times, 95))}


def clustering_times(periods: int) -> dict[str, float]:
    """The scan clustering and DBSCAN on the same returns, median per scan [us]."""
    views, scenario = _views(3, periods, True)
    settings = ScanSettings()
    angles = beam_angles(scenario.lidar_beams, scenario.lidar_fov)
    scans = [
        (v.lidar_ranges[i], v.observed_poses[i])
        for v in views
        if v.lidar_ranges is not None
        for i in range(3)
    ]
    ours = []
    for ranges, _ in scans:
        start = time.perf_counter()
        cluster_scan(ranges, angles, scenario.lidar_range, settings)
        ours.append(time.perf_counter() - start)
    out = {"scan_clustering_us": 1e6 * float(np.median(ours))}
    try:
        from sklearn.cluster import DBSCAN
    except ImportError:
        out["dbscan_us"] = math.nan
        return out
    eps = settings.gap + settings.gap_per_beam * 2.0 * float(angles[1] - angles[0])
    theirs = []
    for ranges, pose in scans:
        points = scan_points(ranges, angles, pose)[ranges < scenario.lidar_range]
        start = time.perf_counter()
        if len(points):
            DBSCAN(eps=eps, min_samples=1).fit(points)
        theirs.append(time.perf_counter() - start)
    out["dbscan_us"] = 1e6 * float(np.median(theirs))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=200)
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()
    figures: dict[str, Any] = {"machine": platform.processor() or platform.machine()}
    print(f"perception per team decision, {args.periods} periods, 32 beams, 8 movers")
    for robots, target in ((3, 1.0), (16, 5.0)):
        for map_known in (True, False):
            t = perception_times(robots, args.periods, map_known)
            figures[f"n{robots}_{'known' if map_known else 'unknown'}"] = t
            verdict = "met" if t["median_ms"] < target else "MISSED"
            print(
                f"  {robots:2d} robots, map {'known  ' if map_known else 'unknown'}: median {t['median_ms']:.3f} ms, "
                f"p95 {t['p95_ms']:.3f} ms (target median < {target:g} ms: {verdict})"
            )
    c = clustering_times(args.periods)
    figures["clustering"] = c
    print(
        f"clustering one scan: scan order {c['scan_clustering_us']:.1f} us, "
        f"scikit-learn DBSCAN {c['dbscan_us']:.1f} us (same returns, same run)"
    )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(figures, handle, indent=1)


if __name__ == "__main__":
    main()
