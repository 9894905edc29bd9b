"""Walk cycles for the PCA + Gaussian family (seed 001, Tilmanne & Dutoit §3–4): two-step cycles of the real train
clips, each starting at a right-foot strike, turned to a common heading and resampled to a fixed length.

A cycle runs from one right-foot strike to the next (stepping phase π to π: both feet step once). Strikes come from
the annotation's own contact rule (``annotate.annotate_clip`` on the clip rebuilt from its windows), so a cycle
starts where every annotated gait says the right foot lands. Only forward walks are kept: the clip's content is
``cfg.content`` (Bandai's sideways ``walk-left``/``walk-right`` and backwards ``walk-back`` are other contents and
stay out; so do the turning walks ``walk-turn-*``), the body turns by at most ``max_turn_deg`` over the cycle, and
the root travels within ``max_drift_deg`` of the heading the cycle starts with. Each kept cycle's root rotations
are turned by minus that starting heading (every cycle faces +Z at its start), every joint's quaternions are made
hemisphere-continuous over the cycle and put in the hemisphere of their mean, the cycle is SLERP-resampled in time
to ``frames`` frames (``ops.resample``: the strike-to-strike span, its end excluded, as it starts the next cycle)
and stored as the rotation vectors (``ops.quaternion.qlog``) of its 21 local rotations: frames x 21 x 3 values.
Its duration (frames at the clip rate) and its stride (the root's ground displacement over the cycle in the starting
heading frame) are kept beside it.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.annotate.annotation import AnnotateConfig, annotate_clip
from pipeline.core.emotions import EMOTIONS, dominant_index
from pipeline.core.skeleton import Skeleton
from pipeline.generators.base import train_clips
from pipeline.ops.geometry import wrap_angle
from pipeline.ops.quaternion import qfix, qlog, qmul, yaw
from pipeline.ops.resample import resample


@dataclass(frozen=True)
class CycleConfig:
    """Which cycles are cut and how (the pipeline params' ``pca_gaussian.cycles``)."""

    frames: int = 40  # samples per cycle after resampling (the paper: 40)
    content: str = "walk"  # forward walks; sideways, backwards and turning walks are other contents
    split: str = "train"
    max_turn_deg: float = 30.0  # heading change over one cycle
    max_drift_deg: float = 25.0  # angle between the cycle's ground displacement and its starting heading
    min_frames: int = 18  # a two-step cycle lasts 0.6-2.0 s at 30 fps; outside that it is no walk cycle
    max_frames: int = 60

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> "CycleConfig":
        d = dict(d or {})
        return cls(**{k: type(getattr(cls, k))(v) for k, v in d.items()})


@dataclass
class Cycles:
    """C cycles: rotation vectors (C, frames, 21, 3) float64, durations (C,) frames at the clip rate, strides
    (C, 2) m (sideways +x, ahead +z of the starting heading), emotion (C, 4) (NaN rows: unlabelled), and per cycle
    its clip, style, label method, first frame in the rebuilt clip and whether it directly follows the cycle
    before it in the same clip (``follows``: the pairs the largest adjacent change is measured on)."""

    rotvec: np.ndarray
    durations: np.ndarray
    strides: np.ndarray
    emotion: np.ndarray
    clip_id: list[str]
    style: list[str]
    label_method: list[str | None]
    start_frame: np.ndarray
    follows: np.ndarray
    dropped: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.durations)

    def flat(self) -> np.ndarray:
        """(C, frames * 21 * 3): one row per cycle, the PCA's observations."""
        return self.rotvec.reshape(len(self), -1)

    def dominant(self) -> np.ndarray:
        """(C,) index of each cycle's dominant emotion (EMOTIONS order), -1 where unlabelled."""
        return dominant_index(self.emotion)

    def counts(self) -> dict[str, Any]:
        """Cycles per style and per dominant emotion, and the cycles left out with their reasons."""
        dominant = self.dominant()
        return {"cycles": len(self), "per_style": dict(sorted(Counter(self.style).items())),
                "per_emotion": {name: int((dominant == k).sum()) for k, name in enumerate(EMOTIONS)},
                "unlabelled": int((dominant < 0).sum()), "clips": len(set(self.clip_id)),
                "duration_frames_p10_p50_p90": [round(float(np.percentile(self.durations, q)), 1)
                                                for q in (10, 50, 90)] if len(self) else [],
                "left_out": dict(sorted(self.dropped.items()))}


def _canonical_rotvec(rotations: torch.Tensor, heading: float, frames: int) -> np.ndarray:
    """(D + 1, 21, 4) local rotations of a strike-to-strike span -> (frames, 21, 3) rotation vectors, the root
    turned by minus ``heading``, time-resampled by SLERP to ``frames`` samples of the span (its end excluded)."""
    turn = yaw(torch.tensor(-heading, dtype=rotations.dtype))
    rotations = torch.cat([qmul(turn.expand_as(rotations[:, 0]), rotations[:, 0])[:, None], rotations[:, 1:]], 1)
    rotations = qfix(rotations, dim=0)
    span = rotations.shape[0] - 1
    root = torch.zeros(rotations.shape[0], 3, dtype=rotations.dtype)
    _, resampled = resample(root, rotations, 1.0, frames / span)  # frame time 1: instants k * span / frames
    resampled = qfix(resampled[:frames], dim=0)
    flip = resampled[..., 0].mean(0) < 0  # each joint in the hemisphere of its mean: one rotation, one vector
    resampled = torch.where(flip[None, :, None], -resampled, resampled)
    return qlog(resampled).numpy()


def cut_cycles(table: pa.Table, arrays: dict[str, np.ndarray], skeleton: Skeleton, cfg: CycleConfig = CycleConfig(),
               annotate: AnnotateConfig = AnnotateConfig()) -> Cycles:
    """The forward-walk cycles of the ``cfg.split`` clips of a split gait table (``io.gait_table.read_gaits``)."""
    clips = train_clips(table, arrays, cfg.split, (cfg.content,), annotate.fps)
    styles = table.column("style").to_pylist()
    methods = table.column("label_method").to_pylist()
    dropped: Counter = Counter()
    out: dict[str, list] = {k: [] for k in ("rotvec", "durations", "strides", "emotion", "clip_id", "style",
                                            "label_method", "start_frame", "follows")}
    for cid in sorted(clips.positions):
        clip_positions = clips.positions[cid]
        first_row = clips.first_row[cid]
        clip_rotations = torch.from_numpy(clips.rotations[cid].astype(np.float64))
        clip_heading = clips.heading[cid].astype(np.float64)
        strikes = annotate_clip(torch.from_numpy(clip_positions), skeleton, annotate)["events"]["right_strike"]
        previous_end = None
        for a, b in zip(strikes[:-1], strikes[1:]):
            span = b - a
            turn = abs(math.degrees(float(wrap_angle(torch.tensor(clip_heading[b] - clip_heading[a])))))
            ground = clip_positions[b, 0, [0, 2]] - clip_positions[a, 0, [0, 2]]
            along = (math.sin(clip_heading[a]), math.cos(clip_heading[a]))
            ahead = ground[0] * along[0] + ground[1] * along[1]
            side = ground[0] * along[1] - ground[1] * along[0]
            drift = math.degrees(math.atan2(abs(side), ahead))  # 90+ for sideways, 180 for backwards
            reason = ("duration_outside_limits" if not cfg.min_frames <= span <= cfg.max_frames else
                      "turning" if turn > cfg.max_turn_deg else
                      "not_forward" if drift > cfg.max_drift_deg else None)
            if reason:
                dropped[reason] += 1
                continue
            out["rotvec"].append(_canonical_rotvec(clip_rotations[a:b + 1], float(clip_heading[a]), cfg.frames))
            out["durations"].append(span)
            out["strides"].append((side, ahead))
            out["emotion"].append(arrays["emotion"][first_row])
            out["clip_id"].append(cid)
            out["style"].append(styles[first_row] or "")
            out["label_method"].append(methods[first_row])
            out["start_frame"].append(a)
            out["follows"].append(previous_end == a)
            previous_end = b
    n = len(out["durations"])
    return Cycles(rotvec=np.array(out["rotvec"], dtype=np.float64).reshape(n, cfg.frames, len(skeleton.names), 3),
                  durations=np.array(out["durations"], dtype=np.int64),
                  strides=np.array(out["strides"], dtype=np.float64).reshape(n, 2),
                  emotion=np.array(out["emotion"], dtype=np.float64).reshape(n, len(EMOTIONS)),
                  clip_id=out["clip_id"], style=out["style"], label_method=out["label_method"],
                  start_frame=np.array(out["start_frame"], dtype=np.int64),
                  follows=np.array(out["follows"], dtype=bool), dropped=dict(dropped))
