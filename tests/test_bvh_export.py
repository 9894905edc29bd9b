"""BVH export: real gaits written as BVH, read back by our reader and run through BVH forward kinematics,
land on the gait's own joint positions (< 1 mm); the bytes are reproducible; the rest pose reads as expected."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pipeline.io.bvh_writer import CM_PER_M, ROTATION_ORDER, bvh_text, export_hierarchy, write_bvh
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import axis_angle, euler_to_quat, quat_to_euler
from pipeline.io.readers.bvh import read_bvh
from pipeline.ingest.retarget import bvh_point_positions

TOLERANCE_M = 1e-3


def _spread_rows(sources: list[str], per_source: int) -> list[int]:
    """Up to ``per_source`` rows of every source, spread over its rows (so several clips, not one)."""
    rows: list[int] = []
    for source in sorted(set(sources)):
        own = [i for i, s in enumerate(sources) if s == source]
        rows += sorted({own[int(k)] for k in np.linspace(0, len(own) - 1, per_source)})
    return rows


def _bvh_positions(path, skeleton) -> torch.Tensor:
    """Canonical joint positions (T, 21, 3) in metres, by our reader and the BVH forward kinematics ingest uses."""
    clip = read_bvh(path)
    points = bvh_point_positions([clip], list(skeleton.names), root_offset="add", up_axis="+Y")
    return points.to(torch.float64) / CM_PER_M


def _rest(frames: int, joints: int) -> torch.Tensor:
    rot = torch.zeros(frames, joints, 4, dtype=torch.float64)
    rot[..., 0] = 1.0
    return rot


@pytest.fixture(scope="module")
def real_rows(annotated):
    table, arrays = annotated
    rows = _spread_rows(table.column("source").to_pylist(), per_source=3)
    return table, arrays, rows


def test_real_gaits_round_trip_under_a_millimetre(real_rows, skeleton, tmp_path):
    table, arrays, rows = real_rows
    offsets = torch.from_numpy(skeleton.offsets)
    sources = table.column("source").to_pylist()
    fps = table.column("fps").to_pylist()
    assert len({sources[i] for i in rows}) >= 3
    worst = 0.0
    for i in rows:
        rotations = torch.from_numpy(arrays["rotations"][i]).to(torch.float64)
        root = torch.from_numpy(arrays["positions"][i][:, 0]).to(torch.float64)
        path = tmp_path / f"gait{i}.bvh"
        write_bvh(path, rotations, root, skeleton, fps[i])
        read_back = _bvh_positions(path, skeleton)
        expected = canonical_positions(root, rotations, offsets, skeleton.parents)
        worst = max(worst, float((read_back - expected).norm(dim=-1).max()))
        stored = torch.from_numpy(arrays["positions"][i]).to(torch.float64)
        assert float((read_back - stored).norm(dim=-1).max()) < TOLERANCE_M
        assert read_bvh(path).fps == pytest.approx(fps[i], rel=1e-6)
    assert worst < TOLERANCE_M


def test_export_is_deterministic(real_rows, skeleton, tmp_path):
    table, arrays, rows = real_rows
    i = rows[len(rows) // 2]
    rotations, root = arrays["rotations"][i], arrays["positions"][i][:, 0]
    write_bvh(tmp_path / "a.bvh", rotations, root, skeleton, 30.0)
    write_bvh(tmp_path / "b.bvh", torch.from_numpy(rotations), torch.from_numpy(root), skeleton, 30.0)
    assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "b.bvh").read_bytes()
    assert (tmp_path / "a.bvh").read_text() == bvh_text(rotations, root, skeleton, 30.0)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary file left


def test_rest_pose_has_zero_rotations_and_canonical_offsets(skeleton, tmp_path):
    root = torch.tensor([[0.0, 0.95, 0.0], [0.1, 0.95, 0.2]], dtype=torch.float64)
    path = tmp_path / "rest.bvh"
    write_bvh(path, _rest(2, skeleton.joint_count), root, skeleton, 30.0)
    clip = read_bvh(path)
    bvh = clip.skeleton
    joints = [n for n, end in zip(bvh.names, bvh.is_end_site) if not end]
    assert len(joints) == 27 and bvh.channel_count == 84
    assert set(skeleton.names) <= set(joints)
    assert bvh.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    assert clip.frame_time == pytest.approx(1 / 30, abs=1e-8)
    for j, name in enumerate(skeleton.names):
        np.testing.assert_allclose(bvh.offsets[bvh.index(name)], skeleton.offsets[j] * CM_PER_M, atol=1e-9)
    for name in joints:
        if "_to_" in name:
            assert bvh.offsets[bvh.index(name)].tolist() == [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(clip.motion[:, :3], root.numpy() * CM_PER_M)
    assert not clip.motion[:, 3:].any()
    text = path.read_text()
    assert "JOINT left_hip\n\t\t{\n\t\t\tOFFSET 9.000000 -7.000000 0.000000\n" in text
    assert "-0.000000" not in text
    rest = np.zeros((skeleton.joint_count, 3))
    for j, p in enumerate(skeleton.parents[1:], start=1):
        rest[j] = rest[p] + skeleton.offsets[j]
    np.testing.assert_allclose(_bvh_positions(path, skeleton).numpy(), root.numpy()[:, None] + rest, atol=1e-6)


def test_a_bone_rotation_sits_on_the_joint_at_the_bone_start(skeleton, tmp_path):
    """q_left_knee (the thigh) = 90° about X: the BVH joint 'left_hip' turns by Xrotation 90, nothing else."""
    rotations = _rest(1, skeleton.joint_count)
    rotations[0, skeleton.index("left_knee")] = axis_angle(torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64),
                                                           torch.tensor(math.pi / 2, dtype=torch.float64))
    root = torch.tensor([[0.0, 1.0, 0.0]], dtype=torch.float64)
    path = tmp_path / "thigh.bvh"
    write_bvh(path, rotations, root, skeleton, 30.0)
    clip = read_bvh(path)
    start = sum(len(c) for c in clip.skeleton.channels[: clip.skeleton.index("left_hip")])
    channels = clip.motion[0, 3:].copy()
    assert clip.motion[0, start + 1] == pytest.approx(90.0)  # ZXY: the X angle is the middle one
    channels[start + 1 - 3] = 0.0
    assert not channels.any()
    points = _bvh_positions(path, skeleton)[0]
    hip, knee = skeleton.index("left_hip"), skeleton.index("left_knee")
    np.testing.assert_allclose((points[knee] - points[hip]).numpy(), [0.0, 0.0, -0.43], atol=1e-6)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_quat_to_euler_inverts_euler_to_quat_even_at_gimbal_lock(order):
    generator = torch.Generator().manual_seed(3)
    random = torch.randn(2000, 4, dtype=torch.float64, generator=generator)
    locked = (torch.rand(200, 3, dtype=torch.float64, generator=generator) - 0.5) * 2 * math.pi
    locked[:100, 1], locked[100:, 1] = math.pi / 2, -math.pi / 2
    q = torch.cat([random / random.norm(dim=-1, keepdim=True), euler_to_quat(locked, order)])
    back = euler_to_quat(quat_to_euler(q, order), order)
    assert float((1.0 - (q * back).sum(-1).abs()).max()) < 1e-12


def test_hierarchy_gives_every_bone_its_own_joint(skeleton):
    joints = export_hierarchy(skeleton)
    carried = sorted(j.bone for j in joints if j.bone >= 0)
    assert carried == list(range(skeleton.joint_count))  # each per-bone rotation appears exactly once
    assert ROTATION_ORDER == "ZXY"
    names = [j.name for j in joints]
    for a, b in [("root", "left_hip"), ("root", "right_hip"), ("root", "lower_back"),
                 ("spine", "neck"), ("spine", "left_shoulder"), ("spine", "right_shoulder")]:
        link = names.index(f"{a}_to_{b}")
        assert joints[link].parent == names.index(a) and joints[names.index(b)].parent == link
