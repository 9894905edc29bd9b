"""The PCA space of whole walk cycles and the Gaussian style models in it (seed 001, Tilmanne & Dutoit §5–7.1).

* **Basis** (§5): up to ``per_style`` cycles of every style (a seeded draw; all of a style with fewer), so that
  each style weighs alike, mean-centred; the principal components by SVD. Every cycle is then projected on it.
  The number kept is the smallest reaching ``variance`` of the basis' cumulative explained variance (the paper:
  80 % at 10 PCs looked impoverished, 90 % at 23 PCs was indistinguishable).
* **Style models** (§6): per emotion, over the cycles whose dominant emotion it is, per PC the mean and standard
  deviation of the scores and the largest change between two cycles that follow each other in one clip; the same
  for the cycle duration. With few cycles an emotion's variance is regularised towards the pooled within-emotion
  variance of all labelled cycles: σ² = (n s² + n₀ s²_pooled) / (n + n₀), n₀ = ``prior_cycles`` (as if n₀ more
  cycles had the pooled spread); an emotion without two adjacent cycles takes the largest change of all labelled
  adjacent pairs.
* **Blending** a point m of the emotion simplex: means, variances and largest changes are the m-weighted sums of
  the four emotions' (so a vertex is that emotion's model, and a mixture's spread is that of a mixture of walks).
* **Sampling** (§7.1): cycle after cycle, scores mean + std · N(0, 1); a score whose deviation from its model's
  mean moves farther from the previous cycle's deviation than the largest change is redrawn (``redraws`` times)
  and then clamped to it; both counted. For one style this is the paper's rule; measured on deviations, a
  transition's means can move with the emotion (on the scores themselves, the change limit of a consistent style
  held a happy-to-sad transition's cycle duration within 2 frames of happy's over 2 s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.core.emotions import EMOTIONS


@dataclass(frozen=True)
class ModelConfig:
    """The pipeline params' ``pca_gaussian.model``."""

    per_style: int = 15  # basis cycles per style (the paper: 15 per style, 11 styles)
    variance: float = 0.90  # cumulative explained variance the kept components reach
    prior_cycles: float = 5.0  # n₀ of the variance regularisation
    # and at least as many components as keep every emotion's affective features (the mean over its cycles of each
    # of the 18) within this many real standard deviations of the cycles themselves (0: variance alone decides)
    emotion_features_sd: float = 0.0
    seed: int = 0  # the basis draw

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> "ModelConfig":
        return cls(**{k: type(getattr(cls, k))(v) for k, v in dict(d or {}).items()})


@dataclass
class PCABasis:
    """mean (P,), components (K_all, P) orthonormal rows, explained (K_all,) variance ratios of the basis cycles,
    basis_rows: which cycles formed it."""

    mean: np.ndarray
    components: np.ndarray
    explained: np.ndarray
    basis_rows: np.ndarray

    def scores(self, x: np.ndarray, k: int | None = None) -> np.ndarray:
        """(N, P) flattened cycles -> (N, k) scores on the first k components (all when None)."""
        return (x - self.mean) @ self.components[:k].T

    def reconstruct(self, z: np.ndarray) -> np.ndarray:
        """(N, k) scores -> (N, P) flattened cycles."""
        return self.mean + z @ self.components[: z.shape[1]]

    def components_for(self, variance: float) -> int:
        """The smallest number of components whose cumulative explained variance reaches ``variance``."""
        cumulative = np.cumsum(self.explained)
        return int(min(len(cumulative), np.searchsorted(cumulative, variance - 1e-12) + 1))


def balanced_rows(styles: list[str], per_style: int, seed: int) -> np.ndarray:
    """Up to ``per_style`` row indices of every style (seeded draw without replacement; all of a smaller style),
    sorted."""
    rng = np.random.default_rng(seed)
    chosen = []
    for style in sorted(set(styles)):
        rows = np.flatnonzero(np.array(styles) == style)
        chosen.extend(rows if len(rows) <= per_style else rng.choice(rows, per_style, replace=False))
    return np.sort(np.array(chosen, dtype=np.int64))


def fit_basis(x: np.ndarray, rows: np.ndarray) -> PCABasis:
    """PCA of the cycles ``x[rows]`` ((N, P) flattened): mean-centred, SVD; at most N - 1 components."""
    basis = x[rows]
    mean = basis.mean(0)
    _, singular, vt = np.linalg.svd(basis - mean, full_matrices=False)
    keep = max(1, min(len(rows) - 1, int((singular > singular[0] * 1e-10).sum())))
    variance = singular[:keep] ** 2
    total = (singular ** 2).sum()
    # a deterministic sign per component (its largest loading positive): the same data, the same basis bytes
    components = vt[:keep] * np.sign(vt[:keep][np.arange(keep), np.abs(vt[:keep]).argmax(1)])[:, None]
    return PCABasis(mean=mean, components=components, explained=variance / total, basis_rows=np.asarray(rows))


@dataclass(frozen=True)
class StyleModel:
    """Gaussian model of one emotion (or a blend): per PC mean, std and largest adjacent change; the same for the
    cycle duration (frames at the clip rate); the cycles it was fitted on (0 for a blend)."""

    mean: np.ndarray
    std: np.ndarray
    max_change: np.ndarray
    duration_mean: float
    duration_std: float
    duration_max_change: float
    cycles: int = 0


def _adjacent_changes(values: np.ndarray, follows: np.ndarray) -> np.ndarray:
    """(pairs, D) absolute changes between each cycle that follows its predecessor and that predecessor."""
    after = np.flatnonzero(follows[1:]) + 1
    return np.abs(values[after] - values[after - 1])


def fit_style_models(scores: np.ndarray, durations: np.ndarray, dominant: np.ndarray, follows: np.ndarray,
                     prior_cycles: float) -> list[StyleModel]:
    """One model per emotion (EMOTIONS order) from the labelled cycles: scores (C, K), durations (C,), dominant
    (C,) emotion index or -1, follows (C,) (``cycles.Cycles.follows``). An emotion without cycles: ValueError."""
    values = np.concatenate([scores, durations[:, None].astype(np.float64)], axis=1)
    labelled = dominant >= 0
    residual = values[labelled] - np.stack([values[dominant == k].mean(0) if (dominant == k).any() else
                                            np.zeros(values.shape[1]) for k in range(len(EMOTIONS))])[dominant[labelled]]
    pooled_var = (residual ** 2).mean(0)
    same = np.concatenate([[False], dominant[1:] == dominant[:-1]]) & follows & labelled
    pooled_change = _adjacent_changes(values, same).max(0) if same.any() else 2.0 * np.sqrt(pooled_var)
    models = []
    for k, name in enumerate(EMOTIONS):
        mine = dominant == k
        n = int(mine.sum())
        if n == 0:
            raise ValueError(f"pca_gaussian: expected cycles of every emotion, found none of {name!r}")
        mean = values[mine].mean(0)
        var = (n * values[mine].var(0) + prior_cycles * pooled_var) / (n + prior_cycles)
        pairs = same & mine
        change = _adjacent_changes(values, pairs).max(0) if pairs.any() else pooled_change
        models.append(StyleModel(mean=mean[:-1], std=np.sqrt(var[:-1]), max_change=change[:-1],
                                 duration_mean=float(mean[-1]), duration_std=float(np.sqrt(var[-1])),
                                 duration_max_change=float(change[-1]), cycles=n))
    return models


def blend(models: list[StyleModel], weights: np.ndarray) -> StyleModel:
    """The model of an emotion vector m (4,) on the simplex: m-weighted means, variances and largest changes."""
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(models),) or (w < -1e-9).any() or abs(w.sum() - 1.0) > 1e-6:
        raise ValueError(f"pca_gaussian.blend: expected {len(models)} non-negative weights summing to 1, found {w}")

    def mix(get) -> np.ndarray:
        return sum(wk * np.asarray(get(m), dtype=np.float64) for wk, m in zip(w, models))
    return StyleModel(mean=mix(lambda m: m.mean), std=np.sqrt(mix(lambda m: m.std ** 2)),
                      max_change=mix(lambda m: m.max_change), duration_mean=float(mix(lambda m: m.duration_mean)),
                      duration_std=float(np.sqrt(mix(lambda m: m.duration_std ** 2))),
                      duration_max_change=float(mix(lambda m: m.duration_max_change)))


def _draw(mean: np.ndarray, std: np.ndarray, previous: np.ndarray | None, limit: np.ndarray, redraws: int,
          rng: np.random.Generator, counts: dict[str, int]) -> np.ndarray:
    """A draw of mean + std N(0, 1) whose deviation from the mean moves at most ``limit`` from the previous cycle's
    deviation (``previous``, None for a first cycle): redrawn, then clamped."""
    value = mean + std * rng.standard_normal(mean.shape)
    if previous is None:
        return value
    for _ in range(redraws):
        far = np.abs(value - mean - previous) > limit
        if not far.any():
            return value
        counts["redrawn"] += int(far.sum())
        value = np.where(far, mean + std * rng.standard_normal(mean.shape), value)
    far = np.abs(value - mean - previous) > limit
    counts["clamped"] += int(far.sum())
    return np.where(far, mean + previous + np.clip(value - mean - previous, -limit, limit), value)


def sample_cycles(models: list[StyleModel], rng: np.random.Generator, redraws: int,
                  previous: tuple[np.ndarray, float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, dict[str, int], tuple[np.ndarray, float]]:
    """One cycle per model in ``models`` (a cycle's model may change from cycle to cycle, as in a transition):
    scores (n, K) and durations (n,) in frames. Each cycle's deviation from its own model's mean stays within the
    model's largest adjacent change of the cycle before's deviation (``previous``: the deviations of a cycle before
    the first, or None), so for one style this is the paper's rule on the scores themselves, and in a transition
    the means move with the emotion while the cycle-to-cycle jitter stays as bounded as in the real walks. Returns
    the counts of redrawn and clamped values and the last cycle's deviations (to continue a chain). Deterministic
    for a seeded ``rng``."""
    counts = {"redrawn": 0, "clamped": 0}
    scores, durations = [], []
    z_dev, d_dev = (None, None) if previous is None else (np.asarray(previous[0]), np.array([previous[1]]))
    for m in models:
        z = _draw(m.mean, m.std, z_dev, m.max_change, redraws, rng, counts)
        d = _draw(np.array([m.duration_mean]), np.array([m.duration_std]), d_dev,
                  np.array([m.duration_max_change]), redraws, rng, counts)
        scores.append(z)
        durations.append(float(d[0]))
        z_dev, d_dev = z - m.mean, d - m.duration_mean
    return np.array(scores), np.array(durations), counts, (z_dev, float(d_dev[0]))


def _cycle_features(flat: np.ndarray, offsets: np.ndarray, parents: list[int], frames: int) -> np.ndarray:
    """(N, P) flattened rotation vectors -> (N, 18) affective features averaged over every 2nd of each cycle's
    frames (root-relative forward kinematics on the canonical skeleton; every 2nd sample halves the cost)."""
    import torch

    from pipeline.ops.features import affective_features
    from pipeline.ops.kinematics import canonical_positions
    from pipeline.ops.quaternion import qexp

    q = qexp(torch.from_numpy(flat.reshape(len(flat), frames, -1, 3)[:, ::2]))
    positions = canonical_positions(torch.zeros(*q.shape[:2], 3, dtype=q.dtype), q,
                                    torch.from_numpy(offsets).to(q.dtype), parents)
    return affective_features(positions).mean(1).numpy()


def emotion_feature_errors(x: np.ndarray, dominant: np.ndarray, basis: PCABasis, k: int, offsets: np.ndarray,
                           parents: list[int], frames: int, real: np.ndarray | None = None) -> np.ndarray:
    """Per emotion (EMOTIONS order; NaN without cycles): the largest difference over the 18 affective features
    between the mean over its cycles (N, P) and the mean over their k-component reconstructions, in standard
    deviations of the labelled cycles' features. What a basis loses of what tells the emotions apart. ``real``:
    the labelled cycles' features (``_cycle_features``), where already computed."""
    labelled = dominant >= 0
    real = _cycle_features(x[labelled], offsets, parents, frames) if real is None else real
    back = _cycle_features(basis.reconstruct(basis.scores(x[labelled], k)), offsets, parents, frames)
    sd = np.maximum(real.std(0), 1e-9)
    d = dominant[labelled]
    return np.array([np.abs((back[d == e].mean(0) - real[d == e].mean(0)) / sd).max() if (d == e).any() else np.nan
                     for e in range(len(EMOTIONS))])


def components_for_emotions(x: np.ndarray, dominant: np.ndarray, basis: PCABasis, max_sd: float, start: int,
                            offsets: np.ndarray, parents: list[int], frames: int) -> tuple[int, dict[int, list[float]]]:
    """The fewest components, from ``start`` on, whose reconstruction keeps every emotion's affective features
    within ``max_sd`` (``emotion_feature_errors``), found by bisection (the errors shrink with more components,
    not strictly: the rule takes the bisection's answer), and the errors of every number tried."""
    tried: dict[int, list[float]] = {}
    real = _cycle_features(x[dominant >= 0], offsets, parents, frames)

    def ok(k: int) -> bool:
        errors = emotion_feature_errors(x, dominant, basis, k, offsets, parents, frames, real)
        tried[k] = [round(float(e), 3) for e in errors]
        return bool(np.nanmax(errors) <= max_sd)

    low, high = start, len(basis.explained)
    if not ok(low):
        while low < high:
            middle = (low + high) // 2
            if ok(middle):
                high = middle
            else:
                low = middle + 1
    return low, dict(sorted(tried.items()))


def reconstruction_errors(x: np.ndarray, basis: PCABasis, k: int, offsets: np.ndarray, parents: list[int],
                          frames: int) -> dict[str, float]:
    """How much of the cycles (N, P) flattened rotation vectors survives k components: the mean joint position
    error (m, root-relative forward kinematics on the canonical skeleton) and the mean rotation error (degrees)
    over joints, frames and cycles."""
    import torch

    from pipeline.ops.kinematics import canonical_positions
    from pipeline.ops.quaternion import qangle, qexp

    def pose(flat: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        q = qexp(torch.from_numpy(flat.reshape(len(flat), frames, -1, 3)))
        return q, canonical_positions(torch.zeros(*q.shape[:2], 3, dtype=q.dtype), q,
                                      torch.from_numpy(offsets).to(q.dtype), parents)

    q_true, p_true = pose(x)
    q_back, p_back = pose(basis.reconstruct(basis.scores(x, k)))
    return {"components": int(k), "cumulative_variance": round(float(np.cumsum(basis.explained)[k - 1]), 4),
            "joint_position_error_m": round(float(torch.linalg.vector_norm(p_back - p_true, dim=-1).mean()), 5),
            "rotation_error_deg": round(float(torch.rad2deg(qangle(q_back, q_true)).mean()), 3)}


def leave_one_clip_out_reading(scores: np.ndarray, dominant: np.ndarray, clips: np.ndarray) -> dict[str, Any]:
    """How well the PC scores (C, K) tell the emotions apart: each labelled cycle (``dominant`` >= 0) read as the
    emotion whose centroid, fitted on the other clips' cycles, is nearest; accuracy, balanced accuracy over the
    emotions present, the majority baseline and the confusion (rows: true, EMOTIONS order). An emotion whose
    cycles all come from one clip has no centroid when that clip is left out, so its cycles cannot be read right.
    """
    k = len(EMOTIONS)
    matrix = np.zeros((k, k), dtype=int)
    labelled = np.flatnonzero(dominant >= 0)
    for clip in sorted(set(clips[labelled])):
        mine = labelled[clips[labelled] == clip]
        others = labelled[clips[labelled] != clip]
        present = [e for e in range(k) if (dominant[others] == e).any()]
        centroids = np.stack([scores[others][dominant[others] == e].mean(0) for e in present])
        nearest = np.linalg.norm(scores[mine][:, None] - centroids[None], axis=-1).argmin(1)
        for truth, guess in zip(dominant[mine], np.array(present)[nearest]):
            matrix[truth, guess] += 1
    rows = matrix.sum(1)
    recall = [matrix[e, e] / rows[e] for e in range(k) if rows[e]]
    return {"cycles": int(rows.sum()), "clips": int(len(set(clips[labelled]))),
            "clips_per_emotion": {name: int(len(set(clips[dominant == e]))) for e, name in enumerate(EMOTIONS)},
            "accuracy": round(float(np.trace(matrix) / rows.sum()), 4),
            "balanced_accuracy": round(float(np.mean(recall)), 4),
            "majority_baseline_accuracy": round(float(rows.max() / rows.sum()), 4),
            "confusion": matrix.tolist()}


def cycle_novelty(models: list[StyleModel], scores: np.ndarray, clips: np.ndarray, per_emotion: int, seed: int,
                  values_per_cycle: int) -> dict[str, Any]:
    """Are drawn cycles new? ``per_emotion`` cycles drawn from each emotion model (first cycles of a chain) and
    the distance from each to its nearest real cycle (scores (C, K) on the same components), beside each real
    cycle's distance to its nearest real cycle of another clip. Distances are RMS rotation-vector differences per
    value (degrees; the score space is an orthonormal part of the 40 x 21 x 3 log-map space), and a drawn cycle
    within 1e-6 of a real one counts as reproduced."""
    rng = np.random.default_rng(seed)
    drawn = np.concatenate([m.mean + m.std * rng.standard_normal((per_emotion, len(m.mean))) for m in models])
    to_real = np.sqrt(((drawn[:, None] - scores[None]) ** 2).sum(-1)).min(1)
    between = np.sqrt(((scores[:, None] - scores[None]) ** 2).sum(-1))
    between[clips[:, None] == clips[None]] = np.inf
    real_nn = between.min(1)
    real_nn = real_nn[np.isfinite(real_nn)]
    to_deg = np.degrees(1.0 / np.sqrt(values_per_cycle))

    def spread(d: np.ndarray) -> dict[str, float]:
        return {q: round(float(np.percentile(d, p) * to_deg), 4) for q, p in (("min", 0), ("p10", 10), ("median", 50),
                                                                              ("p90", 90))}
    return {"drawn_cycles": int(len(drawn)), "drawn_to_nearest_real_deg": spread(to_real),
            "real_to_nearest_real_of_another_clip_deg": spread(real_nn),
            "reproduced": int((to_real < 1e-6).sum())}
