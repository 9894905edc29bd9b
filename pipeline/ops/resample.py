"""Time-based resampling and 60-frame windows.

Rotations are interpolated by SLERP and positions linearly at the target instants; frames are never
dropped or duplicated by index, so any source rate maps onto any target rate without aliasing steps.
"""

from __future__ import annotations

import math

import torch

from pipeline.ops.quaternion import qfix, qslerp

SNAP_FRAMES = 1e-3


def target_times(frames: int, frame_time: float, target_fps: float) -> torch.Tensor:
    """Instants (seconds) of the target frames inside the source clip [0, (frames-1) * frame_time]."""
    duration = (frames - 1) * frame_time
    count = int(math.floor(duration * target_fps + 1e-6)) + 1
    return torch.arange(count, dtype=torch.float64) / target_fps


def resample(root_positions: torch.Tensor, rotations: torch.Tensor, frame_time: float,
             target_fps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Resample a clip in time.

    root_positions: (F, 3); rotations: (F, J, 4), hemisphere-continuous. Returns (N, 3), (N, J, 4).
    """
    frames = root_positions.shape[0]
    times = target_times(frames, frame_time, target_fps)
    u = times / frame_time
    # Instants within 1/1000 of a frame of a source frame take that frame: files store rounded frame
    # times (0.0333333 for 1/30 s), and the drift that rounding builds up is not motion.
    nearest = torch.round(u)
    u = torch.where((u - nearest).abs() < SNAP_FRAMES, nearest, u)
    lo = u.floor().long().clamp(max=frames - 1)
    hi = (lo + 1).clamp(max=frames - 1)
    alpha = (u - lo.to(u.dtype)).to(root_positions.dtype)
    root = torch.lerp(root_positions[lo], root_positions[hi], alpha[:, None])
    if bool((alpha == 0).all()):
        return root, rotations[lo]
    rot = qslerp(rotations[lo], rotations[hi], alpha[:, None, None])
    return root, qfix(rot, dim=0)


def window_starts(frames: int, window: int, stride: int) -> list[int]:
    """Start frames of the full windows of ``window`` frames, every ``stride`` frames."""
    return list(range(0, frames - window + 1, stride)) if frames >= window else []
