"""Synthesis of the planned gaits: batched generation from test-split seed prefixes along the planned trajectory
pieces with per-frame emotions, then the same annotation as real gaits.

The seed prefix is not part of a synthetic gait: only the generated frames are kept. The annotation of contacts
and phase runs on prefix + generated frames (strikes before the first generated frame fix its phase) and is then
cut to the generated frames; movement and affective features are computed on the generated window alone, as for
real windows (pipeline.annotate.annotation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.annotate.annotation import AnnotateConfig, annotate_clip, stored_phase
from pipeline.ops.contacts import phase_rate
from pipeline.ops.features import movement_features, pose_affective_features
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.synth.plan import frame_emotions
from pipeline.synth.trajectories import Trajectory, piece_from
from pipeline.core.skeleton import Skeleton


@dataclass(frozen=True)
class SynthesisConfig:
    prefix: int = 18
    frames: int = 60
    path_ahead_m: float = 8.0
    batch: int = 1000


def synthesize(model: EmotiveGaitNet, arrays: dict[str, np.ndarray], row_of: dict[str, int],
               plan: Sequence[dict[str, Any]], emotions: np.ndarray, trajectories: dict[str, Trajectory],
               skeleton: Skeleton, placement: PlacementConfig, annotate: AnnotateConfig, cfg: SynthesisConfig,
               progress: Callable[[int, int], None] | None = None) -> dict[str, np.ndarray]:
    """Arrays (gaits, ...) for every plan row, in plan order: positions, rotations, root_path, heading, contacts,
    phase, phase_rate, affective, movement, emotion_per_frame, the per-gait emotion (mean over the frames) and
    phase_from_condition (bool per gait)."""
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    parts: dict[str, list[np.ndarray]] = {}
    for first in range(0, len(plan), cfg.batch):
        rows = plan[first:first + cfg.batch]
        seed_rows = np.array([row_of[r["seed_gait_id"]] for r in rows])
        seeds = Seeds.from_arrays(arrays, seed_rows, cfg.prefix)
        shapes = torch.from_numpy(np.stack([piece_from(trajectories[r["trajectory_id"]].points, r["start_m"], cfg.path_ahead_m)
                                            for r in rows]).astype(np.float32))
        per_frame = np.stack([frame_emotions(r["recipe"], emotions, cfg.frames) for r in rows])
        g = generate(model, seeds, place_paths(shapes, seeds), torch.from_numpy(per_frame.astype(np.float32)),
                     offsets, skeleton.parents, placement)
        batch = _annotate(g.positions.double(), g.rotations.double(), torch.from_numpy(arrays["positions"][seed_rows,
                          :cfg.prefix]).double(), g.theta.double(), skeleton, annotate)
        batch.update(positions=g.positions.numpy(), rotations=g.rotations.numpy(),
                     root_path=g.positions[:, :, 0, [0, 2]].numpy(), heading=g.heading.numpy(),
                     emotion_per_frame=per_frame, emotion=per_frame.mean(1))  # rows sum to 1
        for k, v in batch.items():
            parts.setdefault(k, []).append(v if v.dtype == bool else np.asarray(v, dtype=np.float32))
        if progress:
            progress(first + len(rows), len(plan))
    return {k: np.concatenate(v) for k, v in parts.items()}


def _annotate(positions: torch.Tensor, rotations: torch.Tensor, prefix_positions: torch.Tensor,
              conditioned_phase: torch.Tensor, skeleton: Skeleton, cfg: AnnotateConfig) -> dict[str, np.ndarray]:
    """Annotations of generated gaits. Where the contacts give too few strikes to define the stepping phase, the
    phase the generator was conditioned on is kept (``phase_from_condition`` flags those gaits)."""
    prefix = prefix_positions.shape[1]
    contacts, phase, rate, fallback = [], [], [], []
    for n in range(positions.shape[0]):
        ann = annotate_clip(torch.cat([prefix_positions[n], positions[n]]), skeleton, cfg)
        theta = ann["phase"][prefix:]
        fallback.append(not bool(torch.isfinite(theta).all()))
        if fallback[-1]:
            theta = conditioned_phase[n]
        contacts.append(ann["contacts"][prefix:].numpy())
        phase.append(theta.numpy())
        rate.append(phase_rate(theta).numpy())
    offsets = torch.from_numpy(skeleton.offsets)
    return {"contacts": np.stack(contacts), "phase": stored_phase(np.stack(phase)), "phase_rate": np.stack(rate),
            "phase_from_condition": np.array(fallback),
            "affective": pose_affective_features(positions[..., 0, :], rotations, offsets, skeleton.parents).numpy(),
            "movement": movement_features(positions, cfg.lowpass_frames).numpy()}


def copied_frames(synthetic: np.ndarray, real: np.ndarray, decimals: int = 4) -> int:
    """How many synthetic frames repeat a real frame's body pose: the 20 non-root local rotations of (G, T, 21, 4)
    arrays equal after rounding to ``decimals`` (the root's is left out: a copy turned to another heading is
    still a copy)."""
    def keys(a: np.ndarray) -> list[bytes]:
        flat = np.round(a[..., 1:, :].reshape(-1, (a.shape[-2] - 1) * a.shape[-1]).astype(np.float64), decimals)
        return [row.tobytes() for row in flat + 0.0]  # + 0.0: -0.0 and 0.0 are the same value
    real_keys = set(keys(real))
    return sum(k in real_keys for k in keys(synthetic))
