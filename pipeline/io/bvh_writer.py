"""BVH export: one gait on the canonical skeleton as a standard BVH file (Blender, MotionBuilder, ...).

Our rotations are per-bone (q_j turns bone j's own offset o_j; see ``pipeline.ops.kinematics``); BVH's are
classic (a joint's rotation turns the offsets of its *children*). The two agree when every BVH joint sits
at the start of exactly one bone and carries that bone's rotation: the joint at canonical joint p carries
q_c of its only child c. Where several bones leave one joint (the pelvis: both hips and the lower back;
the chest: neck and both shoulders) each bone gets its own zero-offset joint ``<parent>_to_<child>``,
so every bone keeps its own direction exactly. The exported hierarchy (27 joints, 84 channels) is

    root                              6 channels: position, then q_root (pelvis orientation and heading)
      root_to_left_hip                q_left_hip          (OFFSET 0: sits at the pelvis)
        left_hip                      q_left_knee         (OFFSET o_left_hip)
          left_knee                   q_left_heel
            left_heel                 q_left_toe
              left_toe                identity, End Site
      root_to_right_hip ...           (mirror of the left leg)
      root_to_lower_back              q_lower_back
        lower_back                    q_spine
          spine                       identity (its three bones have their own joints)
            spine_to_neck             q_neck
              neck                    q_head
                head                  identity, End Site
            spine_to_left_shoulder    q_left_shoulder
              left_shoulder           q_left_elbow
                left_elbow            q_left_hand
                  left_hand           q_left_hand_index
                    left_hand_index   identity, End Site
            spine_to_right_shoulder ...

Every joint has a rotation channel triple (zero where it carries none), so the rest pose is all zeros and the
file's OFFSETs are the canonical rest offsets. End Sites are drawing stubs (a quarter of the leaf bone, along
it) and carry no data. Units: centimetres (the usual BVH unit; Blender: import with scale 0.01), degrees,
rotation order ZXY (intrinsic, as BVH defines it), Y up, +Z forward. The root OFFSET is zero and its position
channels are absolute. Angles are unwrapped over time so interpolating viewers do not spin.

An exporter: it knows arrays and the canonical skeleton, not sources or the gait table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from pipeline.ops.quaternion import qnormalize, quat_to_euler
from pipeline.io.files import write_bytes
from pipeline.core.skeleton import Skeleton

CM_PER_M = 100.0
ROTATION_ORDER = "ZXY"
END_SITE_FRACTION = 0.25  # End Site stub length as a fraction of the leaf bone
DECIMALS = 6  # fixed-point digits of every number written: deterministic text, ~1e-8 rad / 1e-8 cm


@dataclass(frozen=True)
class ExportJoint:
    """One BVH joint. ``bone`` is the canonical joint whose per-bone rotation it carries (-1: identity)."""

    name: str
    parent: int  # index into the exported joint list, -1 for the root
    offset_m: tuple[float, float, float]
    bone: int
    end_site_m: tuple[float, float, float] | None = None


def export_hierarchy(skeleton: Skeleton) -> tuple[ExportJoint, ...]:
    """The exported joints in file (depth-first) order; see the module docstring for the design."""
    children = [[c for c, p in enumerate(skeleton.parents) if p == j] for j in range(skeleton.joint_count)]
    joints: list[ExportJoint] = []

    def emit(j: int, parent: int, offset: np.ndarray) -> None:
        kids = children[j]
        branching = j == 0 or len(kids) > 1  # these bones need joints of their own
        bone = 0 if j == 0 else (kids[0] if len(kids) == 1 else -1)
        end = None if kids else tuple(float(v) for v in END_SITE_FRACTION * skeleton.offsets[j])
        joints.append(ExportJoint(skeleton.names[j], parent, tuple(float(v) for v in offset), bone, end))
        me = len(joints) - 1
        for c in kids:
            if branching:
                joints.append(ExportJoint(f"{skeleton.names[j]}_to_{skeleton.names[c]}", me, (0.0, 0.0, 0.0), c))
                emit(c, len(joints) - 1, skeleton.offsets[c])
            else:
                emit(c, me, skeleton.offsets[c])

    emit(0, -1, np.zeros(3))
    return tuple(joints)


def motion_channels(rotations: torch.Tensor | np.ndarray, root_positions: torch.Tensor | np.ndarray,
                    skeleton: Skeleton) -> np.ndarray:
    """The MOTION values (T, 6 + 3 * (joints - 1)): root position in cm, then per joint ZXY angles in degrees.

    rotations: (T, J, 4) per-bone local quaternions; root_positions: (T, 3) metres.
    """
    rot = qnormalize(torch.as_tensor(rotations, dtype=torch.float64))
    root = torch.as_tensor(root_positions, dtype=torch.float64)
    frames = rot.shape[0]
    if rot.shape[1:] != (skeleton.joint_count, 4) or root.shape != (frames, 3):
        raise ValueError(f"expected rotations (T, {skeleton.joint_count}, 4) and root positions (T, 3), "
                         f"found {tuple(rot.shape)} and {tuple(root.shape)}")
    if frames == 0 or not (bool(torch.isfinite(rot).all()) and bool(torch.isfinite(root).all())):
        raise ValueError("expected at least one frame of finite rotations and root positions")
    angles = np.degrees(quat_to_euler(rot, ROTATION_ORDER).numpy())  # (T, J, 3)
    columns = [root.numpy() * CM_PER_M]
    for joint in export_hierarchy(skeleton):
        columns.append(angles[:, joint.bone] if joint.bone >= 0 else np.zeros((frames, 3)))
    values = np.concatenate(columns, axis=1)
    values[:, 3:] = np.unwrap(values[:, 3:], period=360.0, axis=0)
    return values


def _number(value: float) -> str:
    return f"{round(float(value), DECIMALS) + 0.0:.{DECIMALS}f}"  # + 0.0: never print "-0.000000"


def _hierarchy_lines(joints: tuple[ExportJoint, ...]) -> list[str]:
    children = [[c for c, jt in enumerate(joints) if jt.parent == j] for j in range(len(joints))]
    rot = " ".join(f"{axis}rotation" for axis in ROTATION_ORDER)
    lines = ["HIERARCHY"]

    def offset(values_m: tuple[float, ...]) -> str:
        return "OFFSET " + " ".join(_number(v * CM_PER_M) for v in values_m)

    def emit(j: int, depth: int) -> None:
        pad, joint = "\t" * depth, joints[j]
        lines.append(f"{pad}{'ROOT' if joint.parent < 0 else 'JOINT'} {joint.name}")
        lines.append(pad + "{")
        lines.append(f"{pad}\t{offset(joint.offset_m)}")
        channels = f"6 Xposition Yposition Zposition {rot}" if joint.parent < 0 else f"3 {rot}"
        lines.append(f"{pad}\tCHANNELS {channels}")
        for c in children[j]:
            emit(c, depth + 1)
        if joint.end_site_m is not None:
            lines.extend([f"{pad}\tEnd Site", pad + "\t{", f"{pad}\t\t{offset(joint.end_site_m)}", pad + "\t}"])
        lines.append(pad + "}")

    emit(0, 0)
    return lines


def bvh_text(rotations: torch.Tensor | np.ndarray, root_positions: torch.Tensor | np.ndarray,
             skeleton: Skeleton, fps: float) -> str:
    """The BVH file's text for one gait (see the module docstring); the same input gives the same text."""
    if not fps > 0:
        raise ValueError(f"expected a positive frame rate, found {fps}")
    values = motion_channels(rotations, root_positions, skeleton)
    lines = _hierarchy_lines(export_hierarchy(skeleton))
    lines += ["MOTION", f"Frames: {values.shape[0]}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(_number(v) for v in row) for row in values]
    return "\n".join(lines) + "\n"


def bvh_file_name(gait_id: str) -> str:
    """A file name for a gait's BVH: its id with path and fragment separators made plain."""
    return gait_id.replace("/", "_").replace("#", "_") + ".bvh"


def write_bvh(path: str | Path, rotations: torch.Tensor | np.ndarray, root_positions: torch.Tensor | np.ndarray,
              skeleton: Skeleton, fps: float) -> None:
    """Write ``bvh_text`` atomically (temporary file + rename), so a reader never sees half a file."""
    data = bvh_text(rotations, root_positions, skeleton, fps).encode("ascii")
    write_bytes(data, path)
