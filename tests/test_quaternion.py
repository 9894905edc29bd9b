"""Quaternion algebra against hand-computed rotations."""

import math

import torch

from pipeline.ops.quaternion import (
    axis_angle,
    euler_to_quat,
    matrix_to_quat,
    qangle,
    qbetween,
    qfix,
    qmul,
    qnormalize,
    qrot,
    qslerp,
)

D = torch.float64


def _q(axis, degrees):
    return axis_angle(torch.tensor(axis, dtype=D), torch.tensor(math.radians(degrees), dtype=D))


def test_rotation_about_z_by_90_degrees_turns_x_into_y():
    assert torch.allclose(qrot(_q([0, 0, 1], 90), torch.tensor([1.0, 0, 0], dtype=D)), torch.tensor([0.0, 1, 0], dtype=D))


def test_qmul_applies_right_factor_first():
    # Rz(90) * Rx(90) applied to +Y: Rx takes +Y to +Z, then Rz leaves +Z.
    q = qmul(_q([0, 0, 1], 90), _q([1, 0, 0], 90))
    assert torch.allclose(qrot(q, torch.tensor([0.0, 1, 0], dtype=D)), torch.tensor([0.0, 0, 1], dtype=D), atol=1e-12)


def test_euler_is_intrinsic_in_channel_order():
    angles = torch.tensor([math.radians(90), math.radians(90)], dtype=D)
    y = torch.tensor([0.0, 1, 0], dtype=D)
    # "Zrotation Xrotation": R = Rz Rx  -> +Y -> +Z ; "Xrotation Zrotation": R = Rx Rz -> +Y -> -X
    assert torch.allclose(qrot(euler_to_quat(angles, "ZX"), y), torch.tensor([0.0, 0, 1], dtype=D), atol=1e-12)
    assert torch.allclose(qrot(euler_to_quat(angles, "XZ"), y), torch.tensor([-1.0, 0, 0], dtype=D), atol=1e-12)


def test_euler_matches_product_of_axis_rotations_for_every_order():
    g = torch.Generator().manual_seed(0)
    angles = (torch.rand(50, 3, generator=g, dtype=D) - 0.5) * 2 * math.pi
    for order in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
        ref = None
        for i, a in enumerate(order):
            axis = [0.0, 0.0, 0.0]
            axis["XYZ".index(a)] = 1.0
            q = axis_angle(torch.tensor(axis, dtype=D).expand(50, 3), angles[:, i])
            ref = q if ref is None else qmul(ref, q)
        assert torch.allclose(euler_to_quat(angles, order), ref, atol=1e-12), order


def test_slerp_halfway_between_identity_and_90_about_y_is_45_about_y():
    mid = qslerp(_q([0, 1, 0], 0), _q([0, 1, 0], 90), torch.tensor(0.5, dtype=D))
    assert torch.allclose(mid, _q([0, 1, 0], 45), atol=1e-12)


def test_slerp_takes_the_short_way_when_signs_differ():
    a, b = _q([0, 0, 1], 10), -_q([0, 0, 1], 30)  # -q is the same rotation as q
    assert math.isclose(float(qangle(qslerp(a, b, torch.tensor(0.5, dtype=D)), _q([0, 0, 1], 20))), 0.0, abs_tol=1e-7)


def test_qbetween_maps_u_onto_v_including_antiparallel():
    u = torch.tensor([[1.0, 0, 0], [0, 1, 0], [0, 0, 2]], dtype=D)
    v = torch.tensor([[0.0, 3, 0], [0, -1, 0], [1, 1, 1]], dtype=D)
    q = qbetween(u, v)
    rotated = qrot(q, u / u.norm(dim=-1, keepdim=True))
    assert torch.allclose(rotated, v / v.norm(dim=-1, keepdim=True), atol=1e-12)
    assert torch.allclose(q.norm(dim=-1), torch.ones(3, dtype=D))


def test_matrix_round_trip():
    q = qnormalize(torch.randn(100, 4, generator=torch.Generator().manual_seed(1), dtype=D))
    eye = torch.eye(3, dtype=D)
    m = torch.stack([qrot(q, eye[i].expand(100, 3)) for i in range(3)], dim=-1)  # columns: rotated axes
    back = matrix_to_quat(m)
    assert torch.allclose(qangle(back, q), torch.zeros(100, dtype=D), atol=1e-6)


def test_qfix_makes_sequences_hemisphere_continuous():
    q = _q([0, 1, 0], 10).expand(6, 4).clone()
    q[[1, 3, 4]] *= -1
    fixed = qfix(q, dim=0)
    assert ((fixed[1:] * fixed[:-1]).sum(-1) > 0).all()
    assert torch.allclose(qangle(fixed, q), torch.zeros(6, dtype=D), atol=1e-7)
