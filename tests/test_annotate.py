"""Contacts, events and the stepping phase: constructed cases with known answers, and the real walks."""

import math

import numpy as np
import pytest
import torch

from pipeline.annotate.annotation import AnnotateConfig, annotate_clip, rebuild_clips
from pipeline.ops.contacts import ContactConfig, foot_contacts, foot_events, median_filter, phase_rate, stepping_phase


def test_stepping_phase_is_linear_between_strikes():
    theta = stepping_phase(41, left_strikes=[10, 30], right_strikes=[20, 40])
    assert float(theta[10]) == pytest.approx(0.0, abs=1e-12)
    assert float(theta[15]) == pytest.approx(math.pi / 2)
    assert float(theta[20]) == pytest.approx(math.pi)
    assert float(theta[25]) == pytest.approx(1.5 * math.pi)
    assert float(theta[30]) == pytest.approx(0.0, abs=1e-12)
    assert float(theta[5]) == pytest.approx(1.5 * math.pi)  # extrapolated before the first strike
    assert torch.allclose(phase_rate(theta), torch.full((41,), math.pi / 10, dtype=torch.float64))
    assert torch.isnan(stepping_phase(10, [3], [])).all()  # one strike: no cycle, no phase


def test_median_filter_removes_single_frame_flicker():
    flags = torch.tensor([[0], [0], [1], [0], [0], [1], [1], [1], [0], [1], [1]], dtype=torch.bool)
    assert median_filter(flags, 3)[:, 0].tolist() == [0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1]


def test_a_point_lands_below_the_landing_speed_and_leaves_above_the_maximum():
    # one point on the floor (y = 0) decelerating 1.5 -> 0 m/s, resting, then accelerating 0 -> 1.5 m/s
    speed = np.concatenate([np.linspace(1.5, 0.0, 16), np.zeros(10), np.linspace(0.0, 1.5, 16)])
    z = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2 / 10.0)])  # 10 fps
    points = torch.zeros(len(z), 1, 3, dtype=torch.float64)
    points[:, 0, 2] = torch.from_numpy(z)
    cfg = ContactConfig(max_speed=1.0, landing_speed=0.5, median_seconds=0.0)
    down = foot_contacts(points, 10.0, cfg)[:, 0].numpy()
    measured = torch.gradient(points[:, 0, 2], spacing=0.1)[0].numpy()
    first, last = np.flatnonzero(down)[[0, -1]]
    assert measured[first] <= 0.5 < measured[first - 1]  # lands once slower than 0.5 m/s, not at 1.0
    assert measured[last] <= 1.0 < measured[last + 1]  # stays down until faster than 1.0 m/s
    assert down[first:last + 1].all()
    single = foot_contacts(points, 10.0, ContactConfig(max_speed=1.0, landing_speed=1.0, median_seconds=0.0))
    assert np.flatnonzero(single[:, 0].numpy())[0] < first


def _synthetic_walk(fps=100.0, cycles=3, stance=0.6, period=1.0):
    """Heel/toe points that rest on the floor for `stance` of each cycle and swing 10 cm up otherwise."""
    t = np.arange(int(cycles * period * fps)) / fps
    points = np.zeros((len(t), 4, 3))
    for k, offset in enumerate((0.0, 0.0, 0.5, 0.5)):  # left heel/toe, right heel/toe; right half a cycle later
        u = ((t / period) - offset) % 1.0
        swing = u >= stance
        lift = np.where(swing, np.sin(np.pi * (u - stance) / (1 - stance)), 0.0)
        stride = 1.4 * period
        progress = np.floor((t / period) - offset) * stride + np.where(swing, (u - stance) / (1 - stance) * stride, 0)
        points[:, k, 1] = 0.1 * lift + (0.08 if k % 2 == 0 else 0.02)
        points[:, k, 2] = progress
    return torch.from_numpy(points), t


def test_contacts_and_events_on_a_synthetic_walk():
    points, t = _synthetic_walk()
    contacts = foot_contacts(points, 100.0)
    left = (contacts[:, 0] | contacts[:, 1]).double().mean().item()
    assert left == pytest.approx(0.6, abs=0.05)
    events = foot_events(contacts, 100.0)
    # left strikes at the start of each cycle (t = 1.0, 2.0 s), right ones half a cycle later
    assert [round(t[i], 2) for i in events["left_strike"]] == pytest.approx([1.0, 2.0], abs=0.03)
    assert [round(t[i], 2) for i in events["right_strike"]] == pytest.approx([0.5, 1.5, 2.5], abs=0.03)
    assert [round(t[i], 2) for i in events["left_off"]] == pytest.approx([0.6, 1.6, 2.6], abs=0.03)


def _walk_clips(full_ingest, content="walk"):
    t, a = full_ingest["table"], full_ingest["arrays"]
    starts = np.round(t.column("t_start").to_numpy() * 30).astype(int)
    clips = rebuild_clips(t.column("clip_id").to_pylist(), starts, a["positions"], 60)
    contents = dict(zip(t.column("clip_id").to_pylist(), t.column("content").to_pylist()))
    return {cid: clip for cid, (clip, _) in clips.items() if contents[cid] == content}


def test_real_walks_alternate_feet_with_plausible_stance(full_ingest, skeleton):
    cfg = AnnotateConfig()
    stance, alternating, clips = [], 0, _walk_clips(full_ingest)
    for cid, clip in clips.items():
        ann = annotate_clip(torch.from_numpy(clip).double(), skeleton, cfg)
        c = ann["contacts"].numpy()
        stance.append(((c[:, 0] + c[:, 1] > 0).mean() + (c[:, 2] + c[:, 3] > 0).mean()) / 2)
        seq = sorted([(f, "L") for f in ann["events"]["left_strike"]] + [(f, "R") for f in ann["events"]["right_strike"]])
        alternating += all(a[1] != b[1] for a, b in zip(seq, seq[1:])) and len(seq) >= 2
    stance = np.array(stance)
    assert 0.55 <= np.median(stance) <= 0.70, np.median(stance)
    assert np.mean((stance > 0.45) & (stance < 0.8)) > 0.95
    assert alternating >= 0.97 * len(clips), f"{alternating} of {len(clips)} walks alternate"


def test_phase_rises_through_every_cycle_and_marks_the_strikes(full_ingest, skeleton):
    cfg = AnnotateConfig()
    checked = 0
    for cid, clip in list(_walk_clips(full_ingest).items())[::5]:
        ann = annotate_clip(torch.from_numpy(clip).double(), skeleton, cfg)
        theta, omega = ann["phase"], ann["phase_rate"]
        assert torch.isfinite(theta).all(), cid
        assert ((theta >= 0) & (theta < 2 * math.pi)).all()
        assert (omega > 0).all() and (omega < math.pi / 2).all(), f"{cid}: phase must rise steadily"
        strikes = sorted([(f, 0.0) for f in ann["events"]["left_strike"]] + [(f, math.pi) for f in ann["events"]["right_strike"]])
        for (f, value), nxt in zip(strikes, strikes[1:] + [(None, None)]):
            if nxt[1] == value:  # a repeated same-foot strike is not an anchor
                continue
            wrapped = math.remainder(float(theta[f]) - value, 2 * math.pi)
            assert abs(wrapped) < 1e-9, f"{cid}: phase {float(theta[f]):.3f} at a strike meant to be {value:.3f}"
        checked += 1
    assert checked > 30


def test_annotated_table_has_documented_columns(annotated):
    table, arrays = annotated
    assert arrays["contacts"].shape[1:] == (60, 4) and set(np.unique(arrays["contacts"])) <= {0.0, 1.0}
    assert arrays["affective"].shape[1:] == (60, 18) and np.isfinite(arrays["affective"]).all()
    assert arrays["movement"].shape[1:] == (60, 5) and np.isfinite(arrays["movement"]).all()
    phase = arrays["phase"][np.isfinite(arrays["phase"])]
    assert ((phase >= 0) & (phase < 2 * math.pi)).all()
    assert not [c for c, v in arrays["clips"].items() if not v["phase_defined"]]
