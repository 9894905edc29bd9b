"""Unit-quaternion algebra over torch tensors, batched over leading dimensions.

Convention: quaternions are ``[w, x, y, z]``; rotations act on column vectors (``qrot(q, v) = q v q*``);
``qmul(a, b)`` applies ``b`` first, then ``a``. Every function is pure and differentiable.
"""

from __future__ import annotations

import torch

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def qmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product. a, b: (..., 4) -> (..., 4)."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def qconj(q: torch.Tensor) -> torch.Tensor:
    """Conjugate (the inverse of a unit quaternion). q: (..., 4)."""
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def qrot(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate vectors by unit quaternions. q: (..., 4), v: (..., 3) -> (..., 3)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * torch.cross(u, v, dim=-1)
    return v + w * t + torch.cross(u, t, dim=-1)


def qnormalize(q: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    """Scale to unit norm. q: (..., 4)."""
    return q / q.norm(dim=-1, keepdim=True).clamp_min(eps)


def qfix(q: torch.Tensor, dim: int = -2) -> torch.Tensor:
    """Hemisphere continuity along a time axis: flip q_t when dot(q_t, q_{t-1}) < 0.

    q: (..., T, J, 4) with time at ``dim`` (default -2 means (..., T, 4) per joint when J is absent;
    pass ``dim=-3`` for (..., T, J, 4)). Returns the same shape.
    """
    q = q.movedim(dim, 0)
    dots = (q[1:] * q[:-1]).sum(-1)
    flips = torch.cumsum((dots < 0).to(torch.int64), dim=0) % 2
    sign = torch.cat([torch.zeros_like(flips[:1]), flips], dim=0)
    out = torch.where(sign.unsqueeze(-1).bool(), -q, q)
    return out.movedim(0, dim)


def axis_angle(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """Quaternion from unit axes (..., 3) and angles (...) in radians."""
    half = 0.5 * angle
    return torch.cat([torch.cos(half).unsqueeze(-1), torch.sin(half).unsqueeze(-1) * axis], dim=-1)


def _axis_times(axis: int, c: torch.Tensor, s: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """q ⊗ (c, s·e_axis): a product with an axis rotation, written out (6 of its 16 terms are zero)."""
    w, v = q[..., 0], [q[..., 1], q[..., 2], q[..., 3]]
    a, b, d = axis, (axis + 1) % 3, (axis + 2) % 3
    out = [None, None, None]
    out[a] = v[a] * c + w * s
    out[b] = v[b] * c + v[d] * s
    out[d] = v[d] * c - v[b] * s
    return torch.stack((w * c - v[a] * s, *out), dim=-1)


def euler_to_quat(angles: torch.Tensor, order: str) -> torch.Tensor:
    """Intrinsic Euler angles to quaternions, as BVH defines them.

    angles: (..., k) in radians, angles[..., i] about axis ``order[i]`` (e.g. order "ZXY", k = len(order)).
    BVH applies the channels left to right as intrinsic rotations: R = R_order[0] R_order[1] R_order[2].
    """
    half = 0.5 * angles
    c, s = torch.cos(half), torch.sin(half)
    first = _AXIS_INDEX[order[0]]
    parts = [c[..., 0], torch.zeros_like(c[..., 0]), torch.zeros_like(c[..., 0]), torch.zeros_like(c[..., 0])]
    parts[1 + first] = s[..., 0]
    q = torch.stack(parts, dim=-1)
    for i, axis_name in enumerate(order[1:], start=1):
        q = _axis_times(_AXIS_INDEX[axis_name], c[..., i], s[..., i], q)
    return q


def qbetween(u: torch.Tensor, v: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    """Shortest-arc rotation taking direction u to direction v. u, v: (..., 3), any non-zero length.

    Antiparallel inputs have no unique shortest arc; a half-turn about an axis perpendicular to u is
    returned so the result is always a valid unit quaternion.
    """
    u = u / u.norm(dim=-1, keepdim=True).clamp_min(eps)
    v = v / v.norm(dim=-1, keepdim=True).clamp_min(eps)
    w = 1.0 + (u * v).sum(-1, keepdim=True)
    q = torch.cat([w, torch.cross(u, v, dim=-1)], -1)
    anti = w < 1e-7
    if bool(anti.any()):  # rare: only then build the fallback axis
        helper = torch.where(u[..., :1].abs() < 0.9, u.new_tensor([1.0, 0.0, 0.0]), u.new_tensor([0.0, 1.0, 0.0]))
        perp = torch.cross(u, helper.expand_as(u), dim=-1)
        perp = perp / perp.norm(dim=-1, keepdim=True).clamp_min(eps)
        q = torch.where(anti, torch.cat([torch.zeros_like(w), perp], -1), q)
    return qnormalize(q)


def matrix_to_quat(m: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) to unit quaternions (..., 4) with w >= 0 (Shepperd's method)."""
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    candidates = torch.stack(
        (
            torch.stack((1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]), -1),
            torch.stack((m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]), -1),
            torch.stack((m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22, m[..., 1, 2] + m[..., 2, 1]), -1),
            torch.stack((m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 - m00 - m11 + m22), -1),
        ),
        dim=-2,
    )
    # Pick the numerically best-conditioned candidate: the one with the largest diagonal term.
    diag = torch.stack((1 + trace, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22), -1)
    best = diag.argmax(-1, keepdim=True)
    q = torch.gather(candidates, -2, best.unsqueeze(-1).expand(best.shape + (4,))).squeeze(-2)
    q = qnormalize(q)
    return torch.where(q[..., :1] < 0, -q, q)


def qslerp(a: torch.Tensor, b: torch.Tensor, t: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    """Spherical linear interpolation along the shorter arc. a, b: (..., 4); t broadcastable to (..., 1)."""
    dot = (a * b).sum(-1, keepdim=True)
    b = torch.where(dot < 0, -b, b)
    dot = dot.abs().clamp(max=1.0)
    theta = torch.acos(dot)
    sin_theta = torch.sin(theta)
    near = sin_theta < eps
    safe = torch.where(near, torch.ones_like(sin_theta), sin_theta)
    wa = torch.where(near, 1.0 - t, torch.sin((1.0 - t) * theta) / safe)
    wb = torch.where(near, t, torch.sin(t * theta) / safe)
    return qnormalize(wa * a + wb * b)


def qangle(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angle in radians of the rotation taking a to b (geodesic distance). a, b: (..., 4) -> (...)."""
    dot = (a * b).sum(-1).abs().clamp(max=1.0)
    return 2.0 * torch.acos(dot)


def qspread(q: torch.Tensor) -> torch.Tensor:
    """The largest angle (radians) between any two of the T rotations (..., T, 4) -> (...): how far a joint turns
    within a sequence, whichever frames it turns between (q and -q are one rotation)."""
    return qangle(q[..., :, None, :], q[..., None, :, :]).amax((-1, -2))


def quat_to_euler(q: torch.Tensor, order: str, locked_cos: float = 1e-9) -> torch.Tensor:
    """Intrinsic Euler angles (..., 3), radians, about ``order``'s axes: the inverse of ``euler_to_quat``.

    q: (..., 4) unit quaternions (q and -q give the same angles). Read off the rotation matrix, so it holds at
    gimbal lock too (there the third angle is set to 0 and the first takes the whole turn); the middle angle is
    in [-π/2, π/2]. Used by the BVH exporter and by the generator's motion loss (paper Eq. 8).
    """
    i, j, k = (_AXIS_INDEX[a] for a in order)
    sign = 1.0 if (j - i) % 3 == 1 else -1.0  # cyclic (XYZ, YZX, ZXY) or anti-cyclic axis order
    eye = torch.eye(3, dtype=q.dtype, device=q.device)
    m = torch.stack([qrot(q, eye[c].expand(q.shape[:-1] + (3,))) for c in range(3)], dim=-1)
    cos_b = torch.hypot(m[..., i, i], m[..., i, j])
    beta = torch.atan2(sign * m[..., i, k], cos_b)
    locked = cos_b < locked_cos
    alpha = torch.where(locked, torch.atan2(sign * m[..., k, j], m[..., j, j]),
                        torch.atan2(-sign * m[..., j, k], m[..., k, k]))
    gamma = torch.where(locked, torch.zeros_like(beta), torch.atan2(-sign * m[..., i, j], m[..., i, i]))
    return torch.stack((alpha, beta, gamma), dim=-1)


def qlog(q: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    """Rotation vectors (..., 3) of unit quaternions (..., 4): axis times angle, the exponential map (Grassia).
    The angle is 2·atan2(|v|, w) in [0, 2π], so q and -q (one rotation) give different vectors: keep a sequence
    hemisphere-continuous (``qfix``) and the vectors are continuous; ``qexp`` returns q itself, not -q."""
    v, w = q[..., 1:], q[..., :1]
    s = torch.linalg.vector_norm(v, dim=-1, keepdim=True)
    angle = 2.0 * torch.atan2(s, w)
    small = s <= eps
    scale = torch.where(small, 2.0 / w.abs().clamp_min(0.5), angle / torch.where(small, torch.ones_like(s), s))
    # -1 (a turn by 2π about no particular axis) has no direction in v: any axis will do, +x here
    full_turn = small & (w < 0)
    return torch.where(full_turn, torch.cat([angle, torch.zeros_like(v[..., :2])], -1), v * scale)


def qexp(r: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    """Unit quaternions (..., 4) of rotation vectors (..., 3) (the inverse of ``qlog``)."""
    angle = torch.linalg.vector_norm(r, dim=-1, keepdim=True)
    half = 0.5 * angle
    scale = torch.where(angle > eps, torch.sin(half) / torch.where(angle > eps, angle, torch.ones_like(angle)),
                        0.5 - angle * angle / 48.0)
    return torch.cat([torch.cos(half), r * scale], dim=-1)


def yaw(angle: torch.Tensor) -> torch.Tensor:
    """Rotations about +Y by ``angle`` (...) radians -> (..., 4); yaw(α) turns +Z towards (sin α, 0, cos α)."""
    half = 0.5 * angle
    zero = torch.zeros_like(half)
    return torch.stack((torch.cos(half), zero, torch.sin(half), zero), dim=-1)
