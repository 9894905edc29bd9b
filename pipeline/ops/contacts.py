"""Foot contacts, gait events and the stepping phase, in torch, batched over leading dims.

Contacts are decided per point (heel and toe of each foot) from two measurements that transfer between
datasets and marker sets: the point's speed in m/s, and its height above the point's own stance height
(its low percentile over the sequence: an ankle joint, a heel marker and a toe joint rest at different
heights). A point is in contact when it is slow AND low, then a median filter removes flicker. "Slow" has
hysteresis: a point lands when its speed drops below ``landing_speed`` and stays down until it exceeds
``max_speed``. A heel still decelerates through ~1 m/s while it is a centimetre or two above the floor, and a
toe accelerates through the same speeds as it pushes off, so one threshold puts strikes early or offs early;
checked against annotated events in reports/contacts.json.

One implementation: annotation (now) and training losses (later) both call these functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from pipeline.ops.geometry import sliding_windows, wrap_phase

CONTACT_POINTS = ("left_heel", "left_toe", "right_heel", "right_toe")


@dataclass(frozen=True)
class ContactConfig:
    max_speed: float = 1.0  # m/s: a point moving faster than this is not (or no longer) on the floor
    landing_speed: float = 0.8  # m/s: a point comes down only once slower than this (<= max_speed)
    max_height: float = 0.05  # m above the point's stance height
    stance_quantile: float = 0.05  # the point's stance height: this quantile of its height over the sequence
    median_seconds: float = 0.1  # median filter length (rounded to an odd number of frames, >= 1)
    min_event_gap_seconds: float = 0.2  # contacts separated by less than this are merged (one step)


def point_speed(points: torch.Tensor, fps: float) -> torch.Tensor:
    """Speed (m/s) of points (..., T, P, 3) by central differences (one-sided at the ends) -> (..., T, P)."""
    if points.shape[-3] < 2:
        return torch.zeros(points.shape[:-1], dtype=points.dtype)
    velocity = torch.gradient(points, spacing=1.0 / fps, dim=-3)[0]
    return velocity.norm(dim=-1)


def median_filter(flags: torch.Tensor, frames: int) -> torch.Tensor:
    """Binary median filter along the time axis of (..., T, P) booleans, odd window, edges replicated."""
    if frames <= 1:
        return flags
    votes = sliding_windows(flags.to(torch.float32).movedim(-2, -1), frames).sum(-1)  # (..., P, T)
    return (votes > frames // 2).movedim(-1, -2)


def foot_contacts(points: torch.Tensor, fps: float, cfg: ContactConfig = ContactConfig()) -> torch.Tensor:
    """Contact flags (..., T, P) for heel/toe points (..., T, P, 3), Y up, metres, floor at y = 0 or below.

    Usually P = 4 in CONTACT_POINTS order.
    """
    speed = point_speed(points, fps)
    height = points[..., 1]
    stance = torch.quantile(height.movedim(-2, -1).float(), cfg.stance_quantile, dim=-1).to(height.dtype)
    low = height <= stance.unsqueeze(-2) + cfg.max_height
    raw = _hysteresis(low & (speed <= cfg.max_speed), low & (speed <= cfg.landing_speed))
    frames = max(1, int(round(cfg.median_seconds * fps)) // 2 * 2 + 1)
    return median_filter(raw, frames)


def _hysteresis(stay: torch.Tensor, land: torch.Tensor) -> torch.Tensor:
    """Flags (..., T, P): inside each run of ``stay``, from its first ``land`` frame to the run's end."""
    t = torch.arange(stay.shape[-2]).view(-1, 1).expand(stay.shape[-2:])
    previous = torch.cat([torch.zeros_like(stay[..., :1, :]), stay[..., :-1, :]], dim=-2)
    run_start = torch.where(stay & ~previous, t, -1).cummax(dim=-2).values
    last_landing = torch.where(land & stay, t, -1).cummax(dim=-2).values
    return stay & (last_landing >= run_start)


def foot_events(contacts: torch.Tensor, fps: float, cfg: ContactConfig = ContactConfig()) -> dict[str, list[int]]:
    """Foot-strike and foot-off frames of one sequence from contacts (T, 4) in CONTACT_POINTS order.

    A foot is down while its heel or toe is; strike = first frame down, off = first frame up again.
    Contact gaps shorter than ``min_event_gap_seconds`` are closed first (one step, not two).
    Returns {"left_strike": [...], "left_off": [...], "right_strike": [...], "right_off": [...]}.
    """
    events: dict[str, list[int]] = {}
    gap = int(round(cfg.min_event_gap_seconds * fps))
    for side, (heel, toe) in (("left", (0, 1)), ("right", (2, 3))):
        down = (contacts[:, heel] | contacts[:, toe]).tolist()
        down = _close_gaps(down, gap)
        strikes = [t for t in range(1, len(down)) if down[t] and not down[t - 1]]
        offs = [t for t in range(1, len(down)) if down[t - 1] and not down[t]]
        events[f"{side}_strike"] = strikes
        events[f"{side}_off"] = offs
    return events


def _close_gaps(down: list[bool], gap: int) -> list[bool]:
    out = list(down)
    t = 0
    while t < len(out):
        if not out[t]:
            start = t
            while t < len(out) and not out[t]:
                t += 1
            if 0 < start and t < len(out) and t - start < gap:
                out[start:t] = [True] * (t - start)
        else:
            t += 1
    return out


def stepping_phase(frames: int, left_strikes: list[int], right_strikes: list[int]) -> torch.Tensor:
    """Stepping phase θ (T,) in [0, 2π): 0 at each left strike, π at the next right strike, linear between.

    Outside the first/last strike the nearest half-cycle's rate is extrapolated; with fewer than two strikes
    in total the phase is undefined and NaN is returned.
    """
    marks = sorted([(t, 0.0) for t in left_strikes] + [(t, torch.pi) for t in right_strikes])
    # Keep alternating marks only (two strikes of the same foot in a row: keep the later one).
    anchors: list[tuple[int, float]] = []
    for t, value in marks:
        if anchors and anchors[-1][1] == value:
            anchors[-1] = (t, value)
        else:
            anchors.append((t, value))
    if len(anchors) < 2:
        return torch.full((frames,), float("nan"), dtype=torch.float64)
    times = torch.tensor([t for t, _ in anchors], dtype=torch.float64)
    unwrapped = torch.tensor([anchors[0][1] + torch.pi * k for k in range(len(anchors))], dtype=torch.float64)
    t = torch.arange(frames, dtype=torch.float64)
    idx = torch.searchsorted(times, t, right=True).clamp(1, len(anchors) - 1)
    t0, t1 = times[idx - 1], times[idx]
    v0, v1 = unwrapped[idx - 1], unwrapped[idx]
    theta = v0 + (t - t0) * (v1 - v0) / (t1 - t0)
    return wrap_phase(theta)


def phase_rate(theta: torch.Tensor) -> torch.Tensor:
    """ω^t = θ^t − θ^{t−1} wrapped to [0, 2π); ω^0 = ω^1. theta: (..., T)."""
    step = wrap_phase(theta[..., 1:] - theta[..., :-1])
    return torch.cat([step[..., :1], step], dim=-1)
