"""Reference gaits: a few windows' numbers kept as golden files, so a change in the numbers is seen, not guessed.

Three reference gaits (tests/conftest.py ``REFERENCE_GAITS``: three sources, three styles), ingested from their own
clips (``reference_ingest``: seconds, so these run in the fast tier; the two ``test_reference_clips_*`` tests check,
in the slow tier, that those windows and their annotations are bit for bit the full data's):

  golden/ingest_reference.json      t_start, scale, positions, rotations, heading at frames 0, 29, 59
  golden/annotation_reference.json  every frame's contacts, phase, phase rate, 18 affective and 5 movement features,
                                    as the annotate stage computes them (pipeline/annotate/annotation.py)
  golden/rollout_reference.json     the first generation of a seeded tiny EmotiveGaitNet (untrained) from the
                                    three gaits' 18-frame prefixes: a few joints per frame, the root features

Tolerances (the data are float32): each is a few times what rounding every float32 input by one unit in the last
place moves the number (measured when the files were made), and far below what any real change of a formula, a
parameter or the network moves it (cm, tenths of a radian).

After a deliberate change (new canonical lengths, a retargeting fix, a contact rule, the network), regenerate with
    make golden          (= EMOGAIT_UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/test_golden.py)
and say in the commit why the numbers moved.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import torch

from pipeline.generators.autoregressive.network import EmotiveGaitNet, GeneratorConfig
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths
from pipeline.generators.autoregressive.training import GaitTensors
from pipeline.ops.contacts import CONTACT_POINTS
from pipeline.ops.features import AFFECTIVE_NAMES, MOVEMENT_NAMES
from tests.conftest import REFERENCE_GAITS

GOLDEN = Path(__file__).parent / "golden"
UPDATE = bool(os.environ.get("EMOGAIT_UPDATE_GOLDEN"))
FRAMES = [0, 29, 59]

# annotation: contacts exact; angles (phase, rad) absolute; features |now - golden| <= atol + rtol |golden|
PHASE_ATOL = 1e-5  # rad; compared on the circle (float32 may store a phase just below 2π as 0)
AFFECTIVE_TOL = {"rtol": 1e-4, "atol": 1e-5}  # one-ulp inputs move them <= 6e-6, the near-flat-triangle ratio 2e-5 rel.
MOVEMENT_TOL = {"rtol": 0.0, "atol": 5e-5}  # m, m/frame, rad; one-ulp inputs move them <= 6e-6
# rollout: the stance-foot placement sums rounding over the frames; one-ulp inputs move joints <= 3.4e-5 m in 24 frames
ROLLOUT_POSITION_ATOL = 2e-4  # m
ROLLOUT_ROOT_ATOL = 2e-4  # h (m), s (m/frame), δ and heading (rad)

TINY = GeneratorConfig(affect_layers=(8, 8, 4), movement_layers=(8, 8, 4), gru_hidden=16, versor_hidden=16,
                       root_hidden=8)
TORCH_SEED = 0
PREFIX = 18
STEPS = 24
ROLLOUT_JOINTS = ("root", "head", "left_hand", "right_hand", "left_heel", "right_toe")
PATH = ((0.0, 0.0), (0.0, 1.5), (3.0, 4.5))  # local (x, z): 1.5 m ahead, then 45° to the left


def _check_or_update(name: str, now: dict) -> dict:
    """The golden file's content; with EMOGAIT_UPDATE_GOLDEN set, ``now`` is written to it and the test skips."""
    path = GOLDEN / name
    if UPDATE:
        path.write_text(json.dumps(now, indent=None, separators=(",", ":")) + "\n")
        pytest.skip(f"golden file {path} rewritten")
    golden = json.loads(path.read_text())
    assert golden.get("about") == now.get("about"), f"{name}: what the file holds changed; regenerate it"
    return golden


def _rounded(x: np.ndarray, decimals: int) -> list:
    return np.round(np.asarray(x, dtype=np.float64), decimals).tolist()


def _wrapped(angle: np.ndarray) -> np.ndarray:
    """Angle differences on the circle, in [-π, π)."""
    return np.remainder(angle + math.pi, 2 * math.pi) - math.pi


def _rows(table) -> list[int]:
    ids = table.column("gait_id").to_pylist()
    return [ids.index(gid) for gid in REFERENCE_GAITS]


# --- ingest --------------------------------------------------------------------------------------------------------

def _ingest_snapshot(ingest):
    table, arrays = ingest["table"], ingest["arrays"]
    out = {}
    for gid, k in zip(REFERENCE_GAITS, _rows(table)):
        out[gid] = {
            "t_start": table.column("t_start")[k].as_py(),
            "scale": round(table.column("scale")[k].as_py(), 6),
            "positions": _rounded(arrays["positions"][k][FRAMES], 4),
            "rotations": _rounded(arrays["rotations"][k][FRAMES], 4),
            "heading": _rounded(arrays["heading"][k][FRAMES], 4),
        }
    return out


def test_reference_gaits_are_unchanged(reference_ingest):
    now = _ingest_snapshot(reference_ingest)
    path = GOLDEN / "ingest_reference.json"
    if UPDATE:
        path.write_text(json.dumps(now) + "\n")
        pytest.skip(f"golden file {path} rewritten")
    golden = json.loads(path.read_text())
    assert set(golden) == set(now)
    for gid, ref in golden.items():
        assert now[gid]["t_start"] == ref["t_start"], gid
        assert now[gid]["scale"] == pytest.approx(ref["scale"], abs=1e-6), gid
        for key in ("positions", "rotations", "heading"):
            np.testing.assert_allclose(now[gid][key], ref[key], atol=2e-4, err_msg=f"{gid} {key}")


@pytest.mark.slow
def test_reference_clips_ingest_as_in_the_full_data(reference_ingest, full_ingest):
    """The fast tier's small ingest is no stand-in: every window of the reference clips, bit for bit."""
    clips = set(reference_ingest["table"].column("clip_id").to_pylist())
    full_ids = full_ingest["table"].column("gait_id").to_pylist()
    full_rows = [k for k, cid in enumerate(full_ingest["table"].column("clip_id").to_pylist()) if cid in clips]
    assert [full_ids[k] for k in full_rows] == reference_ingest["table"].column("gait_id").to_pylist()
    for name, values in reference_ingest["arrays"].items():
        assert np.array_equal(full_ingest["arrays"][name][full_rows], values, equal_nan=True), name
    assert full_ingest["table"].take(full_rows).equals(reference_ingest["table"], check_metadata=False)
    assert reference_ingest["report"]["files_ingested"] == reference_ingest["report"]["files_seen"] == len(clips)


@pytest.mark.slow
def test_reference_clips_annotate_as_in_the_full_data(reference_annotated, annotated):
    """Annotation works per clip, so the reference clips alone get the full data's annotations, bit for bit."""
    table, arrays = reference_annotated
    ids = annotated[0].column("gait_id").to_pylist()
    rows = [ids.index(gid) for gid in table.column("gait_id").to_pylist()]
    for name in ("contacts", "phase", "phase_rate", "affective", "movement"):
        assert np.array_equal(annotated[1][name][rows], arrays[name]), name
    assert arrays["clips"] == {cid: annotated[1]["clips"][cid] for cid in arrays["clips"]}


# --- annotation ----------------------------------------------------------------------------------------------------

def _annotation_snapshot(annotated) -> dict:
    table, arrays = annotated
    gaits = {}
    for gid, k in zip(REFERENCE_GAITS, _rows(table)):
        contacts = arrays["contacts"][k]
        assert set(np.unique(contacts)) <= {0.0, 1.0}, gid
        gaits[gid] = {
            "contacts": {p: "".join(str(int(v)) for v in contacts[:, j]) for j, p in enumerate(CONTACT_POINTS)},
            "phase": _rounded(arrays["phase"][k], 6),
            "phase_rate": _rounded(arrays["phase_rate"][k], 7),
            "affective": _rounded(arrays["affective"][k], 6),
            "movement": _rounded(arrays["movement"][k], 7),
        }
    about = {"what": "annotate stage output (pipeline/annotate/annotation.py) of three reference gaits, every frame",
             "contact_points": list(CONTACT_POINTS), "affective_names": list(AFFECTIVE_NAMES),
             "movement_names": list(MOVEMENT_NAMES), "frames": int(arrays["phase"].shape[1])}
    return {"about": about, "gaits": gaits}


def test_reference_annotations_are_unchanged(reference_annotated):
    now = _annotation_snapshot(reference_annotated)
    golden = _check_or_update("annotation_reference.json", now)
    assert set(golden["gaits"]) == set(now["gaits"])
    for gid, ref in golden["gaits"].items():
        got = now["gaits"][gid]
        for point in CONTACT_POINTS:  # 0/1 per frame: exact
            assert got["contacts"][point] == ref["contacts"][point], f"{gid} {point} contacts"
        np.testing.assert_allclose(_wrapped(np.asarray(got["phase"]) - ref["phase"]), 0.0, atol=PHASE_ATOL,
                                   err_msg=f"{gid} phase")
        np.testing.assert_allclose(got["phase_rate"], ref["phase_rate"], rtol=0, atol=PHASE_ATOL,
                                   err_msg=f"{gid} phase_rate")
        np.testing.assert_allclose(got["affective"], ref["affective"], **AFFECTIVE_TOL, err_msg=f"{gid} affective")
        np.testing.assert_allclose(got["movement"], ref["movement"], **MOVEMENT_TOL, err_msg=f"{gid} movement")


# --- the generator's first rollout ---------------------------------------------------------------------------------

def _emotions() -> torch.Tensor:
    """(3, STEPS, 4): happy throughout; angry -> neutral frame by frame; unlabelled (NaN)."""
    e = torch.zeros(len(REFERENCE_GAITS), STEPS, 4)
    e[0, :, 0] = 1.0
    w = torch.linspace(0.0, 1.0, STEPS)
    e[1, :, 2], e[1, :, 3] = 1.0 - w, w
    e[2] = float("nan")
    return e


def _rollout_snapshot(annotated, skeleton) -> dict:
    table, arrays = annotated
    rows = np.array(_rows(table))
    torch.manual_seed(TORCH_SEED)
    model = EmotiveGaitNet(TINY)
    gaits = GaitTensors.from_arrays(arrays)  # every window of the three clips: the input statistics
    model.set_statistics(gaits.affective, gaits.scalars())
    seeds = Seeds.from_arrays(arrays, rows, prefix=PREFIX)
    paths = place_paths(torch.tensor(PATH), seeds)
    out = generate(model, seeds, paths, _emotions(), torch.from_numpy(skeleton.offsets), skeleton.parents,
                   PlacementConfig())
    params = torch.cat([p.detach().double().reshape(-1) for p in model.parameters()])
    joints = [skeleton.index(n) for n in ROLLOUT_JOINTS]
    agents = {}
    for n, gid in enumerate(REFERENCE_GAITS):
        agents[gid] = {"positions": _rounded(out.positions[n][:, joints], 6),
                       **{k: _rounded(getattr(out, k)[n], 7) for k in ("h", "s", "delta", "heading")}}
    about = {"what": "generate() of a seeded untrained tiny EmotiveGaitNet from the reference gaits' prefixes",
             "config": TINY.to_dict(), "torch_seed": TORCH_SEED, "prefix": PREFIX, "steps": STEPS, "path": PATH,
             "emotions": ["happy", "angry -> neutral", "unlabelled"], "joints": list(ROLLOUT_JOINTS)}
    return {"about": json.loads(json.dumps(about)),
            "parameters": {"count": int(params.numel()), "sum": float(params.sum()),
                           "abs_sum": float(params.abs().sum())},
            "agents": agents}


def test_first_rollout_of_a_seeded_tiny_generator_is_unchanged(reference_annotated, skeleton):
    now = _rollout_snapshot(reference_annotated, skeleton)
    golden = _check_or_update("rollout_reference.json", now)
    # the initial weights first: if they moved (torch's initialisation, the layer layout), nothing below can hold
    assert now["parameters"]["count"] == golden["parameters"]["count"]
    for key in ("sum", "abs_sum"):
        assert now["parameters"][key] == pytest.approx(golden["parameters"][key], rel=1e-6, abs=1e-6), key
    assert set(golden["agents"]) == set(now["agents"])
    for gid, ref in golden["agents"].items():
        got = now["agents"][gid]
        np.testing.assert_allclose(got["positions"], ref["positions"], rtol=0, atol=ROLLOUT_POSITION_ATOL,
                                   err_msg=f"{gid} positions")
        for key in ("h", "s", "delta"):
            np.testing.assert_allclose(got[key], ref[key], rtol=0, atol=ROLLOUT_ROOT_ATOL, err_msg=f"{gid} {key}")
        np.testing.assert_allclose(_wrapped(np.asarray(got["heading"]) - ref["heading"]), 0.0, atol=ROLLOUT_ROOT_ATOL,
                                   err_msg=f"{gid} heading")
