"""Seeded random routes and user-like ground under them (``make validate-routes``, tests).

:func:`random_route` draws a route's waypoints, turn radius and speed from a
``numpy.random.Generator`` (the generator of ``tests/runs/test_random_routes.py``'s pairs);
:func:`user_ground` draws a ``terrain.generate`` section under a route as a user's ground is:
a side slope at any azimuth, rough ground on a broad bump, and now and then a ditch or a kerb
across the route (laid where the route crosses it, perpendicular to its leg there) and
egg-box bumps (:mod:`mmstab.terrain.generators`' ``features``). Same seed, same draws.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np


class RandomRoute(NamedTuple):
    """A drawn route.

    Attributes:
        waypoints: (n, 2) [m] in the map frame, centred on its origin.
        turn_radius: the corner arcs' radius [m]; 0: every corner pivots.
        speed: on straight lines [m/s].
        turns_deg: the signed turn at each interior waypoint [deg].
    """

    waypoints: np.ndarray
    turn_radius: float
    speed: float
    turns_deg: np.ndarray


def random_route(
    rng: np.random.Generator,
    pivot_everywhere: bool,
    waypoints: tuple[int, int] = (3, 5),
    leg: tuple[float, float] = (2.0, 4.0),
    turn_max_deg: float = 90.0,
    sharp_deg: tuple[float, float] = (60.0, 90.0),
    speed: tuple[float, float] = (0.2, 0.3),
) -> RandomRoute:
    """Waypoints, legs and turns either way, at least one pivot.

    One corner (drawn) turns ``sharp_deg`` [deg] (the others up to ``turn_max_deg``). With
    ``pivot_everywhere`` the turn radius is 0; otherwise it is 10-40 % more than the largest
    radius whose arc fits that corner's shorter leg alone, so that corner pivots and the
    others keep an arc when theirs fits.

    Args:
        rng: the draws.
        pivot_everywhere: turn radius 0.
        waypoints: the fewest and most waypoints (at least 3).
        leg: the legs' shortest and longest length [m].
        turn_max_deg: the largest turn of the other corners [deg].
        sharp_deg: the drawn corner's smallest and largest turn [deg].
        speed: the slowest and fastest speed [m/s].
    """
    n = int(rng.integers(waypoints[0], waypoints[1] + 1))
    legs = rng.uniform(leg[0], leg[1], n - 1)
    turns = rng.uniform(-1.0, 1.0, n - 2) * np.radians(turn_max_deg)
    sharp = int(rng.integers(0, n - 2))
    turns[sharp] = rng.choice([-1.0, 1.0]) * rng.uniform(*np.radians(sharp_deg))
    yaw = np.cumsum(np.r_[rng.uniform(-np.pi, np.pi), turns])
    steps = legs[:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
    xy = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
    xy -= 0.5 * (xy.min(axis=0) + xy.max(axis=0))
    if pivot_everywhere:
        radius = 0.0
    else:  # the arc's tangent length R tan(turn / 2) longer than the shorter leg
        fits = min(legs[sharp], legs[sharp + 1]) / np.tan(max(abs(turns[sharp]), 1e-3) / 2)
        radius = float(fits * rng.uniform(1.1, 1.4))
    return RandomRoute(xy, radius, float(rng.uniform(*speed)), np.degrees(turns))


def point_along(waypoints: np.ndarray, s: float) -> tuple[np.ndarray, float]:
    """The point ``s`` [m] along the polyline (2,) [m] and its leg's heading [rad]."""
    legs = np.diff(waypoints, axis=0)
    length = np.linalg.norm(legs, axis=1)
    k = int(np.clip(np.searchsorted(np.cumsum(length), s), 0, len(legs) - 1))
    before = float(np.sum(length[:k]))
    u = legs[k] / length[k]
    return waypoints[k] + (s - before) * u, float(np.arctan2(u[1], u[0]))


def across(waypoints: np.ndarray, s: float, rng: np.random.Generator) -> dict[str, float]:
    """A band feature's ``distance`` [m] and ``azimuth`` [rad] crossing the route at ``s`` [m].

    Perpendicular to the route's leg there, crossed along it or against it (a kerb then
    rises or drops as the route crosses it), through the point ``s`` along the route.
    """
    p, heading = point_along(waypoints, s)
    azimuth = heading + (0.0 if rng.uniform() < 0.5 else np.pi)
    azimuth = float(np.arctan2(np.sin(azimuth), np.cos(azimuth)))
    return {"distance": float(p @ [np.cos(azimuth), np.sin(azimuth)]), "azimuth": azimuth}


def user_ground(
    rng: np.random.Generator, waypoints: np.ndarray, size: list[float], g: Mapping[str, Any]
) -> dict[str, Any]:
    """A ``terrain.generate`` section under the route: user-like ground.

    Fractal rough ground (RMS ``roughness_m``, correlation ``correlation_m`` [m]) on a
    Gaussian bump or dip ``hill_m`` [m] high (radius 1-2 m) on a side slope ``slope_deg``
    [deg] uphill toward any azimuth; with probability each: a ditch (``depth_m``, ``width_m``
    [m]) across the route in its first half, a kerb (``height_m`` [m]) across it in its
    second half (both at least 0.8 m from either end: the robot starts on its ground), and
    egg-box bumps (``amplitude_m``, ``wavelength_m`` [m]) over the map.

    Args:
        rng: the draws.
        waypoints: the route's (n, 2) [m], in the map frame.
        size: the map's size (x, y) [m], centred on the map frame's origin.
        g: the ranges (``problems/validate_routes.yaml``'s ``ground``).
    """
    generate: dict[str, Any] = {
        "kind": "rough",
        "seed": int(rng.integers(0, 2**31)),
        "size": size,
        "resolution": float(g["resolution_m"]),
        "amplitude": float(rng.uniform(*g["roughness_m"])),
        "correlation_length": float(rng.uniform(*g["correlation_m"])),
        "hill_height": float(rng.uniform(*g["hill_m"])),
        "hill_radius": float(rng.uniform(1.0, 2.0)),
        "slope": float(np.radians(rng.uniform(*g["slope_deg"]))),
        "azimuth": float(rng.uniform(-np.pi, np.pi)),
    }
    length = float(np.sum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1)))
    features: dict[str, Any] = {}
    d, k, b = g["ditch"], g["kerb"], g["bumps"]
    draws = rng.uniform(size=3)
    if draws[0] < d["probability"]:
        s = rng.uniform(0.8, max(0.5 * length, 0.8))
        features["ditch"] = {"depth": float(rng.uniform(*d["depth_m"])),
                             "width": float(rng.uniform(*d["width_m"])),
                             **across(waypoints, s, rng)}  # fmt: skip
    if draws[1] < k["probability"]:
        s = rng.uniform(min(0.5 * length + 0.8, length - 0.8), length - 0.8)
        features["kerb"] = {"height": float(rng.uniform(*k["height_m"])),
                            **across(waypoints, s, rng)}  # fmt: skip
    if draws[2] < b["probability"]:
        features["bumps"] = {"amplitude": float(rng.uniform(*b["amplitude_m"])),
                             "wavelength": float(rng.uniform(*b["wavelength_m"]))}  # fmt: skip
    if features:
        generate["features"] = features
    return {"generate": generate}
