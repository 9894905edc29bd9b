"""Controllability of the emotion condition: does the condition move the generated gaits, does a seed keep its own
emotion over the generated frames, and do recognisers that never took part in training (``pipeline.recognition``,
fitted on real train gaits by the caller) read generated gaits as intended.

Protocols (``steps`` generated frames after each seed's prefix, read in blocks of ``block`` frames):
- condition sensitivity: one seed under each of the four one-hot emotions; the mean pairwise distance between the
  four generated gaits' affect summaries (``affect_summary``), as a fraction of the mean pairwise distance between
  the real emotion centroids. 1.0: the condition moves a gait as far as the real emotions differ.
- style retention: seeds of emotion e generated under condition e, recognised as e, per block; beside it the real
  gaits' own blocks (the window's, and the continuation after the prefix where the window has it).
- transitions: the condition interpolated from A to B over the generated frames (seeds of emotion A where there
  are some), the recognisers' probability of B per block, and how often it rises from the first block to the last;
  the same seeds under a constant A condition are the control (a gait losing its seed's style also "rises").
- plan-like recognisability: scores of gaits the synthesis made (the caller runs it), against the intended dominant
  emotion.

Arrays, models and recognisers in, numbers out; this module never reads params or files.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.evaluation.autoregressive import affect_summary, one_hot_transition, straight_path
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.generators.autoregressive.rollout import Generated, PlacementConfig, Seeds, generate, place_paths
from pipeline.recognition import RecognitionInputs, confusion, majority_baseline, scores

# The features a recogniser reads of generated frames: (positions (N,T,21,3), rotations (N,T,21,4)) -> arrays.
FeatureFn = Callable[[torch.Tensor, torch.Tensor], dict[str, np.ndarray]]


@dataclass(frozen=True)
class ControllabilityConfig:
    steps: int = 60  # generated frames per gait (the published gaits' length)
    block: int = 20  # frames per recognised block
    transition_agents: int = 8  # seeds per ordered pair of emotions
    plan_gaits: int = 64  # plan-like gaits (single emotions, the synthesis plan's trajectories) recognised
    seed: int = 0  # recognisers' fitting seed and the plan sample's

    def blocks(self, frames: int, start: int = 0) -> list[tuple[int, int]]:
        return [(a, a + self.block) for a in range(start, frames - self.block + 1, self.block)]


def generated_inputs(g: Generated, features: FeatureFn) -> RecognitionInputs:
    """What a recogniser reads of generated gaits, their features computed by the synthesis annotation."""
    f = features(g.positions.double(), g.rotations.double())
    return RecognitionInputs(positions=g.positions.numpy().astype(np.float32),
                             heading=g.heading.numpy().astype(np.float32),
                             affective=f["affective"].astype(np.float32), movement=f["movement"].astype(np.float32))


def one_hot(k: int, n: int, steps: int) -> torch.Tensor:
    out = torch.zeros(n, steps, 4)
    out[..., k] = 1.0
    return out


def under_each_emotion(model: EmotiveGaitNet, seeds: Seeds, paths: torch.Tensor, steps: int, offsets: torch.Tensor,
                       parents: Sequence[int], placement: PlacementConfig) -> list[Generated]:
    """Every seed generated under each one-hot emotion (EMOTIONS order)."""
    return [generate(model, seeds, paths, one_hot(k, len(seeds), steps), offsets, parents, placement) for k in range(4)]


def mean_pairwise_distance(points: torch.Tensor) -> torch.Tensor:
    """(..., K, D) -> (...): mean Euclidean distance over the K(K-1)/2 pairs."""
    d = torch.cdist(points.double(), points.double())
    k = points.shape[-2]
    i, j = torch.triu_indices(k, k, 1)
    return d[..., i, j].mean(-1)


def condition_sensitivity(summaries: torch.Tensor, centroids: torch.Tensor) -> dict[str, Any]:
    """summaries: (4, N, 18) affect summaries of N seeds under the four conditions; centroids: (4, 18) real."""
    per_seed = mean_pairwise_distance(summaries.transpose(0, 1))  # (N,)
    real = float(mean_pairwise_distance(centroids))
    return {"fraction_of_real": round(float(per_seed.mean()) / real, 4),
            "generated_between_conditions": round(float(per_seed.mean()), 4),
            "real_between_emotion_centroids": round(real, 4),
            "per_seed_fraction_p10_p50_p90": [round(float(np.percentile(per_seed.numpy() / real, q)), 4)
                                              for q in (10, 50, 90)],
            "seeds": int(per_seed.shape[0])}


def nearest_centroid(positions: torch.Tensor, centroids: torch.Tensor, low: torch.Tensor, high: torch.Tensor,
                     scale: torch.Tensor) -> np.ndarray:
    """(N,) index of the real emotion centroid nearest to each gait's affect summary."""
    summary = affect_summary(positions, low, high, scale)
    return torch.cdist(summary.double(), centroids.double()).argmin(-1).numpy()


def recognised(inputs: RecognitionInputs, positions: torch.Tensor, spans: Sequence[tuple[int, int]],
               recognisers: dict[str, Any], centroid_reading: Callable[[torch.Tensor], np.ndarray]
               ) -> dict[str, list[np.ndarray]]:
    """Per reader (the recognisers and ``nearest_centroid``) the predicted emotion (N,) of every span of frames."""
    out: dict[str, list[np.ndarray]] = {name: [] for name in (*recognisers, "nearest_centroid")}
    for a, b in spans:
        crop = inputs.block(a, b)
        for name, r in recognisers.items():
            out[name].append(np.asarray(r.predict(crop)))
        out["nearest_centroid"].append(centroid_reading(positions[:, a:b]))
    return out


def agreement(predicted: dict[str, list[np.ndarray]], wanted: np.ndarray) -> dict[str, dict[str, list[float]]]:
    """Per reader and block: the fraction recognised as ``wanted``, and its mean over the wanted emotions present
    (balanced: the labelled test gaits are not balanced over emotions)."""
    out = {}
    for name, blocks in predicted.items():
        frac, balanced = [], []
        for p in blocks:
            hit = p == wanted
            frac.append(round(float(hit.mean()), 4))
            balanced.append(round(float(np.mean([hit[wanted == k].mean() for k in np.unique(wanted)])), 4))
        out[name] = {"fraction": frac, "balanced": balanced}
    return out


def style_retention(generated: list[Generated], inputs: list[RecognitionInputs], seed_emotion: np.ndarray,
                    recognisers: dict[str, Any], centroid_reading: Callable[[torch.Tensor], np.ndarray],
                    cfg: ControllabilityConfig) -> dict[str, Any]:
    """Seeds of emotion e under condition e recognised as e per block; and every seed under every condition c
    recognised as c (``as_condition``; ``as_condition_mismatched``: c differs from the seed's emotion)."""
    spans = cfg.blocks(cfg.steps)
    n = len(seed_emotion)
    # each seed's gait under its own emotion, grouped by emotion
    groups = [np.flatnonzero(seed_emotion == e) for e in range(4)]
    own_positions = torch.cat([generated[e].positions[torch.from_numpy(rows)] for e, rows in enumerate(groups)])
    own_inputs = RecognitionInputs.concatenate([inputs[e].select(rows) for e, rows in enumerate(groups)])
    wanted = np.concatenate([np.full(len(rows), e) for e, rows in enumerate(groups)])
    kept = agreement(recognised(own_inputs, own_positions, spans, recognisers, centroid_reading), wanted)
    as_condition: dict[str, dict[str, list[float]]] = {}
    mismatched: dict[str, dict[str, list[float]]] = {}
    per_condition = [recognised(inputs[c], generated[c].positions, spans, recognisers, centroid_reading)
                     for c in range(4)]
    for name in per_condition[0]:
        hits = [np.stack([per_condition[c][name][b] == c for c in range(4)]) for b in range(len(spans))]  # (4, N)
        other = seed_emotion[None, :] != np.arange(4)[:, None]
        as_condition[name] = [round(float(h.mean()), 4) for h in hits]
        mismatched[name] = [round(float(h[other].mean()), 4) for h in hits]
    return {"blocks": [[a, b] for a, b in spans], "seeds": n, "recognised_as_seed_emotion": kept,
            "recognised_as_condition": as_condition, "recognised_as_condition_mismatched": mismatched}


def real_style(inputs: RecognitionInputs, positions: torch.Tensor, emotion: np.ndarray, prefix: int,
               recognisers: dict[str, Any], centroid_reading: Callable[[torch.Tensor], np.ndarray],
               cfg: ControllabilityConfig) -> dict[str, Any]:
    """The real reference: real labelled windows recognised as their emotion per block of the window, and per
    block of the continuation after the prefix (as far as the window goes)."""
    frames = positions.shape[1]
    window = cfg.blocks(frames)
    continuation = cfg.blocks(frames, prefix)
    return {"window_blocks": [[a, b] for a, b in window],
            "window": agreement(recognised(inputs, positions, window, recognisers, centroid_reading), emotion),
            "continuation_blocks": [[a, b] for a, b in continuation],
            "continuation": agreement(recognised(inputs, positions, continuation, recognisers, centroid_reading),
                                      emotion),
            "gaits": int(len(emotion))}


def transition_recognition(model: EmotiveGaitNet, pool: Seeds, pool_emotion: np.ndarray, recognisers: dict[str, Any],
                           features: FeatureFn, offsets: torch.Tensor, parents: Sequence[int],
                           placement: PlacementConfig, cfg: ControllabilityConfig) -> dict[str, Any]:
    """Every ordered pair A -> B of one-hot emotions over ``cfg.steps`` frames on a straight line, from up to
    ``cfg.transition_agents`` seeds of emotion A (any labelled seeds where there are none): the recognisers'
    probability of B per block, the fraction of gaits where it rises from the first block to the last, and the
    same for the seeds under a constant A condition (the control)."""
    steps, spans = cfg.steps, cfg.blocks(cfg.steps)
    probs: dict[str, dict[str, list[np.ndarray]]] = {k: {"transition": [], "control": []} for k in recognisers}
    pairs: dict[str, dict[str, Any]] = {}
    for a in range(4):
        rows = np.flatnonzero(pool_emotion == a)
        rows = (rows if len(rows) else np.arange(len(pool_emotion)))[: cfg.transition_agents]
        seeds = Seeds(gaits=pool.gaits.select(torch.from_numpy(rows)), heading=pool.heading[rows])
        paths = place_paths(straight_path(), seeds)
        constant = generate(model, seeds, paths, one_hot(a, len(rows), steps), offsets, parents, placement)
        control_inputs = generated_inputs(constant, features)
        for b in range(4):
            if a == b:
                continue
            g = generate(model, seeds, paths, one_hot_transition(a, b, steps, len(rows)), offsets, parents, placement)
            inputs = generated_inputs(g, features)
            pair = {}
            for name, r in recognisers.items():
                # (n, blocks) probability of the end emotion
                p = np.stack([np.asarray(r.probabilities(inputs.block(s, e)))[:, b] for s, e in spans], 1)
                c = np.stack([np.asarray(r.probabilities(control_inputs.block(s, e)))[:, b] for s, e in spans], 1)
                probs[name]["transition"].append(p)
                probs[name]["control"].append(c)
                pair[name] = [round(float(v), 4) for v in p.mean(0)]
            pairs[f"{EMOTIONS[a]}->{EMOTIONS[b]}"] = {"seeds_of_start_emotion": bool((pool_emotion == a).any()),
                                                      "end_probability_by_block": pair}
    out: dict[str, Any] = {"blocks": [[s, e] for s, e in spans], "frames": steps}
    for name, d in probs.items():
        p, c = np.concatenate(d["transition"]), np.concatenate(d["control"])
        out[name] = {"end_probability_by_block": [round(float(v), 4) for v in p.mean(0)],
                     "rising_fraction": round(float((p[:, -1] > p[:, 0]).mean()), 4),
                     "control_end_probability_by_block": [round(float(v), 4) for v in c.mean(0)],
                     "control_rising_fraction": round(float((c[:, -1] > c[:, 0]).mean()), 4),
                     "gaits": int(p.shape[0])}
    out["pairs"] = pairs
    return out


def recognition_scores(recognisers: dict[str, Any], inputs: RecognitionInputs, intended: np.ndarray) -> dict[str, Any]:
    """Accuracy, balanced accuracy, macro-F1 and the confusion (rows: intended) of each recogniser against
    ``intended`` (N,), and the majority-class baseline of ``intended``."""
    out: dict[str, Any] = {"gaits": int(len(intended)),
                           "intended_counts": {e: int((intended == k).sum()) for k, e in enumerate(EMOTIONS)}}
    for name, r in recognisers.items():
        matrix = confusion(intended, np.asarray(r.predict(inputs)), len(EMOTIONS))
        out.setdefault("majority_baseline", majority_baseline(matrix, EMOTIONS))
        out[name] = {**scores(matrix), "confusion": matrix.tolist()}
    return out
