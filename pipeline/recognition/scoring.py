"""Scores of an emotion recogniser on labelled gaits: confusion matrix, accuracy, balanced accuracy, macro-F1, the
majority-class baseline, and 95 % bootstrap intervals that resample clips (the gaits of one recording are not
independent, so a clip is the unit resampled)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

SCORES = ("accuracy", "balanced_accuracy", "macro_f1")


def confusion(y: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    """(classes, classes) counts, rows: truth, columns: predicted."""
    out = np.zeros((classes, classes), dtype=int)
    np.add.at(out, (np.asarray(y, dtype=int), np.asarray(predicted, dtype=int)), 1)
    return out


def _scores_batched(matrices: np.ndarray) -> dict[str, np.ndarray]:
    """``scores`` of (..., k, k) confusion matrices, unrounded, (...) each."""
    m = np.asarray(matrices, dtype=np.float64)
    tp = np.diagonal(m, axis1=-2, axis2=-1)
    truth, said = m.sum(-1), m.sum(-2)
    present = truth > 0
    f1 = np.where(truth + said > 0, 2 * tp / np.maximum(truth + said, 1), 0.0)
    recall = tp / np.maximum(truth, 1)
    n_present = present.sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return {"accuracy": tp.sum(-1) / np.maximum(m.sum((-2, -1)), 1),
                "balanced_accuracy": np.where(n_present > 0, (recall * present).sum(-1) / n_present, np.nan),
                "macro_f1": np.where(n_present > 0, (f1 * present).sum(-1) / n_present, np.nan)}


def scores(matrix: np.ndarray) -> dict[str, float]:
    """Accuracy, balanced accuracy and macro-F1 of a confusion matrix (rows: truth, columns: predicted).

    Balanced accuracy is the mean recall and macro-F1 the mean F1 over the classes present in the truth (a class
    no tested gait has is left out of both, so neither rewards nor punishes its absence).
    """
    return {k: round(float(v), 4) for k, v in _scores_batched(matrix).items()}


def majority_baseline(matrix: np.ndarray, names: Sequence[str]) -> dict[str, Any]:
    """The scores of always answering the most frequent true class of the tested gaits, from the confusion
    matrix's row sums: the best accuracy any constant answer reaches on them (its balanced accuracy is 1 / the
    classes present). Returns {"class", "accuracy", "balanced_accuracy", "macro_f1"}."""
    truth = np.asarray(matrix).sum(1)
    top = int(np.argmax(truth))
    constant = np.zeros_like(np.asarray(matrix))
    constant[:, top] = truth
    return {"class": names[top], **scores(constant)}


def _clip_confusions(groups: Sequence, y: np.ndarray, predicted: Sequence[np.ndarray], classes: int
                     ) -> np.ndarray:
    """(len(predicted), clips, k, k): each prediction set's confusion matrix restricted to each clip."""
    _, clip = np.unique(np.asarray(groups, dtype=object).astype(str), return_inverse=True)
    clips = int(clip.max()) + 1 if len(clip) else 0
    out = np.zeros((len(predicted), clips, classes, classes), dtype=np.int64)
    for i, p in enumerate(predicted):
        np.add.at(out[i], (clip, np.asarray(y, dtype=int), np.asarray(p, dtype=int)), 1)
    return out


def _resampled_scores(per_clip: np.ndarray, resamples: int, seed: int) -> dict[str, np.ndarray]:
    """Scores (sets, resamples) of the confusions of ``resamples`` draws of the clips with replacement."""
    clips = per_clip.shape[1]
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, clips, size=(resamples, clips))
    counts = np.zeros((resamples, clips), dtype=np.int64)
    np.add.at(counts, (np.repeat(np.arange(resamples), clips), draws.ravel()), 1)
    matrices = np.einsum("rc,sckl->srkl", counts, per_clip)
    return _scores_batched(matrices)


def _interval(values: np.ndarray) -> list[float]:
    finite = values[np.isfinite(values)]
    if not len(finite):
        return [float("nan"), float("nan")]
    lo, hi = np.quantile(finite, [0.025, 0.975])
    return [round(float(lo), 4), round(float(hi), 4)]


def _as_sets(predicted: np.ndarray) -> list[np.ndarray]:
    p = np.asarray(predicted)
    return [p] if p.ndim == 1 else list(p)


def bootstrap_interval(groups: Sequence, y: np.ndarray, predicted: np.ndarray, classes: int,
                       resamples: int = 1000, seed: int = 0) -> dict[str, list[float]]:
    """{score: [lo, hi]}: the 95 % percentile interval of each score over ``resamples`` resamplings of the clips
    (``groups``: one clip identity per gait) with replacement, every gait of a drawn clip taken each time it is
    drawn. ``classes``: the number of classes (the confusion matrices' size). ``predicted`` (N,), or (S, N): the
    answers of S recognisers (seeds) on the same gaits, when the interval is that of their mean score (each draw
    scores every seed on the same clips)."""
    per_clip = _clip_confusions(groups, y, _as_sets(predicted), classes)
    drawn = _resampled_scores(per_clip, resamples, seed)
    return {s: _interval(drawn[s].mean(0)) for s in SCORES}


def bootstrap_delta_interval(groups: Sequence, y: np.ndarray, before: np.ndarray, after: np.ndarray, classes: int,
                             resamples: int = 1000, seed: int = 0) -> dict[str, list[float]]:
    """{score: [lo, hi]}: the 95 % interval of score(after) − score(before) on the same gaits, the two resampled
    together (the same clips in each draw), so the interval is that of the change, not of two separate scores.
    ``before``, ``after``: (N,) or (S, N) as in ``bootstrap_interval`` (the change of the mean over seeds)."""
    b, a = _as_sets(before), _as_sets(after)
    per_clip = _clip_confusions(groups, y, b + a, classes)
    drawn = _resampled_scores(per_clip, resamples, seed)
    return {s: _interval(drawn[s][len(b):].mean(0) - drawn[s][:len(b)].mean(0)) for s in SCORES}
