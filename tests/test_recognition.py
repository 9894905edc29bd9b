"""The independent emotion recognisers on real gaits: both kinds beat chance on real held-out clips, read 20-frame
blocks, and are deterministic for a seed; the bootstrap interval over clips holds the point estimate and narrows
with more clips; the heading-frame normalisation ignores where the body stands and faces; the memorisation
distance is 0 for a train window against the train windows and positive for held-out ones.

The real gaits are the default data's annotated windows, split as the pipeline splits them (``pipeline.split``,
the params' seed and held-out rule): the train split for fitting, val + test held out."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import yaml

from pipeline.audit.memorisation import nearest_window_distance
from pipeline.core.emotions import EMOTIONS
from pipeline.ops.quaternion import qrot, yaw
from pipeline.recognition import (
    RECOGNISERS,
    RecogniserConfig,
    RecognitionInputs,
    bootstrap_interval,
    confusion,
    fit_recogniser,
    heading_frame_poses,
    majority_baseline,
    scores,
)
from stages.common import REPO

PARAMS = yaml.safe_load((REPO / "params.yaml").read_text())
CFG = RecogniserConfig.from_dict(PARAMS["audit"]["recognisers"])


@pytest.fixture(scope="module")
def real(annotated_split):
    torch.set_num_threads(1)
    table, arrays, split, strata = annotated_split
    clip_ids = table.column("clip_id").to_pylist()
    index = {n: i for i, n in enumerate(EMOTIONS)}
    label = np.array([index.get(d, -1) for d in strata])
    inputs = RecognitionInputs.from_arrays(arrays)
    train, held = split == "train", np.isin(split, ["val", "test"])
    return {"inputs": inputs, "label": label, "train": train, "held": held, "clips": np.array(clip_ids),
            "fit": train & (label >= 0), "test": held & (label >= 0)}


@pytest.fixture(scope="module")
def fitted(real):
    return {kind: fit_recogniser(kind, real["inputs"].select(real["fit"]), real["label"][real["fit"]], CFG, 0)
            for kind in RECOGNISERS}


@pytest.mark.parametrize("kind", RECOGNISERS)
def test_both_recognisers_beat_chance_on_real_held_out_clips(real, fitted, kind):
    y = real["label"][real["test"]]
    predicted = fitted[kind].predict(real["inputs"].select(real["test"]))
    matrix = confusion(y, predicted, len(EMOTIONS))
    result, baseline = scores(matrix), majority_baseline(matrix, EMOTIONS)
    assert len(set(y)) == 4 and len(y) > 40
    assert result["balanced_accuracy"] > 0.25 + 0.15, result
    assert result["macro_f1"] > baseline["macro_f1"] + 0.2, (result, baseline)


@pytest.mark.parametrize("kind", RECOGNISERS)
def test_a_recogniser_reads_20_frame_blocks_and_any_length_from_10(real, fitted, kind):
    held = real["inputs"].select(real["test"])
    y = real["label"][real["test"]]
    for start in (0, 20, 40):
        block = held.block(start, start + CFG.block_frames)
        p = fitted[kind].probabilities(block)
        assert p.shape == (len(y), 4) and p.dtype == np.float64 and np.allclose(p.sum(1), 1.0)
        assert scores(confusion(y, p.argmax(1), 4))["balanced_accuracy"] > 0.25 + 0.1
    assert fitted[kind].predict(held.block(5, 15)).shape == (len(y),)
    with pytest.raises(ValueError, match="at least 10 frames"):
        fitted[kind].probabilities(held.block(0, 9))


@pytest.mark.parametrize("kind", RECOGNISERS)
def test_a_recogniser_is_deterministic_for_a_seed(real, fitted, kind):
    rows = np.flatnonzero(real["fit"])[:80]  # a small fit: the property, not the accuracy
    small = real["inputs"].select(rows)
    held = real["inputs"].select(real["test"])
    cfg = RecogniserConfig.from_dict({"summary": {"epochs": 30}, "temporal": {"epochs": 3}})
    a, b, c = (fit_recogniser(kind, small, real["label"][rows], cfg, seed).probabilities(held) for seed in (3, 3, 4))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    state, deterministic = torch.random.get_rng_state(), torch.are_deterministic_algorithms_enabled()
    for mode in (not deterministic, deterministic):  # either global mode is left as it was
        torch.use_deterministic_algorithms(mode)
        fit_recogniser(kind, small, real["label"][rows], cfg, 5)
        assert torch.are_deterministic_algorithms_enabled() == mode
    torch.random.set_rng_state(state)
    fit_recogniser(kind, small, real["label"][rows], cfg, 5)
    assert torch.equal(state, torch.random.get_rng_state())  # the global RNG is left as it was


def test_the_bootstrap_interval_holds_the_estimate_and_narrows_with_more_clips(real, fitted):
    y = real["label"][real["test"]]
    groups = real["clips"][real["test"]]
    predicted = fitted["summary_mlp"].predict(real["inputs"].select(real["test"]))
    point = scores(confusion(y, predicted, 4))
    ci = bootstrap_interval(groups, y, predicted, 4, resamples=500, seed=0)
    assert set(ci) == set(point)
    for s, (lo, hi) in ci.items():
        assert lo <= point[s] <= hi and hi > lo, (s, lo, point[s], hi)
    assert bootstrap_interval(groups, y, predicted, 4, resamples=500, seed=0) == ci  # seeded
    # four times the clips, each answered as this one was: the same estimate, a narrower interval
    more = np.concatenate([np.char.add(groups.astype(str), f"#copy{c}") for c in range(4)])
    wide = bootstrap_interval(more, np.tile(y, 4), np.tile(predicted, 4), 4, resamples=500, seed=0)
    for s in ci:
        assert wide[s][1] - wide[s][0] < 0.75 * (ci[s][1] - ci[s][0]), (s, ci[s], wide[s])
        assert wide[s][0] <= point[s] <= wide[s][1]
    # several recognisers (seeds) on the same gaits: the interval of their mean score holds that mean
    other = fitted["temporal_cnn"].predict(real["inputs"].select(real["test"]))
    mean = {s: (point[s] + scores(confusion(y, other, 4))[s]) / 2 for s in point}
    both = bootstrap_interval(groups, y, np.stack([predicted, other]), 4, resamples=500, seed=0)
    for s, (lo, hi) in both.items():
        assert lo <= mean[s] <= hi, (s, lo, mean[s], hi)
    # one clip: every resample is the same clip, so the interval is the point
    one = groups == groups[0]
    single = bootstrap_interval(groups[one], y[one], predicted[one], 4, resamples=50)
    assert single["accuracy"][0] == single["accuracy"][1] == scores(confusion(y[one], predicted[one], 4))["accuracy"]


def test_the_heading_frame_pose_ignores_where_the_body_stands_and_faces(real):
    inputs = real["inputs"].select(np.flatnonzero(real["held"])[:5])
    positions = torch.from_numpy(inputs.positions.astype(np.float64))
    heading = torch.from_numpy(inputs.heading.astype(np.float64))
    turn = torch.tensor(0.7, dtype=torch.float64)
    moved = qrot(yaw(turn).expand(*positions.shape[:-1], 4), positions) + torch.tensor([3.0, 0.2, -1.0],
                                                                                      dtype=torch.float64)
    assert torch.allclose(heading_frame_poses(positions, heading), heading_frame_poses(moved, heading + turn),
                          atol=1e-9)
    pose = heading_frame_poses(positions, heading)
    assert torch.equal(pose[..., 0, :], torch.zeros_like(pose[..., 0, :]))  # the root at the origin
    # facing +Z: the left/right hips lie across x, not along z, on average
    hips = pose[..., [1, 5], :] if pose.shape[-2] > 5 else pose
    assert float(hips[..., 0].abs().mean()) > float(hips[..., 2].abs().mean())
    assert math.isfinite(float(pose.abs().max()))


def test_memorisation_distance_is_zero_for_a_train_window_and_positive_for_held_out(real):
    train = real["inputs"].select(real["train"])
    own = nearest_window_distance(train.select(slice(0, 50)), train)
    assert np.allclose(own, 0.0, atol=1e-6)
    held = nearest_window_distance(real["inputs"].select(real["held"]), train)
    assert held.shape == (int(real["held"].sum()),) and (held > 1e-3).all()
    # the candidate search against a brute-force one (every reference a candidate), on a part of the windows:
    # never below the true nearest distance, and the same for nearly every window
    references, queries = train.select(slice(0, 300)), real["inputs"].select(np.flatnonzero(real["held"])[:100])
    searched = nearest_window_distance(queries, references)
    exhaustive = nearest_window_distance(queries, references, candidates=len(references))
    assert (searched >= exhaustive - 1e-6).all() and np.isclose(searched, exhaustive, atol=1e-6).mean() >= 0.9


def test_the_config_comes_from_params_and_refuses_unknown_keys():
    params = yaml.safe_load((REPO / "params.yaml").read_text())["audit"]["recognisers"]
    assert CFG.block_frames == params["block_frames"] == 20
    assert CFG.summary.hidden == params["summary"]["hidden"] and CFG.temporal.kernel == params["temporal"]["kernel"]
    with pytest.raises(KeyError, match="hiden"):
        RecogniserConfig.from_dict({"summary": {"hiden": 3}})
    assert RecogniserConfig.from_dict({}) == RecogniserConfig()


def test_a_gait_with_a_nan_is_told_apart(real):
    inputs = real["inputs"].select(np.arange(6))
    assert inputs.finite().all()
    positions = inputs.positions.copy()
    positions[4, 30, 7, 2] = np.nan
    planted = RecognitionInputs(positions, inputs.heading, inputs.affective, inputs.movement)
    assert planted.finite().tolist() == [True, True, True, True, False, True]
    with pytest.raises(ValueError, match="positions"):
        RecognitionInputs(positions[:, :, :20], inputs.heading, inputs.affective, inputs.movement)
