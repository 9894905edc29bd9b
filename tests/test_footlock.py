"""Foot locking (ops.footlock) on real annotated walks: the leg IK reaches where it is asked without changing
bone lengths, a planted contact point stops sliding, what needs no correction is left exactly, and the stance
offsets hold a sliding point and let go of it between stances."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pipeline.ops.footlock import skating_speed
from pipeline.ops.contacts import ContactConfig, foot_contacts
from pipeline.ops.footlock import FOOT_POINTS, LEGS, lock_feet, reach, stance_offsets
from pipeline.ops.kinematics import canonical_kinematics

FPS = 30.0


@pytest.fixture(scope="module")
def walks(reference_annotated, skeleton):
    """(rotations, root positions, positions, offsets) of the reference windows, float64."""
    _, arrays = reference_annotated
    rot = torch.from_numpy(arrays["rotations"]).double()
    pos = torch.from_numpy(arrays["positions"]).double()
    return rot, pos[:, :, 0], pos, torch.from_numpy(skeleton.offsets).double()


def _fk(rot, root, offsets, parents):
    return canonical_kinematics(root, rot, offsets, parents)


def test_reach_to_the_current_ankle_changes_nothing_and_reaches_a_moved_ankle(walks, skeleton):
    rot, root, _, offsets = walks
    positions, globals_ = _fk(rot, root, offsets, skeleton.parents)
    leg = LEGS[0][0]
    same = _fk(reach(rot, positions, globals_, leg, positions[..., leg[2], :]), root, offsets, skeleton.parents)[0]
    assert float((same - positions).abs().max()) < 1e-5
    shift = torch.tensor([0.03, 0.0, -0.04], dtype=rot.dtype)  # a few centimetres: within reach of a bent leg
    moved, moved_globals = _fk(reach(rot, positions, globals_, leg, positions[..., leg[2], :] + shift), root, offsets,
                               skeleton.parents)
    bent = (positions[..., leg[2], :] - positions[..., leg[0], :]).norm(dim=-1) < 0.95 * 0.85
    error = (moved[..., leg[2], :] - positions[..., leg[2], :] - shift).norm(dim=-1)
    assert float(error[bent].max()) < 1e-4
    # bones keep their lengths, the other leg and the foot's world orientation stay
    for joint in leg[1:]:
        parent = skeleton.parents[joint]
        length = (moved[..., joint, :] - moved[..., parent, :]).norm(dim=-1)
        assert float((length - offsets[joint].norm()).abs().max()) < 1e-5
    assert torch.allclose(moved[..., LEGS[1][0], :], positions[..., LEGS[1][0], :], atol=1e-6)
    assert torch.allclose(moved_globals[..., leg[3], :], globals_[..., leg[3], :], atol=1e-6)


def test_stance_offsets_hold_a_sliding_point_and_return_to_zero_between_stances():
    frames = 12
    points = torch.zeros(1, frames, 4, 3, dtype=torch.float64)
    points[0, :, :, 2] = 0.01 * torch.arange(frames, dtype=torch.float64)[:, None]  # every point slides 1 cm/frame
    contacts = torch.zeros(1, frames, 4, dtype=torch.bool)
    contacts[0, 0:4, 0] = True  # left heel down 0..3, then the toe 3..5: one stance, the anchor switches
    contacts[0, 3:6, 1] = True
    contacts[0, 9:12, 0] = True  # the next stance from 9
    left = stance_offsets(points, contacts)[0, :, 0, 1]  # z correction of the left foot
    expected_stance = -0.01 * torch.tensor([0, 1, 2, 3, 3, 4], dtype=torch.float64)  # no step at the switch
    assert torch.allclose(left[:6], expected_stance)
    assert torch.allclose(left[6:9], expected_stance[-1] * torch.tensor([3, 2, 1], dtype=torch.float64) / 4)
    assert torch.allclose(left[9:], -0.01 * torch.arange(3, dtype=torch.float64))
    assert torch.equal(stance_offsets(points, torch.zeros_like(contacts)), torch.zeros(1, frames, 2, 2,
                                                                                      dtype=torch.float64))


def test_locked_walks_skate_less_and_planted_points_stay_put(walks, skeleton):
    rot, root, positions, offsets = walks
    cfg = ContactConfig()
    locked_rot, locked = lock_feet(rot, root, offsets, skeleton.parents, FPS, cfg)
    before, _ = skating_speed(positions, FPS, cfg)
    after, _ = skating_speed(locked, FPS, cfg)
    assert after < 0.8 * before, (before, after)
    # where the original contact point stayed down from one frame to the next, its locked twin barely moves
    points = positions[..., list(FOOT_POINTS), :]
    down = foot_contacts(points, FPS, cfg)
    held = down[:, 1:] & down[:, :-1]
    slide = (locked[:, 1:, list(FOOT_POINTS)] - locked[:, :-1, list(FOOT_POINTS)])[..., [0, 2]].norm(dim=-1)
    original = (points[:, 1:] - points[:, :-1])[..., [0, 2]].norm(dim=-1)
    # the heel while it is the anchor (toes roll about it, so they are not held)
    heel_held = held[..., [0, 2]]
    assert float(slide[..., [0, 2]][heel_held].median()) < 0.25 * float(original[..., [0, 2]][heel_held].median())
    # root, spine and arms untouched
    assert torch.equal(locked_rot[..., 0, :], rot[..., 0, :]) and torch.equal(locked_rot[..., 9:, :], rot[..., 9:, :])
    assert float((locked[..., 9:, :] - positions[..., 9:, :]).abs().max()) < 1e-5


def test_locking_is_deterministic_and_leaves_gaits_without_contacts_alone(walks, skeleton):
    rot, root, positions, offsets = walks
    a = lock_feet(rot, root, offsets, skeleton.parents, FPS)
    b = lock_feet(rot, root, offsets, skeleton.parents, FPS)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    fast_root = root.clone()  # the same poses carried forward at 20 m/s: no point is ever slow, so none is down
    fast_root[..., 2] = fast_root[..., 2] + (20.0 / FPS) * torch.arange(rot.shape[1], dtype=root.dtype)
    out, _ = lock_feet(rot, fast_root, offsets, skeleton.parents, FPS)
    assert torch.equal(out, rot)
    assert np.isfinite(a[1].numpy()).all()
