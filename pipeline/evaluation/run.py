"""The generator's evaluation on held-out gaits, end to end: which gaits each protocol of
``pipeline.evaluation.autoregressive`` runs on (the test split only), the real references, and the acceptance
checks. Takes the split gait table, loaded models and plain configs; returns the report and the rollouts to draw.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.core.skeleton import Skeleton
from pipeline.evaluation.autoregressive import (
    affect_summary,
    emotion_centroids,
    expressiveness,
    long_rollouts,
    rollout_figures,
    skating_speed,
    table1,
    transitions,
)
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds
from pipeline.generators.autoregressive.training import GaitTensors
from pipeline.ops.contacts import ContactConfig


@dataclass(frozen=True)
class EvaluationConfig:
    prefix: int  # frames given to the generator
    rollout_steps: int  # long-horizon rollouts, straight line and a sharp 90-degree turn
    rollout_agents: int
    expressiveness_steps: int
    transition_steps: int  # emotion interpolated from A to B over this many frames
    transition_agents: int


def first_window_per_clip(rows: np.ndarray, clip_ids: list[str]) -> np.ndarray:
    seen, out = set(), []
    for r in rows:
        if clip_ids[r] not in seen:
            seen.add(clip_ids[r])
            out.append(r)
    return np.array(out, dtype=np.int64)


def evaluate_generators(table: pa.Table, arrays: dict[str, np.ndarray], models: dict[str, EmotiveGaitNet],
                        shas: dict[str, str], skeleton: Skeleton, placement: PlacementConfig,
                        contacts: ContactConfig, cfg: EvaluationConfig) -> tuple[dict[str, Any], dict[str, Any]]:
    """(report, rollouts): Table 1, long rollouts, expressiveness and transitions of every model (``full`` and
    ``no_affect`` among them) on the test split of ``table``; rollouts[model][path] for the plots."""
    prefix = cfg.prefix
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    parents = skeleton.parents
    split = np.array(table.column("split").to_pylist())
    content = np.array(table.column("content").to_pylist())
    clip_ids = table.column("clip_id").to_pylist()
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    dominant = [dominant_emotion(None if not labelled[i] else arrays["emotion"][i], EMOTIONS)
                for i in range(len(split))]
    full = models["full"]
    low, high, scale = full.affective_low, full.affective_high, full.affective_std
    report: dict[str, Any] = {"checkpoints_sha256": shas, "split": "test", "prefix": prefix, "fps": placement.fps,
                              "rollout_steps": cfg.rollout_steps, "placement": asdict(placement)}

    # Table 1: every test gait, ground-truth path, its own label.
    test = np.flatnonzero(split == "test")
    gaits = GaitTensors.from_arrays(arrays, test)
    heading = torch.from_numpy(arrays["heading"][test].astype(np.float32))
    emotions = torch.from_numpy(arrays["emotion"][test].astype(np.float32))
    print(f"evaluate: Table-1 protocol on {len(test)} test gaits", flush=True)
    report["table1"] = table1(models, gaits, heading, emotions, offsets, parents, prefix, placement, low, high)
    report["table1_gaits"] = int(len(test))

    # 200-step rollouts from forward-walking test gaits (one window per clip).
    walks = first_window_per_clip(np.flatnonzero((split == "test") & (content == "walk")), clip_ids)
    walks = walks[: cfg.rollout_agents]
    seeds = Seeds.from_arrays(arrays, walks, prefix)
    seed_emotion = torch.from_numpy(arrays["emotion"][walks].astype(np.float32))
    real_walks = np.flatnonzero((split == "test") & (content == "walk"))
    real_pos = torch.from_numpy(arrays["positions"][real_walks])
    real_speed = arrays["movement"][real_walks][..., 1].mean(-1) * placement.fps
    speed_range = [float(np.percentile(real_speed, 5)), float(np.percentile(real_speed, 95))]
    real_skate, real_contact = skating_speed(real_pos, placement.fps, contacts)
    report["real_reference"] = {"walk_windows": int(len(real_walks)), "speed_m_s_p5_p95": [round(v, 4) for v in speed_range],
                                "foot_skating_m_s": round(real_skate, 4), "contact_fraction": round(real_contact, 4)}
    steps = cfg.rollout_steps
    print(f"evaluate: {steps}-step rollouts of {len(walks)} agents on a straight line and a sharp turn", flush=True)
    rollouts, report["long_horizon"] = {}, {}
    for name, model in models.items():
        rollouts[name] = long_rollouts(model, seeds, seed_emotion, offsets, parents, steps, placement)
        report["long_horizon"][name] = {path: rollout_figures(r, placement.fps, contacts, speed_range)
                                        for path, r in rollouts[name].items()}
        for figures in report["long_horizon"][name].values():
            skate = figures["foot_skating_m_s"]
            figures["foot_skating_ratio_to_real"] = round(skate / real_skate, 3) if skate is not None else None

    # Emotions: real centroids from the labelled train gaits; seeds are the labelled test gaits.
    train_lab = np.flatnonzero((split == "train") & labelled)
    train_summary = affect_summary(torch.from_numpy(arrays["positions"][train_lab]), low, high, scale)
    centroids = emotion_centroids(train_summary, [dominant[i] for i in train_lab])
    test_lab = np.flatnonzero((split == "test") & labelled)
    test_summary = affect_summary(torch.from_numpy(arrays["positions"][test_lab]), low, high, scale)
    nearest = torch.cdist(test_summary.double(), centroids.double()).argmin(-1)
    intended = torch.tensor([EMOTIONS.index(dominant[i]) for i in test_lab])
    report["emotion_reference"] = {
        "train_labelled_gaits": int(len(train_lab)), "test_labelled_gaits": int(len(test_lab)),
        "real_test_nearest_centroid_accuracy": round(float((nearest == intended).double().mean()), 4)}
    emo_seeds = Seeds.from_arrays(arrays, test_lab, prefix)
    print(f"evaluate: expressiveness and transitions from {len(test_lab)} labelled test gaits", flush=True)
    report["expressiveness"] = {name: expressiveness(model, emo_seeds, centroids, offsets, parents,
                                                     cfg.expressiveness_steps, placement, low, high, scale)
                                for name, model in models.items()}
    trans_seeds = Seeds.from_arrays(arrays, test_lab[: cfg.transition_agents], prefix)
    report["transitions"] = {name: transitions(model, trans_seeds, centroids, offsets, parents,
                                               cfg.transition_steps, placement, low, high, scale)
                             for name, model in models.items() if name in ("full", "no_affect")}
    report["acceptance"] = acceptance(report)
    return report, rollouts


def acceptance(report: dict) -> dict:
    t1 = report["table1"]
    full = t1["full"]
    lh = report["long_horizon"]["full"]
    out = {
        "beats_zero_velocity": full["pose_error"] < t1["zero_velocity"]["pose_error"]
        and full["rotation_error_deg"] < t1["zero_velocity"]["rotation_error_deg"],
        "beats_constant_velocity": full["pose_error"] < t1["constant_velocity"]["pose_error"]
        and full["rotation_error_deg"] < t1["constant_velocity"]["rotation_error_deg"],
        "no_affect_worse_on_affective_error": t1["no_affect"]["affective_error"] > full["affective_error"],
        "rollouts_finite_and_moving": all(f["finite"] and f["frozen_agents"] == 0 for f in lh.values()),
        "foot_skating_at_most_1_5x_real": all(f["foot_skating_ratio_to_real"] is not None
                                              and f["foot_skating_ratio_to_real"] <= 1.5 for f in lh.values()),
    }
    out["passed"] = all(out.values())
    return out
