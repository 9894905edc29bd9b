"""Geometry of gaits and paths on the ground, in torch: the one implementation of each formula below, batched
over leading dimensions (shapes in each docstring), differentiable wherever the maths is.

Conventions. Ground points are (x, z) (Y is up). A direction is an angle in radians about +Y: 0 along +Z, +π/2
along +X (the body's left when it faces +Z), i.e. atan2(x, z).

* headings and directions of travel: ``heading_angle`` (of a root rotation), ``direction_of`` (of a displacement),
  ``travel_direction`` (from a path's start to a point some frames on), ``path_direction`` (per frame: the mean
  step over about a stride), ``facing_off_travel`` (the heading against that direction: about π for a backward
  walk), ``unit_direction`` (the unit vector of a direction);
* local frames: ``to_local_frame`` (an origin moved to (0, 0), a direction turned onto +z) and its inverse
  ``from_local_frame``;
* polylines: ``segment_lengths``, ``arc_lengths``, ``point_at_arc`` and ``points_at_arcs`` (points at given arc
  lengths), ``resample_polyline`` (points at equal arc length), ``closest_arc``, ``distance_to_polyline``;
  ``path_turns`` (how a path curls: small loops, steps against the travel);
  ``ground_speed`` of a sequence of positions;
* angles: ``wrap_phase`` ([0, 2π)), ``wrap_angle`` and ``wrap_angle_atan2`` ([-π, π));
* axes: ``to_y_up`` (a source's axes onto Y up);
* along time: ``sliding_windows`` (centred, edges replicated) and the ``moving_average`` over them.

The numerics are part of the contract, because stored gaits and trained weights depend on the last bit: the
dtype that comes in goes out, and no operation is reordered. torch's atan2, sin, cos and sqrt round differently
from numpy's and math's, and atan2 even between a contiguous and a strided input, so callers hand in the tensors
they always did (see ``heading_angle``, ``direction_of``, ``unit_direction``). Two pairs here compute the same map
with different rounding: ``point_at_arc`` / ``points_at_arcs`` and ``wrap_angle`` / ``wrap_angle_atan2``.
Generated gaits, the synthesis plan's pieces and the trained checkpoints were each made with one of them, so
merging a pair changes published bytes: a decision for a regeneration, not for a refactor.

This module must never know files, sources, manifests, params, joint names or DVC, nor what a path is for
(generation, the synthesis plan, evaluation): it knows tensors of points and angles.
"""

from __future__ import annotations

import math

import torch

from pipeline.ops.quaternion import qrot

# ------------------------------------------------------------------------------ headings and directions of travel


def direction_of(dx: torch.Tensor, dz: torch.Tensor) -> torch.Tensor:
    """Direction (...) of ground displacements with components dx, dz (...): atan2(dx, dz).

    Components, not a (..., 2) tensor: torch's atan2 rounds differently on strided and contiguous inputs, and the
    callers' layouts are kept."""
    return torch.atan2(dx, dz)


def heading_angle(rotation: torch.Tensor) -> torch.Tensor:
    """Heading (...) of rotations (..., 4) (root rotations: the body's heading): where they turn +Z, about +Y."""
    forward = qrot(rotation, rotation.new_tensor([0.0, 0.0, 1.0]).expand(*rotation.shape[:-1], 3))
    return direction_of(forward[..., 0], forward[..., 2])


def unit_direction(angle: torch.Tensor | float) -> torch.Tensor:
    """Unit ground vectors (..., 2) = (sin, cos) of directions (...): where a direction points.

    A Python float (the synthesis plan's directions) gives a float64 (2,) through ``math``: the plan's geometry
    was built with it, and torch's sin and cos differ from it in the last bit for ~0.1% of angles."""
    if isinstance(angle, float):
        return torch.tensor([math.sin(angle), math.cos(angle)], dtype=torch.float64)
    return torch.stack((torch.sin(angle), torch.cos(angle)), dim=-1)


def travel_direction(path: torch.Tensor, frames: int) -> torch.Tensor:
    """Direction (...) from the start of paths (..., T, 2) to their point ``frames`` on (the last if shorter)."""
    k = min(frames, path.shape[-2] - 1)
    return direction_of(path[..., k, 0] - path[..., 0, 0], path[..., k, 1] - path[..., 0, 1])


def path_direction(root_positions: torch.Tensor, heading: torch.Tensor, frames: int,
                   min_step: float = 1e-3) -> torch.Tensor:
    """Direction of travel (..., T) per frame: the mean ground displacement over a centred window of ``frames``
    (about one stride), so the pelvis' side-to-side sway does not swing it; the body heading where the root
    barely moves (mean step < ``min_step`` m/frame). root_positions (..., T, 3), heading (..., T).

    The generator's reference frame: it predicts the pelvis' rotation relative to this direction.
    """
    ground = root_positions[..., [0, 2]]
    step = ground[..., 1:, :] - ground[..., :-1, :]
    step = torch.cat([step, step[..., -1:, :]], dim=-2)
    mean_x, mean_z = moving_average(step[..., 0], frames), moving_average(step[..., 1], frames)
    moving = torch.sqrt(mean_x ** 2 + mean_z ** 2) > min_step
    return torch.where(moving, direction_of(mean_x, mean_z), heading)


def facing_off_travel(root_positions: torch.Tensor, heading: torch.Tensor, frames: int) -> torch.Tensor:
    """Body heading minus the direction of travel (``path_direction`` over ``frames``), wrapped to [-π, π), per frame
    (..., T): near 0 walking forwards, ±π/2 side-stepping, near ±π walking backwards."""
    return wrap_angle(heading - path_direction(root_positions, heading, frames))


# ---------------------------------------------------------------------------------------------------- local frames


def to_local_frame(points: torch.Tensor, along: torch.Tensor, origin: torch.Tensor | None = None) -> torch.Tensor:
    """Ground points (..., 2) re-expressed in the frame whose origin is ``origin`` (..., 2) (default: (0, 0)) and
    whose +z is the unit direction ``along`` (..., 2) (``unit_direction``): x' to the left, z' ahead."""
    d = points if origin is None else points - origin
    s, c = along[..., 0], along[..., 1]
    return torch.stack((c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]), dim=-1)


def from_local_frame(points: torch.Tensor, along: torch.Tensor, origin: torch.Tensor | None = None) -> torch.Tensor:
    """The inverse of ``to_local_frame``: local ground points (..., 2) back to the frame they were taken from."""
    s, c = along[..., 0], along[..., 1]
    x, z = points[..., 0], points[..., 1]
    world = torch.stack((c * x + s * z, -s * x + c * z), dim=-1)
    return world if origin is None else world + origin


# ------------------------------------------------------------------------------------------------------- polylines


def segment_lengths(polyline: torch.Tensor, correctly_rounded: bool = False) -> torch.Tensor:
    """Lengths (..., K-1) of the segments of polylines (..., K, 2).

    ``correctly_rounded``: sqrt(dx² + dz²) rounded once, as IEEE 754 and numpy round it, instead of
    ``torch.linalg.vector_norm`` (which differs from it in the last bit for ~8% of float64 segments). The synthesis
    plan's trajectory pieces were cut with these lengths; one bit there moves a gait's start point when the start
    falls on a trajectory point."""
    d = polyline[..., 1:, :] - polyline[..., :-1, :]
    return _correctly_rounded_sqrt((d * d).sum(-1)) if correctly_rounded else torch.linalg.vector_norm(d, dim=-1)


def _correctly_rounded_sqrt(x: torch.Tensor) -> torch.Tensor:
    # torch's real sqrt here is not correctly rounded (~1% of float64 values are one ulp off numpy's and math's);
    # its complex sqrt of (x, 0) is libm's real sqrt, which is.
    return torch.sqrt(x.to(torch.complex128)).real.to(x.dtype)


def ground_speed(positions: torch.Tensor) -> torch.Tensor:
    """Ground distance (..., T-1) moved between consecutive frames of positions (..., T, 3) (m/frame)."""
    return segment_lengths(positions[..., [0, 2]])


def arc_lengths(polyline: torch.Tensor, correctly_rounded: bool = False) -> torch.Tensor:
    """Arc length (..., K) at each point of polylines (..., K, 2), from 0 at the first (``correctly_rounded``: see
    ``segment_lengths``)."""
    seg = segment_lengths(polyline, correctly_rounded)
    return torch.cat([torch.zeros_like(seg[..., :1]), seg.cumsum(-1)], dim=-1)


def point_at_arc(paths: torch.Tensor, cumulative: torch.Tensor, arc: torch.Tensor) -> torch.Tensor:
    """Points (N, 2), or (N, T, 2), at arc lengths ``arc`` (N,), or (N, T), along paths (N, K, 2) with arc lengths
    ``cumulative`` (N, K) (``arc_lengths``), each row along its own path; beyond the end the last segment is
    extended (before the start, the first)."""
    arcs = arc[:, None] if arc.dim() == 1 else arc
    k = torch.searchsorted(cumulative.contiguous(), arcs.contiguous()).clamp(1, paths.shape[1] - 1)
    a = torch.gather(paths, 1, (k - 1)[..., None].expand(-1, -1, 2))
    b = torch.gather(paths, 1, k[..., None].expand(-1, -1, 2))
    lo, hi = torch.gather(cumulative, 1, k - 1), torch.gather(cumulative, 1, k)
    u = ((arcs - lo) / (hi - lo).clamp_min(1e-9))[..., None]
    out = a + u * (b - a)
    return out[:, 0] if arc.dim() == 1 else out


def points_at_arcs(polyline: torch.Tensor, arcs: torch.Tensor) -> torch.Tensor:
    """Points (M, 2) at arc lengths ``arcs`` (M,) along one polyline (K, 2): linear between its points (repeated
    points dropped), straight on along its last segment past its end; lengths correctly rounded (the synthesis
    plan's pieces)."""
    s = arc_lengths(polyline, correctly_rounded=True)
    keep = torch.cat([torch.ones(1, dtype=torch.bool), (s[1:] - s[:-1]) > 1e-9])
    s, polyline = s[keep], polyline[keep]
    inside = arcs.clamp(0.0, float(s[-1]))
    out = torch.stack((_interpolate(inside, s, polyline[:, 0]), _interpolate(inside, s, polyline[:, 1])), dim=-1)
    ahead = polyline[-1] - polyline[-2]
    return out + (arcs - inside)[:, None] * ahead / _correctly_rounded_sqrt((ahead * ahead).sum())


def _interpolate(x: torch.Tensor, xp: torch.Tensor, fp: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear fp (K,) over increasing xp (K,) at x (M,) inside [xp[0], xp[-1]], with numpy.interp's
    arithmetic step for step (the plan's pieces were made with it): a knot's own value at a knot, else
    slope * (x - xp[j]) + fp[j]."""
    j = torch.searchsorted(xp, x, right=True) - 1  # xp[j] <= x < xp[j + 1]
    last = xp.shape[0] - 1
    lo = j.clamp(0, last - 1)
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    value = slope * (x - xp[lo]) + fp[lo]
    return torch.where(j >= last, fp[last], torch.where(xp[lo] == x, fp[lo], value))


def resample_polyline(polyline: torch.Tensor, spacing: float, length: float | None = None) -> torch.Tensor:
    """Points (M, 2) every ``spacing`` of arc length along a polyline (K, 2), from its start up to ``length``
    (default: all of it); see ``points_at_arcs``."""
    total = float(arc_lengths(polyline, correctly_rounded=True)[-1]) if length is None else length
    count = int(math.floor(total / spacing + 1e-9)) + 1
    return points_at_arcs(polyline, torch.arange(count, dtype=polyline.dtype) * spacing)


def _segment_projection(points: torch.Tensor, paths: torch.Tensor
                        ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Points (..., P, 2) projected onto every segment of paths (..., K, 2): the fraction along the segment
    (..., P, K-1) in [0, 1] of the closest point, the distance to it (..., P, K-1) and the squared segment lengths
    (..., 1, K-1)."""
    a, b = paths[..., None, :-1, :], paths[..., None, 1:, :]
    ab = b - a
    length2 = (ab * ab).sum(-1).clamp_min(1e-12)
    u = (((points[..., :, None, :] - a) * ab).sum(-1) / length2).clamp(0.0, 1.0)
    distance = torch.linalg.vector_norm(points[..., :, None, :] - (a + u[..., None] * ab), dim=-1)
    return u, distance, length2


def closest_arc(points: torch.Tensor, paths: torch.Tensor, cumulative: torch.Tensor) -> torch.Tensor:
    """Arc length (N,) along paths (N, K, 2) (arc lengths ``cumulative`` (N, K)) of their point closest to points
    (N, 2)."""
    u, distance, length2 = _segment_projection(points[:, None], paths)
    k = distance[:, 0].argmin(-1)
    rows = torch.arange(len(points))
    return cumulative[rows, k] + u[rows, 0, k] * torch.sqrt(length2[rows, 0, k])


def distance_to_polyline(points: torch.Tensor, paths: torch.Tensor) -> torch.Tensor:
    """Distance (N, S) of ground points (N, S, 2) to the polylines paths (N, K, 2)."""
    return _segment_projection(points, paths)[1].min(-1).values


def path_turns(path: torch.Tensor, frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    """How a ground path (..., T, 2) curls: per path the largest turn (radians, >= 0) of its step direction within
    ``frames`` frames (>= 2; over 3π/2: a small loop, a walk's sharpest corner turns far less), and per step
    whether it points against the displacement over ``frames`` frames around it, (..., T - 2 (frames // 2)) bool,
    for the steps from ``frames // 2 - 1`` on. The step direction is unwrapped frame to frame (a step turns by
    less than π from the one before)."""
    step = path[..., 1:, :] - path[..., :-1, :]
    direction = direction_of(step[..., 0], step[..., 1])
    turned = torch.cumsum(wrap_angle(direction[..., 1:] - direction[..., :-1]), -1)
    turning = torch.cat([torch.zeros_like(turned[..., :1]), turned], -1)  # from the first step's direction
    largest = (turning[..., frames:] - turning[..., :-frames]).abs().amax(-1)
    half = frames // 2
    local = path[..., 2 * half:, :] - path[..., :-2 * half, :]
    against = (step[..., half - 1:half - 1 + local.shape[-2], :] * local).sum(-1) < 0
    return largest, against


# ---------------------------------------------------------------------------------------------------------- angles


def wrap_phase(a: torch.Tensor) -> torch.Tensor:
    """Angles (...) wrapped to [0, 2π) (a stepping phase, a phase's rate)."""
    return torch.remainder(a, 2 * math.pi)


def wrap_angle(a: torch.Tensor) -> torch.Tensor:
    """Angles (...) wrapped to [-π, π) (a turn, a difference of directions)."""
    return wrap_phase(a + math.pi) - math.pi


def wrap_angle_atan2(a: torch.Tensor) -> torch.Tensor:
    """Angles (...) wrapped to (-π, π] as atan2(sin a, cos a): the generator's training loss wraps this way (its
    checkpoints were trained with these roundings, which differ from ``wrap_angle``'s)."""
    return torch.atan2(torch.sin(a), torch.cos(a))


def pursue(travel: torch.Tensor, ground: torch.Tensor, paths: torch.Tensor, cumulative: torch.Tensor,
           lookahead_m: float, max_turn: float, offset: torch.Tensor | float = 0.0) -> torch.Tensor:
    """Pure pursuit: directions of travel (N,) turned towards the point ``lookahead_m`` ahead on paths (N, K, 2)
    (arc lengths ``cumulative``) of the one closest to ground points (N, 2), by at most ``max_turn`` rad; ``offset``
    (N,) is subtracted from the wanted direction (a body whose steps run at that angle to its travel)."""
    arc = closest_arc(ground, paths, cumulative)
    target = point_at_arc(paths, cumulative, arc + lookahead_m)
    wanted = direction_of(target[:, 0] - ground[:, 0], target[:, 1] - ground[:, 1])
    return travel + wrap_angle(wanted - offset - travel).clamp(-max_turn, max_turn)


# ------------------------------------------------------------------------------------------------------------ axes


def to_y_up(points: torch.Tensor, axes: tuple[tuple[int, ...], ...]) -> torch.Tensor:
    """Points (..., 3) from a source's axes onto Y up: ``axes`` (3 rows of 3) gives each canonical axis in the
    source's axes (a signed permutation, e.g. Z up: ((1, 0, 0), (0, 0, 1), (0, -1, 0)))."""
    return points @ torch.tensor(axes, dtype=points.dtype).T


# ---------------------------------------------------------------------------------------------------- along time


def sliding_windows(x: torch.Tensor, frames: int) -> torch.Tensor:
    """Centred windows (..., T, frames) of an odd length along the last axis of x (..., T), edges replicated (a
    view of the padded signal)."""
    half = frames // 2
    padded = torch.cat([x[..., :1].expand(*x.shape[:-1], half), x, x[..., -1:].expand(*x.shape[:-1], half)], -1)
    return padded.unfold(-1, frames, 1)


def odd_frames(seconds: float, fps: float) -> int:
    """An odd window length (>= 1 frame) nearest ``seconds`` at ``fps`` (a centred window needs one)."""
    return max(1, int(round(seconds * fps)) // 2 * 2 + 1)


def moving_average(x: torch.Tensor, frames: int) -> torch.Tensor:
    """Centred moving average along the last axis, odd window, edges replicated; (..., T) -> (..., T)."""
    if frames <= 1:
        return x
    return sliding_windows(x, frames).mean(-1)
