"""The floor under a clip, followed along the clip.

A capture floor may be tilted, or the root height may drift over a take: then the clip's single lowest foot point
leaves whole windows with both feet centimetres above the ground. The floor is read where the feet tell it: every
half second (a step) the lowest foot point is a stance foot on the floor. Through those samples runs a robust
local-linear trend (LOWESS), which follows tilts (also a tilted floor walked around in a circle), drifts and steps.
Where the trend rises and falls less than a tolerance the floor is level, and stays the clip's lowest foot point
(unless that is a foot through the floor for a moment, which the robust trend rejects), as every clip of a level
capture always had it; elsewhere the trend is the floor. A clip whose samples stray from the model by more than a
tolerance has no floor we can model, and the caller filters it. Pure functions of heights over frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class FloorConfig:
    """params.yaml ``ingest.floor``."""

    sample_s: float = 0.5  # one floor sample per this many seconds: the lowest foot point in it
    bandwidth_s: float = 2.0  # the trend's local-linear window (Gaussian sigma = bandwidth / 2)
    level_m: float = 0.02  # a trend that rises and falls less than this over the clip: a level floor
    tolerance_m: float = 0.02  # median distance of the samples from the model above this: not modelled
    low_quantile: float = 0.2  # a trend floor is lowered to this quantile of the samples near each frame

    @classmethod
    def from_dict(cls, p: dict[str, Any] | None) -> "FloorConfig":
        return cls(**{k: float(v) for k, v in (p or {}).items()})


@dataclass(frozen=True)
class FloorModel:
    """The floor height under every frame (T,) and what it is: ``level`` or ``trend``; ``drift_m`` the floor's
    rise over the clip (largest minus smallest), ``tilt_deg`` the slope of the plane through it under the path,
    ``residual_m`` the samples' median distance from the trend."""

    heights: np.ndarray
    kind: str
    drift_m: float
    tilt_deg: float
    residual_m: float
    samples: int

    def report(self) -> dict[str, Any]:
        return {"floor": self.kind, "drift_cm": round(100 * self.drift_m, 2), "tilt_deg": round(self.tilt_deg, 2),
                "residual_cm": round(100 * self.residual_m, 2), "samples": self.samples}


def floor_samples(lowest: np.ndarray, per_sample: int) -> tuple[np.ndarray, np.ndarray]:
    """(frames, heights) of the lowest foot point (T,) in each run of ``per_sample`` frames (a last, shorter run
    counts when it holds at least half as many)."""
    frames = []
    for a in range(0, len(lowest), per_sample):
        b = min(a + per_sample, len(lowest))
        if b - a >= max(1, per_sample // 2) or a == 0:
            frames.append(a + int(np.argmin(lowest[a:b])))
    idx = np.asarray(frames, dtype=np.int64)
    return idx, lowest[idx]


def _median(values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The median of the first ``counts`` values of every row of ``values`` (..., K), as np.median computes it
    (the mean of the two middle values of an even count), without its per-call cost for the small rows here."""
    ordered = np.sort(values, axis=-1)
    low = np.take_along_axis(ordered, ((counts - 1) // 2)[..., None], axis=-1)[..., 0]
    high = np.take_along_axis(ordered, (counts // 2)[..., None], axis=-1)[..., 0]
    return (low + high) / 2


def _bisquare(residuals: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Tukey's bisquare robustness weights of the kept residuals of each row (..., K) (0 elsewhere), scaled by six
    median absolute kept residuals (as LOWESS does)."""
    counts = kept.sum(axis=-1)
    spread = _median(np.where(kept, np.abs(residuals), np.inf), counts)
    scale = 6.0 * np.maximum(spread, 1e-6)
    u = np.clip(residuals / scale[..., None], -1.0, 1.0)
    return np.where(kept, (1.0 - u * u) ** 2, 0.0)


def _weighted_lines(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(intercepts, slopes) of the weighted least-squares lines y = a + b x, one per row of weights w (..., K)."""
    sw = w.sum(axis=-1)
    mx, my = (w * x).sum(axis=-1) / sw, (w * y).sum(axis=-1) / sw
    dx = x - mx[..., None]
    var = (w * dx ** 2).sum(axis=-1)
    cov = (w * dx * (y - my[..., None])).sum(axis=-1)
    slope = np.divide(cov, var, out=np.zeros_like(cov), where=var > 0)
    return my - slope * mx, slope


def _plane_tilt(ground: np.ndarray, heights: np.ndarray) -> float:
    """Degrees from horizontal of the plane a + b x + c z through heights (K,) at ground points (K, 2)."""
    # centred, so that along a straight path (x and z in proportion) the least-norm plane still has the slope
    # along the path rather than trading it for the intercept
    design = ground - ground.mean(axis=0)
    (b, c), *_ = np.linalg.lstsq(design, heights - heights.mean(), rcond=None)
    return math.degrees(math.atan(math.hypot(b, c)))


def _lowess(x: np.ndarray, y: np.ndarray, at: np.ndarray, sigma: float, kept: np.ndarray | None = None,
            iterations: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Robust local-linear fit of samples (x, y) (K,) evaluated at ``at`` (..., P) (Gaussian kernel of ``sigma``),
    and the samples' robustness weights (..., K) (0 for an outlier). ``kept`` (..., K) fits several subsets of the
    samples at once (the step search's candidate sides), each at its own row of ``at``; the left-out samples
    weigh nothing."""
    kept = np.ones(at.shape[:-1] + x.shape, bool) if kept is None else kept
    robust = kept.astype(np.float64)

    def kernel(points: np.ndarray) -> np.ndarray:
        return np.exp(-0.5 * ((x - points[..., :, None]) / sigma) ** 2)

    def fit(points: np.ndarray, gauss: np.ndarray) -> np.ndarray:
        a, b = _weighted_lines(x, y, np.where(kept[..., None, :], robust[..., None, :] * gauss + 1e-12, 0.0))
        return a + b * points

    at_samples = kernel(x)  # the same for every subset and every iteration
    for _ in range(iterations):
        robust = _bisquare(y - fit(x, at_samples), kept)
    return fit(at, kernel(at)), robust


def _local_quantile(x: np.ndarray, y: np.ndarray, at: np.ndarray, sigma: float, q: float) -> np.ndarray:
    """The ``q`` quantile of samples (x, y) about each point of ``at``, each sample weighted by a Gaussian of
    ``sigma`` in x: the lower edge of the samples near a point rather than of the whole clip."""
    order = np.argsort(y, kind="stable")
    x, y = x[order], y[order]
    weights = np.exp(-0.5 * ((at[:, None] - x[None, :]) / sigma) ** 2) + 1e-12
    cumulative = np.cumsum(weights, axis=1) / weights.sum(axis=1, keepdims=True)
    return y[np.minimum((cumulative < q).sum(axis=1), len(y) - 1)]


def _candidate_fits(t: np.ndarray, heights: np.ndarray, ks: np.ndarray, before_cut: np.ndarray,
                    after_cut: np.ndarray, sigma: float, block: int = 1 << 21) -> tuple[np.ndarray, np.ndarray]:
    """For each candidate cut (samples [0, k) left of it, [k, K) right), each side's own trend: the largest
    distance of a sample from its side's trend, and the two trends' difference across the cut (at the frames
    ``before_cut`` and ``after_cut`` beside it, seconds). All candidates fitted at once, a block of them at a time
    so that long clips stay within bounded memory."""
    n = len(t)
    split, jump = np.empty(len(ks)), np.empty(len(ks))
    step = max(1, block // (n * n))
    for a in range(0, len(ks), step):
        k = ks[a:a + step, None]
        left_side = np.arange(n)[None, :] < k
        at_samples = np.broadcast_to(t, left_side.shape)
        left, _ = _lowess(t, heights, np.concatenate([at_samples, before_cut[a:a + step, None]], axis=1), sigma,
                          left_side)
        right, _ = _lowess(t, heights, np.concatenate([after_cut[a:a + step, None], at_samples], axis=1), sigma,
                           ~left_side)
        split[a:a + step] = np.abs(heights - np.where(left_side, left[:, :-1], right[:, 1:])).max(axis=1)
        jump[a:a + step] = np.abs(right[:, 0] - left[:, -1])
    return split, jump


def _trend(frames: np.ndarray, heights: np.ndarray, lowest: np.ndarray, fps: float, cfg: FloorConfig,
           depth: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The floor trend under frames [0, len(lowest)) through samples (frames, heights), and the samples' robustness
    weights. A smooth trend through a step in the floor ramps under the feet on both sides of it, so where cutting
    the samples in two fits them at least twice as well (the largest residual: the samples beside the step) and the
    two sides' floors differ by more than ``level_m`` at the cut, each side gets its own trend (and each side may be
    cut once more). The whole trend's misfit leaves out the samples it rejects below it: a foot through the floor
    for a moment (a stance toe dipping during a kick) is no reason to cut, and a cut beside it would follow it as a
    floor. A step leaves samples off the whole trend on both sides, above it as well as below; the cut trends must
    fit every sample."""
    t, every = frames / fps, np.arange(len(lowest)) / fps
    sigma = cfg.bandwidth_s / 2
    whole, robust = _lowess(t, heights, every, sigma)
    if depth == 0 or len(frames) < 8:
        return whole, robust
    residuals = heights - whole[frames]
    judged = (robust > 0) | (residuals > 0)
    worst = np.abs(residuals)[judged].max(initial=0.0)
    # the cut between samples k - 1 and k: the frame where the lowest foot point jumps the most
    ks = np.arange(4, len(frames) - 3)  # at least 2 s of samples on either side
    cuts = np.array([frames[k - 1] + 1 + int(np.argmax(np.abs(np.diff(lowest[frames[k - 1]:frames[k] + 1]))))
                     for k in ks], dtype=np.int64)
    split, jump = _candidate_fits(t, heights, ks, every[cuts - 1], every[cuts], sigma)
    ok = np.flatnonzero((jump > cfg.level_m) & (split <= 0.5 * worst))
    if len(ok) == 0:
        return whole, robust
    best = ok[np.argmin(split[ok])]  # the first of equals, as a scan keeping the strictly better would
    k, cut = int(ks[best]), int(cuts[best])
    left, left_robust = _trend(frames[:k], heights[:k], lowest[:cut], fps, cfg, depth - 1)
    right, right_robust = _trend(frames[k:] - cut, heights[k:], lowest[cut:], fps, cfg, depth - 1)
    return np.concatenate([left, right]), np.concatenate([left_robust, right_robust])


def fit_floor(lowest: np.ndarray, ground: np.ndarray, fps: float, cfg: FloorConfig = FloorConfig()) -> FloorModel:
    """The floor under a clip from the lowest foot point of every frame (T,) (metres, y up) and the root's ground
    position (T, 2) (for the plane's tilt)."""
    lowest = np.asarray(lowest, dtype=np.float64)
    frames, heights = floor_samples(lowest, max(1, round(cfg.sample_s * fps)))
    t = frames / fps
    trend, robust = (_trend(frames, heights, lowest, fps, cfg) if len(t) > 1
                     else (np.full(len(lowest), heights[0]), np.ones(1)))
    kept = robust > 0 if (robust > 0).any() else np.ones(len(heights), bool)  # a trend may reject every sample
    if trend.max() - trend.min() < cfg.level_m:
        # level: the lowest foot point, as a level capture always had it, unless that is a sample the trend
        # rejects (a foot dipping through the floor for a moment); then the lowest one it keeps
        kind, floor = "level", np.full(len(lowest), heights[kept].min())
    else:
        # the trend runs through the middle of the samples (stances); the floor is where the lowest of a few
        # stances reach, as a level floor is the lowest foot point: the trend lowered to the low quantile of the
        # samples about each frame (local, so that where the trend lags a fast rise the floor still meets the feet)
        kind, floor = "trend", trend + _local_quantile(t[kept], (heights - trend[frames])[kept],
                                                       np.arange(len(lowest)) / fps, cfg.bandwidth_s / 2,
                                                       cfg.low_quantile)
    residual = float(np.median(np.abs(heights - trend[frames])))  # how well a smooth floor explains the samples
    tilt = _plane_tilt(ground[frames], floor[frames]) if len(t) > 2 else 0.0
    return FloorModel(floor, kind, float(floor.max() - floor.min()), tilt, residual,
                      len(frames))
