"""The generator's evaluation on held-out gaits, end to end: which gaits each protocol of
``pipeline.evaluation.autoregressive`` runs on (the test split only), the real references, and the acceptance
checks. Takes the split gait table, loaded models and plain configs; returns the report and the rollouts to draw.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.annotate.annotation import AnnotateConfig
from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.core.skeleton import Skeleton
from pipeline.evaluation.autoregressive import (
    affect_summary,
    emotion_centroids,
    expressiveness,
    long_rollouts,
    one_hot_transition,
    rollout_figures,
    table1,
    straight_path,
    transitions,
)
from pipeline.ops.footlock import skating_speed
from pipeline.evaluation.controllability import (
    ControllabilityConfig,
    condition_sensitivity,
    generated_inputs,
    nearest_centroid,
    real_style,
    recognition_scores,
    style_retention,
    transition_recognition,
    under_each_emotion,
)
from pipeline.generators.autoregressive.family import AutoregressiveFamily
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths
from pipeline.generators.autoregressive.training import GaitTensors
from pipeline.ops.contacts import ContactConfig
from pipeline.recognition import RECOGNISERS, RecognitionInputs, RecogniserConfig, fit_recogniser
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, synthesize, window_features
from pipeline.synth.trajectories import piece_from


@dataclass(frozen=True)
class EvaluationConfig:
    prefix: int  # frames given to the generator
    rollout_steps: int  # long-horizon rollouts, straight line and a sharp 90-degree turn
    rollout_agents: int
    expressiveness_steps: int
    transition_steps: int  # emotion interpolated from A to B over this many frames
    transition_agents: int


@dataclass(frozen=True)
class ControlSetup:
    """What the controllability protocols need besides the models: their own config, the recognisers' config,
    the annotation config (features of generated frames, as synthesis computes them) and the synthesis config (its
    plan gives the plan-like gaits and the previews' trajectory)."""

    control: ControllabilityConfig
    recognisers: RecogniserConfig
    annotate: AnnotateConfig
    synthesis: SynthesisConfig
    preview_trajectory: str
    preview_transition: tuple[str, str]


def first_window_per_clip(rows: np.ndarray, clip_ids: list[str]) -> np.ndarray:
    seen, out = set(), []
    for r in rows:
        if clip_ids[r] not in seen:
            seen.add(clip_ids[r])
            out.append(r)
    return np.array(out, dtype=np.int64)


def evaluate_generators(table: pa.Table, arrays: dict[str, np.ndarray], models: dict[str, EmotiveGaitNet],
                        shas: dict[str, str], skeleton: Skeleton, placement: PlacementConfig,
                        contacts: ContactConfig, cfg: EvaluationConfig, setup: ControlSetup | None = None
                        ) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(report, rollouts, previews): Table 1, long rollouts, expressiveness and transitions of every model (``full``
    and ``no_affect`` among them) on the test split of ``table``, and with ``setup`` the controllability protocols
    (``evaluate_controllability``); rollouts[model][path] for the plots; previews: the preview gaits ({} without
    ``setup``)."""
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
    previews: dict[str, Any] = {}
    if setup is not None:
        report["controllability"], previews = evaluate_controllability(
            table, arrays, models, shas, skeleton, placement, centroids, dominant, prefix, setup)
    report["acceptance"] = acceptance(report)
    return report, rollouts, previews


def labelled_rows(split: np.ndarray, dominant: list[str], name: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows of a split whose label has one dominant emotion, and that emotion's index (EMOTIONS order)."""
    rows = np.array([i for i in np.flatnonzero(split == name) if dominant[i] in EMOTIONS], dtype=np.int64)
    return rows, np.array([EMOTIONS.index(dominant[i]) for i in rows], dtype=np.int64)


def evaluate_controllability(table: pa.Table, arrays: dict[str, np.ndarray], models: dict[str, EmotiveGaitNet],
                             shas: dict[str, str], skeleton: Skeleton, placement: PlacementConfig,
                             centroids: torch.Tensor, dominant: list[str], prefix: int, setup: ControlSetup
                             ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The ``controllability`` protocols on the test split: condition sensitivity and style retention of every
    model, the recognisers' reading of transitions and of plan-like gaits for ``full`` and ``no_affect``; both
    recognisers fitted here on the labelled train gaits (never seen by any generator's loss). Returns the report
    section and the preview gaits."""
    cfg = setup.control
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    parents = skeleton.parents
    split = np.array(table.column("split").to_pylist())
    full = models["full"]
    low, high, scale = full.affective_low, full.affective_high, full.affective_std

    def features(positions: torch.Tensor, rotations: torch.Tensor) -> dict[str, np.ndarray]:
        return window_features(positions, rotations, skeleton, setup.annotate)

    def centroid_reading(positions: torch.Tensor) -> np.ndarray:
        return nearest_centroid(positions, centroids, low, high, scale)

    train_rows, train_labels = labelled_rows(split, dominant, "train")
    started = time.perf_counter()
    print(f"evaluate: fitting recognisers {', '.join(RECOGNISERS)} on {len(train_rows)} labelled train gaits",
          flush=True)
    train_inputs = RecognitionInputs.from_arrays(arrays, train_rows)
    recognisers = {kind: fit_recogniser(kind, train_inputs, train_labels, setup.recognisers,
                                        cfg.seed) for kind in RECOGNISERS}
    # The fit time is printed, not reported: eval.json is a DVC metric and must be the same bytes on a rerun.
    print(f"evaluate: recognisers fitted in {time.perf_counter() - started:.1f} s", flush=True)
    out: dict[str, Any] = {"config": asdict(cfg), "recognisers": list(RECOGNISERS),
                           "train_labelled_gaits": int(len(train_rows))}
    test_rows, test_labels = labelled_rows(split, dominant, "test")
    real = RecognitionInputs.from_arrays(arrays, test_rows)
    real_positions = torch.from_numpy(arrays["positions"][test_rows])
    out["real_test"] = {"scores": recognition_scores(recognisers, real, test_labels),
                        **real_style(real, real_positions, test_labels, prefix, recognisers, centroid_reading, cfg)}
    seeds = Seeds.from_arrays(arrays, test_rows, prefix)
    paths = place_paths(straight_path(), seeds)
    out["condition_sensitivity"], out["style_retention"] = {}, {}
    out["transitions"], out["plan_like"], out["plan_like_dominant_one_hot"] = {}, {}, {}
    for name, model in models.items():
        print(f"evaluate: controllability of {name} from {len(test_rows)} labelled test seeds", flush=True)
        generated = under_each_emotion(model, seeds, paths, cfg.steps, offsets, parents, placement)
        summaries = torch.stack([affect_summary(g.positions, low, high, scale) for g in generated])
        out["condition_sensitivity"][name] = condition_sensitivity(summaries, centroids)
        inputs = [generated_inputs(g, features) for g in generated]
        out["style_retention"][name] = style_retention(generated, inputs, test_labels, recognisers, centroid_reading,
                                                       cfg)
        if name in ("full", "no_affect"):
            out["transitions"][name] = transition_recognition(model, seeds, test_labels, recognisers, features,
                                                              offsets, parents, placement, cfg)
    work = SynthesisPlan.prepare(table, arrays, setup.synthesis)
    rows = plan_sample(work, cfg)
    trajectories = {t.id: t for t in work.trajectories}
    intended = np.array([EMOTIONS.index(dominant_emotion(work.emotions[r["recipe"]["emotion"]], EMOTIONS))
                         for r in rows])
    dominant_only = np.eye(len(EMOTIONS))[np.argmax(work.emotions, axis=-1)]
    for name in ("full", "no_affect"):
        if name not in models:
            continue
        print(f"evaluate: plan-like recognisability of {name}: {len(rows)} gaits synthesized as the plan makes them",
              flush=True)
        family = AutoregressiveFamily(models[name], shas[name], arrays, work.row_of, skeleton, placement, prefix)
        made = synthesize(family, rows, work.emotions, trajectories, skeleton, setup.annotate,
                          replace(setup.synthesis, frames=cfg.steps))
        plan_inputs = RecognitionInputs.from_arrays(made)
        out["plan_like"][name] = {"trajectories": sorted({r["trajectory_id"] for r in rows}),
                                  **recognition_scores(recognisers, plan_inputs, intended)}
        # the same rows under the one-hot of their dominant emotion: how much of a miss is the mixtures'?
        made = synthesize(family, rows, dominant_only, trajectories, skeleton, setup.annotate,
                          replace(setup.synthesis, frames=cfg.steps))
        out["plan_like_dominant_one_hot"][name] = recognition_scores(recognisers, RecognitionInputs.from_arrays(made),
                                                                     intended)
    content = np.array(table.column("content").to_pylist())
    previews = preview_gaits(full, arrays, content, test_rows, test_labels, work, setup, offsets, parents, placement,
                             prefix)
    return out, previews


def plan_sample(work: SynthesisPlan, cfg: ControllabilityConfig) -> list[dict[str, Any]]:
    """Up to ``cfg.plan_gaits`` single-emotion rows of the synthesis plan, as many of each dominant emotion as
    there are (a quarter each where the plan allows), drawn with ``cfg.seed``."""
    rng = np.random.default_rng([cfg.seed, 11])
    singles = [r for r in work.plan if r["recipe"]["kind"] == "single"]
    by_emotion: dict[str, list[dict[str, Any]]] = {e: [] for e in EMOTIONS}
    for r in singles:
        d = dominant_emotion(work.emotions[r["recipe"]["emotion"]], EMOTIONS)
        if d in by_emotion:
            by_emotion[d].append(r)
    out = []
    for e in EMOTIONS:
        pool = by_emotion[e]
        out += [pool[i] for i in sorted(rng.permutation(len(pool))[: cfg.plan_gaits // len(EMOTIONS)])]
    return out


def preview_gaits(model: EmotiveGaitNet, arrays: dict[str, np.ndarray], content: np.ndarray,
                  test_rows: np.ndarray, test_labels: np.ndarray, work: SynthesisPlan, setup: ControlSetup,
                  offsets: torch.Tensor, parents, placement: PlacementConfig, prefix: int) -> dict[str, Any]:
    """One seed (the labelled test walk of the transition's start emotion of median speed, else of any emotion,
    else the first labelled test gait) on the preview trajectory under each one-hot emotion, and the same seed
    in the preview transition with its two constant emotions beside it:
    {"emotions": [(title, positions (T, 21, 3))], "transition": [...], "seed_row": row}."""
    steps = setup.control.steps
    start, end = (EMOTIONS.index(e) for e in setup.preview_transition)
    walks = np.array([c == "walk" for c in content[test_rows]])
    candidates = np.flatnonzero((test_labels == start) & walks)
    candidates = candidates if len(candidates) else np.flatnonzero(walks)
    if len(candidates):  # the walk of typical speed (a clip's first window may be the first slow steps)
        speed = arrays["movement"][test_rows[candidates], :, 1].mean(-1)
        pick = int(test_rows[candidates[np.argmin(np.abs(speed - np.median(speed)))]])
    else:
        pick = int(test_rows[0])
    seeds = Seeds.from_arrays(arrays, np.array([pick]), prefix)
    trajectory = {t.id: t for t in work.trajectories}[setup.preview_trajectory]
    shape = torch.from_numpy(piece_from(trajectory.points, 0.0, setup.synthesis.path_ahead_m).astype(np.float32))
    paths = place_paths(shape, seeds)
    generated = under_each_emotion(model, seeds, paths, steps, offsets, parents, placement)
    seed_name = EMOTIONS[test_labels[list(test_rows).index(pick)]]
    emotions = [(f"{EMOTIONS[k]} (seed {seed_name})\n{setup.preview_trajectory}", g.positions[0].numpy())
                for k, g in enumerate(generated)]
    g = generate(model, seeds, paths, one_hot_transition(start, end, steps, 1), offsets, parents, placement)
    transition = [(f"constant {EMOTIONS[start]}", generated[start].positions[0].numpy()),
                  (f"{EMOTIONS[start]} -> {EMOTIONS[end]}", g.positions[0].numpy()),
                  (f"constant {EMOTIONS[end]}", generated[end].positions[0].numpy())]
    return {"emotions": emotions, "transition": transition, "seed_row": pick}


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
        "foot_skating_at_most_1_2x_real": all(f["foot_skating_ratio_to_real"] is not None  # issue 11's goal
                                              and f["foot_skating_ratio_to_real"] <= 1.2 for f in lh.values()),
    }
    control = report.get("controllability")
    if control is not None:  # issue 11: the condition must show, read by both independent recognisers
        kinds = control["recognisers"]
        kept = control["style_retention"]["full"]["recognised_as_seed_emotion"]
        rising = control["transitions"]["full"]
        out["condition_sensitivity_at_least_0_8"] = control["condition_sensitivity"]["full"]["fraction_of_real"] >= 0.8
        out["style_retention_last_block_at_least_0_70"] = all(kept[k]["fraction"][-1] >= 0.70 for k in kinds)
        out["transitions_end_emotion_rising_at_least_0_8"] = all(rising[k]["rising_fraction"] >= 0.8 for k in kinds)
    out["passed"] = all(out.values())
    return out
