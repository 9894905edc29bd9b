"""The controllability protocols (issue 11) on real data: the default data's annotated windows split as the
pipeline splits them, a small network trained briefly with the emotion levers, the recognisers fitted on the real
train split. A copy of the network whose condition input is cut (the condition's weights zeroed) is the control:
its gaits cannot depend on the condition, and the figures must say so."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.evaluation.autoregressive import affect_summary, emotion_centroids
from pipeline.evaluation.controllability import ControllabilityConfig, condition_sensitivity
from pipeline.evaluation.report import controllability_markdown, plot_controllability
from pipeline.evaluation.run import ControlSetup, evaluate_controllability
from pipeline.generators.autoregressive.critic import CriticConfig
from pipeline.generators.autoregressive.network import CONDITION, GeneratorConfig, LossWeights
from pipeline.generators.autoregressive.training import GaitTensors, TrainConfig, checkpoint_bytes, train_generator
from pipeline.io.files import sha256_bytes
from pipeline.recognition import RECOGNISERS, RecogniserConfig
from pipeline.synth.synthesis import SynthesisConfig
from stages.common import load_params
from stages.configs import annotate_config, placement_config

pytestmark = pytest.mark.slow  # a network trained briefly, recognisers fitted, hundreds of gaits generated


@pytest.fixture(scope="module")
def split_gaits(annotated_split):
    torch.set_num_threads(1)
    return annotated_split


@pytest.fixture(scope="module")
def trained(split_gaits, skeleton):
    """A small network trained briefly with the emotion levers (seeded): what the protocols read."""
    _, arrays, split, _ = split_gaits
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    rows = np.flatnonzero((split == "train") & (labelled | (np.arange(len(split)) % 8 == 0)))
    gaits = GaitTensors.from_arrays(arrays, rows)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    cfg = TrainConfig(epochs=30, batch_size=32, batches_per_epoch=1, validate_every=30, seed=1, threads=1,
                      device="cpu", teacher_forcing_decay=0.9, learning_rate=3e-3, labelled_share=0.5, mismatch=0.5)
    result = train_generator(gaits, gaits.select(slice(0, 8)), offsets, skeleton.parents,
                             GeneratorConfig(gru_hidden=64, versor_hidden=64), cfg, LossWeights(style=2.0),
                             critic_cfg=CriticConfig(epochs=100))
    return result.model.eval(), sha256_bytes(checkpoint_bytes(result.model, {}))


def cut_condition(model):
    """The same network with the weights that read the condition (the encoders' last CONDITION inputs) zeroed."""
    cut = copy.deepcopy(model)
    with torch.no_grad():
        for encoder in (cut.enc_affect, cut.enc_movement):
            first = next(m for m in encoder.modules() if isinstance(m, torch.nn.Linear))
            first.weight[:, -CONDITION:] = 0.0
    return cut


@pytest.fixture(scope="module")
def controllability(split_gaits, trained, skeleton):
    table, arrays, split, dominant = split_gaits
    params = load_params()
    model, sha = trained
    models = {"full": model, "no_affect": cut_condition(model)}  # "no_affect" here: the condition cut
    rows = np.flatnonzero((split == "train") & np.isin(dominant, EMOTIONS))
    low, high, scale = model.affective_low, model.affective_high, model.affective_std
    centroids = emotion_centroids(affect_summary(torch.from_numpy(arrays["positions"][rows]), low, high, scale),
                                  [dominant[i] for i in rows])
    setup = ControlSetup(control=ControllabilityConfig(steps=60, block=20, transition_agents=2, plan_gaits=16, seed=0),
                         recognisers=RecogniserConfig.from_dict((params.get("audit") or {}).get("recognisers")),
                         annotate=annotate_config(params),
                         synthesis=SynthesisConfig.from_dict(params["synthesize"], frames=60),
                         preview_trajectory="arc_left_r4", preview_transition=("sad", "happy"))
    out, previews = evaluate_controllability(table, arrays, models, {"full": sha, "no_affect": sha}, skeleton,
                                             placement_config(params), centroids, dominant,
                                             int(params["train"]["prefix"]), setup)
    return out, previews, centroids


def test_condition_sensitivity_is_one_for_the_real_centroids_and_zero_for_one_gait(split_gaits):
    _, arrays, split, dominant = split_gaits
    rows = np.flatnonzero((split == "train") & np.isin(dominant, EMOTIONS))
    summary = affect_summary(torch.from_numpy(arrays["positions"][rows]), torch.full((18,), -1e3),
                             torch.full((18,), 1e3), torch.ones(18))
    centroids = emotion_centroids(summary, [dominant[i] for i in rows])
    as_real = condition_sensitivity(centroids[:, None].expand(-1, 5, -1), centroids)
    assert as_real["fraction_of_real"] == pytest.approx(1.0, abs=1e-4)
    same = condition_sensitivity(summary[:5][None].expand(4, -1, -1), centroids)
    assert same["fraction_of_real"] == 0.0 and same["real_between_emotion_centroids"] > 0.05


def test_cutting_the_condition_removes_every_effect_it_had(controllability):
    out, _, _ = controllability
    cut, full = out["condition_sensitivity"]["no_affect"], out["condition_sensitivity"]["full"]
    assert cut["fraction_of_real"] < 1e-4
    assert full["fraction_of_real"] > cut["fraction_of_real"] + 0.02  # the trained network reads its condition
    # identical gaits under the four conditions: each is "recognised as its condition" for exactly one of four
    for reader, by_block in out["style_retention"]["no_affect"]["recognised_as_condition"].items():
        assert by_block == pytest.approx([0.25] * 3, abs=1e-4), reader
    for kind in RECOGNISERS:  # a transition is its constant-start control when the condition is cut
        t = out["transitions"]["no_affect"][kind]
        assert t["end_probability_by_block"] == pytest.approx(t["control_end_probability_by_block"], abs=1e-4)


def test_figures_are_in_range_and_the_real_reference_is_recognised(controllability):
    out, _, _ = controllability
    assert out["recognisers"] == list(RECOGNISERS)
    for name, v in out["style_retention"].items():
        assert v["blocks"] == [[0, 20], [20, 40], [40, 60]]
        for reader in (*RECOGNISERS, "nearest_centroid"):
            for key in ("fraction", "balanced"):
                values = v["recognised_as_seed_emotion"][reader][key]
                assert len(values) == 3 and all(0.0 <= x <= 1.0 for x in values), (name, reader, key)
    real = out["real_test"]
    assert real["continuation_blocks"] == [[18, 38], [38, 58]]
    for kind in RECOGNISERS:  # fitted on the train split, read the real test gaits above chance
        assert real["scores"][kind]["balanced_accuracy"] > 0.4, kind
        assert np.mean(real["window"][kind]["balanced"]) > 0.3, kind
    for name, p in out["plan_like"].items():
        assert p["gaits"] == 16 and sum(p["intended_counts"].values()) == 16
        assert set(p["majority_baseline"]) == {"class", "accuracy", "balanced_accuracy", "macro_f1"}
        for kind in RECOGNISERS:
            assert all(0.0 <= p[kind][s] <= 1.0 for s in ("accuracy", "balanced_accuracy", "macro_f1"))
            assert np.asarray(p[kind]["confusion"]).sum() == 16
    for kind in RECOGNISERS:
        t = out["transitions"]["full"][kind]
        assert t["gaits"] == 12 * 2 and 0.0 <= t["rising_fraction"] <= 1.0


def test_previews_and_report(controllability, tmp_path):
    out, previews, _ = controllability
    assert [t.split(" ")[0] for t, _ in previews["emotions"]] == list(EMOTIONS)
    shapes = {p.shape for _, p in previews["emotions"] + previews["transition"]}
    assert shapes == {(60, 21, 3)} and len(previews["transition"]) == 3
    assert not np.allclose(previews["emotions"][0][1], previews["emotions"][1][1])  # the condition moves the gait
    text = "\n".join(controllability_markdown(out))
    assert "Condition sensitivity" in text and "temporal CNN" in text and "plan-like, full" in text
    plot_controllability({"controllability": out}, tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_plan_rows_are_also_read_under_their_dominant_one_hot(controllability):
    out, _, _ = controllability
    one_hot = out["plan_like_dominant_one_hot"]["full"]
    assert one_hot["gaits"] == out["plan_like"]["full"]["gaits"] == 16
    assert one_hot["intended_counts"] == out["plan_like"]["full"]["intended_counts"]
    # with the condition cut, a row's gait is the same under its mixture and under its one-hot: so are the readings
    cut, cut_one_hot = out["plan_like"]["no_affect"], out["plan_like_dominant_one_hot"]["no_affect"]
    for kind in RECOGNISERS:
        assert np.asarray(one_hot[kind]["confusion"]).sum() == 16
        assert cut_one_hot[kind]["confusion"] == cut[kind]["confusion"], kind
    text = "\n".join(controllability_markdown(out))
    for name in ("full", "no_affect"):
        assert f"plan-like under the dominant one-hot, {name}" in text
