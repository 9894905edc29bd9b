"""No memorisation: how close each gait lies to its nearest real train-split window, for synthetic gaits and, as
the yardstick, for real held-out windows (other clips by construction).

The distance between two windows is the mean joint position error (m) over their frames and joints of the
root-relative poses in each frame's heading frame (``recognition.heading_frame_poses``, the temporal
recogniser's normalisation), frame i against frame i. The nearest window is searched on every ``frame_stride``-th
frame: the ``candidates`` nearest by Euclidean distance of the flattened poses (``torch.cdist``, in chunks), then
the exact mean joint error of those candidates on the same frames, the least of which is the gait's distance.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from pipeline.recognition import RecognitionInputs, heading_frame_poses

_CHUNK = 512


def _poses(inputs: RecognitionInputs, frame_stride: int) -> torch.Tensor:
    """(N, T', J, 3) heading-frame poses on every ``frame_stride``-th frame."""
    positions = torch.from_numpy(np.ascontiguousarray(inputs.positions[:, ::frame_stride], dtype=np.float32))
    heading = torch.from_numpy(np.ascontiguousarray(inputs.heading[:, ::frame_stride], dtype=np.float32))
    return heading_frame_poses(positions, heading)


def nearest_window_distance(queries: RecognitionInputs, references: RecognitionInputs, frame_stride: int = 2,
                            candidates: int = 8) -> np.ndarray:
    """(len(queries),) mean joint position error (m) of each query window to its nearest reference window (same
    frame count), searched as the module docstring says."""
    if queries.frames != references.frames:
        raise ValueError(f"nearest_window_distance: expected windows of one length, found {queries.frames} "
                         f"(queries) and {references.frames} (references) frames")
    if not len(queries) or not len(references):
        return np.zeros(len(queries))
    ref = _poses(references, frame_stride)
    flat_ref = ref.flatten(1)
    k = min(candidates, len(references))
    out = []
    with torch.no_grad():
        for start in range(0, len(queries), _CHUNK):
            q = _poses(queries.select(slice(start, start + _CHUNK)), frame_stride)
            nearest = torch.cdist(q.flatten(1), flat_ref).topk(k, largest=False).indices  # (n, k)
            error = (q[:, None] - ref[nearest]).norm(dim=-1).mean((-2, -1))  # (n, k)
            out.append(error.min(-1).values.double().numpy())
    return np.concatenate(out)


def distribution(values: np.ndarray) -> dict[str, Any]:
    """{gaits, median, p5, p95, mean} of distances (m)."""
    if not len(values):
        return {"gaits": 0}
    p5, median, p95 = np.quantile(values, [0.05, 0.5, 0.95])
    return {"gaits": int(len(values)), "median": round(float(median), 4), "p5": round(float(p5), 4),
            "p95": round(float(p95), 4), "mean": round(float(np.mean(values)), 4)}


def memorisation(inputs: RecognitionInputs, train: np.ndarray, held_out: np.ndarray, synthetic: np.ndarray,
                 families: dict[str, np.ndarray], frame_stride: int = 2, candidates: int = 8
                 ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Distances to the nearest real train window (row masks ``train``, ``held_out``: real val/test windows,
    ``synthetic``, ``families``: synthetic row masks per generator family): their distributions and the check
    that synthetic gaits lie no closer (median) than real held-out windows; and the distances themselves
    ({"synthetic", "real_held_out"}) for the histogram."""
    references = inputs.select(train)
    distances = {"real_held_out": nearest_window_distance(inputs.select(held_out), references, frame_stride,
                                                          candidates),
                 "synthetic": nearest_window_distance(inputs.select(synthetic), references, frame_stride,
                                                      candidates)}
    out: dict[str, Any] = {"train_windows": int(train.sum()), "frame_stride": frame_stride, "candidates": candidates,
                           "real_held_out": distribution(distances["real_held_out"]),
                           "synthetic": distribution(distances["synthetic"])}
    index = np.flatnonzero(synthetic)
    if len(families) > 1:
        out["families"] = {n: distribution(distances["synthetic"][np.isin(index, np.flatnonzero(m))])
                           for n, m in families.items()}
    if len(distances["synthetic"]) and len(distances["real_held_out"]):
        out["check"] = {"synthetic_median_ge_real_heldout_median":
                        bool(out["synthetic"]["median"] >= out["real_held_out"]["median"])}
    return out, distances
