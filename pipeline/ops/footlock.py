"""Foot locking: the horizontal slide of a stance foot taken out by two-bone leg IK (foot-skate cleanup after
Kovar, Schreiner & Gleicher, SCA 2002), batched over gaits.

A generated pose need not keep a planted foot still: the root placement (``generators.autoregressive.rollout``)
pins only the lowest heel/toe point, so the other foot in double support, or the toe while the heel is lowest,
can slide. Here, per foot, while its heel or toe is in contact (``ops.contacts.foot_contacts``, the annotation's
rule), the contact point (the heel while it is down, else the toe) is held where it was at the start of the
stance: its horizontal drift is accumulated into an offset, and the foot (ankle and toe together, its world
orientation kept) is moved back by it. The hip stays; the thigh and shin turn in the leg's own bending plane to
reach the moved ankle (law of cosines), the knee staying on the side it bends to. Between stances the offset
returns linearly to zero, so the swing foot lands where the network put it. Heights are left as they are.

Rotations are per bone (``ops.kinematics``): joint knee's rotation orients the thigh, ankle's the shin, toe's the
foot. Arrays in, arrays out; this module never knows where a gait came from.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from pipeline.core.skeleton import canonical_skeleton
from pipeline.ops.contacts import CONTACT_POINTS, ContactConfig, foot_contacts
from pipeline.ops.kinematics import canonical_kinematics
from pipeline.ops.quaternion import qbetween, qconj, qmul, qrot

_SKELETON = canonical_skeleton()
FOOT_POINTS = tuple(_SKELETON.index(name) for name in CONTACT_POINTS)  # the joints of the contact points
# Per side: hip, knee, ankle (heel), toe joints, and the foot's (heel, toe) columns of CONTACT_POINTS.
LEGS = tuple((tuple(_SKELETON.index(f"{side}_{joint}") for joint in ("hip", "knee", "heel", "toe")),
              (CONTACT_POINTS.index(f"{side}_heel"), CONTACT_POINTS.index(f"{side}_toe")))
             for side in ("left", "right"))


def stance_offsets(points: torch.Tensor, contacts: torch.Tensor) -> torch.Tensor:
    """Horizontal corrections (N, T, 2, 2) (x, z) per foot that hold each stance's contact point still.

    points: (N, T, 4, 3) heel/toe positions in CONTACT_POINTS order; contacts: (N, T, 4) bool. Zero at a stance's
    first frame and outside stances before the first; between stances linear back to zero; after the last stance
    the last offset is kept.
    """
    n, frames = points.shape[:2]
    out = []
    for _, (heel, toe) in LEGS:
        down_heel, down_toe = contacts[..., heel], contacts[..., toe]
        stance = down_heel | down_toe
        anchor = torch.where(down_heel[..., None], points[..., heel, :], points[..., toe, :])[..., [0, 2]]
        offset = torch.zeros(n, 2, dtype=points.dtype)
        rows = [offset]
        for t in range(1, frames):
            held = stance[:, t] & stance[:, t - 1]
            same = (down_heel[:, t] == down_heel[:, t - 1])[:, None]
            moved = torch.where(same, anchor[:, t] - anchor[:, t - 1], torch.zeros_like(offset))
            offset = torch.where(held[:, None], offset - moved, torch.zeros_like(offset))
            rows.append(offset)
        offsets = torch.stack(rows, dim=1)  # (N, T, 2): in stances; zero elsewhere
        t = torch.arange(frames).expand(n, frames)
        previous = torch.where(stance, t, -1).cummax(dim=1).values  # last stance frame at or before t
        following = torch.where(stance, t, frames).flip(1).cummin(dim=1).values.flip(1)  # first at or after t
        last = offsets.gather(1, previous.clamp_min(0)[..., None].expand(-1, -1, 2))
        share = ((following - t) / (following - previous).clamp_min(1)).to(points.dtype)
        swing = torch.where((following < frames)[..., None], last * share[..., None], last)
        out.append(torch.where(stance[..., None], offsets,
                               torch.where((previous >= 0)[..., None], swing, torch.zeros_like(offsets))))
    return torch.stack(out, dim=2)


def reach(rotations: torch.Tensor, positions: torch.Tensor, globals_: torch.Tensor, leg: Sequence[int],
          target: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    """Local rotations (..., 21, 4) with one leg turned so its ankle reaches ``target`` (..., 3), the hip and the
    foot's world orientation kept. positions, globals_: forward kinematics of ``rotations``."""
    hip_j, knee_j, ankle_j, toe_j = leg
    hip, knee, ankle = positions[..., hip_j, :], positions[..., knee_j, :], positions[..., ankle_j, :]
    thigh, shin = knee - hip, ankle - knee
    l1, l2 = thigh.norm(dim=-1, keepdim=True), shin.norm(dim=-1, keepdim=True)
    to_target = target - hip
    d = to_target.norm(dim=-1, keepdim=True)
    e = to_target / d.clamp_min(eps)
    d = torch.minimum(torch.maximum(d, (l1 - l2).abs() + 1e-4), l1 + l2)  # out of reach: as near as it goes
    cos_a = ((l1 ** 2 + d ** 2 - l2 ** 2) / (2 * l1 * d)).clamp(-1.0, 1.0)
    # the knee stays on its side of the hip-ankle line; a straight knee bends the way the body faces
    bend = thigh - (thigh * e).sum(-1, keepdim=True) * e
    forward = qrot(globals_[..., 0, :], torch.tensor([0.0, 0.0, 1.0], dtype=thigh.dtype).expand_as(thigh))
    forward = forward - (forward * e).sum(-1, keepdim=True) * e
    bend = torch.where(bend.norm(dim=-1, keepdim=True) > 1e-4 * l1, bend, forward)
    w = bend / bend.norm(dim=-1, keepdim=True).clamp_min(eps)
    new_knee = hip + l1 * (cos_a * e + torch.sqrt(1.0 - cos_a ** 2) * w)
    new_ankle = hip + d * e
    g_knee = qmul(qbetween(thigh, new_knee - hip), globals_[..., knee_j, :])
    g_ankle = qmul(qbetween(shin, new_ankle - new_knee), globals_[..., ankle_j, :])
    out = rotations.clone()
    out[..., knee_j, :] = qmul(qconj(globals_[..., hip_j, :]), g_knee)
    out[..., ankle_j, :] = qmul(qconj(g_knee), g_ankle)
    out[..., toe_j, :] = qmul(qconj(g_ankle), globals_[..., toe_j, :])
    return out


def lock_feet(rotations: torch.Tensor, root_positions: torch.Tensor, offsets: torch.Tensor, parents: Sequence[int],
              fps: float, contacts: ContactConfig = ContactConfig()) -> tuple[torch.Tensor, torch.Tensor]:
    """Gaits with their stance feet held still: rotations (N, T, 21, 4) local (row 0 the root's world rotation),
    root_positions (N, T, 3), offsets (21, 3) -> (rotations, positions (N, T, 21, 3)). Frames whose feet need no
    correction keep their rotations exactly."""
    offsets = offsets.to(rotations.dtype)
    positions, globals_ = canonical_kinematics(root_positions, rotations, offsets, parents)
    down = foot_contacts(positions[..., list(FOOT_POINTS), :], fps, contacts)
    shift = stance_offsets(positions[..., list(FOOT_POINTS), :], down)  # (N, T, 2, 2)
    out = rotations
    for side, (leg, _) in enumerate(LEGS):
        move = shift[..., side, :]
        target = positions[..., leg[2], :] + torch.stack((move[..., 0], torch.zeros_like(move[..., 0]),
                                                          move[..., 1]), dim=-1)
        locked = reach(out, positions, globals_, leg, target)
        moved = (move.abs().amax(-1) > 0)[..., None, None]
        out = torch.where(moved, locked, out)
    return out, canonical_kinematics(root_positions, out, offsets, parents)[0]


def skating_speed(positions: torch.Tensor, fps: float, cfg: ContactConfig) -> tuple[float, float]:
    """Mean horizontal speed (m/s) of heel/toe points while in contact (None if no point is ever in contact), and
    the contact fraction. positions: (N, T, 21, 3) world."""
    points = positions[:, :, list(canonical_skeleton().foot_joints)].double()
    contacts = foot_contacts(points, fps, cfg)  # (N, T, 4)
    velocity = torch.gradient(points[..., [0, 2]], spacing=1.0 / fps, dim=1)[0]
    speed = torch.linalg.vector_norm(velocity, dim=-1)
    return float(speed[contacts].mean()) if bool(contacts.any()) else None, float(contacts.double().mean())
