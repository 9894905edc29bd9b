"""The levers that make the generator follow its emotion condition (issue 11), on real labelled gaits: the style
critic reads real held-out windows, mismatched conditions, labelled batches, mirrored training gaits, and a
short training run under the style term that makes the condition readable in generated frames."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.ops.features import AFFECTIVE_NAMES, affective_features
from pipeline.generators.autoregressive.critic import (CriticConfig, fit_critic, random_crops, style_loss,
                                                     style_match_loss)
from pipeline.generators.autoregressive.fit import mirrored
from pipeline.generators.autoregressive.network import (
    EmotiveGaitNet,
    GeneratorConfig,
    LossWeights,
    generator_losses,
    travel_frame_positions,
)
from pipeline.generators.autoregressive.training import (
    BatchSampler,
    GaitTensors,
    TrainConfig,
    mismatched_conditions,
    rollout,
    style_targets,
    targets,
    train_generator,
)

TINY = GeneratorConfig(affect_layers=(8, 8, 4), movement_layers=(8, 8, 4), gru_hidden=32, versor_hidden=32,
                       root_hidden=8)


@pytest.fixture(scope="module")
def labelled(annotated):
    """Labelled real windows, alternately assigned to a fit and a held-out half by clip."""
    table, arrays = annotated
    rows = np.flatnonzero(~np.isnan(arrays["emotion"]).any(-1))
    clips = np.array(table.column("clip_id").to_pylist())[rows]
    order = {c: k for k, c in enumerate(sorted(set(clips)))}
    held = np.array([order[c] % 3 == 0 for c in clips])
    return arrays, rows[~held], rows[held]


@pytest.fixture(scope="module")
def offsets(skeleton):
    return torch.from_numpy(skeleton.offsets).to(torch.float32)


@pytest.fixture(scope="module")
def critic(labelled, offsets, skeleton):
    """The style critic fitted on the fit half's windows: (critic, figures, fit gaits)."""
    arrays, fit_rows, _ = labelled
    fit = GaitTensors.from_arrays(arrays, fit_rows)
    pose = travel_frame_positions(fit.q, offsets, skeleton.parents)
    return (*fit_critic(pose, fit.condition[:, :4], _bounds(fit), CriticConfig(epochs=200)), fit)


def _net(g: GaitTensors, seed: int = 0) -> EmotiveGaitNet:
    """A TINY network, seeded, with the statistics of ``g``."""
    torch.manual_seed(seed)
    model = EmotiveGaitNet(TINY)
    model.set_statistics(g.affective, g.scalars())
    return model


def _bounds(g: GaitTensors) -> tuple[torch.Tensor, ...]:
    model = _net(g)
    return model.affective_low, model.affective_high, model.affective_mean, model.affective_std


def _recalls(said: torch.Tensor, truth: torch.Tensor) -> list[float]:
    return [float((said[truth == k] == k).double().mean()) for k in range(len(EMOTIONS)) if (truth == k).any()]


def test_the_critic_reads_held_out_real_windows_well_above_chance(labelled, critic, offsets, skeleton):
    arrays, fit_rows, held_rows = labelled
    critic, figures, _ = critic
    held = GaitTensors.from_arrays(arrays, held_rows)
    assert figures["windows"] == len(fit_rows) and figures["crops"] == 4 * len(fit_rows)
    with torch.no_grad():
        said = critic(travel_frame_positions(held.q, offsets, skeleton.parents)[:, 18:]).argmax(-1)
    truth = held.condition[:, :4].argmax(-1)
    recalls = _recalls(said, truth)
    assert len(recalls) >= 3 and np.mean(recalls) > 0.45, recalls  # chance: 0.25
    assert not any(p.requires_grad for p in critic.parameters())  # frozen: the generator cannot move it


def _match_per_gait(critic, pose, target):
    """style_match_loss of each gait on its own (B,)."""
    return torch.stack([style_match_loss(critic, pose[i:i + 1], target[i:i + 1]) for i in range(len(pose))])


def test_the_critic_keeps_the_real_centroids_and_a_real_window_is_nearest_its_own(labelled, critic, offsets,
                                                                                 skeleton):
    arrays, _, held_rows = labelled
    critic, _, fit = critic
    pose = travel_frame_positions(fit.q, offsets, skeleton.parents)
    # the centroids are the class means of the standardised statistics of the very crops the critic was fitted on
    cfg = CriticConfig(epochs=200)
    crops = random_crops(pose, cfg.crop_frames, cfg.crops, torch.Generator().manual_seed(cfg.seed))
    label = fit.condition[:, :4].argmax(-1).repeat_interleave(cfg.crops)
    with torch.no_grad():
        x = critic.standardised(crops)
    for k in label.unique().tolist():
        assert torch.allclose(critic.centroids[k], x[label == k].mean(0), atol=1e-4)
    held = GaitTensors.from_arrays(arrays, held_rows)
    held_pose = travel_frame_positions(held.q, offsets, skeleton.parents)[:, 18:]
    truth = held.condition[:, :4].argmax(-1)
    with torch.no_grad():
        own = _match_per_gait(critic, held_pose, held.condition[:, :4])
        other = torch.stack([_match_per_gait(critic, held_pose, torch.nn.functional.one_hot(
            (truth + k) % 4, 4).float()) for k in (1, 2, 3)]).mean(0)
    assert float((own < other).double().mean()) > 0.6  # held-out real windows: nearer their own emotion's statistics
    assert float(style_match_loss(critic, pose[:4], fit.condition[:4, :4])) > 0


def test_style_matching_sees_a_posture_past_the_real_range_that_the_critic_cannot(labelled, critic, offsets,
                                                                                skeleton):
    """A head tilted towards the right shoulder past anything real gaits do: the critic reads the angle at the
    neck clamped to the real range (it cannot reward going further), and style matching reads it as it is, so it
    pulls such a posture back; clamped, it would see no difference between two such tilts."""
    arrays, _, held_rows = labelled
    critic, _, _ = critic
    held = GaitTensors.from_arrays(arrays, held_rows[:6])
    pose = travel_frame_positions(held.q, offsets, skeleton.parents)[:, 18:]
    names = list(AFFECTIVE_NAMES)
    r = names.index("angle_12_11_17")  # the angle at the neck between the head and the right shoulder

    def tilted(share: float) -> torch.Tensor:
        out = pose.clone()
        out[:, :, 12] = pose[:, :, 12] + share * (pose[:, :, 17] - pose[:, :, 12])
        return out

    some, more = tilted(0.4), tilted(0.6)
    assert float(affective_features(some)[..., r].max()) < float(critic.affective_low[r])  # past the real range
    for bounded, differs in ((True, False), (False, True)):
        a, b = critic.statistics(some, bounded)[:, r], critic.statistics(more, bounded)[:, r]
        assert (not torch.allclose(a, b)) is differs
    target = held.condition[:, :4]
    wanted = target @ critic.centroids
    for p in (pose, some, more):
        expected = torch.nn.functional.huber_loss(critic.standardised(p, bounded=False), wanted, reduction="none",
                                                  delta=1.0).mean()
        assert torch.allclose(style_match_loss(critic, p, target), expected)
    assert float(style_match_loss(critic, more, target)) > float(style_match_loss(critic, some, target)) \
        > float(style_match_loss(critic, pose, target))


def test_style_matching_to_own_frames_keeps_each_gaits_deviation_from_its_emotion(labelled, critic, offsets,
                                                                                  skeleton):
    """Two real windows of one emotion differ. Pulled to the emotion's centroid, both cost something and are pulled
    to one point; pulled to their own frames moved by the centroids' difference, each real window costs nothing
    under its own emotion, and under another emotion the two targets stay as far apart as the windows are."""
    arrays, _, held_rows = labelled
    critic, _, _ = critic
    held = GaitTensors.from_arrays(arrays, held_rows)
    truth = held.condition[:, :4].argmax(-1)
    k = int(torch.mode(truth).values)
    rows = torch.nonzero(truth == k).flatten()[:2]
    pose = travel_frame_positions(held.q[rows], offsets, skeleton.parents)[:, 18:]
    own = held.condition[rows, :4]
    with torch.no_grad():
        assert float(style_match_loss(critic, pose, own)) > 0.05  # the centroid: every real window pays
        assert float(style_match_loss(critic, pose, own, pose, own)) == 0.0
        other = torch.nn.functional.one_hot(torch.full((2,), (k + 1) % 4), 4).float()
        shift = (other - own) @ critic.centroids
        stats = critic.standardised(pose, bounded=False)
        # under the other emotion a gait is asked to move by the centroids' difference only ...
        assert float(style_match_loss(critic, pose, other, pose, own)) == pytest.approx(float(
            torch.nn.functional.huber_loss(stats, stats + shift, delta=1.0)))
        # ... and the two targets differ as the windows do: one window does not meet the other's
        assert float(style_match_loss(critic, pose[:1], other[:1], pose[1:], own[1:])) > 0.05


def test_mismatched_conditions_change_only_labelled_gaits_and_stay_on_the_simplex(labelled):
    arrays, fit_rows, _ = labelled
    g = GaitTensors.from_arrays(arrays, fit_rows[:40])
    unlabelled = torch.zeros(8, 5)
    condition = torch.cat([g.condition, unlabelled])
    out, mismatched = mismatched_conditions(condition, 1.0, torch.Generator().manual_seed(0))
    assert mismatched[:40].all() and not mismatched[40:].any()
    assert torch.equal(out[40:], unlabelled) and torch.equal(out[:, -1], condition[:, -1])
    assert torch.allclose(out[:40, :4].sum(-1), torch.ones(40)) and (out[:40, :4] >= 0).all()
    one_hot = (out[:40, :4] == 1.0).any(-1)
    assert 0 < int(one_hot.sum()) < 40  # one-hots of another emotion and random mixtures
    assert (out[:40][one_hot, :4].argmax(-1) != condition[:40][one_hot, :4].argmax(-1)).all()
    # probability 0: nothing changes and no random number is drawn (plain training's stream is kept)
    draws = torch.Generator().manual_seed(0)
    same, none = mismatched_conditions(condition, 0.0, draws)
    assert torch.equal(same, condition) and not none.any()
    assert torch.equal(draws.get_state(), torch.Generator().manual_seed(0).get_state())
    targets_ = style_targets(out)
    assert torch.isnan(targets_[40:]).all() and torch.allclose(targets_[:40], out[:40, :4])
    sharp = style_targets(out, 3.0)  # one-hots stay, a mixture's dominant emotion takes more of the target
    assert torch.equal(sharp[:40][one_hot], targets_[:40][one_hot])
    assert torch.allclose(sharp[:40].sum(-1), torch.ones(40))
    assert (sharp[:40][~one_hot].max(-1).values > targets_[:40][~one_hot].max(-1).values).all()
    assert torch.equal(sharp[:40].argmax(-1), targets_[:40].argmax(-1))


def test_batches_hold_the_labelled_share_and_visit_every_gait():
    labelled = torch.zeros(100, dtype=torch.bool)
    labelled[::10] = True  # 10 labelled of 100
    sampler = BatchSampler(labelled, 16, 0.5, torch.Generator().manual_seed(1))
    batches = [sampler.next() for _ in range(12)]
    assert all(len(b) == 16 and int(labelled[b].sum()) == 8 for b in batches)
    seen = torch.cat(batches).unique()
    assert set(torch.nonzero(labelled).flatten().tolist()) <= set(seen.tolist())
    plain = BatchSampler(labelled, 16, 0.0, torch.Generator().manual_seed(1))
    assert torch.equal(plain.next(), torch.randperm(100, generator=torch.Generator().manual_seed(1))[:16])


def test_mirrored_training_gaits_keep_their_labels_and_swap_sides(labelled, skeleton):
    arrays, fit_rows, _ = labelled
    rows = fit_rows[:6]
    images = mirrored(arrays, rows, skeleton)
    assert np.array_equal(images["emotion"], arrays["emotion"][rows])
    assert np.allclose(images["positions"][..., 0], -arrays["positions"][rows][..., [skeleton.names.index(
        n.replace("left", "#").replace("right", "left").replace("#", "right")) for n in skeleton.names], 0])
    back = mirrored({**arrays, **{k: np.concatenate([v, arrays[k][len(rows):]]) for k, v in images.items()}},
                    np.arange(len(rows)), skeleton)
    assert np.allclose(back["positions"], arrays["positions"][rows], atol=1e-5)


def test_the_style_term_trains_the_generator_and_reaches_it_through_the_rollout(critic, offsets, skeleton):
    critic, _, g = critic
    model = _net(g, 0)
    batch = g.select(slice(0, 8))
    condition, _ = mismatched_conditions(batch.condition, 1.0, torch.Generator().manual_seed(2))
    pred = rollout(model, batch, offsets, skeleton.parents, 18, condition=condition)
    losses = generator_losses(pred, targets(batch, 18), model, offsets, skeleton.parents,
                              LossWeights(style=1.0, style_match=1.0), torch.full((8,), 0.25), critic,
                              style_targets(condition))
    assert losses.style is not None and float(losses.style.detach()) > 0
    assert losses.style_match is not None and float(losses.style_match.detach()) > 0
    for term in (losses.style, losses.style_match):
        model.zero_grad()
        term.backward(retain_graph=True)
        grads = {n: p.grad for n, p in model.named_parameters() if p.grad is not None and float(p.grad.abs().sum()) > 0}
        assert any(n.startswith("gru") for n in grads) and any(n.startswith("enc_affect") for n in grads)
    # a mismatched pair's content terms count with its weight: all at 0.25 is the same mean as all at 1
    same = generator_losses(pred, targets(batch, 18), model, offsets, skeleton.parents, LossWeights(),
                            torch.ones(8))
    assert float(same.pose) == pytest.approx(float(losses.pose), rel=1e-5)
    assert float(style_loss(torch.zeros(1, 4), torch.tensor([[1.0, 0, 0, 0]]))) == pytest.approx(np.log(4))


def test_steps_on_the_style_term_move_the_critic_reading_towards_the_condition(critic, offsets, skeleton):
    """A few optimiser steps on the style term alone, on mismatched pairs (prefix of one emotion, condition of
    another): the critic's probability of the condition in the free-running frames rises. The term points the
    network at the condition through the whole autoregressive rollout."""
    critic, _, g = critic
    model = _net(g, 0)
    batch = g.select(slice(0, 16))
    condition, mismatched = mismatched_conditions(batch.condition, 1.0, torch.Generator().manual_seed(3))
    assert mismatched.all()
    wanted = style_targets(condition)

    def reading() -> tuple[torch.Tensor, torch.Tensor]:
        pred = rollout(model, batch, offsets, skeleton.parents, 18, condition=condition)
        logits = critic(travel_frame_positions(pred["q"], offsets, skeleton.parents))
        return (torch.softmax(logits, -1) * wanted).sum(-1).mean(), style_loss(logits, wanted)

    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    before = float(reading()[0])
    for _ in range(8):
        optimiser.zero_grad()
        reading()[1].backward()
        optimiser.step()
    after = float(reading()[0])
    assert after > before + 0.05, (before, after)


def test_training_with_every_lever_is_reproducible_and_keeps_its_critic(annotated, offsets, skeleton):
    _, arrays = annotated
    rows = np.concatenate([np.flatnonzero(~np.isnan(arrays["emotion"]).any(-1))[::6],
                           np.flatnonzero(np.isnan(arrays["emotion"]).any(-1))[::40]])
    g = GaitTensors.from_arrays(arrays, rows)
    cfg = TrainConfig(epochs=2, batch_size=16, batches_per_epoch=1, validate_every=2, seed=3, threads=1,
                      device="cpu", labelled_share=0.5, mismatch=0.5)
    runs = [train_generator(g, g.select(slice(0, 8)), offsets, skeleton.parents, TINY, cfg, LossWeights(style=2.0),
                            critic_cfg=CriticConfig(epochs=50)) for _ in range(2)]
    assert runs[0].history == runs[1].history and "train_style" in runs[0].history[-1]
    assert "val_style" in runs[0].history[-1]
    assert all(torch.equal(a, b) for a, b in zip(runs[0].model.state_dict().values(),
                                                 runs[1].model.state_dict().values()))
    assert runs[0].critic_figures == runs[1].critic_figures and runs[0].critic_figures["windows"] > 0


def test_guidance_one_is_plain_generation_and_more_guidance_moves_along_the_condition(labelled, offsets, skeleton):
    from pipeline.evaluation.autoregressive import straight_path
    from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths

    arrays, fit_rows, _ = labelled
    g = GaitTensors.from_arrays(arrays, fit_rows)
    model = _net(g, 1)
    seeds = Seeds.from_arrays(arrays, fit_rows[:4], prefix=18)
    paths = place_paths(straight_path(), seeds)
    happy, sad = torch.zeros(4, 12, 4), torch.zeros(4, 12, 4)
    happy[..., 0], sad[..., 1] = 1.0, 1.0

    def run(emotions: torch.Tensor, w: float) -> torch.Tensor:
        return generate(model, seeds, paths, emotions, offsets, skeleton.parents, PlacementConfig(guidance=w)).versors

    assert torch.equal(run(happy, 1.0), generate(model, seeds, paths, happy, offsets, skeleton.parents).versors)
    # guidance amplifies what the condition changes: the two emotions end up further apart
    gap = {w: float((run(happy, w) - run(sad, w)).norm()) for w in (1.0, 2.0)}
    assert gap[2.0] > 1.2 * gap[1.0], gap


def test_sharpened_emotions_keep_vertices_and_grow_the_dominant_component():
    from pipeline.generators.autoregressive.network import sharpened

    m = torch.tensor([[0.4, 0.3, 0.2, 0.1], [0.0, 1.0, 0.0, 0.0], [float("nan")] * 4])
    assert sharpened(m, 1.0) is m
    out = sharpened(m, 4.0)
    assert torch.allclose(out[:2].sum(-1), torch.ones(2))
    assert torch.equal(out[1], m[1]) and torch.isnan(out[2]).all()
    assert out[0].argmax() == 0 and out[0, 0] > 0.7 and (torch.diff(out[0]) < 0).all()  # the order is kept


def test_expression_sharpness_leaves_one_hot_conditions_and_moves_mixtures_to_their_dominant(labelled, offsets,
                                                                                            skeleton):
    from pipeline.evaluation.autoregressive import straight_path
    from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths

    arrays, fit_rows, _ = labelled
    model = _net(GaitTensors.from_arrays(arrays, fit_rows), 1)
    seeds = Seeds.from_arrays(arrays, fit_rows[:4], prefix=18)
    paths = place_paths(straight_path(), seeds)
    happy, mixture = torch.zeros(4, 12, 4), torch.tensor([0.45, 0.25, 0.2, 0.1]).expand(4, 12, 4)
    happy[..., 0] = 1.0

    def run(emotions: torch.Tensor, p: float):
        return generate(model, seeds, paths, emotions, offsets, skeleton.parents,
                        PlacementConfig(guidance=2.0, expression_sharpness=p))

    assert torch.equal(run(happy, 6.0).versors, run(happy, 1.0).versors)  # a vertex is its own sharpening
    sharp, plain = run(mixture, 6.0), run(mixture, 1.0)
    assert torch.allclose(sharp.condition[..., :4].sum(-1), torch.ones(4, 12))
    assert float(sharp.condition[0, 0, 0]) > 0.9 > float(plain.condition[0, 0, 0])  # the condition the net was fed
    to_happy = {p: float((g.versors - run(happy, 1.0).versors).norm()) for p, g in (("sharp", sharp), ("plain", plain))}
    assert to_happy["sharp"] < 0.5 * to_happy["plain"], to_happy
