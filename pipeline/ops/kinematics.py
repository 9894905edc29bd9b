"""Forward kinematics: the one implementation used by ingest, annotation, training and export.

A skeleton is a parent list in topological order (parents[j] < j, the root has parent -1). We use the
paper's per-bone form (§3.2.1): joint j's rotation turns *its own* rest offset o_j (the bone from its
parent to j) into the posed bone, and rotations compose down the tree:

    G_j = G_parent(j) q_j,     X_j = X_parent(j) + G_j o_j,     X_0 = root position.

Every bone therefore has its own rotation, so the three bones leaving the pelvis (and the chest) can
each follow the source's direction exactly. The classic BVH form (a joint's rotation moves its
*children*) is the same computation with each rotation moved one level down: see
``rotations_from_bvh_form``.

This module knows arrays only: not files, not sources, not features.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import torch

from pipeline.ops.quaternion import qmul, qrot


def forward_kinematics(
    rotations: torch.Tensor,
    translations: torch.Tensor,
    parents: Sequence[int],
) -> tuple[torch.Tensor, torch.Tensor]:
    """Joint positions and global rotations (per-bone form, see module docstring).

    rotations:    (..., J, 4) unit quaternions local to the parent's bone frame.
    translations: (..., J, 3) or (J, 3); row 0 is the root's world position, row j the rest offset o_j.
    parents:      length-J parent indices, topologically ordered, parents[0] == -1.
    Returns positions (..., J, 3) and global rotations (..., J, 4).

    Joints of one depth are computed together (7 levels for the canonical skeleton instead of 20 joints one
    by one): the same products per joint, so the same numbers, in fewer and larger tensor operations. A joint's
    parent is always one level up, so each level reads only the level before it.
    """
    translations = translations.expand(rotations.shape[:-1] + (3,))
    levels, inverse = _levels(tuple(parents), str(rotations.device))
    globals_ = [rotations[..., :1, :]]
    positions = [translations[..., :1, :]]
    for joints, parent_slots in levels:
        g = qmul(globals_[-1].index_select(-2, parent_slots), rotations.index_select(-2, joints))
        positions.append(positions[-1].index_select(-2, parent_slots) + qrot(g, translations.index_select(-2, joints)))
        globals_.append(g)
    return (torch.cat(positions, dim=-2).index_select(-2, inverse),
            torch.cat(globals_, dim=-2).index_select(-2, inverse))


@functools.lru_cache(maxsize=32)
def _levels(parents: tuple[int, ...], device: str) -> tuple[tuple, torch.Tensor]:
    """Joints grouped by depth: (((joints, their parents' slots in the level above), ...), the permutation from
    the levels' order back to joint order)."""
    if parents[0] >= 0 or any(p >= j for j, p in enumerate(parents) if j):
        raise ValueError(f"parents must be topologically ordered with the root first, found {list(parents)}")
    depth = [0] * len(parents)
    for j, p in enumerate(parents[1:], start=1):
        depth[j] = depth[p] + 1
    order = [0]
    above = [0]
    levels = []
    for d in range(1, max(depth) + 1):
        joints = [j for j in range(len(parents)) if depth[j] == d]
        slots = [above.index(parents[j]) for j in joints]
        levels.append((torch.tensor(joints, device=device), torch.tensor(slots, device=device)))
        order += joints
        above = joints
    inverse = torch.tensor([order.index(j) for j in range(len(parents))], device=device)
    return tuple(levels), inverse


def rotations_from_bvh_form(joint_rotations: torch.Tensor, parents: Sequence[int]) -> torch.Tensor:
    """Per-bone rotations equivalent to BVH-style rotations (where q_j moves j's children).

    joint_rotations: (..., J, 4). Returns (..., J, 4): bone j takes its parent's rotation; the root
    bone has none (identity), because BVH does not rotate the root translation.
    """
    idx = torch.tensor([max(p, 0) for p in parents], device=joint_rotations.device)
    moved = joint_rotations.index_select(-2, idx).clone()
    moved[..., 0, :] = moved.new_tensor([1.0, 0.0, 0.0, 0.0])
    return moved


def canonical_kinematics(
    root_positions: torch.Tensor,
    rotations: torch.Tensor,
    offsets: torch.Tensor,
    parents: Sequence[int],
) -> tuple[torch.Tensor, torch.Tensor]:
    """Positions (..., J, 3) and global rotations (..., J, 4) on a fixed-offset skeleton (the canonical one).

    root_positions: (..., 3); rotations: (..., J, 4); offsets: (J, 3) rest offsets (row 0 unused).
    """
    translations = torch.cat(
        [root_positions.unsqueeze(-2), offsets[1:].expand(rotations.shape[:-2] + offsets[1:].shape)], dim=-2
    )
    return forward_kinematics(rotations, translations, parents)


def canonical_positions(
    root_positions: torch.Tensor,
    rotations: torch.Tensor,
    offsets: torch.Tensor,
    parents: Sequence[int],
) -> torch.Tensor:
    """Positions (..., J, 3) on a fixed-offset skeleton (``canonical_kinematics`` without the global rotations)."""
    return canonical_kinematics(root_positions, rotations, offsets, parents)[0]
