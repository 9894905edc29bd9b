"""Pose discontinuities: steps between consecutive frames that no body can make.

A converter's T-pose in frame 0, a rest pose at the end, a teleported frame or frames dropped from the middle of a
capture all show the same way: some joint moves further in one frame than a physical speed allows. The clip is cut
at every such step; the pieces long enough for a gait window are kept as clips of their own, the others dropped,
and each step is reported with its frame. Pure functions of joint positions; nothing here knows files.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Discontinuity:
    """The step from ``frame`` to ``frame + 1`` (source frames): ``joint`` moved at ``speed`` m/s."""

    frame: int
    joint: int
    speed: float


def pose_jumps(points: torch.Tensor, frame_time: float, max_speed: float) -> list[Discontinuity]:
    """Steps of joint positions (T, J, 3) in metres where a joint moves faster than ``max_speed`` m/s."""
    if points.shape[0] < 2:
        return []
    speed = (points[1:] - points[:-1]).norm(dim=-1) / frame_time  # (T - 1, J)
    fastest, joint = speed.max(dim=-1)
    frames = torch.nonzero(~(fastest <= max_speed)).flatten().tolist()  # a NaN step is a discontinuity too
    return [Discontinuity(f, int(joint[f]), float(fastest[f])) for f in frames]


def continuous_spans(frames: int, jumps: list[Discontinuity], min_frames: int) -> tuple[list[tuple[int, int]],
                                                                                       list[tuple[int, int]]]:
    """The clip (``frames`` frames) cut at every jump: (kept spans, dropped spans), each span (first, end) with end
    exclusive; a span is kept when it holds at least ``min_frames`` frames."""
    cuts = [0] + [j.frame + 1 for j in jumps] + [frames]
    spans = [(a, b) for a, b in zip(cuts, cuts[1:]) if b > a]
    return [s for s in spans if s[1] - s[0] >= min_frames], [s for s in spans if s[1] - s[0] < min_frames]
