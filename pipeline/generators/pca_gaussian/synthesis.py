"""Walks from the PCA + Gaussian model (seed 001 §7, with our placement): cycle after cycle, scores drawn from the
emotion's blended Gaussians, reconstructed, turned back into quaternions, laid on a time line at their drawn
durations, cross-faded, steered along the planned path and carried by the stance foot.

* **Emotion per cycle:** a cycle's model is the blend (``model.blend``) at the per-frame emotion of the frame it
  starts at, so a transition moves m cycle by cycle from its start emotion to its end emotion (the paper's future
  work, §9). The weights are the dataset's expression rule m^p / Σ m^p (``generate.expression_sharpness``, shared
  with the autoregressive family, so a mixture label reads the same for every family: mostly its dominant
  emotion, shaded by the next).
* **Time line:** each gait starts at a seeded random point of its first cycle (not always at a right strike) and
  runs ``context`` frames (never published; annotation's context, as a seed prefix is) before its frames. A cycle
  of duration D frames covers D frames of the line; frame f reads its cycle at sample 40 (f - start) / D by SLERP
  between the two nearest of the cycle's samples (its last sample leads to its first: a cycle is periodic).
* **Joining:** within ``crossfade_frames`` of a boundary the two cycles, each read periodically, are SLERPed with a
  smoothstep weight from the one ending to the one beginning.
* **Heading:** each reconstructed cycle's pelvis heading loses its mean and linear trend over the cycle (a cycle
  neither faces aside nor turns); the body's direction ψ steers towards the point ``lookahead_m`` ahead on the
  path (pure pursuit, at most ``max_turn_deg_per_s``), and the pelvis is yaw(ψ) times the cycle's.
* **Root:** the lowest heel/toe point among the feet that the cycle's own stepping phase (π at each cycle's start)
  says are down stays where it stood (``rollout.placed_step``, paper §7.2; with ``generate.forward_steps_only``
  its part against the travel direction is dropped, as for the autoregressive family), and stays at the real
  walks' median height of the lowest foot point (so the root rises and falls with the legs); then root
  smoothing (its own window, ``WalkSettings.root_smoothing_s``, by the autoregressive family's rule) and the same
  foot locking as the autoregressive family (``generate`` params).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.generators.autoregressive.network import FOOT_JOINTS, sharpened
from pipeline.generators.autoregressive.rollout import PlacementConfig, placed_step, smoothed_root, swinging_points
from pipeline.generators.base import GeneratedMotion, fit_placed
from pipeline.generators.pca_gaussian.model import StyleModel, blend, sample_cycles
from pipeline.ops.footlock import lock_feet
from pipeline.ops.geometry import (
    arc_lengths,
    direction_of,
    heading_angle,
    odd_frames,
    pursue,
    unit_direction,
    wrap_phase,
)
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import qexp, qfix, qmul, qslerp, yaw


@dataclass(frozen=True)
class WalkSettings:
    """How cycles become a walk (the pipeline params' ``pca_gaussian.synthesis``)."""

    crossfade_frames: float = 6.0
    context: int = 18
    redraws: int = 5
    # the root smoothing of this family, by the autoregressive family's rule (the shortest window whose root speed
    # change per frame is at most real walks'): 0 s gives 0.094 m/s, 0.1 s 0.062; real 0.092
    root_smoothing_s: float = 0.1
    # laid onto its path after the walk (``generate.path_fit_s``) instead of steered along it; off: the fit moves
    # the stance feet, whose locking then bends the legs (toe spread variation +0.5-1.0 real SD; summary MLP
    # recognisability 0.597 -> 0.552), while the stance-foot steering keeps this family 0.8-1.9x real sway off its path
    path_fit: bool = False

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> WalkSettings:
        return cls(**{k: type(getattr(cls, k))(v) for k, v in dict(d or {}).items()})


@dataclass
class CycleModel:
    """What synthesis needs of a fit: the basis mean (P,) and kept components (k, P), the four emotion models, the
    cycles' sample count and joints, and the real walks' median height of the lowest heel/toe point (m)."""

    mean: np.ndarray
    components: np.ndarray
    models: list[StyleModel]
    frames: int
    joints: int
    foot_floor_m: float

    def quaternions(self, scores: np.ndarray) -> torch.Tensor:
        """(n, k) scores -> (n, frames, joints, 4) hemisphere-continuous local rotations, the pelvis heading of
        each cycle without its mean and linear trend."""
        flat = self.mean + scores @ self.components[: scores.shape[1]]
        q = qfix(qexp(torch.from_numpy(flat.reshape(len(scores), self.frames, self.joints, 3))), dim=-3)
        heading = torch.from_numpy(np.unwrap(heading_angle(q[:, :, 0]).numpy(), axis=1))
        k = torch.arange(self.frames, dtype=q.dtype)
        centred = k - k.mean()
        slope = ((heading - heading.mean(1, keepdim=True)) * centred).sum(1, keepdim=True) / (centred ** 2).sum()
        trend = heading.mean(1, keepdim=True) + slope * centred
        root = qmul(yaw(-trend), q[:, :, 0])
        return torch.cat([root[:, :, None], q[:, :, 1:]], 2)


def _time_line(model: CycleModel, emotions: np.ndarray, frames: int, context: int, settings: WalkSettings,
               rng: np.random.Generator, counts: dict[str, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One gait's cycles: scores (n, k), start times (n,) and durations (n,) covering frames 0 .. frames - 1 of
    the line (plus the cross-fade margin); emotions (T, 4) per gait frame (line frame f is gait frame f - context)."""
    scores, starts, durations = [], [], []
    previous, start = None, None
    while start is None or start < frames + settings.crossfade_frames:
        at = int(np.clip(round((start if start is not None else 0.0) - context), 0, len(emotions) - 1))
        z, d, c, previous = sample_cycles([blend(model.models, emotions[at])], rng, settings.redraws, previous)
        for key, v in c.items():
            counts[key] = counts.get(key, 0) + v
        duration = max(float(d[0]), 8.0)  # a drawn duration this short is no step; a floor keeps the line moving
        if start is None:
            start = -rng.uniform(0.0, duration)  # the gait starts anywhere in its first cycle
        scores.append(z[0])
        starts.append(start)
        durations.append(duration)
        start = start + duration
    return np.array(scores), np.array(starts), np.array(durations)


def _read(cycle: torch.Tensor, tau: torch.Tensor, duration: torch.Tensor) -> torch.Tensor:
    """Cycles (F, S, J, 4) read periodically at local times tau (F,) frames of durations (F,) -> (F, J, 4)."""
    samples = cycle.shape[1]
    u = torch.remainder(tau / duration * samples, samples)
    lo = u.floor().long().clamp(max=samples - 1)
    hi = (lo + 1) % samples
    rows = torch.arange(len(u))
    return qslerp(cycle[rows, lo], cycle[rows, hi], (u - lo.to(u.dtype))[:, None, None])


def _pose_line(q: torch.Tensor, starts: np.ndarray, durations: np.ndarray, frames: int, fade: float
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Local rotations (frames, J, 4) of one gait's line and its stepping phase (frames,): π at every cycle start."""
    t = torch.arange(frames, dtype=q.dtype)
    s = torch.from_numpy(starts).to(q.dtype)
    d = torch.from_numpy(durations).to(q.dtype)
    index = (torch.searchsorted(s, t, right=True) - 1).clamp(0, len(s) - 1)
    current = _read(q[index], t - s[index], d[index])
    phase = wrap_phase(math.pi + 2 * math.pi * (t - s[index]) / d[index])
    if fade <= 0:
        return current, phase
    # the nearest boundary, and the cycles on both sides of it
    following = (index + 1).clamp(max=len(s) - 1)
    to_next = s[following] - t
    to_prev = t - s[index]
    near_next = (to_next <= to_prev) & (following != index)
    boundary_later = torch.where(near_next, following, index)
    boundary_earlier = (boundary_later - 1).clamp(min=0)
    boundary = s[boundary_later]
    weight = ((t - boundary) / fade + 0.5).clamp(0.0, 1.0)
    weight = weight * weight * (3 - 2 * weight)  # smoothstep
    earlier = _read(q[boundary_earlier], t - s[boundary_earlier], d[boundary_earlier])
    later = _read(q[boundary_later], t - s[boundary_later], d[boundary_later])
    faded = qslerp(earlier, later, weight[:, None, None])
    inside = (weight > 0) & (weight < 1) & (boundary_later != boundary_earlier)
    return torch.where(inside[:, None, None], faded, current), phase


def walk(model: CycleModel, rows: Sequence[dict[str, Any]], paths: torch.Tensor, emotions: torch.Tensor,
         offsets: torch.Tensor, parents: Sequence[int], placement: PlacementConfig,
         settings: WalkSettings = WalkSettings()) -> tuple[GeneratedMotion, dict[str, int]]:
    """Gaits for plan rows (each seeded by its ``plan_seed``): paths (N, K, 2) ground (x, z) in each gait's own
    frame, starting at (0, 0) towards +Z (the gait starts there, facing that way); emotions (N, T, 4) per frame.
    Also the counts of redrawn and clamped scores."""
    n, frames = emotions.shape[:2]
    line = settings.context + frames
    counts: dict[str, int] = {}
    poses, phases = [], []
    expressed = sharpened(emotions.double(), placement.expression_sharpness).numpy()
    for r, row in enumerate(rows):
        rng = np.random.default_rng(int(row["plan_seed"]))
        scores, starts, durations = _time_line(model, expressed[r], line, settings.context, settings, rng, counts)
        pose, phase = _pose_line(model.quaternions(scores), starts, durations, line, settings.crossfade_frames)
        poses.append(pose)
        phases.append(phase)
    local = torch.stack(poses).to(torch.float32)  # (N, L, J, 4), the pelvis without its heading
    theta = torch.stack(phases).to(torch.float32)
    offsets = offsets.to(torch.float32)
    foot_joints = list(FOOT_JOINTS)
    paths = paths.to(torch.float32)
    cumulative = arc_lengths(paths)
    ground = paths[:, 0].clone()
    travel = direction_of(paths[:, 1, 0] - paths[:, 0, 0], paths[:, 1, 1] - paths[:, 0, 1])
    fitted = settings.path_fit and placement.path_fit_s > 0  # then it walks straight on and is laid on the path
    max_turn = 0.0 if fitted else math.radians(placement.max_turn_deg_per_s) / placement.fps
    rotations, roots = [], []
    previous_feet = None
    for t in range(line):
        travel = pursue(travel, ground, paths, cumulative, placement.lookahead_m, max_turn)
        root_rotation = qmul(yaw(travel), local[:, t, 0])
        pose = torch.cat([root_rotation[:, None], local[:, t, 1:]], 1)
        relative = canonical_positions(torch.zeros(n, 3), pose, offsets, parents)[:, foot_joints]
        if previous_feet is not None:
            swinging = swinging_points(theta[:, t], placement.stance_fraction)
            ground = ground + placed_step(previous_feet, relative, unit_direction(travel), placement, swinging)
        previous_feet = relative
        height = model.foot_floor_m - relative[..., 1].min(-1).values
        rotations.append(pose)
        roots.append(torch.stack((ground[:, 0], height, ground[:, 1]), -1))
    rotations = torch.stack(rotations, 1)
    root = torch.stack(roots, 1)
    positions = canonical_positions(root, rotations, offsets, parents)
    window = odd_frames(settings.root_smoothing_s, placement.fps)
    if window > 1:
        half = window // 2
        positions = torch.cat([positions[:, :half], smoothed_root(positions[:, half:], positions[:, :half, 0, [0, 2]],
                                                                  window)], 1)
    if fitted:
        positions, rotations, _ = fit_placed(positions, rotations, paths, placement)
    if placement.foot_lock:
        rotations, positions = lock_feet(rotations, positions[..., 0, :], offsets, parents, placement.fps,
                                         placement.contacts)
    c = settings.context
    return GeneratedMotion(positions=positions[:, c:], rotations=rotations[:, c:],
                           heading=heading_angle(rotations[:, c:, 0]), context_positions=positions[:, :c],
                           conditioned_phase=theta[:, c:], placed_paths=paths), counts
