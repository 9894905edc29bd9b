"""C3D marker data: the reader on the real c3d.org files, their ingest outcomes, and malformed files built at
run time (truncated header, bad parameter section, truncated data, all-invalid residuals).

The real files are read in place from the mocap root; bad files are written to tmp_path only.
"""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from pipeline.ingest.run import IngestConfig, run_ingest
from pipeline.ingest.markers import fill_short_gaps, harrington_hip_centres, runs
from pipeline.io.readers.c3d import C3dError, positions_m_y_up, read_c3d
from pipeline.io.manifests import load_manifest
from tests.conftest import MOCAP, repo_path

MANIFEST = repo_path("manifests", "sources", "c3d_org_samples.yaml")
ROOT = MOCAP / "c3d_org_samples" / "tests" / "c3d_org_samples"
WALK1 = ROOT / "sample_00" / "Motion Analysis Corporation" / "Walk1.c3d"
EMG = ROOT / "sample_00" / "Innovative Sports Training" / "Gait with EMG.c3d"
FLOAT_INTEL = ROOT / "sample_01" / "Eb015pr.c3d"  # PC REAL format, 26 points, 16 analog channels

# Every pinned file's expected outcome and a fragment its reason must contain.
OUTCOMES = {
    "sample_00/Vicon Motion Systems/pyCGM2 lower limb CGM24 Walking01.c3d": ("filtered", "lower-body only"),
    "sample_00/Motion Analysis Corporation/Walk1.c3d": ("ingested", None),
    "sample_00/Codamotion/codamotion_gaitwands_20150204.c3d": ("filtered", "lower-body only"),
    "sample_00/Innovative Sports Training/Gait with EMG.c3d": ("filtered", "lower-body only"),
    "sample_01/Eb015pi.c3d": ("filtered", "content 'unknown' is not a gait"),
    "sample_01/Eb015pr.c3d": ("filtered", "content 'unknown' is not a gait"),
    "sample_03/gait-raw.c3d": ("filtered", "no upper-body markers for the canonical skeleton"),
    "sample_03/gait-pig.c3d": ("filtered", "no upper-body markers for the canonical skeleton"),
    "sample_04/sub_labels.c3d": ("filtered", "lower-body only"),
    "sample_06/newwalk.c3d": ("filtered", "lower-body only"),
    "sample_09/VER4C3D.c3d": ("filtered", "lower-body only"),
    "sample_09/PlugInC3D.c3d": ("filtered", "lower-body only"),
    "sample_11/evart.c3d": ("quarantined", "analog samples per point frame (17) = ANALOG:RATE / POINT:RATE, "
                                           "found 1000 / 60 = 16.67"),
    "sample_23/Vicon_analysis.c3d": ("filtered", "lower-body only"),
    "sample_26/Walking_Hybrid_1_1.c3d": ("filtered", "lower-body only (marker set qualisys_hybrid)"),
    "sample_30/marche281.c3d": ("filtered", "lower-body only (marker set biogesta)"),
}


@pytest.fixture(scope="module")
def manifest():
    return load_manifest(MANIFEST)


@pytest.fixture(scope="module")
def ingested(manifest, skeleton, ingest_config):
    windows, report = run_ingest([manifest], skeleton, ingest_config, workers=1, progress=False)
    return windows, report


def _entries(report):
    return {e["path"].removeprefix("tests/c3d_org_samples/"): e for e in report["quarantine"] + report["filtered"]}


# --- the real files ---------------------------------------------------------------------------------------------

def test_every_c3d_file_is_accounted_for_with_a_reason(ingested, manifest):
    windows, report = ingested
    assert report["files_seen"] == len(manifest.files) == len(OUTCOMES) == 16
    assert report["files_seen"] == report["files_ingested"] + report["files_quarantined"] + report["files_filtered"]
    entries = _entries(report)
    ingested_files = {w["file"].removeprefix("tests/c3d_org_samples/") for w in windows}
    for rel, (status, fragment) in OUTCOMES.items():
        if status == "ingested":
            assert rel in ingested_files and rel not in entries, rel
            continue
        entry = entries[rel]
        assert entry in (report["quarantine"] if status == "quarantined" else report["filtered"]), rel
        assert fragment in entry["reason"], (rel, entry["reason"])


@pytest.mark.usefixtures("mocap")
def test_malformed_evart_reason_names_the_file_and_expected_vs_found():
    path = ROOT / "sample_11" / "evart.c3d"
    with pytest.raises(C3dError) as info:
        read_c3d(path)
    err = info.value
    assert err.path == str(path) and "17" in err.expected and "16.67" in err.found
    assert str(err).startswith(f"{path}: expected ")


def test_lower_body_reason_lists_the_missing_upper_body_markers(ingested):
    reason = _entries(ingested[1])["sample_03/gait-pig.c3d"]["reason"]
    assert "marker set plug_in_gait" in reason and "head (LFHD, RFHD, LBHD, RBHD)" in reason


def test_full_body_trial_goes_through_retargeting_into_the_gait_table(ingested, skeleton):
    windows, _ = ingested
    assert [w["gait_id"] for w in windows] == [
        "c3d_org_samples/tests/c3d_org_samples/sample_00/Motion Analysis Corporation/Walk1#w000"]
    w = windows[0]
    assert w["positions"].shape == (60, 21, 3) and w["source_fps"] == 60.0 and w["t_start"] == 0.0
    assert 0.75 < w["source_leg_m"] < 1.0  # hip centre (Harrington) -> knee -> ankle of an adult, in metres
    assert w["emotion"] is None and w["label_method"] is None
    feet = w["positions"][:, list(skeleton.foot_joints), 1]
    assert 0.0 <= feet.min() < 0.05 and w["positions"][:, 12, 1].mean() > 1.4  # floor at 0 (clip-wide), head up
    speed = np.linalg.norm(np.diff(w["root_path"], axis=0), axis=1).mean() * 30
    assert 1.0 < speed < 1.6  # SOURCES.md: ~1.28 m/s


@pytest.mark.usefixtures("mocap")
def test_z_up_and_millimetres_become_y_up_metres():
    """Walk1 (mm) and Gait with EMG (POINT:UNITS 'm'): pelvis ~1 m above the heels, walking horizontally."""
    for path, units in ((WALK1, "mm"), (EMG, "m")):
        clip = read_c3d(path)
        assert clip.units == units
        heel = "LHEE" if "LHEE" in clip.labels else "LCAL"
        pelvis = positions_m_y_up(clip.positions[:, clip.index("LASI")], clip.unit_scale_m, "+Z")
        foot = positions_m_y_up(clip.positions[:, clip.index(heel)], clip.unit_scale_m, "+Z")
        height = np.nanmedian(pelvis[:, 1] - foot[:, 1])
        assert 0.75 < height < 1.15, (path.name, height)
        ok = np.flatnonzero(np.isfinite(pelvis).all(-1))
        travel = pelvis[ok[-1]] - pelvis[ok[0]]
        duration = (ok[-1] - ok[0]) / clip.rate
        assert abs(travel[1]) < 0.1 and 1.0 < np.linalg.norm(travel[[0, 2]]) / duration < 1.6, path.name


@pytest.mark.usefixtures("mocap")
def test_subject_prefixed_labels_are_resolved():
    pig = read_c3d(ROOT / "sample_03" / "gait-pig.c3d")
    assert pig.subjects == ("A22",)
    assert "LTOE" in pig.labels and not any(lab.startswith("A22:") for lab in pig.labels)
    assert pig.raw_labels[pig.index("LTOE")] == "A22:LTOE"
    matt = read_c3d(ROOT / "sample_04" / "sub_labels.c3d")
    assert {"RANK", "RTOE", "LANK", "LTOE", "SACR"} <= set(matt.labels)
    assert matt.raw_labels[matt.index("RANK")] == "Matt:RANK"


@pytest.mark.usefixtures("mocap")
def test_duplicated_labels_keep_the_column_with_data_and_drop_ambiguous_ones():
    clip = read_c3d(WALK1)
    assert len(set(clip.labels)) == len(clip.labels)
    assert clip.valid[:, clip.index("RKNE")].all()  # of the two RKNE columns, the one with data
    assert "VMID" not in clip.labels  # three different VMID trajectories: ambiguous
    assert any("'VMID' appears 3 times with different data" in n for n in clip.notes)


@pytest.mark.usefixtures("mocap")
def test_unflagged_zero_samples_are_gaps():
    clip = read_c3d(ROOT / "sample_23" / "Vicon_analysis.c3d")
    k = clip.index("LTOE")
    assert clip.zero_samples["LTOE"] == int((~clip.valid[:, k]).sum()) > 100
    assert np.isnan(clip.positions[~clip.valid[:, k], k]).all()
    finite = clip.positions[np.isfinite(clip.positions).all(-1)]
    assert not (finite == 0).all(-1).any()  # no (0, 0, 0) left as a position


@pytest.mark.usefixtures("mocap")
def test_non_standard_residual_words_are_decoded_and_coordinates_trusted():
    """marche281.c3d: every residual word reads as negative to py-c3d; as 16-bit words it is valid."""
    clip = read_c3d(ROOT / "sample_30" / "marche281.c3d")
    assert clip.valid.all() and np.isfinite(clip.positions).all()
    assert any("non-standard" in n and "0x7f007f00" in n and "coordinates trusted" in n for n in clip.notes)
    heel = positions_m_y_up(clip.positions[:, clip.index("TLNG")], clip.unit_scale_m, "+Z")
    c7 = positions_m_y_up(clip.positions[:, clip.index("C7")], clip.unit_scale_m, "+Z")
    assert 1.3 < np.median(c7[:, 1] - heel[:, 1]) < 1.6  # C7 above the heel of a standing adult
    assert np.abs(np.diff(heel, axis=0)).max() < 0.05  # continuous at 240 Hz: no garbage


@pytest.mark.usefixtures("mocap")
def test_events_in_both_label_styles():
    walk1 = read_c3d(WALK1)  # contexts "LHS", "RTO", labels empty
    assert [(e.kind, e.side) for e in walk1.events[:2]] == [("foot_strike", "left"), ("foot_off", "right")]
    assert walk1.events[0].time == pytest.approx(0.5667, abs=1e-3)
    cgm = read_c3d(ROOT / "sample_00" / "Vicon Motion Systems" / "pyCGM2 lower limb CGM24 Walking01.c3d")
    assert len(cgm.events) == 17 and any("Left-FP/General" in n for n in cgm.notes)
    assert cgm.first_frame == 63 and cgm.start_time == pytest.approx(0.62)


# --- gap filling and joint centres -----------------------------------------------------------------------------

def test_short_interior_gaps_are_filled_long_and_edge_gaps_are_not():
    x = np.tile(np.arange(20.0)[:, None, None], (1, 1, 3))
    x[3:6] = np.nan  # 3 frames: filled
    x[8:16] = np.nan  # 8 frames: too long
    x[18:] = np.nan  # edge: never extrapolated
    out = fill_short_gaps(x, max_frames=4)
    assert np.allclose(out.positions[3:6, 0, 0], [3, 4, 5])
    assert np.isnan(out.positions[8:16]).all() and np.isnan(out.positions[18:]).all()
    assert out.filled.tolist() == [3] and out.long_gaps.tolist() == [1]
    assert runs(np.isfinite(out.positions[:, 0, 0])) == [(0, 8), (16, 18)]


def test_harrington_hip_centres_lie_below_behind_and_inside_the_asis():
    lasi, rasi = np.array([[0.12, 1.0, 0.0]]), np.array([[-0.12, 1.0, 0.0]])  # facing +Z, left on +X
    sacrum = np.array([[0.0, 1.0, -0.16]])
    left, right = harrington_hip_centres(lasi, rasi, sacrum)
    width, depth = 240.0, 160.0  # mm
    assert left[0] == pytest.approx([(0.33 * width + 7.3) / 1000, 1.0 + (-0.30 * width - 10.9) / 1000,
                                      (-0.24 * depth - 9.9) / 1000])
    assert right[0] == pytest.approx(left[0] * [-1, 1, 1])


# --- malformed files, built at run time ------------------------------------------------------------------------

def _truncated_header(data: bytes) -> bytes:
    return data[:300]


def _bad_parameter_section(data: bytes) -> bytes:
    out = bytearray(data)
    start = (out[0] - 1) * 512
    out[start + 4:start + 4 + 32] = b"\xff" * 32  # the first group record: garbage lengths and ids
    return bytes(out)


def _bad_processor(data: bytes) -> bytes:
    out = bytearray(data)
    out[(out[0] - 1) * 512 + 3] = 99
    return bytes(out)


def _truncated_data(data: bytes) -> bytes:
    return data[: len(data) // 2]


def _all_invalid_residuals(data: bytes) -> bytes:
    """Eb015pr (Intel float): every point's 4th word set to -1.0, the C3D flag for 'invalid'."""
    out = bytearray(data)
    data_block, points, analog_words = struct.unpack("<H", data[16:18])[0], data[2] | data[3] << 8, \
        struct.unpack("<H", data[4:6])[0]
    frames = struct.unpack("<H", data[8:10])[0] - struct.unpack("<H", data[6:8])[0] + 1
    frame_bytes = (4 * points + analog_words) * 4
    start = (data_block - 1) * 512
    for f in range(frames):
        for p in range(points):
            at = start + f * frame_bytes + p * 16 + 12
            out[at:at + 4] = struct.pack("<f", -1.0)
    return bytes(out)


BAD = {
    "truncated_header.c3d": (_truncated_header, "expected a 512-byte header block, found a file of 300 bytes"),
    "bad_parameters.c3d": (_bad_parameter_section, "(parameter section)"),
    "bad_processor.c3d": (_bad_processor, "expected processor type 84 (Intel), 85 (DEC) or 86 (MIPS)"),
    "truncated_data.c3d": (_truncated_data, "bytes: truncated after"),
    "all_invalid.c3d": (_all_invalid_residuals, "every residual negative in all 26 points x 450 frames"),
}


@pytest.fixture(scope="module")
def bad_ingest(tmp_path_factory, manifest, skeleton, mocap):
    root = tmp_path_factory.mktemp("c3d_bad")
    base = FLOAT_INTEL.read_bytes()
    doc = yaml.safe_load(MANIFEST.read_text())
    doc["name"] = "c3d_bad"
    doc["globs"] = ["*.c3d"]
    doc["label_rule"] = {"pattern": r"^(?P<trial>.+)\.c3d$", "fixed": {"content": "walk", "style": "plain"},
                         "emotions": []}
    doc["files"] = []
    (root / "c3d_bad").mkdir()
    for name, (corrupt, _) in BAD.items():
        data = corrupt(base)
        (root / "c3d_bad" / name).write_bytes(data)
        doc["files"].append({"path": name, "sha256": hashlib.sha256(data).hexdigest()})
    path = root / "c3d_bad.yaml"
    path.write_text(yaml.safe_dump(doc))
    cfg = IngestConfig(mocap_root=root)
    _, report = run_ingest([load_manifest(path)], skeleton, cfg, workers=1, progress=False)
    return root, report


@pytest.mark.parametrize("name", sorted(BAD))
def test_malformed_c3d_is_quarantined_with_a_reason(bad_ingest, name):
    root, report = bad_ingest
    entries = {e["path"]: e for e in report["quarantine"]}
    assert name in entries, report["filtered"]
    reason = entries[name]["reason"]
    assert reason.startswith(f"malformed C3D: {root / 'c3d_bad' / name}: expected "), reason
    assert BAD[name][1] in reason, reason


@pytest.mark.usefixtures("mocap")
def test_malformed_c3d_raises_c3d_error_never_anything_else():
    base = FLOAT_INTEL.read_bytes()
    rng = np.random.default_rng(7)
    start = (base[0] - 1) * 512
    for _ in range(40):  # random damage to the parameter section: always a C3dError (or a clean read)
        data = bytearray(base)
        for i in rng.integers(start + 4, start + 1500, size=20):
            data[int(i)] = int(rng.integers(0, 256))
        try:
            read_c3d("fuzz.c3d", bytes(data))
        except C3dError as err:
            assert str(err).startswith("fuzz.c3d: expected ")


def test_bad_file_beside_good_ones_does_not_stop_the_good(bad_ingest):
    _, report = bad_ingest
    assert report["files_seen"] == len(BAD) == report["files_quarantined"]


@pytest.mark.usefixtures("mocap")
def test_reader_on_good_float_file_matches_the_int_twin():
    """Eb015pi (INT) and Eb015pr (REAL) hold the same capture: same labels, positions within int resolution."""
    a, b = read_c3d(ROOT / "sample_01" / "Eb015pi.c3d"), read_c3d(FLOAT_INTEL)
    assert a.labels == b.labels and a.rate == b.rate == 50.0
    both = a.valid & b.valid
    assert both.mean() > 0.95
    assert np.nanmax(np.abs(a.positions[both] - b.positions[both])) < 1.0  # mm


def test_files_are_never_copied_into_the_repository():
    tops = [p for p in Path(repo_path()).iterdir() if p.name not in (".venv", ".git", ".dvc")]
    assert not [f for top in tops for f in ([top] if top.is_file() else top.rglob("*")) if f.suffix == ".c3d"]
