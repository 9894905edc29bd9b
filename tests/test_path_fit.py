"""Laying walks onto their paths (ops.path_fit): a swaying walk bent onto an arc keeps its sway and its speed and
its travel line lies on the arc; a walk already on its path stays there; real walks turned by the fit are the
same bodies (the pelvis' yaw and the joints' positions agree, bones keep their lengths)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pipeline.ops.geometry import arc_lengths, distance_to_polyline, odd_frames
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.path_fit import fit_ground, fit_poses, straightened

FPS = 30.0
STRIDE = odd_frames(1.0, FPS)


def _swaying_walk(frames: int = 90, speed: float = 1.3, sway: float = 0.03, turn_deg_per_s: float = 0.0
                  ) -> torch.Tensor:
    """(1, frames, 2) a walk from (0, 0) towards +Z (turning steadily left by ``turn_deg_per_s``) whose root sways
    sideways by ``sway`` with a 1.1 s stride."""
    t = torch.arange(frames, dtype=torch.float64) / FPS
    heading = math.radians(turn_deg_per_s) * t
    step = speed / FPS
    between = heading + 0.5 * math.radians(turn_deg_per_s) / FPS  # each step along the chord of its turn
    ahead = torch.stack([torch.sin(between), torch.cos(between)], -1) * step
    centre = torch.cat([torch.zeros(1, 2, dtype=torch.float64), ahead[:-1].cumsum(0)], 0)
    left = torch.stack([torch.cos(heading), -torch.sin(heading)], -1)
    return (centre + sway * torch.sin(2 * math.pi * t / 1.1)[:, None] * left)[None]


def _arc(radius: float, length: float = 8.0, spacing: float = 0.05) -> torch.Tensor:
    """(1, K, 2) an arc turning left from (0, 0) towards +Z."""
    s = torch.arange(int(length / spacing) + 1, dtype=torch.float64) * spacing
    a = s / radius
    return torch.stack([radius * (1 - torch.cos(a)), radius * torch.sin(a)], -1)[None]


def test_a_straight_swaying_walk_bent_onto_an_arc_keeps_its_sway_and_speed():
    walk = _swaying_walk()
    path = _arc(2.0)
    placed, turn = fit_ground(walk, path, STRIDE, corner_m=0.2, turn_m=0.6)
    # before: the straight walk leaves the arc; after: it sways about it as it swayed about its own line
    before = float(distance_to_polyline(walk, path).mean())
    after = float(distance_to_polyline(placed, path).mean())
    own = float(distance_to_polyline(walk, torch.tensor([[[0.0, -1.0], [0.0, 5.0]]], dtype=torch.float64)).mean())
    assert before > 0.5
    assert abs(after - own) < 0.005, (after, own)
    # the distance walked is kept (a bent line is as long as a straight one), so is the speed within a stride
    walked = arc_lengths(walk)[0, -1]
    assert float((arc_lengths(placed)[0, -1] - walked).abs() / walked) < 0.02
    # the body turns with the arc: 1.3 m/s on a 2 m radius is 37 deg/s
    rate = float(torch.rad2deg(turn[0, 30:60].diff().mean()) * FPS)
    assert abs(rate - math.degrees(1.3 / 2.0)) < 3.0, rate


def test_a_walk_already_on_its_path_stays_put():
    walk = _swaying_walk(turn_deg_per_s=math.degrees(1.3 / 3.0))  # a 3 m radius, walked exactly
    path = _arc(3.0)
    placed, turn = fit_ground(walk, path, STRIDE, corner_m=0.2, turn_m=0.6)
    # it sways about the path as it did, less what of a 1.1 s stride's sway a one-second average keeps in the
    # line (the line is laid onto the path; ~15 % here); it moves by centimetres, turns by degrees
    before, after = distance_to_polyline(walk, path).mean(), distance_to_polyline(placed, path).mean()
    assert 0.8 * before < after <= before
    assert float((placed - walk).norm(dim=-1).max()) < 0.035
    assert float(turn.abs().max()) < math.radians(6.0)


def test_straightening_takes_out_the_turning_and_keeps_the_sway():
    straight, travel = straightened(_swaying_walk(turn_deg_per_s=40.0), STRIDE)
    plain, _ = straightened(_swaying_walk(), STRIDE)
    middle = slice(STRIDE, -STRIDE)  # where the centred average sees a whole stride
    assert float((straight - plain)[:, middle].norm(dim=-1).max()) < 0.01
    assert float(torch.rad2deg(travel[0, middle].diff().mean()) * FPS) == pytest.approx(40.0, abs=1.0)


def test_fitted_real_walks_are_the_same_bodies(reference_annotated, skeleton):
    _, arrays = reference_annotated
    rotations = torch.from_numpy(arrays["rotations"]).double()
    positions = torch.from_numpy(arrays["positions"]).double()
    offsets = torch.from_numpy(skeleton.offsets).double()
    start = positions[:, :1, 0, [0, 2]]
    paths = _arc(1.5).expand(len(positions), -1, -1) + start  # each walk bent onto an arc from where it starts
    moved, turned, turn = fit_poses(positions, rotations, paths, STRIDE, 0.2, 0.6)
    # the turned pelvis and the moved root give exactly the moved joints
    assert torch.allclose(canonical_positions(moved[:, :, 0], turned, offsets, skeleton.parents), moved, atol=1e-6)
    assert torch.equal(turned[:, :, 1:], rotations[:, :, 1:])
    assert torch.equal(moved[..., 1], positions[..., 1])  # heights unchanged
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            length = (moved[..., joint, :] - moved[..., parent, :]).norm(dim=-1)
            original = (positions[..., joint, :] - positions[..., parent, :]).norm(dim=-1)
            assert float((length - original).abs().max()) < 1e-9
    # and they now walk along the arc, as close to it as real roots sway about their own travel line (~0.02 m)
    deviation = distance_to_polyline(moved[:, :, 0, [0, 2]], paths).mean(-1)
    walking = np.asarray(arrays["root_path"][:, -1] - arrays["root_path"][:, 0])
    forward = torch.from_numpy(np.linalg.norm(walking, axis=-1) > 1.0)  # windows that walk somewhere
    assert forward.any()
    assert float(deviation[forward].mean()) < 0.04, deviation[forward]
    assert bool(torch.isfinite(turn).all())
