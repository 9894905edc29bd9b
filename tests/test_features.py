"""Affective and movement features: hand-computed values, invariances, gradients, one code path."""

import math

import numpy as np
import pytest
import torch

from pipeline.ops.features import (
    AFFECTIVE_NAMES,
    affective_features,
    heron_area,
    movement_features,
    pose_affective_features,
)
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import axis_angle, qnormalize

D = torch.float64


def _rest_pose(skeleton):
    """The canonical T-pose, root at (0, 1, 0)."""
    rot = torch.zeros(21, 4, dtype=D)
    rot[:, 0] = 1
    return canonical_positions(torch.tensor([0.0, 1.0, 0.0], dtype=D), rot, torch.from_numpy(skeleton.offsets), skeleton.parents)


def test_features_of_the_rest_pose_match_hand_computation(skeleton):
    f = affective_features(_rest_pose(skeleton))
    o = skeleton.offsets
    # 7, 8: straight arms -> elbow angles pi; 15, 16: straight legs -> knee angles pi
    for k in (7, 8, 15, 16):
        assert float(f[k]) == pytest.approx(math.pi, abs=1e-7)
    # 9: at the neck between head (straight up) and left shoulder: the shoulder is spine + o13; neck = spine + o11
    neck_to_shoulder = o[13] - o[11]
    expected = math.atan2(abs(neck_to_shoulder[0]), neck_to_shoulder[1])  # angle from +Y
    assert float(f[9]) == pytest.approx(expected, abs=1e-7)
    assert float(f[10]) == pytest.approx(expected, abs=1e-7)  # mirror image
    # 2: d(left index, neck) / d(left index, root), positions by hand
    root = np.array([0.0, 1.0, 0.0])
    spine = root + o[9] + o[10]
    neck = spine + o[11]
    index = spine + o[13] + o[14] + o[15] + o[16]
    assert float(f[2]) == pytest.approx(np.linalg.norm(index - neck) / np.linalg.norm(index - root), rel=1e-9)
    # 13: d(left toe, right toe) / d(neck, root): toes at x = +-0.09
    assert float(f[13]) == pytest.approx(0.18 / np.linalg.norm(neck - root), rel=1e-9)
    # 14: at the root between the toes: two equal legs, half-angle atan(0.09 / drop)
    drop = -(o[1][1] + o[2][1] + o[3][1] + o[4][1])
    toe = np.array([0.09, -drop, 0.13])
    expected = math.acos(np.dot(toe, toe * [-1, 1, 1]) / np.dot(toe, toe))
    assert float(f[14]) == pytest.approx(expected, abs=1e-9)


# A constructed pose (metres, Y up): left elbow bent 90° (hand forward), right arm hanging straight, left knee
# bent, right leg straight, head forward of the neck.
POSE = np.array([
    [0.0, 1.0, 0.0], [0.1, 0.9, 0.0], [0.1, 0.5, 0.1], [0.1, 0.1, 0.0], [0.1, 0.05, 0.15],  # root, left leg
    [-0.1, 0.9, 0.0], [-0.1, 0.5, 0.0], [-0.1, 0.1, 0.0], [-0.1, 0.0, 0.15],  # right leg
    [0.0, 1.1, 0.0], [0.0, 1.3, 0.0], [0.0, 1.5, 0.0], [0.0, 1.6, 0.05],  # lower back, spine, neck, head
    [0.2, 1.45, 0.0], [0.2, 1.15, 0.0], [0.2, 1.15, 0.3], [0.2, 1.15, 0.4],  # left arm
    [-0.2, 1.45, 0.0], [-0.2, 1.15, 0.0], [-0.2, 0.9, 0.0], [-0.2, 0.8, 0.0],  # right arm
])


def _angle(a, v, b):
    u, w = POSE[a] - POSE[v], POSE[b] - POSE[v]
    return math.acos(np.dot(u, w) / (np.linalg.norm(u) * np.linalg.norm(w)))


def _dist(a, b):
    return float(np.linalg.norm(POSE[a] - POSE[b]))


def _area(a, b, c):
    return 0.5 * float(np.linalg.norm(np.cross(POSE[b] - POSE[a], POSE[c] - POSE[a])))


def test_every_feature_of_a_constructed_pose_matches_hand_computation():
    f = affective_features(torch.from_numpy(POSE)).numpy()
    expected = [
        _angle(17, 9, 13), _angle(19, 9, 15),  # 0, 1: shoulders / hands seen from the lower back
        _dist(16, 11) / _dist(16, 0), _dist(20, 11) / _dist(20, 0), _dist(16, 20) / _dist(11, 0),  # 2-4
        _area(17, 9, 13) / _area(17, 0, 13), _area(19, 9, 15) / _area(19, 0, 15),  # 5, 6
        math.pi / 2, math.pi,  # 7, 8: left elbow square, right arm straight
        _angle(12, 11, 13), _angle(12, 11, 17), _angle(12, 0, 2), _angle(12, 0, 6),  # 9-12
        _dist(4, 8) / _dist(11, 0), _angle(8, 0, 4),  # 13, 14
        math.acos(-15 / 17), math.pi,  # 15: left knee (thigh (0,.4,-.1) vs shank (0,-.4,-.1)); 16: right leg straight
        _area(20, 11, 16) / _area(8, 0, 4),  # 17
    ]
    np.testing.assert_allclose(f, expected, rtol=1e-9, atol=1e-7)
    # a few by plain arithmetic: shoulders 0.4 apart, 0.35 above the lower back -> angle 2 atan(0.2 / 0.35)
    assert f[0] == pytest.approx(2 * math.atan2(0.2, 0.35), abs=1e-9)
    # toes 0.2 apart (x) and 0.05 apart (y); neck 0.5 above the root
    assert f[13] == pytest.approx(math.hypot(0.2, 0.05) / 0.5, rel=1e-9)
    # head 0.1 up and 0.05 forward of the neck, left shoulder 0.2 out and 0.05 down: angle between them
    assert f[9] == pytest.approx(math.acos((0.1 * -0.05) / (math.hypot(0.1, 0.05) * math.hypot(0.2, 0.05))), abs=1e-9)


def test_heron_area_matches_the_cross_product():
    g = torch.Generator().manual_seed(3)
    a, b, c = (torch.randn(200, 3, generator=g, dtype=D) for _ in range(3))
    cross = 0.5 * torch.linalg.vector_norm(torch.cross(b - a, c - a, dim=-1), dim=-1)
    assert torch.allclose(heron_area(a, b, c), cross, rtol=1e-9, atol=1e-12)


def test_affective_features_ignore_uniform_scale_and_rotation_about_y(full_ingest):
    pos = torch.from_numpy(full_ingest["arrays"]["positions"][::40]).double()  # ~50 real gaits
    f = affective_features(pos)
    turn = axis_angle(torch.tensor([0.0, 1.0, 0.0], dtype=D), torch.tensor(1.234, dtype=D))
    from pipeline.ops.quaternion import qrot

    moved = qrot(turn.expand(pos.shape[:-1] + (4,)), pos) * 1.7 + torch.tensor([3.0, 0.2, -5.0], dtype=D)
    assert torch.allclose(affective_features(moved), f, atol=1e-5)
    m = movement_features(pos, 9)
    m2 = movement_features(qrot(turn.expand(pos.shape[:-1] + (4,)), pos), 9)
    assert torch.allclose(m2, m, atol=1e-6)  # the path features are rotation free too


def test_gradcheck_forward_kinematics_and_features(skeleton):
    g = torch.Generator().manual_seed(0)
    rot = qnormalize(torch.randn(2, 21, 4, generator=g, dtype=D)).requires_grad_(True)
    root = torch.randn(2, 3, generator=g, dtype=D).requires_grad_(True)
    offsets = torch.from_numpy(skeleton.offsets)
    assert torch.autograd.gradcheck(lambda r, q: canonical_positions(r, q, offsets, skeleton.parents), (root, rot))
    assert torch.autograd.gradcheck(lambda r, q: pose_affective_features(r, q, offsets, skeleton.parents), (root, rot))
    pos = (torch.randn(1, 12, 21, 3, generator=g, dtype=D) + torch.linspace(0, 1, 12, dtype=D)[:, None, None])
    assert torch.autograd.gradcheck(lambda p: movement_features(p, 3), (pos.requires_grad_(True),))


def test_annotation_equals_the_training_path(annotated, skeleton):
    """The stored affective features are what the generator's loss computes from the same rotations."""
    _, arrays = annotated
    rows = slice(None, None, 25)
    pos = torch.from_numpy(arrays["positions"][rows]).double()
    rot = torch.from_numpy(arrays["rotations"][rows]).double()
    training = pose_affective_features(pos[..., 0, :], rot, torch.from_numpy(skeleton.offsets), skeleton.parents)
    assert torch.equal(training.float(), torch.from_numpy(arrays["affective"][rows]))
    # and positions-based features agree wherever the feature is well conditioned (not 6: a near-flat triangle)
    direct = affective_features(pos)
    keep = [k for k in range(18) if k != 6]
    assert torch.allclose(direct[..., keep], training[..., keep], atol=1e-4)


# The design notes' table of the 18 affective features, written with the joints' names (manifests/skeleton.yaml) rather
# than the library's index table, and computed below in numpy by plain vector algebra (arccos of the normalised
# dot product, cross-product areas), not by the library's atan2 / Heron formulas.
DESIGN_FEATURES = (
    ("angle", "lower_back", "right_shoulder", "left_shoulder"),  # 0: shoulders seen from the lower back
    ("angle", "lower_back", "right_hand", "left_hand"),  # 1: hands seen from the lower back
    ("distance_ratio", ("left_hand_index", "neck"), ("left_hand_index", "root")),  # 2
    ("distance_ratio", ("right_hand_index", "neck"), ("right_hand_index", "root")),  # 3
    ("distance_ratio", ("left_hand_index", "right_hand_index"), ("neck", "root")),  # 4
    ("area_ratio", ("right_shoulder", "lower_back", "left_shoulder"), ("right_shoulder", "root", "left_shoulder")),
    ("area_ratio", ("right_hand", "lower_back", "left_hand"), ("right_hand", "root", "left_hand")),  # 6
    ("angle", "left_elbow", "left_shoulder", "left_hand"),  # 7
    ("angle", "right_elbow", "right_shoulder", "right_hand"),  # 8
    ("angle", "neck", "head", "left_shoulder"),  # 9
    ("angle", "neck", "head", "right_shoulder"),  # 10
    ("angle", "root", "head", "left_knee"),  # 11
    ("angle", "root", "head", "right_knee"),  # 12
    ("distance_ratio", ("left_toe", "right_toe"), ("neck", "root")),  # 13
    ("angle", "root", "right_toe", "left_toe"),  # 14
    ("angle", "left_knee", "left_hip", "left_heel"),  # 15
    ("angle", "right_knee", "right_hip", "right_heel"),  # 16
    ("area_ratio", ("right_hand_index", "neck", "left_hand_index"), ("right_toe", "root", "left_toe")),  # 17
)


def _design_features(positions: np.ndarray, skeleton) -> np.ndarray:
    """The design table computed by hand: positions (..., 21, 3) float64 -> (..., 18)."""
    def p(name):
        return positions[..., skeleton.index(name), :]

    def length(v):
        return np.sqrt((v * v).sum(-1))

    def area(a, b, c):
        return 0.5 * length(np.cross(p(b) - p(a), p(c) - p(a)))

    out = []
    for kind, *joints in DESIGN_FEATURES:
        if kind == "angle":
            vertex, a, b = joints
            u, w = p(a) - p(vertex), p(b) - p(vertex)
            out.append(np.arccos(np.clip((u * w).sum(-1) / (length(u) * length(w)), -1.0, 1.0)))
        elif kind == "distance_ratio":
            (a, b), (c, d) = joints
            out.append(length(p(a) - p(b)) / length(p(c) - p(d)))
        else:
            top, bottom = joints
            out.append(area(*top) / area(*bottom))
    return np.stack(out, axis=-1)


def _generic_pose(skeleton) -> np.ndarray:
    """The rest pose (from the skeleton's offsets) with every joint moved a few cm at random: no two features are
    alike and no triangle is flat, so a wrong joint, kind or order in the library's table changes a number."""
    pose = np.zeros((21, 3))
    for j, parent in enumerate(skeleton.parents):
        if parent >= 0:
            pose[j] = pose[parent] + skeleton.offsets[j]
    return pose + np.random.default_rng(11).normal(scale=0.04, size=pose.shape)


def test_feature_table_is_the_design_table(skeleton):
    """Each of the 18 features, as the library computes it, equals the design table's definition by hand."""
    assert len(AFFECTIVE_NAMES) == len(DESIGN_FEATURES) == 18
    assert [n.split("_")[0] for n in AFFECTIVE_NAMES] == [k.split("_")[0] for k, *_ in DESIGN_FEATURES]
    pose = _generic_pose(skeleton)
    got = affective_features(torch.from_numpy(pose)).numpy()
    expected = _design_features(pose, skeleton)
    assert len(np.unique(np.round(expected, 3))) == 18  # generic: a swapped feature could not hide
    for k, name in enumerate(AFFECTIVE_NAMES):
        assert got[k] == pytest.approx(expected[k], rel=1e-9, abs=1e-12), f"feature {k} ({name}): {DESIGN_FEATURES[k]}"


def test_feature_table_is_the_design_table_on_real_poses(reference_ingest, skeleton):
    """The same on every frame of the reference clips (real poses: bent knees, hanging arms, near-flat triangles)."""
    positions = reference_ingest["arrays"]["positions"].astype(np.float64)
    got = affective_features(torch.from_numpy(positions)).numpy()
    expected = _design_features(positions, skeleton)
    for k, name in enumerate(AFFECTIVE_NAMES):
        np.testing.assert_allclose(got[..., k], expected[..., k], rtol=1e-9, atol=1e-12,
                                   err_msg=f"feature {k} ({name}): {DESIGN_FEATURES[k]}")


def test_movement_features_on_a_straight_walk():
    t = torch.arange(30, dtype=D)
    pos = torch.zeros(30, 21, 3, dtype=D)
    pos[:, :, 2] = 0.05 * t[:, None]  # 5 cm per frame along +Z
    pos[:, 0, 1] = 1.0 + 0.01 * torch.sin(t)
    pos[:, 1, 0], pos[:, 5, 0] = 0.1, -0.1  # left hip on +X: facing +Z
    m = movement_features(pos, 5)
    assert torch.allclose(m[:, 1], torch.full((30,), 0.05, dtype=D))  # s
    assert torch.allclose(m[:, 2], torch.full((30,), 0.05, dtype=D))  # low-passed s
    assert torch.allclose(m[:, 3], torch.zeros(30, dtype=D), atol=1e-12)  # heading along the path
    assert torch.allclose(m[:, 4], torch.zeros(30, dtype=D), atol=1e-12)  # no curvature
    assert float(m[:, 0].mean()) == pytest.approx(0.0, abs=1e-12)
    pos[:, 1, 0], pos[:, 5, 0] = -0.1, 0.1  # now facing -Z while moving +Z: walking backwards
    assert torch.allclose(movement_features(pos, 5)[:, 3], torch.full((30,), math.pi, dtype=D))
