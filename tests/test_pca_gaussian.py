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
    scores, durations, counts, last = a
    for t in range(1, len(chain)):  # each cycle's deviation from its model's mean moves within the limit
        step = (scores[t] - chain[t].mean) - (scores[t - 1] - chain[t - 1].mean)
        assert (np.abs(step) <= chain[t].max_change + 1e-9).all()
        step = (durations[t] - chain[t].duration_mean) - (durations[t - 1] - chain[t - 1].duration_mean)
        assert abs(step) <= chain[t].duration_max_change + 1e-9
        if chain[t] is chain[t - 1]:  # one style: the paper's rule on the scores themselves
            assert (np.abs(scores[t] - scores[t - 1]) <= chain[t].max_change + 1e-9).all()
    assert set(counts) == {"redrawn", "clamped"} and sum(counts.values()) > 0  # few cycles: the limit bites
    assert np.allclose(last[0], scores[-1] - chain[-1].mean)
    # a chain continued from the deviations of the cycle before keeps the limit across the join
    first = sample_cycles(chain[:6], np.random.default_rng(3), redraws=5)
    rest = sample_cycles(chain[6:], np.random.default_rng(5), redraws=5, previous=first[3])
    assert (np.abs((rest[0][0] - chain[6].mean) - first[3][0]) <= chain[6].max_change + 1e-9).all()
    # a chain of one model draws around that model's mean
    many = sample_cycles([models[3]] * 400, np.random.default_rng(0), redraws=5)[0]
    assert np.all(np.abs(many.mean(0) - models[3].mean) < 0.5 * models[3].std + 1e-9)
    assert math.isfinite(float(many.sum()))


# ------------------------------------------------------------------------------------------------- synthesis

@pytest.fixture(scope="module")
def family(annotated_split, skeleton):
    from pipeline.generators.pca_gaussian.family import PCAGaussianFamily, fit, model_bytes
    from pipeline.io.files import sha256_bytes
    from stages.configs import placement_config

    table, arrays, _, _ = annotated_split
    params = load_params()
    f = fit(table, arrays, skeleton, annotate=annotate_config(params))
    placement = placement_config(params)
    return PCAGaussianFamily(f.model, sha256_bytes(model_bytes(f, CycleConfig(), ModelConfig())), skeleton,
                             placement), f


def _rows(n: int, seed: int = 0) -> list[dict]:
    return [{"plan_seed": seed + i, "gait_id": f"pca-{i}"} for i in range(n)]


def test_fit_reports_what_it_was_fitted_on(family):
    fam, f = family
    assert f.components == f.basis.components_for(0.90) and f.model.components.shape[0] == f.components
    assert 0.0 < f.model.foot_floor_m < 0.05  # the heel/toe joints' height over the floor in stance: cm
    assert [m.cycles for m in f.model.models] == [int((f.cycles.dominant() == k).sum()) for k in range(4)]


def test_walks_are_seeded_shaped_and_follow_their_path(family):
    from pipeline.evaluation.autoregressive import straight_path, turn_path
    from pipeline.ops.geometry import distance_to_polyline

    fam, _ = family
    emotions = torch.tensor([1.0, 0.0, 0.0, 0.0]).expand(4, 60, 4)
    for path in (straight_path(), turn_path()):
        paths = path[None].expand(4, *path.shape).float()
        a = fam.generate(_rows(4), paths, emotions)
        b = fam.generate(_rows(4), paths, emotions)
        assert torch.equal(a.positions, b.positions) and torch.equal(a.rotations, b.rotations)
        assert a.positions.shape == (4, 60, 21, 3) and a.context_positions.shape == (4, 18, 21, 3)
        assert float(a.conditioned_phase.min()) >= 0 and float(a.conditioned_phase.max()) < 2 * math.pi
        root = a.positions[..., 0, [0, 2]]
        walked = torch.linalg.vector_norm(root[:, -1] - root[:, 0], dim=-1)
        assert float(walked.min()) > 1.0  # two seconds of walking
        off = torch.stack([distance_to_polyline(root[i], paths[i]) for i in range(4)])
        assert float(off.max()) < 0.35, float(off.max())
        assert torch.linalg.vector_norm(a.context_positions[:, 0, 0, [0, 2]], dim=-1).max() < 0.1  # starts at the start
    c = fam.generate(_rows(4, seed=100), paths, emotions)
    assert not torch.equal(c.positions, a.positions)


def test_cycles_join_without_jumps_and_feet_stay_planted(family, annotated_split):
    from pipeline.evaluation.autoregressive import straight_path
    from pipeline.ops.footlock import skating_speed
    from pipeline.ops.quaternion import qangle
    from stages.configs import contact_config

    fam, _ = family
    emotions = torch.eye(4).repeat_interleave(4, 0)[:, None].expand(16, 60, 4)
    out = fam.generate(_rows(16), straight_path()[None].expand(16, -1, -1).float(), emotions)
    _, arrays, split, _ = annotated_split
    content = np.array(annotated_split[0].column("content").to_pylist())
    walks = (split == "train") & (content == "walk")
    real = torch.from_numpy(arrays["positions"][walks][:200])

    def fastest(rotations: torch.Tensor) -> float:  # p99 over frames of the fastest joint's turn, deg per frame
        change = torch.rad2deg(qangle(rotations[:, 1:, 1:], rotations[:, :-1, 1:])).amax(-1)
        return float(torch.quantile(change.flatten().double(), 0.99))
    # cycle boundaries are cross-faded: no frame turns a joint much faster than real walks do
    assert fastest(out.rotations) < 1.5 * fastest(torch.from_numpy(arrays["rotations"][walks][:200]))
    synthetic, _ = skating_speed(out.positions, 30.0, contact_config(load_params()))
    reference, _ = skating_speed(real, 30.0, contact_config(load_params()))
    assert synthetic <= 1.2 * reference


def test_a_transition_changes_the_walk_cycle_by_cycle(family):
    from pipeline.evaluation.autoregressive import straight_path

    fam, _ = family
    blend = torch.linspace(0, 1, 60)[:, None]
    happy_to_sad = (1 - blend) * torch.tensor([1.0, 0, 0, 0]) + blend * torch.tensor([0, 1.0, 0, 0])
    out = fam.generate(_rows(8), straight_path()[None].expand(8, -1, -1).float(), happy_to_sad.expand(8, 60, 4))
    rate = torch.diff(torch.from_numpy(np.unwrap(out.conditioned_phase.numpy(), axis=1)), dim=1)
    # sad cycles last longer (the models' durations): the stepping phase slows from the first to the last frames
    assert float(rate[:, -15:].mean()) < 0.85 * float(rate[:, :15].mean())


def test_the_model_file_is_deterministic_and_walks_as_the_fit_does(family, tmp_path, skeleton):
    from pipeline.evaluation.autoregressive import straight_path
    from pipeline.generators.pca_gaussian.family import PCAGaussianFamily, load_model, model_bytes
    from pipeline.io.files import write_bytes

    fam, f = family
    data = model_bytes(f, CycleConfig(), ModelConfig())
    assert data == model_bytes(f, CycleConfig(), ModelConfig())
    sha = write_bytes(data, tmp_path / "model.pt")
    model, extra, digest = load_model(tmp_path / "model.pt")
    assert digest == sha and extra["format"] == "emogait-pca-gaussian/1"
    assert len(extra["cycle_ids"]) == len(f.cycles) and extra["model_cycles"] == [m.cycles for m in f.model.models]
    loaded = PCAGaussianFamily(model, digest, skeleton, fam.placement)
    paths = straight_path()[None].expand(4, -1, -1).float()
    emotions = torch.eye(4)[:, None].expand(4, 60, 4)
    assert torch.equal(loaded.generate(_rows(4), paths, emotions).positions,
                       fam.generate(_rows(4), paths, emotions).positions)
    (tmp_path / "other.pt").write_bytes(b"not a model")
    with pytest.raises(Exception):
        load_model(tmp_path / "other.pt")


def test_leave_one_clip_out_reading_needs_two_clips_per_emotion():
    from pipeline.generators.pca_gaussian.model import leave_one_clip_out_reading

    rng = np.random.default_rng(0)
    centres = np.eye(4) * 10.0
    dominant = np.repeat(np.arange(4), 6)  # two clips of three cycles per emotion
    clips = np.array([f"e{e}c{c}" for e in range(4) for c in range(2) for _ in range(3)])
    scores = centres[dominant] + rng.normal(0, 0.5, (24, 4))
    read = leave_one_clip_out_reading(scores, dominant, clips)
    assert read["balanced_accuracy"] == 1.0 and read["cycles"] == 24 and read["clips"] == 8
    # one clip of emotion 0: left out, no centroid of its own emotion is left, so it is never read right
    single = np.where(np.char.startswith(clips, "e0"), "e0c0", clips)
    read = leave_one_clip_out_reading(scores, dominant, single)
    assert read["confusion"][0][0] == 0 and read["balanced_accuracy"] == 0.75
    assert read["clips_per_emotion"]["happy"] == 1


def test_cycle_novelty_counts_a_reproduced_cycle():
    from pipeline.generators.pca_gaussian.model import StyleModel, cycle_novelty

    scores = np.random.default_rng(1).normal(size=(10, 3))
    clips = np.array([f"c{i // 2}" for i in range(10)])

    def model(mean, std):
        return StyleModel(mean=mean, std=np.full(3, std), max_change=np.ones(3), duration_mean=30.0,
                          duration_std=1.0, duration_max_change=2.0)
    copying = cycle_novelty([model(scores[3], 0.0)], scores, clips, per_emotion=5, seed=0, values_per_cycle=3)
    assert copying["reproduced"] == 5 and copying["drawn_to_nearest_real_deg"]["median"] == 0.0
    drawing = cycle_novelty([model(scores[3], 1.0)], scores, clips, per_emotion=5, seed=0, values_per_cycle=3)
    assert drawing["reproduced"] == 0 and drawing["drawn_to_nearest_real_deg"]["min"] > 0


def test_plan_rows_become_published_rows_of_the_family(family, annotated_split, tmp_path):
    """Plan rows through the family-agnostic synthesis (annotation, path deviation) into the published schema:
    the family's ids, its generator name and model sha256, no seed, and its placed paths followed."""
    from pipeline.publish.table import generator_entry, synthetic_table
    from pipeline.synth.plan import recipe_json
    from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, synthesize

    fam, _ = family
    table, arrays, _, _ = annotated_split
    params = load_params()
    cfg = SynthesisConfig.from_dict({**params["synthesize"], "batch": 4}, frames=60)
    work = SynthesisPlan.prepare(table, arrays, cfg)
    rows = work.plan[::1000][:5]
    out = synthesize(fam, rows, work.emotions, {t.id: t for t in work.trajectories}, fam.skeleton,
                     annotate_config(params), cfg)
    assert out["positions"].shape == (5, 60, 21, 3) and not out["phase_from_condition"].any()
    assert np.isfinite(out["path_deviation_m"]).all() and out["path_deviation_m"].max() < 0.35
    entry = generator_entry(fam.name, fam.description, fam.model_sha256, fam.seeded)
    published = synthetic_table(rows, [recipe_json(r["recipe"], work.emotions) for r in rows], out, entry, table,
                                named_family="autoregressive_affect")
    assert published.column("gait_id").to_pylist() == [r["gait_id"].replace("syn-", "syn-pca_gaussian-", 1)
                                                         for r in rows]
    assert set(published.column("generator").to_pylist()) == {"pca_gaussian"}
    assert set(published.column("checkpoint_sha256").to_pylist()) == {fam.model_sha256}
    assert published.column("seed_gait_id").null_count == 5
    # the model file's lineage: the cycles each emotion model was fitted on
    from pipeline.generators.pca_gaussian.family import PCAGaussianFamily, model_bytes

    (tmp_path / "model.pt").write_bytes(model_bytes(family[1], CycleConfig(), ModelConfig()))
    loaded = PCAGaussianFamily.from_file(tmp_path / "model.pt", fam.skeleton, fam.placement)
    cycles = loaded.lineage()["cycles_per_emotion_model"]
    assert [len(cycles[e]) for e in ("happy", "sad", "angry", "neutral")] == [m.cycles for m in fam.model.models]
    assert loaded.model_sha256 == fam.model_sha256


def test_the_emotion_condition_moves_the_family_s_gaits(family, annotated_split):
    """Condition sensitivity as evaluate_families measures it for every family: the same plan rows under the four
    one-hot emotions, affect summaries vs the real emotion centroids."""
    from pipeline.evaluation.families import AffectReference, family_sensitivity, sensitivity_rows, under_one_hot
    from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan

    fam, _ = family
    table, arrays, _, _ = annotated_split
    cfg = SynthesisConfig.from_dict(load_params()["synthesize"], frames=60)
    work = SynthesisPlan.prepare(table, arrays, cfg)
    split = np.array(table.column("split").to_pylist())
    train = np.flatnonzero((split == "train") & ~np.isnan(arrays["emotion"]).any(-1))
    reference = AffectReference(arrays["positions"][train], arrays["emotion"][train])
    rows = sensitivity_rows(work.plan, 6)
    assert len(rows) == 6 and all(r["recipe"]["kind"] == "single" for r in rows)
    generated = under_one_hot(fam, rows, work.emotions, {t.id: t for t in work.trajectories}, cfg)
    assert not torch.equal(generated[0].positions, generated[1].positions)
    figures = family_sensitivity(generated, reference)
    assert figures["seeds"] == 6 and 0.2 < figures["fraction_of_real"] < 5.0, figures


def test_the_emotion_feature_rule_keeps_more_components_where_the_basis_loses_emotion(family, skeleton):
    """The basis at 90 % variance loses what tells the emotions apart (their mean affective features move by
    SDs); every component gives them back (exactly for the emotions whose few cycles all formed the balanced
    basis, nearly for neutral's 102); the rule stops at the first number within the bound it is given."""
    from pipeline.generators.pca_gaussian.model import components_for_emotions, emotion_feature_errors

    _, f = family
    x, dominant, frames = f.cycles.flat(), f.cycles.dominant(), f.model.frames
    args = (skeleton.offsets, skeleton.parents, frames)
    everything = emotion_feature_errors(x, dominant, f.basis, len(f.basis.explained), *args)
    assert everything[:3].max() < 1e-6 and everything[3] < 0.05
    at_start = np.nanmax(emotion_feature_errors(x, dominant, f.basis, f.components, *args))
    assert at_start > 1.0  # measured on the default data: sad's features 3.3 SDs off at 12 components
    loose, tried = components_for_emotions(x, dominant, f.basis, at_start + 1.0, f.components, *args)
    assert loose == f.components and list(tried) == [f.components]
    k, tried = components_for_emotions(x, dominant, f.basis, 0.5, f.components, *args)
    assert f.components < k <= len(f.basis.explained) and max(tried[k]) <= 0.5


def test_forward_steps_only_keeps_the_root_from_stepping_back_on_the_plan(family, annotated_split):
    """The placement's ``forward_steps_only`` (a ``generate`` param, shared with the autoregressive family): without
    it a stance point that slips forward carries the root back and its path curls (about 1 gait in 30 of the plan's
    rows); with it the root keeps going and walks as far."""
    from dataclasses import replace

    from pipeline.publish.limitations import root_path_figures
    from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, synthesize

    fam, _ = family
    assert fam.placement.forward_steps_only  # the default params
    free = replace(fam, placement=replace(fam.placement, forward_steps_only=False), counts={})
    table, arrays, _, _ = annotated_split
    params = load_params()
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=60)
    work = SynthesisPlan.prepare(table, arrays, cfg)
    rows = work.plan[::10]
    figures, walked = {}, {}
    for name, f in (("forward", fam), ("free", free)):
        root_path = synthesize(f, rows, work.emotions, {t.id: t for t in work.trajectories}, fam.skeleton,
                               annotate_config(params), cfg)["root_path"].astype(np.float64)
        figures[name] = root_path_figures(root_path, 15)
        walked[name] = float(np.linalg.norm(np.diff(root_path, axis=1), axis=-1).sum())
    assert figures["free"]["loops"] > 0.02 and figures["free"]["frames_against_travel"] > 0.002, figures
    assert figures["forward"]["loops"] <= 0.25 * figures["free"]["loops"], figures
    assert figures["forward"]["reversals"] <= 0.25 * figures["free"]["reversals"], figures
    # fewer steps against the travel are left (the sway at a turn can still point one back)
    assert figures["forward"]["frames_against_travel"] < figures["free"]["frames_against_travel"], figures
    assert walked["forward"] > 0.98 * walked["free"]
