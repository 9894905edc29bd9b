"""Evaluation of the generator on held-out gaits: the paper's Table-1 protocol with baselines and ablations,
200-step rollouts (speed, foot skating, trajectory deviation), emotion expressiveness and transitions.

Everything here takes arrays and models and returns numbers; the `evaluate` stage picks the test split, writes
the report and draws the plots. Pose errors are measured on the pose alone (joint positions relative to the root,
in the frame of the direction of travel, from the 21 versors: a method is not rewarded or punished for the
trajectory it was given) and divided by the diagonal of the ground-truth character's bounding box in that frame
over the window (~1.9 m for an adult); rotation errors are geodesic angles of the 21 versors, in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.ops.contacts import ContactConfig
from pipeline.ops.features import affective_features
from pipeline.ops.footlock import skating_speed
from pipeline.ops.geometry import distance_to_polyline
from pipeline.generators.autoregressive.rollout import (
    Generated,
    PlacementConfig,
    Seeds,
    generate,
    place_paths,
    prefix_of,
)
from pipeline.generators.autoregressive.network import EmotiveGaitNet, travel_frame_positions
from pipeline.ops.quaternion import qangle, qconj, qmul, qnormalize
from pipeline.generators.autoregressive.training import GaitTensors


# --- Table 1 ----------------------------------------------------------------------------------------------

def zero_velocity(q_prefix: torch.Tensor, steps: int) -> torch.Tensor:
    """Repeat the last prefix frame: (N, P, 21, 4) -> (N, steps, 21, 4)."""
    return q_prefix[:, -1:].expand(-1, steps, -1, -1).clone()


def constant_velocity(q_prefix: torch.Tensor, steps: int) -> torch.Tensor:
    """Continue every joint's last frame-to-frame rotation: q_{t+1} = q_t (q_{t-1}^{-1} q_t)."""
    change = qmul(qconj(q_prefix[:, -2]), q_prefix[:, -1])
    out, q = [], q_prefix[:, -1]
    for _ in range(steps):
        q = qnormalize(qmul(q, change))
        out.append(q)
    return torch.stack(out, dim=1)


def pose_errors(q_pred: torch.Tensor, q_true: torch.Tensor, offsets: torch.Tensor, parents: Sequence[int],
                clip_low: torch.Tensor | float = -math.inf, clip_high: torch.Tensor | float = math.inf
                ) -> dict[str, torch.Tensor]:
    """Per gait and frame (N, S): relative position error, rotation error (deg), affective |error| (N, S, 18) with
    the features clipped to [clip_low, clip_high] (the training 1st/99th percentiles: the heavy-tailed area ratio
    would otherwise decide the mean)."""
    pred = travel_frame_positions(q_pred, offsets, parents)
    true = travel_frame_positions(q_true, offsets, parents)
    extent = true.reshape(true.shape[0], -1, 3)
    diagonal = torch.linalg.vector_norm(extent.max(1).values - extent.min(1).values, dim=-1)  # (N,)
    position = torch.linalg.vector_norm(pred - true, dim=-1)[..., 1:].mean(-1) / diagonal[:, None]
    rotation = torch.rad2deg(qangle(q_pred, q_true)).mean(-1)
    affective = (affective_features(pred).clamp(clip_low, clip_high)
                 - affective_features(true).clamp(clip_low, clip_high)).abs()
    return {"position": position, "rotation": rotation, "affective": affective}


def table1(models: dict[str, EmotiveGaitNet], gaits: GaitTensors, heading: torch.Tensor, emotions: torch.Tensor,
           offsets: torch.Tensor, parents: Sequence[int], prefix: int, placement: PlacementConfig,
           clip_low: torch.Tensor, clip_high: torch.Tensor) -> dict[str, dict]:
    """The paper's protocol: ``prefix`` frames in, the rest predicted on the ground-truth path; per method the mean
    relative position error, rotation error (deg), affective-feature error and, for the networks, the root's
    distance to the ground-truth root. Also the errors per predicted frame (horizon curves).

    emotions: (N, 4) labels (NaN rows: unlabelled); clip_low/high: see ``pose_errors``."""
    steps = gaits.q.shape[1] - prefix
    truth = gaits.q[:, prefix:]
    # The root as the paper places it (by ŝ along the given path): the travel frame then follows the ground-truth
    # path as in training, and root_distance_m measures the predicted speed. The stance-foot placement of
    # generated gaits moves the root, not the pose, and is measured by the rollouts.
    # No guidance and no foot lock either: Table 1 measures the network's own prediction (both are generation
    # choices).
    placement = replace(placement, root_advance="predicted_speed", guidance=1.0, foot_lock=False)
    seeds = Seeds(gaits=prefix_of(gaits, prefix), heading=heading[:, :prefix])
    paths = gaits.root_position[:, prefix - 1:, [0, 2]]
    predictions = {"zero_velocity": zero_velocity(gaits.q[:, :prefix], steps),
                   "constant_velocity": constant_velocity(gaits.q[:, :prefix], steps)}
    root_error = {}
    for name, model in models.items():
        generated = generate(model, seeds, paths, emotions[:, None].expand(-1, steps, -1), offsets, parents, placement)
        predictions[name] = generated.versors
        root = generated.positions[:, :, 0, [0, 2]]
        root_error[name] = torch.linalg.vector_norm(root - gaits.root_position[:, prefix:, [0, 2]], dim=-1)
    out = {}
    for name, q in predictions.items():
        errors = pose_errors(q, truth, offsets, parents, clip_low, clip_high)
        out[name] = {
            "pose_error": round(float(errors["position"].mean()), 5),
            "rotation_error_deg": round(float(errors["rotation"].mean()), 3),
            "affective_error": round(float(errors["affective"].mean()), 5),
            "pose_error_by_frame": [round(float(v), 5) for v in errors["position"].mean(0)],
            "rotation_error_deg_by_frame": [round(float(v), 3) for v in errors["rotation"].mean(0)],
        }
        if name in root_error:
            out[name]["root_distance_m"] = round(float(root_error[name].mean()), 4)
    return out


# --- long rollouts ----------------------------------------------------------------------------------------

def straight_path(length_m: float = 40.0) -> torch.Tensor:
    return torch.tensor([[0.0, 0.0], [0.0, length_m]])


def turn_path(before_m: float = 2.5, angle_deg: float = 90.0, after_m: float = 40.0) -> torch.Tensor:
    """Straight ahead, then a sharp turn to the left (+x is the body's left when facing +z)."""
    a = math.radians(angle_deg)
    return torch.tensor([[0.0, 0.0], [0.0, before_m], [after_m * math.sin(a), before_m + after_m * math.cos(a)]])


@dataclass
class Rollout:
    path: torch.Tensor  # (N, K, 2)
    generated: Generated


def long_rollouts(model: EmotiveGaitNet, seeds: Seeds, emotions: torch.Tensor, offsets: torch.Tensor,
                  parents: Sequence[int], steps: int, placement: PlacementConfig) -> dict[str, Rollout]:
    """``steps`` frames on a straight line and on a path with a sharp turn, from every seed."""
    out = {}
    for name, shape in (("straight", straight_path()), ("sharp_turn", turn_path())):
        paths = place_paths(shape, seeds)
        out[name] = Rollout(paths, generate(model, seeds, paths, emotions[:, None].expand(-1, steps, -1), offsets,
                                            parents, placement))
    return out


def rollout_figures(rollout: Rollout, fps: float, contacts: ContactConfig, real_speed: Sequence[float]) -> dict:
    g = rollout.generated
    speed = g.advance * fps  # (N, S) m/s, as placed
    block = min(50, speed.shape[1])
    blocks = speed[:, : speed.shape[1] // block * block].reshape(speed.shape[0], -1, block).mean(-1)
    root = g.positions[:, :, 0, [0, 2]]
    skate, contact_fraction = skating_speed(g.positions, fps, contacts)
    rotation_change = torch.rad2deg(qangle(g.rotations[:, 1:], g.rotations[:, :-1])).numpy()  # deg / frame
    deviation = distance_to_polyline(root, rollout.path)
    last = speed[:, -50:].mean(-1)
    return {
        "finite": bool(torch.isfinite(g.positions).all()),
        "speed_m_s_mean": round(float(speed.mean()), 4),
        "speed_m_s_by_50_frames": [round(float(v), 4) for v in blocks.mean(0)],
        "frozen_agents": int((last < 0.5 * real_speed[0]).sum()),
        "agents": int(speed.shape[0]),
        "real_speed_m_s_p5_p95": [round(float(v), 4) for v in real_speed],
        "foot_skating_m_s": round(skate, 4) if skate is not None else None,
        "contact_fraction": round(contact_fraction, 4),
        "max_joint_rotation_change_deg_per_frame_p99": round(float(np.percentile(rotation_change, 99)), 3),
        "trajectory_deviation_m": round(float(deviation.mean()), 4),
        "trajectory_deviation_m_max": round(float(deviation.max()), 4),
    }


# --- emotions ---------------------------------------------------------------------------------------------

def affect_summary(positions: torch.Tensor, low: torch.Tensor, high: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """Per gait: mean over frames of the 18 affective features, clipped to the training range and divided by
    their training standard deviation: (N, T, 21, 3) -> (N, 18)."""
    return (affective_features(positions).clamp(low, high) / scale).mean(1)


def emotion_centroids(summaries: torch.Tensor, dominant: Sequence[str]) -> torch.Tensor:
    """(4, 18) mean summary per emotion (EMOTIONS order) over the gaits whose dominant emotion it is."""
    rows = []
    for name in EMOTIONS:
        idx = [i for i, d in enumerate(dominant) if d == name]
        rows.append(summaries[idx].mean(0) if idx else torch.full_like(summaries[0], float("nan")))
    return torch.stack(rows)


def expressiveness(model: EmotiveGaitNet, seeds: Seeds, centroids: torch.Tensor, offsets: torch.Tensor,
                   parents: Sequence[int], steps: int, placement: PlacementConfig, low: torch.Tensor,
                   high: torch.Tensor, scale: torch.Tensor) -> dict:
    """Generate from every seed with each one-hot emotion and measure them against the real emotion centroids
    (``centroid_distances``)."""
    paths = place_paths(straight_path(), seeds)
    summaries = []
    for k in range(len(EMOTIONS)):
        target = torch.zeros(len(seeds), steps, 4)
        target[..., k] = 1.0
        g = generate(model, seeds, paths, target, offsets, parents, placement)
        summaries.append(affect_summary(g.positions, low, high, scale))
    return centroid_distances(torch.stack(summaries), centroids)


def centroid_distances(summaries: torch.Tensor, centroids: torch.Tensor) -> dict:
    """summaries (4, N, 18): N gaits generated under each one-hot emotion (EMOTIONS order); centroids (4, 18) real.
    Distances of the gaits to their own emotion's centroid vs the others, and how often their own is the nearest."""
    same, other, hits = [], [], 0
    per_emotion = {}
    for k, name in enumerate(EMOTIONS):
        dist = torch.cdist(summaries[k].double(), centroids.double())  # (N, 4)
        same.append(dist[:, k])
        other.append(torch.cat([dist[:, :k], dist[:, k + 1:]], -1).mean(-1))
        nearest = dist.argmin(-1)
        hits += int((nearest == k).sum())
        per_emotion[name] = {"distance_same": round(float(dist[:, k].mean()), 4),
                             "nearest_is_intended": round(float((nearest == k).double().mean()), 4)}
    same_t, other_t = torch.cat(same), torch.cat(other)
    total = summaries.shape[0] * summaries.shape[1]
    return {"distance_to_same_emotion": round(float(same_t.mean()), 4),
            "distance_to_other_emotions": round(float(other_t.mean()), 4),
            "same_closer_than_others": round(float((same_t < other_t).double().mean()), 4),
            "nearest_centroid_accuracy": round(hits / max(total, 1), 4), "chance": 0.25, "per_emotion": per_emotion}


def one_hot_transition(a: int, b: int, steps: int, n: int) -> torch.Tensor:
    """(n, steps, 4): the emotion interpolated linearly per frame from one-hot ``a`` to one-hot ``b``,
    renormalised (the evaluation's transitions; the plan's own are ``synth.plan.frame_emotions``)."""
    u = torch.linspace(0.0, 1.0, steps)[None, :, None]
    start, end = torch.zeros(4), torch.zeros(4)
    start[a], end[b] = 1.0, 1.0
    emotion = (1 - u) * start + u * end
    return (emotion / emotion.sum(-1, keepdim=True)).expand(n, -1, -1)


def transitions(model: EmotiveGaitNet, seeds: Seeds, centroids: torch.Tensor, offsets: torch.Tensor,
                parents: Sequence[int], steps: int, placement: PlacementConfig, low: torch.Tensor,
                high: torch.Tensor, scale: torch.Tensor, blocks: int = 4) -> dict:
    """Emotion interpolated linearly per frame from A to B (every ordered pair of one-hot emotions), renormalised;
    the affect summary of each of ``blocks`` consecutive stretches is projected on the axis from centroid A to
    centroid B. Reports how often the projection rises monotonically and its mean rise (A -> B = 1)."""
    paths = place_paths(straight_path(), seeds)
    monotone, rises, pairs = [], [], {}
    for a in range(4):
        for b in range(4):
            if a == b:
                continue
            g = generate(model, seeds, paths, one_hot_transition(a, b, steps, len(seeds)), offsets, parents, placement)
            axis = (centroids[b] - centroids[a]).double()
            stretches = g.positions.reshape(len(seeds), blocks, steps // blocks, *g.positions.shape[2:])
            summary = torch.stack([affect_summary(stretches[:, i], low, high, scale) for i in range(blocks)], 1)
            projection = ((summary.double() - centroids[a].double()) @ axis) / axis.dot(axis)  # (N, blocks)
            steps_up = projection[:, 1:] - projection[:, :-1]
            monotone.append((steps_up > 0).all(-1))
            rises.append(projection[:, -1] - projection[:, 0])
            pairs[f"{EMOTIONS[a]}->{EMOTIONS[b]}"] = {
                "monotone_fraction": round(float((steps_up > 0).all(-1).double().mean()), 4),
                "mean_projection_by_block": [round(float(v), 4) for v in projection.mean(0)]}
    mono, rise = torch.cat(monotone), torch.cat(rises)
    return {"monotone_fraction": round(float(mono.double().mean()), 4), "mean_rise": round(float(rise.mean()), 4),
            "rising_fraction": round(float((rise > 0).double().mean()), 4), "pairs": pairs}
