"""Trajectories for synthetic gaits: given as data, sampled as ground points, cut into the pieces
that single gaits walk.

Trajectories are given as data (the pipeline params' ``synthesize.trajectories``): a list of pieces, each either
``[length_m, curvature_start, curvature_end]`` (a clothoid: curvature in 1/m changing linearly along the piece,
positive to the left; constant curvature is an arc, zero a straight line) or ``[turn_deg]`` (a corner). A path
starts at (0, 0) heading +z (x, z ground coordinates; +x is the body's left), which
``pipeline.generators.autoregressive.rollout.place_paths`` moves to each seed's last root position and direction
of travel.

Points are numpy arrays (K, 2), as the plan and its report keep them; their geometry (arc lengths, points at arc
lengths, local frames, directions) is pipeline.ops.geometry's, reached through torch at this boundary in the
arrays' own dtype.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import torch

from pipeline.ops.geometry import arc_lengths, points_at_arcs, to_local_frame, travel_direction, unit_direction

SPACING_M = 0.05
TRAVEL_FRAMES = 30  # a path's direction of travel: from its start to its point this many frames on (1 s at 30 fps)


@dataclass(frozen=True)
class Trajectory:
    id: str
    family: str
    pieces: tuple[tuple[float, ...], ...]
    starts_within_m: float  # gaits start at arc lengths spread over [0, this]

    @cached_property
    def points(self) -> np.ndarray:
        return trajectory_points(self.pieces)


def trajectory_points(pieces: Sequence[Sequence[float]], spacing: float = SPACING_M) -> np.ndarray:
    """(K, 2) ground points (x, z) of a piecewise-clothoid path from (0, 0) heading +z, every ``spacing`` m."""
    heading, point, out = 0.0, np.zeros(2), [np.zeros(2)]
    for piece in pieces:
        if len(piece) == 1:
            heading += math.radians(piece[0])
            continue
        length, k0, k1 = piece
        n = max(1, int(round(length / spacing)))
        ds = length / n
        for i in range(n):
            kappa = k0 + (k1 - k0) * (i + 0.5) / n
            middle = heading + 0.5 * kappa * ds  # the chord of an arc points along its middle tangent
            point = point + ds * unit_direction(middle).numpy()
            heading += kappa * ds
            out.append(point)
    return np.asarray(out)


def start_pose(points: np.ndarray, start_m: float) -> tuple[int, float]:
    """Index of the trajectory point at (or just before) arc length ``start_m`` and the direction (rad, atan2(x, z))
    in which the trajectory arrives there (+z at its start), so a gait starting at a corner walks the corner."""
    s = arc_lengths(torch.from_numpy(points), correctly_rounded=True).numpy()
    i = min(max(int(np.searchsorted(s, start_m, side="right")) - 1, 0), len(points) - 2)
    return i, (0.0 if i == 0 else float(travel_direction(torch.from_numpy(points[i - 1:i + 1]), 1)))


def piece_from(points: np.ndarray, start_m: float, length_m: float, spacing: float = SPACING_M) -> np.ndarray:
    """The stretch (M, 2) of a trajectory from arc length ``start_m``, ``length_m`` long, in the local frame of its
    start (see ``start_pose``), every ``spacing`` m; past the trajectory's end it goes on straight."""
    i, direction = start_pose(points, start_m)
    arcs = torch.arange(int(round(length_m / spacing)) + 1, dtype=torch.float64) * spacing
    piece = points_at_arcs(torch.from_numpy(points[i:]), arcs)
    return to_local_frame(piece, unit_direction(direction), piece[0]).numpy()


def onto(path: np.ndarray, origin: np.ndarray, direction: float) -> np.ndarray:
    """A path (T, 2) moved from its own start frame (first point, its ``travel_direction`` over ``TRAVEL_FRAMES``)
    to start at ``origin`` heading ``direction``: the inverse of taking it into that frame."""
    p = torch.from_numpy(path)
    # the displacement in the path's dtype, its direction in float64 (as the plan's other directions)
    turn = float(travel_direction((p - p[0]).double(), TRAVEL_FRAMES)) - direction
    return (to_local_frame(p, unit_direction(turn), p[0]) + torch.from_numpy(origin)).numpy()


def trajectories_from_spec(spec: dict[str, dict[str, Any]], default_start_span: float) -> list[Trajectory]:
    return [Trajectory(id=tid, family=str(t["family"]), pieces=tuple(tuple(float(v) for v in p) for p in t["pieces"]),
                       starts_within_m=float(t.get("starts_within_m", default_start_span)))
            for tid, t in spec.items()]
