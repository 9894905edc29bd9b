"""Pose discontinuities and drifting floors, built at run time from real clips of the three BVH skeleton families
(Bandai Namco at 30 fps, CMU 131 at 120 fps, PyMO's demo at 120 fps) and ingested through the real ingest.

Each real clip is written back through one formatter (so that the clean clip and its edited copies parse from the
same numbers), then edited: a T-pose frame (every rotation channel 0) before its first frame or after its last, a
teleported frame in the middle (the root 1 m aside), and, for the floor, the root raised along the walk (a 3°
tilted floor), over the clip (15 cm drift) or halfway (a 5 cm step). All copies of a family are the files of one
temporary source, ingested by one ``run_ingest`` (as the default data is).
"""

from __future__ import annotations

import copy
import hashlib
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from pipeline.core.skeleton import load_skeleton
from pipeline.ingest.run import IngestConfig, run_ingest
from pipeline.io.manifests import load_manifest
from pipeline.io.readers.bvh import read_bvh
from pipeline.ops.floor import FloorConfig, fit_floor
from pipeline.viz.stick_figures import render_floor_models
from stages.common import REPO, SKELETON
from tests.conftest import MOCAP

FAMILIES = {  # source: a walk of it
    "bandai_namco_motiondataset": "dataset/Bandai-Namco-Research-Motiondataset-1/data/dataset-1_walk_happy_001.bvh",
    "cmu_bvh11": "resources/131_01.bvh",
    "pymo_demo": "demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh",
}
ARRAYS = ("positions", "rotations", "root_path", "heading")
TOLERANCE_M = FloorConfig().tolerance_m


def _header(path: Path, frames: int) -> str:
    """The file's text up to its Frame Time line, with the frame count set."""
    lines = path.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.strip().startswith("Frame Time"))
    head = [f"Frames: {frames}" if line.strip().startswith("Frames") else line for line in lines[:at + 1]]
    return "\n".join(head) + "\n"


def _bvh(path: Path, motion: np.ndarray) -> bytes:
    body = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in motion)
    return (_header(path, len(motion)) + body + "\n").encode()


def _variants(source: str, path: Path) -> dict[str, bytes]:
    clip = read_bvh(path)
    motion = np.asarray(clip.motion, dtype=np.float64)
    channels = [c for joint in clip.skeleton.channels for c in joint]
    assert len(channels) == motion.shape[1]
    position = np.array([c.endswith("position") for c in channels])
    # the joint whose position channels travel (Bandai's ROOT is a static joint above the moving hips)
    starts = np.cumsum([0] + [len(joint) for joint in clip.skeleton.channels])
    moving = max((j for j, joint in enumerate(clip.skeleton.channels) if "Xposition" in joint),
                 key=lambda j: np.ptp(motion[:, starts[j] + clip.skeleton.channels[j].index("Xposition")]))
    root_x, root_y, root_z = (starts[moving] + clip.skeleton.channels[moving].index(f"{a}position") for a in "XYZ")
    manifest = yaml.safe_load((REPO / "manifests/sources" / f"{source}.yaml").read_text())
    metre = 1.0 / manifest["unit_scale_m"]  # source units per metre
    t_pose = np.where(position, motion[0], 0.0)
    rest = np.where(position, motion[-1], 0.0)
    middle = len(motion) // 2
    teleport = motion.copy()
    teleport[middle, root_x] += metre
    ground = motion[:, [root_x, root_z]] - motion[0, [root_x, root_z]]
    along = ground @ (ground[-1] / np.linalg.norm(ground[-1]))  # distance along the walk's overall direction
    raised = {"tilted_3deg": math.tan(math.radians(3.0)) * along,
              "drift_15cm": 0.15 * metre * np.arange(len(motion)) / (len(motion) - 1),
              "step_5cm": 0.05 * metre * (np.arange(len(motion)) >= middle)}
    out = {"clean": motion, "t_pose_first": np.vstack([t_pose, motion]), "rest_pose_last": np.vstack([motion, rest]),
           "teleport": teleport}
    for name, lift in raised.items():
        edited = motion.copy()
        edited[:, root_y] += lift
        out[name] = edited
    return {name: _bvh(path, m) for name, m in out.items()}


@pytest.fixture(scope="module", params=sorted(FAMILIES))
def family(request, tmp_path_factory, mocap):
    source = request.param
    path = MOCAP / source / FAMILIES[source]
    root = tmp_path_factory.mktemp(source)
    folder = root / f"repair_{source}"
    folder.mkdir()
    pins = []
    for name, data in _variants(source, path).items():
        (folder / f"{name}.bvh").write_bytes(data)
        pins.append({"path": f"{name}.bvh", "sha256": hashlib.sha256(data).hexdigest()})
    doc = copy.deepcopy(yaml.safe_load((REPO / "manifests/sources" / f"{source}.yaml").read_text()))
    doc.update(name=f"repair_{source}", globs=["*.bvh"], files=pins, gait_contents=["walk"],
               label_rule={"pattern": r"^(?P<case>[a-z0-9_]+)\.bvh$", "fixed": {"content": "walk", "style": "test"},
                           "emotions": []})
    doc.pop("joint_map_overrides", None)
    (root / f"repair_{source}.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    manifest = load_manifest(root / f"repair_{source}.yaml")
    cfg = IngestConfig(mocap_root=root, target_fps=30, window=60, stride=30, min_gait_speed=0.2, chunk_frames=10 ** 6)
    windows, report, floors = run_ingest([manifest], load_skeleton(SKELETON), cfg, workers=1, progress=False,
                                         floor_series=True)
    by_case: dict[str, list[dict]] = {}
    for w in windows:
        by_case.setdefault(Path(w["file"]).stem, []).append(w)
    return SimpleNamespace(source=source, windows=by_case, report=report, floors=floors,
                           frame_time=read_bvh(path).frame_time)


def _events(report: dict, case: str) -> list[dict]:
    return [e for e in report["discontinuities"]["events"] if e["path"] == f"{case}.bvh"]


def _same_windows(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b) > 0
    for x, y in zip(a, b):
        assert x["gait_id"].split("/")[-1].split("#")[1] == y["gait_id"].split("/")[-1].split("#")[1]
        for name in ARRAYS:
            assert x[name].tobytes() == y[name].tobytes(), (x["gait_id"], name)


def test_clean_clip_has_no_discontinuity_and_a_level_floor(family):
    assert _events(family.report, "clean") == []
    clips = [c for c in family.report["floor"]["clips"] if c["path"] == "clean.bvh"]
    assert len(clips) == 1 and family.windows["clean"]


@pytest.mark.parametrize("case, frame, action", [("t_pose_first", 0, "trimmed at the start"),
                                                 ("rest_pose_last", None, "trimmed at the end")])
def test_a_pose_frame_at_either_end_is_trimmed_and_the_windows_equal_the_clean_clip(family, case, frame, action):
    events = _events(family.report, case)
    assert len(events) == 1 and events[0]["action"] == action, events
    if frame is not None:
        assert events[0]["frame"] == frame and events[0]["speed_mps"] > 15.0
    _same_windows(family.windows[case], family.windows["clean"])
    shift = family.frame_time if case == "t_pose_first" else 0.0
    for x, y in zip(family.windows[case], family.windows["clean"]):
        assert x["t_start"] == pytest.approx(y["t_start"] + shift, abs=1e-9)


def test_a_teleported_frame_cuts_the_clip_in_two_and_is_reported(family):
    events = _events(family.report, "teleport")
    assert [e["action"] for e in events] == ["frames dropped around it"] * 2, events
    assert events[1]["frame"] == events[0]["frame"] + 1  # the teleported frame alone between the two steps
    clips = sorted({w["clip_id"] for w in family.windows["teleport"]})
    assert [c.rsplit("@", 1)[1] for c in clips] == ["1", "2"]
    first = [w for w in family.windows["teleport"] if w["clip_id"].endswith("@1")]
    clean_span = [w for w in family.windows["clean"] if w["t_end"] <= first[-1]["t_end"] + 1e-9]
    assert len(first) == len(clean_span)
    for x, y in zip(first, clean_span):  # the frames before the teleport are the clean clip's (on its own floor)
        assert x["rotations"].tobytes() == y["rotations"].tobytes()
        assert x["root_path"].tobytes() == y["root_path"].tobytes()


@pytest.mark.parametrize("case", ["tilted_3deg", "drift_15cm", "step_5cm"])
def test_a_floor_that_tilts_drifts_or_steps_is_followed(family, case):
    clips = [c for c in family.report["floor"]["clips"] if c["path"] == f"{case}.bvh"]
    assert len(clips) == 1 and clips[0]["floor"] == "trend", clips
    lowest = np.array([w["positions"][:, [3, 4, 7, 8], 1].min() for w in family.windows[case]])
    clean = np.array([w["positions"][:, [3, 4, 7, 8], 1].min() for w in family.windows["clean"]])
    # every window within ±2 cm (measured: at most 1.4 cm, a Bandai Namco window on the tilted floor)
    assert np.abs(lowest).max() <= TOLERANCE_M, lowest
    assert np.abs(clean).max() <= TOLERANCE_M
    if case == "drift_15cm":  # on top of the clip's own (a real floor may drift a few cm already)
        own = next(c for c in family.report["floor"]["clips"] if c["path"] == "clean.bvh")["drift_cm"]
        assert 13.0 <= clips[0]["drift_cm"] <= 15.0 + own + 3.0, (clips, own)


def _stance_heights(seconds: float, fps: float = 30.0) -> np.ndarray:
    """The lowest foot point of a walk on a level floor: at the floor in stance, up to 4 cm in double-limb
    transfer, twice a second (a step), with 3 mm of marker jitter."""
    t = np.arange(int(seconds * fps)) / fps
    jitter = np.random.default_rng(0).normal(0.0, 0.003, len(t))
    return 0.02 * (1.0 - np.cos(2.0 * np.pi * 2.0 * t)) + np.abs(jitter)


def test_a_foot_dipping_for_a_second_is_not_a_floor_step():
    # CMU 131_02's stance toe sinks 6 cm for a second of a high kick; a floor that followed it would drop the body
    lowest = _stance_heights(10.0)
    dipped = lowest.copy()
    dipped[30:60] -= 0.06
    ground = np.zeros((len(lowest), 2))
    model = fit_floor(dipped, ground, 30.0)
    assert model.kind == "level" and model.drift_m == 0.0
    assert abs(model.heights[0] - fit_floor(lowest, ground, 30.0).heights[0]) < 0.005


def test_a_floor_step_is_followed_on_both_sides():
    lowest = _stance_heights(10.0)
    lowest[150:] += 0.05
    model = fit_floor(lowest, np.zeros((len(lowest), 2)), 30.0)
    assert model.kind == "trend" and 0.04 <= model.drift_m <= 0.06
    corrected = lowest - model.heights
    for a in range(0, len(lowest), 60):  # every two seconds a stance foot stands on the floor
        assert abs(corrected[a:a + 60].min()) <= 0.01, (a, corrected[a:a + 60].min())


def test_the_floor_plot_draws_each_trend_clip_raw_and_corrected(family, tmp_path):
    skeleton = load_skeleton(SKELETON)
    by_case = {clip_id.rsplit("/", 1)[-1]: (lowest, floor, positions) for clip_id, lowest, floor, positions in
               family.floors}
    assert {"tilted_3deg", "drift_15cm", "step_5cm"} <= set(by_case)
    for lowest, floor, positions in by_case.values():
        # the corrected clip's lowest foot point is the raw one less the floor (both above the raw clip's lowest)
        corrected = positions[:, list(skeleton.foot_joints), 1].min(axis=1)
        np.testing.assert_allclose(corrected, lowest - floor, atol=2e-5)
    out = tmp_path / "floor.png"
    render_floor_models(family.floors, 30.0, out, skeleton)
    first = out.read_bytes()
    render_floor_models(family.floors, 30.0, out, skeleton)
    assert first[:8] == b"\x89PNG\r\n\x1a\n" and out.read_bytes() == first


def test_the_step_search_fits_all_its_candidates_at_once_as_it_would_one_by_one():
    # the batched LOWESS (every candidate cut's two sides in one array) must equal a fit of each side alone
    from pipeline.ops.floor import _candidate_fits, _lowess, _median
    rng = np.random.default_rng(1)
    values = rng.normal(size=(40, 9))
    counts = rng.integers(1, 10, size=40)
    expected = [np.median(row[:c]) for row, c in zip(values, counts)]
    assert np.array_equal(_median(np.where(np.arange(9) < counts[:, None], values, np.inf), counts), expected)
    t = np.arange(14) * 0.5
    heights = 0.01 * rng.normal(size=14) + np.where(t > 3.2, 0.05, 0.0)  # a 5 cm step, jittered
    ks = np.arange(4, 11)
    before, after = t[ks - 1] + 0.1, t[ks] - 0.1
    split, jump = _candidate_fits(t, heights, ks, before, after, sigma=1.0, block=14 * 14 * 2)  # 2 per block
    for i, k in enumerate(ks):
        left, _ = _lowess(t[:k], heights[:k], np.append(t[:k], before[i]), 1.0)
        right, _ = _lowess(t[k:], heights[k:], np.append(after[i], t[k:]), 1.0)
        assert split[i] == pytest.approx(np.abs(heights - np.concatenate([left[:-1], right[1:]])).max(), abs=1e-12)
        assert jump[i] == pytest.approx(abs(right[0] - left[-1]), abs=1e-12)
    assert ks[np.argmin(split)] == 7  # the cut at the step (between t = 3.0 and 3.5) explains the samples best
