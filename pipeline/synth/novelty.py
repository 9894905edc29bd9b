"""Novelty of the synthesis plan: new trajectories w.r.t. the training clips' root paths, new
emotions w.r.t. the training labels.

Novelty of a trajectory (stated test): aligned at its start and initial direction with every training clip's
root path aligned at each of that clip's window starts (position and direction of travel there), the mean
distance at equal arc length over their common length must exceed ``min_mean_distance_m`` wherever the common
length is at least ``min_compared_m``; clips shorter than that from a start cannot hold the shape and are not
compared. A 2-s gait walks only ~2.5 m of its trajectory; such pieces are not claimed novel (the report says how
many come close to a training window's path).

Novelty of an emotion: its L1 distance to every distinct training label exceeds ``min_l1_to_training``.

Paths are numpy arrays, compared in float64; their geometry is pipeline.ops.geometry's, through torch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.annotate.annotation import rebuild_clips
from pipeline.ops.geometry import resample_polyline, to_local_frame, travel_direction, unit_direction
from pipeline.synth.trajectories import TRAVEL_FRAMES

# ------------------------------------------------------------------------------------------------- trajectories


@dataclass(frozen=True)
class TrainingPaths:
    """Training root paths, one from every window start of every clip, each in its start frame (start at the
    origin, direction of travel along +z) and resampled at equal arc length; NaN past a path's end."""

    clip_ids: list[str]
    points: np.ndarray  # (P, K, 2)
    lengths_m: np.ndarray  # (P,)
    spacing: float


def training_paths(root_paths: np.ndarray, clip_ids: Sequence[str], starts: np.ndarray, window: int,
                   spacing: float = 0.1) -> TrainingPaths:
    """From overlapping windows: root_paths (rows, window, 2), starts their first frames in the clip."""
    ids, aligned = [], []
    for cid, (clip, placed) in rebuild_clips(clip_ids, starts, root_paths, window).items():
        for _, first in placed:
            path = torch.from_numpy(clip[first:].astype(np.float64))
            along = unit_direction(float(travel_direction(path, TRAVEL_FRAMES)))
            ids.append(cid)
            aligned.append(resample_polyline(to_local_frame(path, along, path[0]), spacing).numpy())
    points = np.full((len(aligned), max(len(a) for a in aligned), 2), np.nan)
    for i, a in enumerate(aligned):
        points[i, :len(a)] = a
    return TrainingPaths(ids, points, np.array([(len(a) - 1) * spacing for a in aligned]), spacing)


def nearest_training_path(points: np.ndarray, training: TrainingPaths, min_compared_m: float,
                          exclude_clip: str | None = None) -> dict[str, Any]:
    """Smallest mean distance at equal arc length, over their common length, between a path given in its start
    frame and the training paths at least ``min_compared_m`` long (other than ``exclude_clip``'s)."""
    mine = resample_polyline(torch.from_numpy(np.asarray(points, dtype=np.float64)), training.spacing).numpy()
    mine = mine[: training.points.shape[1]]
    usable = training.lengths_m >= min_compared_m - 1e-9
    if exclude_clip is not None:
        usable &= np.array([c != exclude_clip for c in training.clip_ids])
    rows = np.flatnonzero(usable)
    if not len(rows):
        return {"distance_m": math.inf, "clip_id": None, "compared_m": 0.0, "compared_paths": 0}
    gaps = np.linalg.norm(training.points[rows, : len(mine)] - mine[None], axis=-1)  # NaN past a path's end
    distance = np.nanmean(gaps, axis=1)
    best = int(np.argmin(distance))
    compared = (int(np.isfinite(gaps[best]).sum()) - 1) * training.spacing
    return {"distance_m": float(distance[best]), "clip_id": training.clip_ids[rows[best]],
            "compared_m": round(compared, 2), "compared_paths": len(rows)}


def training_nearest_distances(training: TrainingPaths, min_compared_m: float) -> np.ndarray:
    """The reference for the novelty threshold: how far each training clip's longest path lies from the nearest
    path of another clip."""
    longest: dict[str, int] = {}
    for i, cid in enumerate(training.clip_ids):
        if cid not in longest or training.lengths_m[i] > training.lengths_m[longest[cid]]:
            longest[cid] = i
    out = []
    for cid, i in longest.items():
        if training.lengths_m[i] < min_compared_m:
            continue
        path = training.points[i][np.isfinite(training.points[i, :, 0])]
        nearest = nearest_training_path(path, training, min_compared_m, exclude_clip=cid)
        if nearest["clip_id"] is not None:
            out.append(nearest["distance_m"])
    return np.array(out)


# ----------------------------------------------------------------------------------------------------- emotions


def distinct_labels(labels: np.ndarray) -> np.ndarray:
    return np.unique(np.round(labels, 6), axis=0)


def l1_to_labels(emotions: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(N,) L1 distance of each emotion vector to its nearest (distinct) label."""
    return np.abs(emotions[:, None] - distinct_labels(labels)[None]).sum(-1).min(-1)


def novel_emotions(count: int, training_labels: np.ndarray, min_l1: float, rng: np.random.Generator,
                   max_draws: int = 1_000_000) -> np.ndarray:
    """``count`` points of the 4-emotion simplex (uniform, Dirichlet(1,1,1,1)), each farther than ``min_l1`` (L1)
    from every distinct training label; float64 rows summing to 1."""
    out: list[np.ndarray] = []
    draws = 0
    while len(out) < count:
        batch = rng.dirichlet(np.ones(4), size=256)
        draws += len(batch)
        far = l1_to_labels(batch, training_labels) > min_l1
        out.extend(batch[far][: count - len(out)])
        if draws > max_draws:
            raise ValueError(f"only {len(out)} of {count} emotions farther than L1 {min_l1} from the training labels")
    return np.asarray(out)
