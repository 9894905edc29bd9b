"""The ingest report and gait table on the default data: every input accounted for, labels as documented."""

import csv
import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from pipeline.core.emotions import EMOTIONS
from pipeline.io.files import read_meta
from tests.conftest import MOCAP

SOURCES = {"bandai_namco_motiondataset", "cmu_bvh11", "cmu_iclone", "pymo_demo", "bvh_python_tests"}


def test_every_file_is_accounted_for(full_ingest, manifests):
    r = full_ingest["report"]
    assert r["files_seen"] == r["files_ingested"] + r["files_quarantined"] + r["files_filtered"]
    assert r["files_seen"] == sum(len(m.files) for m in manifests.values()) == 361
    assert len(r["quarantine"]) == r["files_quarantined"] and len(r["filtered"]) == r["files_filtered"]
    assert all(e["reason"] for e in r["quarantine"] + r["filtered"])
    for name, s in r["per_source"].items():
        assert s["files_seen"] == s["files_ingested"] + s["files_quarantined"] + s["files_filtered"], name
    assert r["gaits"] == len(full_ingest["windows"]) == sum(s["gaits"] for s in r["per_source"].values())
    assert r["frames_in"] == sum(s["frames_in"] for s in r["per_source"].values())


def test_all_five_bvh_sources_ingest(full_ingest):
    per = full_ingest["report"]["per_source"]
    assert set(per) == SOURCES
    assert all(per[s]["files_ingested"] >= 1 and per[s]["gaits"] >= 1 for s in SOURCES), per


@pytest.mark.usefixtures("mocap")
def test_manifests_pin_the_documented_files():
    rows = {r["local"]: r["sha256"] for r in csv.DictReader(open(MOCAP / "manifest.csv")) if r["kind"] == "bvh"}
    from stages.common import SOURCES as FOLDER
    from pipeline.io.manifests import load_manifests

    pinned = {f"{m.name}/{f.path}": f.sha256 for m in load_manifests(FOLDER, formats=("bvh",))
              for f in m.files}
    assert pinned == rows


def test_bandai_emotion_walks_are_actor_intended_one_hot(full_ingest):
    t = full_ingest["table"]
    emotion = full_ingest["arrays"]["emotion"]
    files, methods = t.column("file").to_pylist(), t.column("label_method").to_pylist()
    expected = {"happy": 0, "sad": 1, "angry": 2, "normal": 3}
    seen = set()
    for k, f in enumerate(files):
        name = f.rsplit("/", 1)[-1]
        if not name.startswith("dataset-1_walk_"):
            continue
        style = name.split("_")[2]
        if style in expected:
            assert methods[k] == "actor_intended", f
            np.testing.assert_array_equal(emotion[k], np.eye(4, dtype=np.float32)[expected[style]])
            seen.add(style)
        else:
            assert methods[k] is None and np.isnan(emotion[k]).all(), f"{f}: style {style} must stay unlabelled"
    assert seen == set(expected)


def test_labels_always_say_how_they_were_made(full_ingest):
    t = full_ingest["table"]
    emotion = full_ingest["arrays"]["emotion"]
    methods = np.array([m is not None for m in t.column("label_method").to_pylist()])
    labelled = ~np.isnan(emotion).any(axis=1)
    assert (methods == labelled).all()
    np.testing.assert_allclose(emotion[labelled].sum(axis=1), 1.0)
    assert set(t.column("label_method").drop_null().to_pylist()) <= {"actor_intended", "style_mapping"}


def test_schema_metadata_describes_the_arrays(full_ingest, skeleton):
    meta = read_meta(full_ingest["path"])
    assert meta["shapes"]["positions"] == [60, 21, 3] and meta["shapes"]["rotations"] == [60, 21, 4]
    assert meta["joint_names"] == list(skeleton.names) and meta["emotion_order"] == list(EMOTIONS)
    schema = pq.read_schema(full_ingest["path"])
    assert schema.field("positions").type.list_size == 60 * 21 * 3
    windows = full_ingest["windows"]
    ids = [w["gait_id"] for w in windows]
    assert len(set(ids)) == len(ids) and ids == sorted(ids)
    for w in windows[:50]:
        assert abs((w["t_end"] - w["t_start"]) - 59 / 30) < 1e-9


def test_report_is_json_serialisable(full_ingest):
    json.dumps(full_ingest["report"])


def test_missing_mocap_root_stops_with_what_to_fetch(tmp_path):
    import pytest
    import yaml

    from stages import ingest
    from stages.common import PARAMS

    params = yaml.safe_load(PARAMS.read_text())
    params["data"]["mocap_root"] = str(tmp_path / "nowhere")
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(params))
    with pytest.raises(SystemExit) as stop:
        ingest.main(path, out_gaits=tmp_path / "g.parquet", out_report=tmp_path / "r.json",
                    out_preview=tmp_path / "p.png")
    message = str(stop.value.code)
    assert "does not exist" in message and "BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset" in message
    assert "74ead3ba1ae4696404e6086233779f60de8bf9ef" in message and "350 files" in message
    assert not (tmp_path / "g.parquet").exists()
