"""Laying a walk onto its planned path (motion path editing, after Gleicher 2001): the walk's own turning is taken
out, its travel line (the straightened root path averaged over about a stride) is bent onto the path, and what the
body does around that line (the pelvis' sway, the speed's rise and fall within a stride) is kept in the line's
frame.

Steering alone cannot do this. A pursuit that turns the body towards a point ahead cuts every curve by about
lookahead² / 2r, lags after every corner and steers on the swaying root: the families' placed roots deviated
1.5-4.8 times as far from their paths as real roots sway about their own travel line.

* **Straightening** (``straightened``): each frame's step is turned by minus the walk's direction of travel there
  (its mean step over the window) and the steps are chained. A walk that turned is now a straight walk with its
  sway; taking the line of the unstraightened walk instead would keep, as "sway", the corner it cut.
* **Travel line** (``travel_line``): the straightened path averaged over the window; near each end, where the
  window does not fit, continued along its trend (so the last frames keep their sway).
* **Path**: rounded twice by averaging its points over arc length: over ``corner_m`` for the root to follow,
  over ``turn_m`` for the body to face along (a corner becomes a fillet a walker turns along: 0.6 m at 1.3 m/s is
  14 frames, 90° at the families' 240°/s turn limit).
* **Laying**: with the line's point c_t, direction τ_t and arc length s_t (counted from where the walk's first
  point projects onto the path), the root goes to Q(s_t) + R(θ_t) R(τ_t)⁻¹ (q_t - c_t), q_t the straightened
  root, Q the root's path and θ_t the facing path's direction at s_t; the whole body turns about the root by
  θ_t - τ_t - (the direction of travel straightening took out), averaged over the window as the line is.

Arc length along the line is kept, so speeds and strides are the walk's own. Where the turn changes within a
stance the stance foot slides; the families' foot locking, after this, holds it.
"""

from __future__ import annotations

import torch

from pipeline.ops.geometry import (
    arc_lengths,
    closest_arc,
    direction_of,
    from_local_frame,
    moving_average,
    point_at_arc,
    to_local_frame,
    unit_direction,
    wrap_angle,
)
from pipeline.ops.quaternion import qmul, qrot, yaw


def _mirrored_average(points: torch.Tensor, frames: int) -> torch.Tensor:
    """Centred moving average of sequences of points (N, T, 2) over an odd ``frames``, each end continued by the
    sequence mirrored through its end point (a path's straight end stays straight, and its end point stays)."""
    half = min(frames // 2, points.shape[1] - 1)
    if half <= 0:
        return points
    back = torch.arange(half, 0, -1)  # half, ..., 1 frames in from each end
    head = 2 * points[:, :1] - points[:, back]
    tail = 2 * points[:, -1:] - points[:, -1 - back.flip(0)]
    padded = torch.cat([head, points, tail], 1).transpose(1, 2)
    return moving_average(padded, 2 * half + 1).transpose(1, 2)[:, half:half + points.shape[1]]


def _half_window(frames: int, length: int) -> int:
    """Half an odd window of ``frames``, shortened so that a sequence of ``length`` holds half + 1 whole windows
    (each end's trend is read over that many)."""
    return max(0, min(frames // 2, (length - 1) // 3))


def _inside(x: torch.Tensor, half: int) -> torch.Tensor:
    """Centred moving averages (N, T - 2 half, D) of sequences x (N, T, D) over 2 half + 1 frames, where they fit."""
    return x.unfold(1, 2 * half + 1, 1).mean(-1) if half > 0 else x


def _continued(inside: torch.Tensor, half: int) -> torch.Tensor:
    """Sequences (N, T - 2 half, D) continued by ``half`` frames past each end along the trend of the ``half`` + 1
    values next to it -> (N, T, D). A steady turn or a straight line stays so to its ends, and the last frames keep
    their sway; replicated ends lag a turn, mirrored or shrinking ones take the end's sway into the average."""
    if half <= 0:
        return inside
    back = torch.arange(half, 0, -1, dtype=inside.dtype)[:, None]
    head = inside[:, :1] - (inside[:, half:half + 1] - inside[:, :1]) / half * back
    tail = inside[:, -1:] + (inside[:, -1:] - inside[:, -1 - half:-half]) / half * back.flip(0)
    return torch.cat([head, inside, tail], 1)


def _averaged(x: torch.Tensor, frames: int) -> torch.Tensor:
    """Sequences x (N, T, D) averaged over a centred window of ``frames`` (odd), continued past the ends by the
    averages' trend."""
    half = _half_window(frames, x.shape[1])
    return _continued(_inside(x, half), half)


def travel_line(ground: torch.Tensor, frames: int) -> torch.Tensor:
    """The travel line (N, T, 2) of root ground paths (N, T, 2): their centred average over ``frames`` (odd),
    continued past the ends by its trend."""
    return _averaged(ground, frames)


def straightened(ground: torch.Tensor, frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Root ground paths (N, T, 2) with their turning taken out: each frame's step turned by minus the walk's
    direction of travel there (the direction of its mean step over ``frames``, centred, continued past the ends by
    its trend) and the steps chained from (0, 0) (N, T, 2), and those directions (N, T). What is left is the walk
    along a straight line with its sway and its speed."""
    step = ground[:, 1:] - ground[:, :-1]
    step = torch.cat([step[:, :1], step], 1)
    half = _half_window(frames, step.shape[1])
    mean = _inside(step, half)
    direction = direction_of(mean[..., 0], mean[..., 1])
    unwrapped = direction[:, :1] + torch.cat([torch.zeros_like(direction[:, :1]),
                                              wrap_angle(direction.diff(dim=1)).cumsum(1)], 1)
    travel = _continued(unwrapped[..., None], half)[..., 0]
    local = to_local_frame(step[:, 1:], unit_direction(travel[:, 1:]))
    return torch.cat([torch.zeros_like(local[:, :1]), local.cumsum(1)], 1), travel


def _rounded(paths: torch.Tensor, arc_m: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Paths (N, K, 2) (points about equally spaced) with their points averaged over about ``arc_m`` of arc length,
    and their arc lengths (N, K)."""
    spacing = float(arc_lengths(paths)[:, -1].mean()) / max(paths.shape[1] - 1, 1)
    rounded = _mirrored_average(paths, max(1, int(round(arc_m / max(spacing, 1e-6)))) // 2 * 2 + 1)
    return rounded, arc_lengths(rounded)


def fit_ground(ground: torch.Tensor, paths: torch.Tensor, frames: int, corner_m: float, turn_m: float
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Root ground paths (N, T, 2) laid onto paths (N, K, 2) (points about equally spaced), from where their first
    point projects onto the path: the new ground paths and the turn (N, T) rad each frame's body takes (see the
    module docstring)."""
    straight, travel = straightened(ground, frames)
    line = travel_line(straight, frames)
    ahead = torch.cat([line[:, 1:2] - line[:, :1], line[:, 2:] - line[:, :-2], line[:, -1:] - line[:, -2:-1]], 1)
    tau = direction_of(ahead[..., 0], ahead[..., 1])
    path, cumulative = _rounded(paths, corner_m)
    arcs = closest_arc(ground[:, 0], path, cumulative)[:, None] + arc_lengths(line)
    facing, facing_cumulative = _rounded(paths, turn_m)
    eps = torch.full_like(arcs, 0.05)  # the facing path's direction read over ±5 cm
    towards = (point_at_arc(facing, facing_cumulative, arcs + eps)
               - point_at_arc(facing, facing_cumulative, arcs - eps))
    theta = direction_of(towards[..., 0], towards[..., 1])
    around = to_local_frame(straight, unit_direction(tau), line)
    placed = from_local_frame(around, unit_direction(theta), point_at_arc(path, cumulative, arcs))
    # the body's turn, averaged as the line is: what is left of a stride's sway in a one-second mean step would
    # swing the body about its root, and its feet with it, by a degree or two every frame
    turn = wrap_angle(theta - tau - travel)
    unwrapped = turn[:, :1] + torch.cat([torch.zeros_like(turn[:, :1]), wrap_angle(turn.diff(dim=1)).cumsum(1)], 1)
    return placed, wrap_angle(_averaged(unwrapped[..., None], frames)[..., 0])


def fit_poses(positions: torch.Tensor, rotations: torch.Tensor, paths: torch.Tensor, frames: int, corner_m: float,
              turn_m: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Walks (positions (N, T, J, 3), rotations (N, T, J, 4), the root first) laid onto paths (N, K, 2): the whole
    body of each frame turned about its root and moved with it (``fit_ground``), heights unchanged; and the turns
    (N, T)."""
    root = positions[:, :, 0]
    ground, turn = fit_ground(root[..., [0, 2]], paths, frames, corner_m, turn_m)
    spin = yaw(turn)
    relative = qrot(spin[:, :, None].expand(*positions.shape[:-1], 4), positions - root[:, :, None])
    moved = torch.stack([ground[..., 0], root[..., 1], ground[..., 1]], -1)
    pelvis = qmul(spin, rotations[:, :, 0])
    return relative + moved[:, :, None], torch.cat([pelvis[:, :, None], rotations[:, :, 1:]], 2), turn
