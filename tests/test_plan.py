"""The synthesis plan: trajectory geometry, novelty of emotions and shapes, the 5,000-gait arithmetic, and the
published table's lineage, on the real training data."""

from __future__ import annotations

import math

import numpy as np
import pytest

import torch

from pipeline.annotate.annotation import rebuild_clips
from pipeline.ops.geometry import arc_lengths, to_local_frame, travel_direction, unit_direction
from pipeline.synth.novelty import nearest_training_path, novel_emotions, training_paths
from pipeline.synth.plan import build_plan, frame_emotions, transition_rounds
from pipeline.synth.synthesis import copied_frames, walking_figures
from pipeline.synth.trajectories import TRAVEL_FRAMES, piece_from, trajectories_from_spec, trajectory_points
from stages.common import load_params

PARAMS = load_params()["synthesize"]


def test_an_arc_keeps_its_radius_and_a_corner_turns():
    points = trajectory_points([[math.pi * 2, 0.5, 0.5]])  # a half circle of radius 2 to the left
    centre = np.array([2.0, 0.0])
    assert np.allclose(np.linalg.norm(points - centre, axis=-1), 2.0, atol=1e-3)
    assert np.allclose(points[-1], [4.0, 0.0], atol=1e-2)
    assert abs(float(arc_lengths(torch.from_numpy(points))[-1]) - 2 * math.pi) < 1e-2
    corner = trajectory_points([[2, 0, 0], [90], [2, 0, 0]])
    assert np.allclose(corner[-1], [2.0, 2.0], atol=1e-6)  # +x is the left
    piece = piece_from(corner, 1.02, 3.0)  # starts at the point at or before 1.02 m: the one at 1 m
    assert np.allclose(piece[0], 0) and np.allclose(piece[20], [0.0, 1.0], atol=1e-6)
    assert np.allclose(piece[-1], [2.0, 1.0], atol=1e-6)  # 1 m on, then 2 m after the left turn
    at_corner = piece_from(corner, 2.02, 1.0)
    assert np.allclose(piece_from(trajectory_points([[45], [3, 0, 0]]), 0.0, 1.0)[-1],
                       [math.sqrt(0.5), math.sqrt(0.5)], atol=1e-6)  # a new heading is a turn from the seed's
    assert np.allclose(at_corner[-1], [1.0, 0.0], atol=1e-6)  # a gait starting at the corner walks it


def test_novel_emotions_are_far_from_every_training_label_and_on_the_simplex():
    labels = np.eye(4)
    emotions = novel_emotions(100, labels, 0.5, np.random.default_rng(1))
    assert emotions.shape == (100, 4) and np.allclose(emotions.sum(-1), 1) and (emotions >= 0).all()
    assert np.abs(emotions[:, None] - labels[None]).sum(-1).min() > 0.5
    with pytest.raises(ValueError, match="farther than L1"):
        novel_emotions(5, labels, 1.9, np.random.default_rng(1), max_draws=10_000)  # no simplex point is that far


def test_transition_rounds_are_disjoint_and_never_repeat_a_pair():
    rounds = transition_rounds(100, 3, np.random.default_rng(3))
    assert [len(r) for r in rounds] == [50, 50, 50]
    for pairs in rounds:
        assert sorted(i for p in pairs for i in p) == list(range(100))
    everything = [frozenset(p) for pairs in rounds for p in pairs]
    assert len(set(everything)) == 150


def test_the_default_plan_has_exactly_5000_gaits_with_their_recipes():
    trajectories = trajectories_from_spec(PARAMS["trajectories"], PARAMS["start_span_m"])
    emotions = novel_emotions(PARAMS["emotions"], np.eye(4), PARAMS["min_l1_to_training"], np.random.default_rng(0))
    pools = {0: ["h1", "h2"], 1: ["s1"], 2: ["a1", "a2"], 3: ["n1", "n2", "n3"], -1: ["h1"]}
    plan = build_plan(trajectories, emotions, pools, PARAMS["transition_rounds"], PARAMS["seed"])
    assert len(trajectories) == 20 and len(plan) == 5000
    assert len({r["gait_id"] for r in plan}) == 5000 and len({r["plan_seed"] for r in plan}) == 5000
    kinds = [r["recipe"]["kind"] for r in plan]
    assert kinds.count("single") == 2000 and kinds.count("transition") == 3000
    assert plan == build_plan(trajectories, emotions, pools, PARAMS["transition_rounds"], PARAMS["seed"])
    # every seed walks the emotion its gait starts with (a transition: its start emotion)
    for r in plan:
        start = emotions[r["recipe"]["emotion" if r["recipe"]["kind"] == "single" else "from"]]
        assert r["seed_gait_id"] in pools[int(np.argmax(start))]
    assert {r["seed_gait_id"] for r in plan} == {g for k, ids in pools.items() if k >= 0 for g in ids}
    # an emotion without seeds falls back to the whole pool
    fallback = build_plan(trajectories[:1], emotions, {0: ["h1"], -1: ["any"]}, 1, PARAMS["seed"])
    assert {r["seed_gait_id"] for r in fallback} == {"h1", "any"}
    transition = next(r["recipe"] for r in plan if r["recipe"]["kind"] == "transition")
    per_frame = frame_emotions(transition, emotions, 60)
    assert np.allclose(per_frame.sum(-1), 1) and np.allclose(per_frame[0], emotions[transition["from"]])
    assert np.allclose(per_frame[-1], emotions[transition["to"]])


def test_trajectory_novelty_rejects_a_training_path_and_accepts_the_planned_shapes(annotated):
    table, arrays = annotated
    clip_ids = table.column("clip_id").to_pylist()
    starts = np.round(table.column("t_start").to_numpy() * 30).astype(int)
    paths = training_paths(arrays["root_path"], clip_ids, starts, 60)
    novelty = PARAMS["novelty"]
    least, threshold = novelty["min_compared_m"], novelty["min_mean_distance_m"]
    # a training clip's own path, in its start frame, is found at distance ~0: the test can fail
    cid, (clip, _) = next((c, v) for c, v in rebuild_clips(clip_ids, starts, arrays["root_path"], 60).items()
                          if float(arc_lengths(torch.from_numpy(v[0]))[-1]) > 5)
    path = torch.from_numpy(clip.astype(np.float64))
    own = to_local_frame(path, unit_direction(float(travel_direction(path, TRAVEL_FRAMES))), path[0]).numpy()
    assert nearest_training_path(own, paths, least)["distance_m"] < 1e-6
    assert nearest_training_path(own, paths, least, exclude_clip=cid)["clip_id"] != cid
    straight = nearest_training_path(trajectory_points([[12, 0, 0]]), paths, least)
    assert straight["distance_m"] < threshold  # walking straight ahead is not new
    for t in trajectories_from_spec(PARAMS["trajectories"], PARAMS["start_span_m"]):
        assert nearest_training_path(t.points, paths, least)["distance_m"] > threshold, t.id


def test_copied_frames_finds_a_copied_pose_even_turned(annotated):
    _, arrays = annotated
    real = arrays["rotations"][:20]
    fake = real[:2].copy()
    fake[..., 1:, :] += 0.01  # every pose changed
    assert copied_frames(fake, real) == 0
    fake[1, 7] = real[5, 3]
    fake[1, 7, 0] = [0.0, 0.0, 1.0, 0.0]  # the root turned: still a copy
    assert copied_frames(fake, real) == 1


def test_walking_figures_tell_a_walk_from_stepping_in_a_circle():
    t = np.arange(61) / 30.0  # 2 s at 30 fps
    straight = np.stack([np.zeros_like(t), 1.2 * t], -1)  # 1.2 m/s ahead
    angle = 2 * np.pi * t / 2.0  # one full circle of radius 0.3 m in the 2 s
    circle = np.stack([0.3 * np.sin(angle), 0.3 * (1 - np.cos(angle))], -1)
    emotions = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    out = walking_figures(np.stack([straight, circle]), emotions, 30.0)
    assert set(out) == {"happy", "angry"}
    assert out["happy"] == {"gaits": 1, "net_speed_m_s": 1.2, "path_speed_m_s": 1.2}
    assert out["angry"]["net_speed_m_s"] < 0.01 and abs(out["angry"]["path_speed_m_s"] - 0.3 * np.pi) < 0.01
