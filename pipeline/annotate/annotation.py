"""Annotation of gait windows: foot contacts, stepping phase, movement and affective features.

Windows of one clip overlap, so contacts and the stepping phase are computed on the clip rebuilt from its
windows (they need strikes before and after a window's edges) and then cut back into windows; the
per-frame features are computed on each window. Every formula lives in pipeline.ops.contacts and
pipeline.ops.features; this module only arranges the data.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.ops.contacts import CONTACT_POINTS, ContactConfig, foot_contacts, foot_events, phase_rate, stepping_phase
from pipeline.ops.features import AFFECTIVE_NAMES, MOVEMENT_NAMES, movement_features, pose_affective_features
from pipeline.ops.geometry import odd_frames
from pipeline.core.schema import ANNOTATIONS, units
from pipeline.core.skeleton import Skeleton


@dataclass(frozen=True)
class AnnotateConfig:
    fps: float = 30.0
    contacts: ContactConfig = field(default_factory=ContactConfig)
    lowpass_seconds: float = 0.3

    @property
    def lowpass_frames(self) -> int:
        return odd_frames(self.lowpass_seconds, self.fps)


def rebuild_clips(clip_ids: Sequence[str], starts: np.ndarray, positions: np.ndarray,
                  window: int) -> dict[str, tuple[np.ndarray, list[tuple[int, int]]]]:
    """{clip_id: (clip positions (T, 21, 3), [(row, first frame), ...])} from overlapping windows; frames count
    from the clip's first window (a clip cut from the middle of a file starts later in it)."""
    rows_by_clip: dict[str, list[int]] = defaultdict(list)
    for row, cid in enumerate(clip_ids):
        rows_by_clip[cid].append(row)
    clips = {}
    for cid, rows in rows_by_clip.items():
        firsts = [int(starts[r]) for r in rows]
        firsts = [f - min(firsts) for f in firsts]
        clip = np.zeros((max(firsts) + window, *positions.shape[2:]), dtype=positions.dtype)
        for r, s in zip(rows, firsts):
            clip[s:s + window] = positions[r]
        clips[cid] = (clip, list(zip(rows, firsts)))
    return clips


def annotate_clip(positions: torch.Tensor, skeleton: Skeleton, cfg: AnnotateConfig) -> dict[str, Any]:
    """Contacts (T, 4), events, phase θ (T,) and ω (T,) of one clip (T, 21, 3)."""
    points = positions[:, [skeleton.index(n) for n in CONTACT_POINTS]]
    contacts = foot_contacts(points, cfg.fps, cfg.contacts)
    events = foot_events(contacts, cfg.fps, cfg.contacts)
    theta = stepping_phase(positions.shape[0], events["left_strike"], events["right_strike"])
    return {"contacts": contacts, "events": events, "phase": theta, "phase_rate": phase_rate(theta)}


def stored_phase(phase: np.ndarray) -> np.ndarray:
    """The stepping phase as stored (float32): float32 rounds phases just below 2π up to 2π; keep [0, 2π)."""
    out = np.asarray(phase, dtype=np.float32).copy()
    out[out >= np.float32(2 * np.pi)] = 0.0
    return out


def annotate_windows(clip_ids: Sequence[str], t_start: np.ndarray, positions: np.ndarray, rotations: np.ndarray,
                     skeleton: Skeleton, cfg: AnnotateConfig) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Annotations for every window: arrays (rows, ...) and a summary per clip.

    The affective features go through the generator's own path (forward kinematics of the stored
    rotations, ``pose_affective_features``), so annotation and training compute them identically.
    """
    rows, window = positions.shape[0], positions.shape[1]
    starts = np.round(np.asarray(t_start) * cfg.fps).astype(int)
    out = {
        "contacts": np.zeros((rows, window, len(CONTACT_POINTS)), np.float32),
        "phase": np.zeros((rows, window), np.float32),
        "phase_rate": np.zeros((rows, window), np.float32),
    }
    summary: dict[str, Any] = {}
    for cid, (clip, placed) in rebuild_clips(clip_ids, starts, positions, window).items():
        ann = annotate_clip(torch.from_numpy(clip).double(), skeleton, cfg)
        for r, s in placed:
            for name in ("contacts", "phase", "phase_rate"):
                out[name][r] = ann[name][s:s + window].numpy()
        down = ann["contacts"].numpy()
        summary[cid] = {
            "frames": int(clip.shape[0]),
            "left_strikes": len(ann["events"]["left_strike"]),
            "right_strikes": len(ann["events"]["right_strike"]),
            "stance_fraction": float(((down[:, 0] + down[:, 1] > 0).mean() + (down[:, 2] + down[:, 3] > 0).mean()) / 2),
            "phase_defined": bool(torch.isfinite(ann["phase"]).all()),
        }
    out["phase"] = stored_phase(out["phase"])
    pos = torch.from_numpy(positions).double()
    offsets = torch.from_numpy(skeleton.offsets)
    out["affective"] = pose_affective_features(pos[..., 0, :], torch.from_numpy(rotations).double(), offsets,
                                               skeleton.parents).to(torch.float32).numpy()
    out["movement"] = movement_features(pos, cfg.lowpass_frames).to(torch.float32).numpy()
    return out, summary


ANNOTATION_META = {
    "contact_points": list(CONTACT_POINTS),
    "affective_names": list(AFFECTIVE_NAMES),
    "movement_names": list(MOVEMENT_NAMES),
    "units": units(ANNOTATIONS),
}


def annotation_report(table: pa.Table, clips: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Counts, clips without a stepping phase, stance fractions (all clips, walks) and the per-clip figures."""
    stance = np.array([c["stance_fraction"] for c in clips.values()])
    contents = dict(zip(table.column("clip_id").to_pylist(), table.column("content").to_pylist()))
    walk_stance = np.array([c["stance_fraction"] for cid, c in clips.items() if contents[cid] == "walk"])
    return {
        "gaits": table.num_rows,
        "clips": len(clips),
        "clips_without_phase": sorted(cid for cid, c in clips.items() if not c["phase_defined"]),
        "stance_fraction": {"all_median": float(np.median(stance)),
                            "walk_median": float(np.median(walk_stance)) if walk_stance.size else None,
                            "walk_p05": float(np.percentile(walk_stance, 5)) if walk_stance.size else None,
                            "walk_p95": float(np.percentile(walk_stance, 95)) if walk_stance.size else None},
        "per_clip": clips,
    }
