"""Pose affective features and root movement features (the paper §3.2.3-3.2.4), in torch.

The one implementation: annotation calls these on stored positions, the generator's losses will call them
on forward kinematics of predicted rotations (``pose_affective_features``), so the two can never drift.
All functions are differentiable and batched over leading dimensions.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from pipeline.ops.geometry import ground_speed, moving_average
from pipeline.ops.kinematics import canonical_positions

# The 18 affective features, indices in the canonical 21-joint numbering, in the paper's released order.
#   ("angle", (a, v, b))          angle at v between a and b (radians)
#   ("distance_ratio", (a, b, c, d))   d(a, b) / d(c, d)
#   ("area_ratio", (a, b, c, d, e, f)) area(a, b, c) / area(d, e, f), areas by Heron's formula
AFFECTIVE_FEATURES: tuple[tuple[str, tuple[int, ...]], ...] = (
    ("angle", (17, 9, 13)),  # shoulders seen from the lower back
    ("angle", (19, 9, 15)),  # hands seen from the lower back
    ("distance_ratio", (16, 11, 16, 0)),
    ("distance_ratio", (20, 11, 20, 0)),
    ("distance_ratio", (16, 20, 11, 0)),
    ("area_ratio", (17, 9, 13, 17, 0, 13)),
    ("area_ratio", (19, 9, 15, 19, 0, 15)),
    ("angle", (13, 14, 15)),  # left elbow
    ("angle", (17, 18, 19)),  # right elbow
    ("angle", (12, 11, 13)),
    ("angle", (12, 11, 17)),
    ("angle", (12, 0, 2)),
    ("angle", (12, 0, 6)),
    ("distance_ratio", (4, 8, 11, 0)),
    ("angle", (8, 0, 4)),
    ("angle", (1, 2, 3)),  # left knee
    ("angle", (5, 6, 7)),  # right knee
    ("area_ratio", (20, 11, 16, 8, 0, 4)),
)
AFFECTIVE_NAMES = tuple(f"{kind}_{'_'.join(map(str, joints))}" for kind, joints in AFFECTIVE_FEATURES)
MOVEMENT_NAMES = ("root_height", "root_speed", "root_speed_lowpass", "heading_to_path_angle", "path_curvature")

_EPS = 1e-12


def angle_at(a: torch.Tensor, v: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angle (radians, [0, π]) at v between a and b; (..., 3) -> (...). atan2 form: exact near 0 and π."""
    u, w = a - v, b - v
    return torch.atan2(torch.linalg.vector_norm(torch.cross(u, w, dim=-1), dim=-1), (u * w).sum(-1))


def distance(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return torch.linalg.vector_norm(a - b, dim=-1)


def heron_area(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """Triangle area from its side lengths (Heron, in Kahan's numerically stable ordering); (..., 3) -> (...)."""
    sides = torch.stack((distance(a, b), distance(b, c), distance(c, a)), dim=-1)
    x, y, z = torch.sort(sides, dim=-1, descending=True).values.unbind(-1)  # x >= y >= z
    product = (x + (y + z)) * (z - (x - y)) * (z + (x - y)) * (x + (y - z))
    return 0.25 * torch.sqrt(product.clamp_min(_EPS * _EPS))


def affective_features(positions: torch.Tensor) -> torch.Tensor:
    """The 18 affective features per frame: positions (..., 21, 3) -> (..., 18). Scale and rotation free."""
    p = positions.unbind(-2)
    out = []
    for kind, j in AFFECTIVE_FEATURES:
        if kind == "angle":
            out.append(angle_at(p[j[0]], p[j[1]], p[j[2]]))
        elif kind == "distance_ratio":
            out.append(distance(p[j[0]], p[j[1]]) / distance(p[j[2]], p[j[3]]).clamp_min(_EPS))
        else:
            out.append(heron_area(p[j[0]], p[j[1]], p[j[2]]) / heron_area(p[j[3]], p[j[4]], p[j[5]]).clamp_min(_EPS))
    return torch.stack(out, dim=-1)


def pose_affective_features(root_positions: torch.Tensor, rotations: torch.Tensor, offsets: torch.Tensor,
                            parents: Sequence[int]) -> torch.Tensor:
    """Affective features of poses given as rotations (the generator's path): FK, then the same features."""
    return affective_features(canonical_positions(root_positions, rotations, offsets, parents))


def body_heading(positions: torch.Tensor, left_hip: int = 1, right_hip: int = 5) -> torch.Tensor:
    """Unit heading vectors (..., 2) in the ground plane as (x, z): perpendicular to the hip axis, forward.

    From positions only (forward = hip axis x up), so it applies equally to predicted poses.
    """
    across = positions[..., left_hip, :] - positions[..., right_hip, :]
    forward = torch.stack((-across[..., 2], across[..., 0]), dim=-1)
    return forward / torch.linalg.vector_norm(forward, dim=-1, keepdim=True).clamp_min(_EPS)


def movement_features(positions: torch.Tensor, lowpass_frames: int) -> torch.Tensor:
    """Root movement features per frame: positions (..., T, 21, 3) -> (..., T, 5) in MOVEMENT_NAMES order.

    h: root height minus its mean over the sequence; s: ground-plane root displacement per frame (s^0 = s^1);
    s̄: s low-passed (moving average of ``lowpass_frames``); δ: unsigned angle between the body heading and
    the path tangent τ^t = p^{t+1} − p^t (0 where the root does not move); κ = ‖τ^t − τ^{t−1}‖ (κ^0 = κ^1).
    """
    root = positions[..., 0, :]
    height = root[..., 1] - root[..., 1].mean(dim=-1, keepdim=True)
    ground = root[..., [0, 2]]
    tangent = ground[..., 1:, :] - ground[..., :-1, :]  # (..., T-1, 2)
    step = ground_speed(root)
    speed = torch.cat([step[..., :1], step], dim=-1)
    tangent = torch.cat([tangent, tangent[..., -1:, :]], dim=-2)  # forward difference, last repeated
    heading = body_heading(positions)
    cross = heading[..., 0] * tangent[..., 1] - heading[..., 1] * tangent[..., 0]
    dot = (heading * tangent).sum(-1)
    moving = torch.linalg.vector_norm(tangent, dim=-1) > 1e-6
    delta = torch.where(moving, torch.atan2(cross.abs(), dot), torch.zeros_like(dot))
    turn = torch.linalg.vector_norm(tangent[..., 1:, :] - tangent[..., :-1, :], dim=-1)
    curvature = torch.cat([turn[..., :1], turn], dim=-1)
    return torch.stack((height, speed, moving_average(speed, lowpass_frames), delta, curvature), dim=-1)
