"""The PCA + Gaussian family's cycles, basis and style models (seed 001), on the real default data."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pipeline.annotate.annotation import annotate_clip, rebuild_clips
from pipeline.generators.pca_gaussian.cycles import CycleConfig, cut_cycles
from pipeline.generators.pca_gaussian.model import (
    ModelConfig,
    balanced_rows,
    blend,
    fit_basis,
    fit_style_models,
    reconstruction_errors,
    sample_cycles,
)
from pipeline.ops.geometry import heading_angle
from pipeline.ops.quaternion import qexp, qlog, qnormalize
from stages.common import load_params
from stages.configs import annotate_config


@pytest.fixture(scope="module")
def cycles(annotated_split, skeleton):
    table, arrays, _, _ = annotated_split
    return cut_cycles(table, arrays, skeleton, CycleConfig(), annotate_config(load_params()))


@pytest.fixture(scope="module")
def fitted(cycles):
    cfg = ModelConfig()
    rows = balanced_rows(cycles.style, cfg.per_style, cfg.seed)
    basis = fit_basis(cycles.flat(), rows)
    k = basis.components_for(cfg.variance)
    scores = basis.scores(cycles.flat(), k)
    models = fit_style_models(scores, cycles.durations, cycles.dominant(), cycles.follows, cfg.prior_cycles)
    return basis, k, models


def test_rotation_vectors_round_trip_every_unit_quaternion():
    q = qnormalize(torch.randn(2000, 4, dtype=torch.float64))
    q[:4] = torch.tensor([[1.0, 0, 0, 0], [-1.0, 0, 0, 0], [0, 1.0, 0, 0], [-0.5, 0.5, 0.5, 0.5]])
    assert torch.allclose(qexp(qlog(q)), q, atol=1e-12)
    r = torch.randn(500, 3, dtype=torch.float64)
    assert torch.allclose(qlog(qexp(r / r.norm(dim=-1, keepdim=True) * 3.0)), r / r.norm(dim=-1, keepdim=True) * 3.0,
                          atol=1e-12)


def test_cycles_are_forward_walk_cycles_from_right_strike_to_right_strike(cycles, annotated_split, skeleton):
    table, arrays, _, _ = annotated_split
    assert len(cycles) > 500 and cycles.rotvec.shape[1:] == (40, 21, 3)
    counts = cycles.counts()
    assert all(counts["per_emotion"][e] >= 3 for e in ("happy", "sad", "angry", "neutral")), counts
    content = dict(zip(table.column("clip_id").to_pylist(), table.column("content").to_pylist()))
    assert {content[c] for c in cycles.clip_id} == {"walk"}  # no sideways, backwards or turning walks
    assert (cycles.strides[:, 1] > 0).all() and (np.abs(np.degrees(np.arctan2(np.abs(cycles.strides[:, 0]),
                                                                              cycles.strides[:, 1]))) <= 25).all()
    assert 18 <= cycles.durations.min() and cycles.durations.max() <= 60
    # every cycle starts at a right-foot strike of its clip, by the annotation's own rule
    clip = cycles.clip_id[0]
    rows = [i for i, c in enumerate(table.column("clip_id").to_pylist()) if c == clip]
    starts = np.round(table.column("t_start").to_numpy()[rows] * 30.0).astype(int)
    positions = rebuild_clips([clip] * len(rows), starts, arrays["positions"][rows], 60)[clip][0]
    strikes = annotate_clip(torch.from_numpy(positions), skeleton, annotate_config(load_params()))["events"]
    mine = [s for c, s in zip(cycles.clip_id, cycles.start_frame) if c == clip]
    assert mine and set(mine) <= set(strikes["right_strike"])
    # turned to a common heading: every cycle faces +Z at its start
    root = qexp(torch.from_numpy(cycles.rotvec[:, 0, 0]))
    assert float(heading_angle(root).abs().max()) < 1e-6


def test_pca_with_every_component_reconstructs_the_basis_cycles_exactly(cycles, fitted):
    basis, k, _ = fitted
    x = cycles.flat()[basis.basis_rows]
    assert np.allclose(basis.reconstruct(basis.scores(x)), x, atol=1e-9)
    assert np.allclose(basis.components @ basis.components.T, np.eye(len(basis.components)), atol=1e-9)
    assert abs(basis.explained.sum() - 1.0) < 1e-9 and np.all(np.diff(basis.explained) <= 1e-12)
    # the kept components: fewer than all, reaching the configured variance, and they lose little
    assert 5 <= k < len(basis.explained) and np.cumsum(basis.explained)[k - 1] >= 0.90 > np.cumsum(basis.explained)[k - 2]


def test_basis_balances_styles_and_reconstruction_improves_with_components(cycles, fitted, skeleton):
    basis, k, _ = fitted
    per_style = {s: sum(cycles.style[i] == s for i in basis.basis_rows) for s in set(cycles.style)}
    assert max(per_style.values()) == 15 and all(v == min(15, cycles.style.count(s)) for s, v in per_style.items())
    few = reconstruction_errors(cycles.flat(), basis, 3, skeleton.offsets, skeleton.parents, 40)
    kept = reconstruction_errors(cycles.flat(), basis, k, skeleton.offsets, skeleton.parents, 40)
    assert kept["joint_position_error_m"] < few["joint_position_error_m"] and kept["joint_position_error_m"] < 0.05
    assert kept["rotation_error_deg"] < few["rotation_error_deg"]


def test_the_blend_at_a_vertex_is_that_emotions_model_and_a_mixture_lies_between(fitted):
    _, _, models = fitted
    for k, model in enumerate(models):
        vertex = blend(models, np.eye(4)[k])
        for name in ("mean", "std", "max_change"):
            assert np.allclose(getattr(vertex, name), getattr(model, name), atol=1e-12)
        assert vertex.duration_mean == pytest.approx(model.duration_mean)
        assert vertex.duration_std == pytest.approx(model.duration_std)
    half = blend(models, np.array([0.5, 0.5, 0.0, 0.0]))
    assert np.allclose(half.mean, 0.5 * (models[0].mean + models[1].mean))
    assert half.duration_mean == pytest.approx(0.5 * (models[0].duration_mean + models[1].duration_mean))
    with pytest.raises(ValueError):
        blend(models, np.array([0.7, 0.7, 0.0, 0.0]))


def test_emotion_models_differ_where_real_emotions_do(fitted):
    _, _, models = fitted
    happy, sad = models[0], models[1]
    assert sad.duration_mean > happy.duration_mean + 5  # sad walks take longer cycles (real labelled walks)
    separation = np.abs(happy.mean - sad.mean) / np.sqrt(0.5 * (happy.std ** 2 + sad.std ** 2))
    assert separation.max() > 3.0


def test_seeded_sampling_is_deterministic_and_keeps_adjacent_cycles_within_the_recorded_change(fitted):
    _, _, models = fitted
    chain = [models[0]] * 4 + [blend(models, np.array([0.5, 0.0, 0.5, 0.0]))] * 4 + [models[2]] * 4
    a = sample_cycles(chain, np.random.default_rng(3), redraws=5)
    b = sample_cycles(chain, np.random.default_rng(3), redraws=5)
    c = sample_cycles(chain, np.random.default_rng(4), redraws=5)
    assert all(np.array_equal(x, y) for x, y in zip(a[:2], b[:2])) and a[2] == b[2]
    assert not np.array_equal(a[0], c[0])
    scores, durations, counts = a
    for t in range(1, len(chain)):
        assert (np.abs(scores[t] - scores[t - 1]) <= chain[t].max_change + 1e-12).all()
        assert abs(durations[t] - durations[t - 1]) <= chain[t].duration_max_change + 1e-12
    assert set(counts) == {"redrawn", "clamped"}
    # a chain of one model draws around that model's mean
    many, _, _ = sample_cycles([models[3]] * 400, np.random.default_rng(0), redraws=5)
    assert np.all(np.abs(many.mean(0) - models[3].mean) < 0.5 * models[3].std + 1e-9)
    assert math.isfinite(float(many.sum()))
