"""Planar lidar: every robot's beams against obstacles, team-mates and the workspace boundary.

One compiled pass over K environments, N robots and B beams, as the physics. A beam starts at
the robot's true centre (the sensor measures the world from where the robot is, whatever its
localization believes) and reads the distance to the first disc (obstacle or other robot) or
boundary wall it meets, capped at the range. A robot whose centre lies inside a disc or outside
the workspace reads 0 on every beam (it has collided; the episode ends on this step).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["beam_angles", "cast_beams"]


def beam_angles(beams: int, fov: float) -> NDArray[np.float64]:
    """Beam directions relative to the heading [rad], shape (B,).

    A full circle (``fov`` = 2 pi) spaces the beams 2 pi / B apart starting straight ahead; a
    narrower field spans [-fov/2, fov/2] with both edges included (one beam looks straight ahead).
    """
    if fov >= 2 * math.pi:
        return 2 * math.pi * np.arange(beams) / beams
    if beams == 1:
        return np.zeros(1)
    return np.linspace(-fov / 2, fov / 2, beams)


@njit(cache=True)
def cast_beams(
    state: NDArray[np.float64],
    discs: NDArray[np.float64],
    robot_radius: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
    workspace: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (K, N, B) with exact ranges [m] (no noise; see the module docstring).

    Parameters
    ----------
    state : ndarray, shape (K, 3, N)
        True poses, rows x, y, theta.
    discs : ndarray, shape (K, 3, M)
        The discs the beams hit besides the robots, rows x, y, radius [m] (the obstacles, and the
        movers after them).
    robot_radius : ndarray, shape (N,)
        Radii of the robots, which the other robots' beams hit.
    angles : ndarray, shape (B,)
        Beam directions relative to the heading [rad] (:func:`beam_angles`).
    max_range : float
        Reading of a beam that meets nothing [m].
    workspace : ndarray, shape (4,)
        x_min, x_max, y_min, y_max [m].
    out : ndarray, shape (K, N, B)
    """
    n_envs, _, n_robots = state.shape
    n_obstacles = discs.shape[2]
    n_discs = n_obstacles + n_robots
    n_beams = angles.shape[0]
    disc_dx = np.empty(n_discs)
    disc_dy = np.empty(n_discs)
    disc_r2 = np.empty(n_discs)
    disc_d2 = np.empty(n_discs)
    # the robot's beam directions, computed once per robot (both passes read them)
    ray_c = np.empty(n_beams)
    ray_s = np.empty(n_beams)
    x_min, x_max, y_min, y_max = workspace[0], workspace[1], workspace[2], workspace[3]
    # each beam's direction is the heading's turned by its angle: two trig calls per beam here,
    # a rotation (4 products) per beam and robot below
    beam_cos, beam_sin = np.cos(angles), np.sin(angles)
    # the beams are evenly spaced (beam_angles): angle b = first + b * spacing
    first = angles[0]
    spacing = angles[1] - angles[0] if n_beams > 1 else 1.0
    for k in range(n_envs):
        for i in range(n_robots):
            x, y, theta = state[k, 0, i], state[k, 1, i], state[k, 2, i]
            heading_cos, heading_sin = math.cos(theta), math.sin(theta)
            inside = x < x_min or x > x_max or y < y_min or y > y_max
            # the discs this robot can see, relative to its centre; beyond range + radius they
            # cannot cut a beam, so they are left out once here instead of once per beam
            count = 0
            for e in range(n_discs):
                if e < n_obstacles:
                    cx, cy, r = discs[k, 0, e], discs[k, 1, e], discs[k, 2, e]
                else:
                    j = e - n_obstacles
                    if j == i:
                        continue
                    cx, cy, r = state[k, 0, j], state[k, 1, j], robot_radius[j]
                dx, dy = cx - x, cy - y
                d2 = dx * dx + dy * dy
                if d2 <= r * r:
                    inside = True
                reach = max_range + r
                if d2 < reach * reach:
                    disc_dx[count], disc_dy[count] = dx, dy
                    disc_r2[count], disc_d2[count] = r * r, d2
                    count += 1
            if inside:
                for b in range(n_beams):
                    out[k, i, b] = 0.0
                continue
            for b in range(n_beams):
                ray_c[b] = heading_cos * beam_cos[b] - heading_sin * beam_sin[b]
                ray_s[b] = heading_sin * beam_cos[b] + heading_cos * beam_sin[b]
            # pass 1, the walls within range (most robots see none: then every beam reads the range)
            east, west = x_max - x < max_range, x - x_min < max_range
            north, south = y_max - y < max_range, y - y_min < max_range
            if east or west or north or south:
                for b in range(n_beams):
                    c, s = ray_c[b], ray_s[b]
                    best = max_range
                    # the robot is inside the workspace, so the exit distance along the beam
                    if east and c > 0.0:
                        best = min(best, (x_max - x) / c)
                    elif west and c < 0.0:
                        best = min(best, (x_min - x) / c)
                    if north and s > 0.0:
                        best = min(best, (y_max - y) / s)
                    elif south and s < 0.0:
                        best = min(best, (y_min - y) / s)
                    out[k, i, b] = best
            else:
                for b in range(n_beams):
                    out[k, i, b] = max_range
            # pass 2, every visible disc: only the beams within its angular half-width can meet
            # it (bounded above by tan, r / sqrt(d^2 - r^2) >= asin(r / d), so none is missed);
            # each of those is tested exactly, as a beam-by-beam search would
            for q in range(count):
                dx, dy, r2, d2 = disc_dx[q], disc_dy[q], disc_r2[q], disc_d2[q]
                bearing = math.atan2(dy * heading_cos - dx * heading_sin, dx * heading_cos + dy * heading_sin)
                half = math.sqrt(r2 / (d2 - r2)) + 1e-9
                for shift in (-2.0 * math.pi, 0.0, 2.0 * math.pi):
                    low = max(0, math.ceil((bearing + shift - half - first) / spacing))
                    high = min(n_beams - 1, math.floor((bearing + shift + half - first) / spacing))
                    for b in range(low, high + 1):
                        along = dx * ray_c[b] + dy * ray_s[b]
                        if along <= 0.0:
                            continue  # behind the robot (the robot is outside every disc)
                        across2 = d2 - along * along
                        if across2 >= r2:
                            continue
                        hit = along - math.sqrt(r2 - across2)
                        if hit < out[k, i, b]:
                            out[k, i, b] = hit
