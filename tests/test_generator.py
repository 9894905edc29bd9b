"""The generator on real gaits: every loss term trains the network, training is reproducible, generation is
batched and deterministic, the baselines and the root placement do what they say."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from pipeline.evaluation.autoregressive import constant_velocity, pose_errors, straight_path, turn_path, zero_velocity
from pipeline.io.files import write_bytes
from pipeline.generators.autoregressive.rollout import (PlacementConfig, Seeds, generate, place_paths, placed_step,
                                                      smoothed_root, stance_step, swinging_points)
from pipeline.generators.autoregressive.fit import variant_configs
from pipeline.generators.autoregressive.network import (FOOT_JOINTS, EmotiveGaitNet, GeneratorConfig, LossWeights,
                                                       fixed_bones, generator_losses)
from pipeline.ops.geometry import distance_to_polyline, odd_frames, unit_direction
from pipeline.ops.quaternion import euler_to_quat, qangle, qnormalize, quat_to_euler
from pipeline.generators.autoregressive.training import (
    GaitTensors,
    TrainConfig,
    checkpoint_bytes,
    load_checkpoint,
    rollout,
    targets,
    train_generator,
)

TINY = GeneratorConfig(affect_layers=(8, 8, 4), movement_layers=(8, 8, 4), gru_hidden=16, versor_hidden=16,
                       root_hidden=8)
TERMS = ("motion", "pose", "affective", "root", "foot")


@pytest.fixture(scope="module")
def gaits(annotated):
    _, arrays = annotated
    rows = np.arange(0, len(arrays["positions"]), 37)[:48]  # ~48 real windows from all sources
    return arrays, rows, GaitTensors.from_arrays(arrays, rows)


@pytest.fixture(scope="module")
def offsets(skeleton):
    return torch.from_numpy(skeleton.offsets).to(torch.float32)


def _model(g: GaitTensors, cfg: GeneratorConfig = TINY, seed: int = 0) -> EmotiveGaitNet:
    torch.manual_seed(seed)
    model = EmotiveGaitNet(cfg)
    model.set_statistics(g.affective, g.scalars())
    return model


@pytest.mark.parametrize("term", TERMS)
def test_every_loss_term_has_gradient_reaching_the_parameters(gaits, offsets, skeleton, term):
    _, _, g = gaits
    model = _model(g)
    pred = rollout(model, g.select(slice(0, 8)), offsets, skeleton.parents, prefix=18, teacher_forcing=0.0)
    losses = generator_losses(pred, targets(g.select(slice(0, 8)), 18), model, offsets, skeleton.parents)
    getattr(losses, term).backward()
    grads = {name: p.grad for name, p in model.named_parameters()}
    reached = [name for name, grad in grads.items() if grad is not None and float(grad.abs().sum()) > 0]
    if term == "root":
        assert any(n.startswith(("fc_root", "fc_h", "fc_s", "fc_delta")) for n in reached), reached
    else:  # the pose-based terms train the recurrent pose model, through FK and the features
        assert any(n.startswith("gru") for n in reached) and any(n.startswith("fc_versors") for n in reached), reached
    # ... and, fed back through the autoregression, the encoders as well
    assert any(n.startswith(("enc_affect", "enc_movement")) for n in reached), reached


def test_the_affective_term_depends_on_the_predictions_not_only_on_the_truth(gaits, offsets, skeleton):
    """The paper's released code computed it on detached numpy arrays; here moving a prediction moves it."""
    _, _, g = gaits
    model = _model(g)
    batch = g.select(slice(0, 4))
    pred = rollout(model, batch, offsets, skeleton.parents, prefix=18)
    base = generator_losses(pred, targets(batch, 18), model, offsets, skeleton.parents).affective
    bent = dict(pred)
    bent["q"] = qnormalize(pred["q"] + 0.2 * torch.randn_like(pred["q"], generator=None))
    moved = generator_losses(bent, targets(batch, 18), model, offsets, skeleton.parents).affective
    assert float(moved.detach()) != pytest.approx(float(base.detach()))


def test_loss_weights_switch_terms_off(gaits, offsets, skeleton):
    _, _, g = gaits
    model = _model(g)
    batch = g.select(slice(0, 4))
    pred = rollout(model, batch, offsets, skeleton.parents, prefix=18)
    only_root = LossWeights(motion=0, pose=0, affective=0, root=1, foot=0)
    losses = generator_losses(pred, targets(batch, 18), model, offsets, skeleton.parents, only_root)
    assert float(losses.total.detach()) == pytest.approx(float(losses.root.detach()))


def test_motion_joint_weights_scale_only_the_named_joints_share_of_the_motion_term(gaits, offsets, skeleton):
    _, _, g = gaits
    model = _model(g)
    batch = g.select(slice(0, 4))
    pred = rollout(model, batch, offsets, skeleton.parents, prefix=18)
    target = targets(batch, 18)

    def motion(**joints):
        return float(generator_losses(pred, target, model, offsets, skeleton.parents,
                                      LossWeights(versor=0.0, motion_joints=joints)).motion.detach())

    base = motion()
    head_only = motion(**{n: (1.0 if n == "head" else 0.0) for n in skeleton.names})
    assert 0.0 < head_only < base
    assert motion(head=11.0) == pytest.approx(base + 10.0 * head_only, rel=1e-5)
    assert motion(head=1.0) == pytest.approx(base, rel=1e-6)


def test_motion_joint_weights_come_from_params_and_reject_unknown_joints():
    train = {"loss": {"motion": 1, "motion_joints": {"neck": 11, "head": 11}},
             "variants": {"full": {}, "no_affect": {"loss": {"affective": 0}}}}
    variants = variant_configs(train)
    assert all(w.motion_joints == {"neck": 11.0, "head": 11.0} for _, _, w in variants.values())
    assert variants["no_affect"][2].affective == 0.0
    with pytest.raises(ValueError, match="nose"):
        LossWeights(motion_joints={"nose": 2.0})


def test_training_is_reproducible_and_checkpoints_are_byte_identical(gaits, offsets, skeleton, tmp_path):
    _, _, g = gaits
    train, val = g.select(slice(0, 32)), g.select(slice(32, 48))
    cfg = TrainConfig(epochs=3, batch_size=16, batches_per_epoch=0, validate_every=1, seed=3, threads=1, device="cpu")
    runs = [train_generator(train, val, offsets, skeleton.parents, TINY, cfg, LossWeights()) for _ in range(2)]
    a, b = (checkpoint_bytes(r.model, {"epochs": 3}) for r in runs)
    assert a == b
    assert runs[0].history == runs[1].history
    assert runs[0].history[-1]["train_total"] < runs[0].history[0]["train_total"]  # it learns
    other = train_generator(train, val, offsets, skeleton.parents, TINY, TrainConfig(**{**cfg.__dict__, "seed": 4}),
                            LossWeights())
    assert checkpoint_bytes(other.model, {"epochs": 3}) != a  # the seed matters
    sha = write_bytes(a, tmp_path / "m.pt")
    model, extra, sha2 = load_checkpoint(tmp_path / "m.pt")
    assert sha == sha2 and extra["epochs"] == 3
    assert all(torch.equal(p, q) for p, q in zip(model.state_dict().values(), runs[0].model.state_dict().values()))


def test_generation_is_batched_and_deterministic(gaits, offsets, skeleton):
    arrays, rows, g = gaits
    model = _model(g, GeneratorConfig(gru_hidden=32, versor_hidden=32))
    seeds = Seeds.from_arrays(arrays, rows[:5], prefix=18)
    paths = place_paths(turn_path(), seeds)
    emotions = torch.zeros(5, 30, 4)
    emotions[..., 1] = 1.0
    emotions[2] = float("nan")  # an unlabelled agent in the same batch
    together = generate(model, seeds, paths, emotions, offsets, skeleton.parents)
    again = generate(model, seeds, paths, emotions, offsets, skeleton.parents)
    assert torch.equal(together.positions, again.positions)
    assert together.positions.shape == (5, 30, 21, 3) and together.rotations.shape == (5, 30, 21, 4)
    for n in range(5):  # each agent alone gives what it got in the batch
        one = Seeds(gaits=seeds.gaits.select(slice(n, n + 1)), heading=seeds.heading[n:n + 1])
        alone = generate(model, one, paths[n:n + 1], emotions[n:n + 1], offsets, skeleton.parents)
        # float rounding differs between batch sizes; the stance-foot placement sums it over the frames (< 0.5 mm)
        assert torch.allclose(alone.positions[0], together.positions[n], atol=5e-4)
    norms = torch.linalg.vector_norm(together.rotations, dim=-1)
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-5)
    assert torch.equal(together.condition[2], torch.zeros(30, 5))  # NaN emotion -> unlabelled condition


def test_fixed_bones_of_a_source_stay_fixed_in_generated_gaits(annotated, offsets, skeleton):
    """Retargeting fixes the Bandai hips, lower back and hand tips (one versor per clip); the network must not drift
    them (it did, ~7 degrees over a gait, through its residual versor head), while the other joints move."""
    table, arrays = annotated
    sources = np.array(table.column("source").to_pylist())
    rows = np.flatnonzero(sources == "bandai_namco_motiondataset")[::50][:4]
    seeds = Seeds.from_arrays(arrays, rows, prefix=18)
    fixed = fixed_bones(seeds.gaits.q)
    named = {skeleton.names[j] for j in np.flatnonzero(fixed.all(0).numpy())}
    assert fixed.any(0).tolist() == fixed.all(0).tolist()  # the same joints in every clip of the source
    assert named == {"left_hip", "right_hip", "lower_back", "left_hand_index", "right_hand_index"}, named
    assert not fixed[:, 0].any()
    model = _model(GaitTensors.from_arrays(arrays, rows))
    emotions = torch.zeros(len(rows), 30, 4)
    emotions[..., 2] = 1.0
    out = generate(model, seeds, place_paths(straight_path(), seeds), emotions, offsets, skeleton.parents)
    last = seeds.gaits.q[:, -1]
    drift = qangle(out.versors, last[:, None].expand_as(out.versors))  # (N, S, 21) rad from the seed's last versor
    assert drift[fixed[:, None].expand_as(drift)].max() < 1e-3
    moving = ~fixed
    moving[:, 0] = False
    assert drift.amax(1)[moving].median() > math.radians(1.0)  # the untrained network does move the others


def test_bone_lengths_of_generated_gaits_are_the_canonical_ones(gaits, offsets, skeleton):
    arrays, rows, g = gaits
    model = _model(g)
    seeds = Seeds.from_arrays(arrays, rows[:3], prefix=18)
    out = generate(model, seeds, place_paths(straight_path(), seeds), torch.full((3, 20, 4), 0.25), offsets,
                   skeleton.parents)
    for j, p in enumerate(skeleton.parents[1:], start=1):
        length = torch.linalg.vector_norm(out.positions[:, :, j] - out.positions[:, :, p], dim=-1)
        assert torch.allclose(length, torch.full_like(length, float(skeleton.bone_lengths[j])), atol=1e-5)


def test_paths_start_at_the_seed_and_point_its_way(gaits):
    arrays, rows, _ = gaits
    seeds = Seeds.from_arrays(arrays, rows[:6], prefix=18)
    paths = place_paths(straight_path(10.0), seeds)
    start = seeds.gaits.root_position[:, -1, [0, 2]]
    assert torch.allclose(paths[:, 0], start)
    direction = paths[:, 1] - paths[:, 0]
    travel = seeds.travel_direction()
    assert torch.allclose(torch.atan2(direction[:, 0], direction[:, 1]), travel, atol=1e-4)
    # lateral deviation of points on the path is zero, of a point 1 m aside is 1 m
    on = paths[:, None, 0] + 0.3 * direction[:, None] / 10.0
    assert torch.allclose(distance_to_polyline(on, paths), torch.zeros(6, 1), atol=1e-5)


def test_root_follows_a_turning_path_when_the_network_walks(gaits, offsets, skeleton):
    """With the root heads zeroed (the residual keeps each root feature at its last value) and the seeds' speed
    set to a walking pace, the placement follows a 90° turn to within half a metre."""
    arrays, rows, g = gaits
    model = _model(g)
    with torch.no_grad():
        for head in (model.fc_s, model.fc_h, model.fc_delta):
            head.weight.zero_()
            head.bias.zero_()
    seeds = Seeds.from_arrays(arrays, rows[:4], prefix=18)
    seeds.gaits.s.fill_(1.3 / 30)
    paths = place_paths(turn_path(), seeds)
    out = generate(model, seeds, paths, torch.full((4, 200, 4), 0.25), offsets, skeleton.parents,
                   PlacementConfig(max_turn_deg_per_s=240.0, root_advance="predicted_speed"))
    assert torch.allclose(out.s, torch.full_like(out.s, 1.3 / 30))
    root = out.positions[:, :, 0, [0, 2]]
    travelled = torch.linalg.vector_norm(root[:, 1:] - root[:, :-1], dim=-1).sum(-1)
    assert torch.allclose(travelled, torch.full((4,), 199 * 1.3 / 30), rtol=1e-4)
    deviation = distance_to_polyline(root, paths)
    assert float(deviation.max()) < 0.5
    assert float(deviation[:, -30:].max()) < 0.05  # back on the path after the turn


def test_stance_foot_steps_recover_the_root_travel_of_real_walks(annotated):
    """Moving the root by the opposite of the lowest heel/toe point's root-relative motion retraces real walks: the
    real stance foot barely slides, so the summed steps land where the real root went."""
    table, arrays = annotated
    rows = np.flatnonzero(np.array(table.column("content").to_pylist()) == "walk")[::5]
    positions = torch.from_numpy(arrays["positions"][rows]).double()
    root = positions[:, :, :1].clone()
    root[..., 1] = 0.0
    feet = (positions - root)[:, :, list(FOOT_JOINTS)]
    steps = sum(stance_step(feet[:, t - 1], feet[:, t], 0.002, 0.1) for t in range(1, positions.shape[1]))
    travelled = positions[:, -1, 0, [0, 2]] - positions[:, 0, 0, [0, 2]]
    error = torch.linalg.vector_norm(steps - travelled, dim=-1) / torch.linalg.vector_norm(travelled, dim=-1)
    assert len(rows) > 150
    assert float(error.median()) < 0.03 and float(np.percentile(error.numpy(), 90)) < 0.1
    # the same with the swing foot ruled out by the real stepping phase: real swing feet are never the lowest, so
    # the gate changes (almost) nothing on real walks
    theta = torch.from_numpy(arrays["phase"][rows]).double()
    gated = sum(stance_step(feet[:, t - 1], feet[:, t], 0.002, 0.1, swinging_points(theta[:, t], 0.6))
                for t in range(1, positions.shape[1]))
    gated_error = torch.linalg.vector_norm(gated - travelled, dim=-1) / torch.linalg.vector_norm(travelled, dim=-1)
    assert float(gated_error.median()) < 0.03 and float(np.percentile(gated_error.numpy(), 90)) < 0.1


def test_swinging_points_follow_the_stepping_phase():
    theta = torch.tensor([0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi, 1.9 * math.pi])
    swing = swinging_points(theta, 0.6)  # columns: left heel, left toe, right heel, right toe
    assert not swing[0].any() and not swing[2].any()  # at each strike both feet are down (double support)
    assert swing[1].tolist() == [False, False, True, True]  # after the left strike the right foot swings
    assert swing[3].tolist() == [True, True, False, False] and swing[4].tolist() == [True, True, False, False]
    assert swinging_points(torch.tensor([0.8 * math.pi]), 0.3).all()  # running: a flight phase, both swing


def test_a_swing_foot_skimming_below_the_stance_foot_does_not_carry_the_root_back():
    previous = torch.zeros(1, 4, 3)
    previous[0, :2, 1], previous[0, 2:, 1] = 0.05, 0.06  # left (stance) at 5 cm, right (swing) at 6 cm
    now = previous.clone()
    now[0, :2, 2] -= 0.04  # the stance foot moves back 4 cm under the body: the root moves forward 4 cm
    now[0, 2:, 2] += 0.08  # the swing foot moves forward 8 cm ...
    now[0, 2:, 1] = 0.01  # ... and dips below the stance foot
    swing = torch.tensor([[False, False, True, True]])
    assert float(stance_step(previous, now, 0.002, 0.1)[0, 1]) < 0  # the lowest point rules: the root goes back
    assert torch.allclose(stance_step(previous, now, 0.002, 0.1, swing)[0], torch.tensor([0.0, 0.04]))


def test_a_placed_step_against_the_travel_loses_that_part_only_when_the_placement_says_so():
    previous = torch.zeros(2, 4, 3)
    now = previous.clone()
    now[0, :, 2] += 0.03  # the stance point slips forward: the root would go back 3 cm ...
    now[1, :, 0] -= 0.02  # ... or 2 cm sideways, which is not against the travel
    along = torch.tensor([[0.0, 1.0], [0.0, 1.0]])  # travelling +z
    kept = placed_step(previous, now, along, PlacementConfig())
    assert torch.allclose(kept, torch.tensor([[0.0, -0.03], [0.02, 0.0]]))
    forward = placed_step(previous, now, along, PlacementConfig(forward_steps_only=True))
    assert torch.allclose(forward, torch.tensor([[0.0, 0.0], [0.02, 0.0]]))
    slow = placed_step(previous, now, along, PlacementConfig(max_speed_m_s=0.3))  # 1 cm per frame at 30 fps
    assert torch.allclose(torch.linalg.vector_norm(slow, dim=-1), torch.tensor([0.01, 0.01]))


def test_stance_foot_placement_keeps_the_lowest_point_planted(gaits, offsets, skeleton):
    arrays, rows, g = gaits
    model = _model(g)
    seeds = Seeds.from_arrays(arrays, rows[:6], prefix=18)
    out = generate(model, seeds, place_paths(straight_path(), seeds), torch.full((6, 40, 4), 0.25), offsets,
                   skeleton.parents, PlacementConfig(root_advance="stance_foot", max_speed_m_s=100.0))
    feet = out.positions[:, :, list(FOOT_JOINTS)]
    height = 0.5 * (feet[:, 1:, :, 1] + feet[:, :-1, :, 1])
    lowest = height.argmin(-1, keepdim=True)  # (N, S-1, 1)
    slide = torch.linalg.vector_norm(feet[:, 1:, :, [0, 2]] - feet[:, :-1, :, [0, 2]], dim=-1).gather(-1, lowest)
    gap = height.sort(-1).values[..., 1:2] - height.min(-1, keepdim=True).values
    clear = gap > 0.02  # one point clearly lowest: it does not move at all
    assert int(clear.sum()) > 100
    assert float(slide[clear].max()) < 1e-4
    assert torch.allclose(out.advance[:, 1:], torch.linalg.vector_norm(
        out.positions[:, 1:, 0, [0, 2]] - out.positions[:, :-1, 0, [0, 2]], dim=-1), atol=1e-5)


def test_forward_steps_only_never_carries_the_root_back_against_its_travel(gaits, offsets, skeleton):
    arrays, rows, g = gaits
    model = _model(g)
    seeds = Seeds.from_arrays(arrays, rows[:12], prefix=18)
    paths, emotions = place_paths(straight_path(), seeds), torch.full((12, 40, 4), 0.25)

    def ahead(cfg: PlacementConfig) -> torch.Tensor:  # each placed root step along the frame's travel direction
        out = generate(model, seeds, paths, emotions, offsets, skeleton.parents, cfg)
        ground = torch.cat([seeds.gaits.root_position[:, -1:, [0, 2]], out.positions[:, :, 0, [0, 2]]], 1)
        return (ground.diff(dim=1) * unit_direction(out.travel)).sum(-1)

    free, forward = ahead(PlacementConfig()), ahead(PlacementConfig(forward_steps_only=True))
    assert int((free < -1e-4).sum()) > 0  # the untrained network's steps do hesitate and go back
    assert float(forward.min()) > -1e-6
    assert float(forward.clamp_min(0).sum()) > 0.5 * float(free.clamp_min(0).sum())  # it still walks


def test_foot_lock_publishes_the_locked_legs_of_the_same_walk(gaits, offsets, skeleton):
    from pipeline.ops.footlock import lock_feet

    arrays, rows, g = gaits
    model = _model(g)
    seeds = Seeds.from_arrays(arrays, rows[:6], prefix=18)
    paths, emotions = place_paths(straight_path(), seeds), torch.full((6, 40, 4), 0.25)
    free = generate(model, seeds, paths, emotions, offsets, skeleton.parents, PlacementConfig())
    locked = generate(model, seeds, paths, emotions, offsets, skeleton.parents, PlacementConfig(foot_lock=True))
    rotations, positions = lock_feet(free.rotations, free.positions[..., 0, :], offsets, skeleton.parents, 30.0)
    assert torch.equal(locked.rotations, rotations) and torch.equal(locked.positions, positions)
    assert not torch.equal(locked.rotations, free.rotations)  # some stance foot was held
    # only the legs change; the root, the pelvis and the network's own inputs are the same
    for name in ("heading", "travel", "s", "h", "advance"):
        assert torch.equal(getattr(locked, name), getattr(free, name)), name
    assert torch.equal(locked.versors[..., 0, :], free.versors[..., 0, :])
    assert torch.equal(locked.versors[..., 1:, :], locked.rotations[..., 1:, :])


def test_odd_frames_are_the_nearest_odd_window():
    assert [odd_frames(s, 30.0) for s in (0.0, 0.1, 0.2, 0.3, 0.4)] == [1, 3, 7, 9, 13]


def test_root_smoothing_keeps_a_steady_walk_and_removes_the_stance_handover_jumps(annotated):
    table, arrays = annotated
    rows = np.flatnonzero(np.array(table.column("content").to_pylist()) == "walk")[:20]
    real = torch.from_numpy(arrays["positions"][rows]).double()
    prefix, generated = real[:, :18, 0, [0, 2]], real[:, 18:]
    # a steady walk along a line (the prefix on the same line) is left where it is
    line = torch.linspace(0.0, 2.0, 60, dtype=torch.float64)[None, :, None] * torch.tensor([0.6, 0.8])
    steady = torch.zeros(1, 42, 21, 3, dtype=torch.float64)
    steady[..., [0, 2]] = line[:, 18:, None]
    assert torch.allclose(smoothed_root(steady, line[:, :18], 7), steady, atol=1e-12)
    # a real walk whose root lurches 2 cm ahead in one frame at two stance handovers ...
    jumps = generated.clone()
    for frame in (12, 27):
        jumps[:, frame:, :, 2] += 0.02
    out = smoothed_root(jumps, prefix, 7)
    speed = lambda p: torch.linalg.vector_norm(p[:, 1:, 0, [0, 2]] - p[:, :-1, 0, [0, 2]], dim=-1)  # noqa: E731
    change = lambda p: (speed(p)[:, 1:] - speed(p)[:, :-1]).abs().mean()  # noqa: E731
    assert float(change(out)) < 0.5 * float(change(jumps)) and float(change(out)) < 1.5 * float(change(generated))
    # ... loses the lurches, keeps its course, its heights and its poses (every joint moves with the root)
    moved = torch.linalg.vector_norm(out[..., 0, [0, 2]] - jumps[..., 0, [0, 2]], dim=-1).amax(1)  # per walk
    assert float(moved.median()) < 0.02 and float(moved.max()) < 0.03  # real sway and lurches averaged: ~2 cm
    assert torch.equal(out[..., 1], jumps[..., 1])
    assert torch.allclose(out - out[..., :1, :], jumps - jumps[..., :1, :], atol=1e-12)
    # and the first frame, averaged with the prefix, stays by the walk's own first frame (no lurch there yet)
    assert float(torch.linalg.vector_norm(out[:, 0, 0, [0, 2]] - generated[:, 0, 0, [0, 2]], dim=-1).max()) < 0.02
    assert torch.equal(smoothed_root(jumps, prefix, 1), jumps)


def test_root_smoothing_in_generation_moves_only_the_ground_path(gaits, offsets, skeleton):
    arrays, rows, g = gaits
    model = _model(g)
    seeds = Seeds.from_arrays(arrays, rows[:6], prefix=18)
    paths, emotions = place_paths(straight_path(), seeds), torch.full((6, 40, 4), 0.25)
    free = generate(model, seeds, paths, emotions, offsets, skeleton.parents, PlacementConfig())
    smooth = generate(model, seeds, paths, emotions, offsets, skeleton.parents, PlacementConfig(root_smoothing_s=0.2))
    assert torch.equal(smooth.positions, smoothed_root(free.positions, seeds.gaits.root_position[..., [0, 2]], 7))
    assert torch.equal(smooth.rotations, free.rotations) and torch.equal(smooth.heading, free.heading)
    path = torch.cat([seeds.gaits.root_position[:, -1:, [0, 2]], smooth.positions[..., 0, [0, 2]]], 1)
    assert torch.allclose(smooth.advance, torch.linalg.vector_norm(path.diff(dim=1), dim=-1))


def test_baselines(gaits, offsets, skeleton):
    _, _, g = gaits
    zero = zero_velocity(g.q[:, :18], 42)
    assert torch.equal(zero[:, 10], g.q[:, 17])
    const = constant_velocity(g.q[:, :18], 42)
    step = qangle(g.q[:, 17], g.q[:, 16])
    assert torch.allclose(qangle(const[:, 0], g.q[:, 17]), step, atol=1e-3)
    errors = pose_errors(g.q[:, 18:], g.q[:, 18:], offsets, skeleton.parents)
    assert float(errors["position"].max()) == 0.0 and float(errors["rotation"].max()) < 0.1


def test_euler_angles_round_trip():
    q = qnormalize(torch.randn(500, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(1)))
    back = euler_to_quat(quat_to_euler(q, "ZYX"), "ZYX")
    assert float(qangle(q, back).max()) < 1e-6
    assert torch.allclose(quat_to_euler(-q, "ZYX"), quat_to_euler(q, "ZYX"))
    quarter = euler_to_quat(torch.tensor([[math.pi / 2, 0.0, 0.0]], dtype=torch.float64), "ZYX")
    assert torch.allclose(quat_to_euler(quarter, "ZYX"), torch.tensor([[math.pi / 2, 0.0, 0.0]], dtype=torch.float64))
