"""Time-based resampling: exact where it must be, SLERP-correct in between."""

import math

import pytest
import torch

from pipeline.ops.quaternion import axis_angle, qangle
from pipeline.ops.resample import resample, target_times, window_starts

D = torch.float64


def _spin(frames, fps, deg_per_s):
    """A clip turning at constant speed about Y while moving at 1 m/s along X."""
    t = torch.arange(frames, dtype=D) / fps
    angle = torch.deg2rad(deg_per_s * t)
    rot = axis_angle(torch.tensor([0.0, 1, 0], dtype=D).expand(frames, 3), angle)[:, None].repeat(1, 3, 1)
    root = torch.stack([t, torch.ones_like(t), torch.zeros_like(t)], dim=-1)
    return root, rot


def test_resampling_to_the_own_rate_reproduces_the_clip():
    root, rot = _spin(97, 120.0, 200.0)
    r2, q2 = resample(root, rot, 1 / 120.0, 120.0)
    assert torch.equal(r2, root) and torch.equal(q2, rot)


@pytest.mark.usefixtures("mocap")
def test_resampling_a_real_clip_to_its_own_rate_reproduces_it(manifests, skeleton):
    from pipeline.io.readers.bvh import read_bvh
    from pipeline.ingest.retarget import bvh_point_positions, map_joints, referenced_points, retarget_to_canonical
    from tests.conftest import MOCAP

    m = manifests["pymo_demo"]
    clip = read_bvh(MOCAP / m.name / m.files[0].path)
    jm = m.joint_map(m.files[0].path)
    names = referenced_points(jm)
    motion = retarget_to_canonical(map_joints(names, bvh_point_positions([clip], names, m.root_offset, m.up_axis),
                                              jm, skeleton), skeleton, m.unit_scale_m)
    root, rot = resample(motion.root_positions, motion.rotations, clip.frame_time, clip.fps)
    assert torch.equal(root, motion.root_positions) and torch.equal(rot, motion.rotations)


def test_integer_ratio_takes_every_fourth_frame():
    root, rot = _spin(121, 120.0, 90.0)
    r2, q2 = resample(root, rot, 1 / 120.0, 30.0)
    assert r2.shape[0] == 31
    assert torch.allclose(r2, root[::4]) and torch.allclose(q2, rot[::4])


def test_non_integer_ratio_interpolates_in_time():
    fps, speed = 100.0, 150.0  # 100 -> 30 fps: target instants fall between source frames
    root, rot = _spin(201, fps, speed)
    r2, q2 = resample(root, rot, 1 / fps, 30.0)
    t = target_times(201, 1 / fps, 30.0)
    assert len(t) == 61 and math.isclose(float(t[-1]), 2.0)
    expected = axis_angle(torch.tensor([0.0, 1, 0], dtype=D).expand(len(t), 3), torch.deg2rad(speed * t))
    # constant angular velocity about a fixed axis: SLERP is exact, frame dropping would be off by up to 1.5 deg
    assert float(qangle(q2[:, 0], expected).max()) < 1e-6
    assert torch.allclose(r2[:, 0], t)


def test_windows_cover_the_clip_with_the_stride():
    assert window_starts(59, 60, 30) == []
    assert window_starts(60, 60, 30) == [0]
    assert window_starts(150, 60, 30) == [0, 30, 60, 90]
