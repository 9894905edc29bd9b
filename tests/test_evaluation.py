"""Evaluation measures on real gaits: foot skating, emotion centroids, the Table-1 error definitions."""

from __future__ import annotations

import numpy as np
import torch

from pipeline.ops.contacts import ContactConfig
from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.evaluation.autoregressive import affect_summary, emotion_centroids, pose_errors
from pipeline.ops.footlock import skating_speed
from pipeline.generators.autoregressive.training import GaitTensors


def _walks(annotated):
    table, arrays = annotated
    content = np.array(table.column("content").to_pylist())
    return arrays, np.flatnonzero(content == "walk")[::5]


def test_real_walks_barely_skate_and_a_sliding_body_does(annotated):
    arrays, rows = _walks(annotated)
    positions = torch.from_numpy(arrays["positions"][rows])
    real, contact = skating_speed(positions, 30.0, ContactConfig())
    assert real < 0.2 and 0.4 < contact < 0.8
    drift = torch.zeros_like(positions)
    drift[..., 0] = 0.3 * torch.arange(positions.shape[1])[:, None] / 30.0  # the whole body slides at 0.3 m/s
    slid, _ = skating_speed(positions + drift, 30.0, ContactConfig())
    assert slid > real + 0.15


def test_emotion_centroids_separate_the_real_labelled_gaits(annotated):
    table, arrays = annotated
    labelled = np.flatnonzero(~np.isnan(arrays["emotion"]).any(-1))
    assert len(labelled) > 200
    positions = torch.from_numpy(arrays["positions"][labelled])
    low, high = torch.full((18,), -1e3), torch.full((18,), 1e3)
    summary = affect_summary(positions, low, high, torch.ones(18))
    dominant = [dominant_emotion(arrays["emotion"][i], EMOTIONS) for i in labelled]
    centroids = emotion_centroids(summary, dominant)
    assert centroids.shape == (4, 18) and bool(torch.isfinite(centroids).all())
    nearest = torch.cdist(summary.double(), centroids.double()).argmin(-1)
    intended = torch.tensor([EMOTIONS.index(d) for d in dominant])
    assert float((nearest == intended).double().mean()) > 0.5  # the real emotions differ in these features


def test_pose_error_is_relative_to_the_character_size(annotated, skeleton):
    _, arrays = annotated
    g = GaitTensors.from_arrays(arrays, np.arange(0, 200, 20))
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    q = g.q[:, 18:]
    same = pose_errors(q, q, offsets, skeleton.parents)
    assert float(same["position"].max()) == 0.0
    shifted = pose_errors(g.q[:, 17:-1], q, offsets, skeleton.parents)  # one frame late
    assert 0.0 < float(shifted["position"].mean()) < 0.05 and 0.5 < float(shifted["rotation"].mean()) < 10.0
