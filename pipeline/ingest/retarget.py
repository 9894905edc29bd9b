"""Retargeting: a source skeleton's motion onto the canonical 21-joint skeleton.

Steps: source joint positions by forward kinematics -> the manifest's joint map picks (or
combines, for virtual joints) the source points that sit at each canonical joint -> each canonical
bone keeps its source *direction* and takes its canonical *length* -> per-bone local rotations relative
to the canonical rest pose (shortest arc in the parent bone's frame, so no twist is invented) -> the
root path scaled by the canonical/source leg-length ratio.

A transform: it knows arrays and joint names, never files or sources.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.ops.geometry import to_y_up
from pipeline.ops.kinematics import forward_kinematics, rotations_from_bvh_form
from pipeline.ops.quaternion import euler_to_quat, matrix_to_quat, qbetween, qconj, qfix, qmul, qrot
from pipeline.io.readers.bvh import BvhClip
from pipeline.core.skeleton import Skeleton
from pipeline.io.manifests import AXES_TO_Y_UP


class RetargetError(ValueError):
    """The motion cannot be mapped onto the canonical skeleton; the message names frame and joint."""


@dataclass(frozen=True)
class CanonicalMotion:
    root_positions: torch.Tensor  # (F, 3) metres, canonical scale
    rotations: torch.Tensor  # (F, J, 4) per-bone local rotations, hemisphere-continuous
    scale: float  # canonical leg length / source leg length (source units -> metres of the canonical body)
    source_leg_m: float  # source leg length in metres (by the manifest's unit scale)


def referenced_points(joint_map: Mapping[str, Any]) -> list[str]:
    """Every source point name a joint map uses."""
    names: list[str] = []
    for value in joint_map.values():
        names.extend([value] if isinstance(value, str) else list(value))
    return names


def bvh_point_positions(clips: Sequence[BvhClip], points: Sequence[str], root_offset: str,
                        up_axis: str) -> torch.Tensor:
    """World positions (sum of frames, len(points), 3) of named joints / End Sites, source units, Y up.

    clips: one or more clips with the same hierarchy layout (names, parents, channels); their frames are
    stacked so forward kinematics runs once for all of them. OFFSETs may differ between the clips.
    Only the joints on the paths from the root to the requested points are evaluated.
    root_offset: "add" (root position channels are relative to the ROOT OFFSET) or "ignore" (absolute).
    """
    skel = clips[0].skeleton
    missing = [p for p in points if p not in skel.names]
    if missing:
        raise RetargetError(f"the joint map names {missing} which the file lacks (it has {len(skel.names)} joints)")
    starts = np.cumsum([0] + [len(c) for c in skel.channels])  # first motion column of each joint
    keep: set[int] = set()
    for p in points:
        j = skel.index(p)
        while j >= 0 and j not in keep:
            keep.add(j)
            j = skel.parents[j]
    order = sorted(keep)
    remap = {j: k for k, j in enumerate(order)}
    parents = [remap.get(skel.parents[j], -1) for j in order]
    motion = np.concatenate([c.motion for c in clips], dtype=np.float32)  # ample for mm; halves memory traffic
    frames = motion.shape[0]
    offsets = np.stack([c.skeleton.offsets[order] for c in clips]).astype(np.float32)  # (clips, J, 3)
    if (offsets == offsets[0]).all():
        trans = np.repeat(offsets[:1], frames, axis=0)
    else:  # e.g. Bandai: every file has its own Hips OFFSET (a start position)
        trans = np.repeat(offsets, [c.frames for c in clips], axis=0)
    root_base = trans[:, 0].copy()
    groups: dict[str, tuple[list[int], list[list[int]]]] = {}  # rotation order -> (joints, motion columns)
    for k, j in enumerate(order):
        rot_axes = ""
        rot_cols: list[int] = []
        for c, name in enumerate(skel.channels[j]):
            col = starts[j] + c
            axis = "XYZ".index(name[0])
            if name.endswith("position"):
                add_offset = skel.parents[j] < 0 and root_offset == "add"
                trans[:, k, axis] = motion[:, col] + root_base[:, axis] if add_offset else motion[:, col]
            else:
                rot_axes += name[0]
                rot_cols.append(col)
        if rot_axes:
            ks, cols = groups.setdefault(rot_axes, ([], []))
            ks.append(k)
            cols.append(rot_cols)
    to_rad = np.float32(np.pi / 180.0)
    if len(groups) == 1 and len(next(iter(groups.values()))[0]) == len(order):
        (axes, (_, cols)), = groups.items()  # the usual case: one rotation order on every joint
        rot = euler_to_quat(torch.from_numpy(motion[:, np.asarray(cols)]) * to_rad, axes)
    else:
        rot = torch.zeros(frames, len(order), 4)
        rot[..., 0] = 1.0
        for axes, (ks, cols) in groups.items():
            rot[:, ks] = euler_to_quat(torch.from_numpy(motion[:, np.asarray(cols)]) * to_rad, axes)
    positions, _ = forward_kinematics(rotations_from_bvh_form(rot, parents), torch.from_numpy(trans), parents)
    selected = positions.index_select(-2, torch.tensor([remap[skel.index(p)] for p in points]))
    if up_axis == "+Y":
        return selected
    return to_y_up(selected, AXES_TO_Y_UP[up_axis])


def map_joints(point_names: Sequence[str], point_positions: torch.Tensor, joint_map: Mapping[str, Any],
               skeleton: Skeleton) -> torch.Tensor:
    """Canonical joint positions (F, 21, 3) from source points by the joint map.

    A map value is a point name, or {point: weight, ...}: an affine combination (weights sum to 1) that
    defines a virtual joint, e.g. a fingertip extended along the forearm.
    """
    columns = {name: k for k, name in enumerate(point_names)}
    out = []
    for joint in skeleton.names:
        if joint not in joint_map:
            raise RetargetError(f"the joint map has no entry for canonical joint {joint!r}")
        value = joint_map[joint]
        if isinstance(value, str):
            out.append(point_positions[:, columns[value]])
        else:
            weights = {k: float(w) for k, w in value.items()}
            if abs(sum(weights.values()) - 1.0) > 1e-9:
                raise RetargetError(f"virtual joint {joint!r}: weights must sum to 1, found {sum(weights.values())}")
            out.append(sum(w * point_positions[:, columns[k]] for k, w in weights.items()))
    return torch.stack(out, dim=1)


def source_leg_length(points: torch.Tensor, skeleton: Skeleton) -> float:
    """Median over frames of the mean leg length (hip->knee + knee->ankle), in the points' units."""
    legs = sum((points[:, c] - points[:, p]).norm(dim=-1) for p, c in skeleton.leg_bones) / 2.0
    return float(legs.median())


def check_source_body(points: torch.Tensor, skeleton: Skeleton, unit_scale_m: float,
                      leg_range_m: tuple[float, float] = (0.4, 1.4)) -> tuple[float, float]:
    """Validate one clip's mapped points; return (scale, source leg length in metres).

    points: (F, 21, 3) source positions of the canonical joints. Raises RetargetError naming the frame
    and bone when a bone has no length (no direction to keep) or the legs are not human-sized.
    """
    parents = skeleton.parents
    leg = source_leg_length(points, skeleton)
    leg_m = leg * unit_scale_m
    if not leg_range_m[0] <= leg_m <= leg_range_m[1]:
        raise RetargetError(
            f"leg length {leg_m:.3f} m (at {unit_scale_m} m per unit) is outside the human range "
            f"{leg_range_m[0]}-{leg_range_m[1]} m: check the manifest's units"
        )
    lengths = (points[:, 1:] - points[:, list(parents[1:])]).norm(dim=-1)
    degenerate = lengths < 1e-3 * leg
    if bool(degenerate.any()):
        f, b = (int(x) for x in degenerate.nonzero()[0])
        j = b + 1
        raise RetargetError(
            f"frame {f}: bone {skeleton.names[parents[j]]}->{skeleton.names[j]} has length "
            f"{float(lengths[f, b]):.3g} source units; expected a non-zero bone to take its direction from"
        )
    return skeleton.leg_length / leg, leg_m


def bone_rotations(points: torch.Tensor, skeleton: Skeleton) -> torch.Tensor:
    """Per-bone local rotations (F, 21, 4) that give every canonical bone the direction it has in ``points``.

    points: (F, 21, 3) positions of the canonical joints in any units (frames of several clips may be
    stacked: each frame is solved on its own). Not yet hemisphere-continuous: see ``qfix``.
    """
    # Work in level order (joints sorted by depth) so that each depth level is a contiguous slice.
    order = [j for level in skeleton.depth_levels for j in level]
    position_in_order = {j: k for k, j in enumerate(order)}
    parents = skeleton.parents
    idx = torch.tensor(order)
    parent_idx = torch.tensor([parents[j] if parents[j] >= 0 else 0 for j in order])
    pts = points.index_select(1, idx)
    bones = pts - points.index_select(1, parent_idx)  # (F, 21, 3) in level order; row 0 unused
    rest = torch.from_numpy(skeleton.offsets[order]).to(points)
    rest = rest / rest.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    # Root: pelvis frame from the hip axis (the body's left, +X at rest) and the lower back (up, +Y).
    left = points[:, skeleton.index("left_hip")] - points[:, skeleton.index("right_hip")]
    up = points[:, skeleton.index("lower_back")] - points[:, 0]
    x = left / left.norm(dim=-1, keepdim=True)
    z = torch.cross(x, up, dim=-1)
    z = z / z.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    y = torch.cross(z, x, dim=-1)
    root = matrix_to_quat(torch.stack((x, y, z), dim=-1))
    local = [root.unsqueeze(1)]
    glob = [root.unsqueeze(1)]  # global rotations, level by level, in level order
    start = 1
    for level in skeleton.depth_levels[1:]:
        stop = start + len(level)
        parent_glob = torch.cat(glob, dim=1).index_select(
            1, torch.tensor([position_in_order[parents[j]] for j in level]))
        # The shortest arc from the rest offset to the posed direction, in the parent bone's frame.
        direction = qrot(qconj(parent_glob), bones[:, start:stop])
        q = qbetween(rest[start:stop].expand_as(direction), direction)
        local.append(q)
        glob.append(qmul(parent_glob, q))
        start = stop
    inverse = torch.tensor([position_in_order[j] for j in range(len(order))])
    return torch.cat(local, dim=1).index_select(1, inverse)


def retarget_to_canonical(points: torch.Tensor, skeleton: Skeleton, unit_scale_m: float) -> CanonicalMotion:
    """One clip: root path and hemisphere-continuous per-bone rotations on the canonical skeleton.

    points: (F, 21, 3) source positions of the canonical joints (source units, Y up).
    """
    scale, leg_m = check_source_body(points, skeleton, unit_scale_m)
    return CanonicalMotion(
        root_positions=points[:, 0] * scale,
        rotations=qfix(bone_rotations(points, skeleton), dim=0),
        scale=scale,
        source_leg_m=leg_m,
    )
