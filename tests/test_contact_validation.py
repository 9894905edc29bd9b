"""Foot-contact validation on the real annotated C3D trials: our detector meets the acceptance figures and is
no worse than the Zeni et al. (2008) reference (gaitalytics); the matching and scoring rules themselves."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pipeline.annotate.contact_validation import (
    Event,
    ValidationConfig,
    acceptance,
    match_events,
    score,
    summarize,
    validate,
)
from pipeline.ops.contacts import ContactConfig
from stages import validate_contacts
from stages.configs import contact_config, validation_config
from stages.common import SOURCES, load_params
from tests.conftest import MOCAP

ANNOTATED = {  # file -> annotated foot strikes + foot offs (EVENT group; "Left-FP" force-plate marks excluded)
    "Walk1.c3d": 8,
    "pyCGM2 lower limb CGM24 Walking01.c3d": 17,
    "gait-pig.c3d": 9,
    "sub_labels.c3d": 8,
    "PlugInC3D.c3d": 8,
    "VER4C3D.c3d": 8,
    "Vicon_analysis.c3d": 17,
}


@pytest.fixture(scope="module")
def validation(mocap):
    params = load_params()
    cfg, vcfg = contact_config(params), validation_config(params)
    trials, skipped = validate_contacts.load_trials(MOCAP, SOURCES, vcfg)
    figures, events = validate(trials, cfg, vcfg)
    return {"trials": trials, "skipped": skipped, "figures": figures, "events": events}


def _by_name(per_file):
    return {k.rsplit("/", 1)[-1]: v for k, v in per_file.items()}


def test_every_annotated_trial_is_validated_and_the_rest_say_why(validation):
    assert {t.name.rsplit("/", 1)[-1]: len(t.annotated) for t in validation["trials"]} == ANNOTATED
    reasons = {s["file"].rsplit("/", 1)[-1]: s["reason"] for s in validation["skipped"]}
    assert len(reasons) == 16 - len(ANNOTATED)
    assert "analog samples per point frame" in reasons["evart.c3d"]
    assert all(r == "no annotated foot strike / foot off events" for k, r in reasons.items() if k != "evart.c3d")


def test_our_detector_meets_the_acceptance_figures(validation):
    ours = validation["figures"]["ours"]["overall"]
    assert ours["annotated_events"] == 75 and ours["evaluable_events"] == 73
    assert ours["matched_evaluable_fraction"] >= 0.95
    assert ours["matched_fraction"] >= 0.95  # of all 75, counting the two at which a marker is occluded
    assert ours["median_abs_error_ms"] <= 20.0
    assert ours["p90_abs_error_ms"] <= 35.0
    assert abs(ours["mean_signed_error_ms"]) <= 5.0  # landing hysteresis: strikes neither early nor late
    assert ours["false_events_per_s"] < 0.6
    assert acceptance(validation["figures"])["passed"]


def test_one_speed_threshold_puts_strikes_early(validation):
    """Without the landing hysteresis (landing speed = leaving speed) strikes come early and fewer match."""
    cfg = contact_config(load_params())
    single = ContactConfig(**{**cfg.__dict__, "landing_speed": cfg.max_speed})
    figures, _ = validate(validation["trials"], single, ValidationConfig(), reference=False)
    ours, hyst = figures["ours"]["overall"], validation["figures"]["ours"]["overall"]
    assert ours["mean_signed_error_ms"] < hyst["mean_signed_error_ms"] - 2.0
    assert ours["matched_events"] < hyst["matched_events"]


def test_our_detector_is_no_worse_than_zeni(validation):
    ours = validation["figures"]["ours"]["overall"]
    zeni = validation["figures"]["zeni_gaitalytics"]["overall"]
    assert "errors" not in validation["figures"]["zeni_gaitalytics"]
    assert zeni["annotated_events"] == 75 and zeni["matched_events"] >= 55  # the reference really ran
    assert ours["matched_evaluable_fraction"] >= zeni["matched_evaluable_fraction"]
    assert ours["matched_fraction"] >= zeni["matched_fraction"]
    assert ours["median_abs_error_ms"] <= zeni["median_abs_error_ms"]
    assert ours["p90_abs_error_ms"] <= zeni["p90_abs_error_ms"]
    assert ours["false_events_per_s"] <= zeni["false_events_per_s"]


def test_per_file_figures(validation):
    per_file = _by_name(validation["figures"]["ours"]["per_file"])
    for name, figures in per_file.items():
        assert figures["matched_fraction"] >= 0.85, (name, figures)
        assert figures["median_abs_error_ms"] <= 25.0, (name, figures)
    # the misses that remain are explained in the report: two events at which a marker is occluded ...
    unmatched = [(n, u["kind"], u["side"], u["time"], u["evaluable"]) for n, f in per_file.items()
                 for u in f["unmatched"]]
    assert sorted(unmatched) == [
        ("Vicon_analysis.c3d", "foot_strike", "right", 5.6, False),
        ("gait-pig.c3d", "foot_off", "right", 2.6, False),
        # ... and one right strike of the CGM24 trial annotated at foot flat, 60 ms after the ankle settles
        ("pyCGM2 lower limb CGM24 Walking01.c3d", "foot_strike", "right", 3.33, True),
    ]


def test_derived_events_alternate_and_sit_inside_tracked_data(validation):
    for trial in validation["trials"]:
        for side in ("left", "right"):
            kinds = [e.kind for e in validation["events"]["ours"][trial.name] if e.side == side]
            assert all(a != b for a, b in zip(kinds, kinds[1:])), (trial.name, side, kinds)


def test_matching_is_one_to_one_nearest_first():
    annotated = [Event("foot_strike", "left", 1.00), Event("foot_strike", "left", 1.04)]
    derived = [Event("foot_strike", "left", 1.03), Event("foot_strike", "right", 1.00),
               Event("foot_off", "left", 1.00)]
    assert match_events(annotated, derived, 0.05) == [(1, 0, pytest.approx(-0.01))]
    # float32 event times on the tolerance edge still match
    assert match_events([Event("foot_off", "left", np.float32(3.87))], [Event("foot_off", "left", 3.92)], 0.05)


def test_false_events_count_only_inside_the_annotated_span():
    annotated = [Event("foot_strike", "left", 2.0), Event("foot_strike", "left", 3.0)]
    derived = [Event("foot_strike", "left", 2.01), Event("foot_off", "left", 2.5),  # one false, inside
               Event("foot_strike", "left", 0.5), Event("foot_off", "left", 4.0)]  # outside span ± 0.5 s
    s = summarize(score(annotated, derived, ValidationConfig()))
    assert s["matched_events"] == 1 and s["false_events"] == 1
    assert s["false_events_per_s"] == pytest.approx(1 / 2.0)
    assert s["unmatched"] == [{"kind": "foot_strike", "side": "left", "time": 3.0, "evaluable": True}]


@pytest.mark.slow  # the whole validation again, through the stage
def test_stage_writes_deterministic_report_and_plot(tmp_path, validation):
    report = validate_contacts.main(out_report=tmp_path / "contacts.json", out_plot=tmp_path / "contacts.png")
    text = (tmp_path / "contacts.json").read_text()
    assert json.loads(text) == json.loads(json.dumps(report))
    assert report["detectors"] == json.loads(json.dumps(validation["figures"]))  # same numbers as the library
    assert report["contact_config"] == ContactConfig(**load_params()["annotate"]["contacts"]).__dict__
    assert (tmp_path / "contacts.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
