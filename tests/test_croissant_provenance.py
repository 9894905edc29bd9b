"""The Croissant 1.1 and PROV-JSON documents of a published directory, built from real gaits.

The directory is written with the project's own writers: real annotated gaits from ``data/split`` plus two
synthetic-looking ones, with every lineage column of the published contract (nullable where it does not
apply). Croissant is checked by the real ``mlcroissant`` validator and loader; PROV by its structure, against
the repository's own ``dvc.lock``.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import mlcroissant as mlc
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
import yaml

from pipeline.publish.croissant import (CROISSANT_NAME, croissant_metadata, croissant_problems, write_croissant)
from pipeline.dataset import read_table, verify, write_hdf5_atomic, write_sha256sums
from pipeline.io.files import write_parquet
from pipeline.io.gait_table import array_column, column_array
from pipeline.publish.provenance import PROVENANCE_NAME, holds, prov_document, write_provenance
from stages.common import REPO
from stages.lineage import stage_graph

LOCK = REPO / "dvc.lock"
MLCROISSANT = Path(sys.executable).parent / "mlcroissant"
ARRAYS = ("positions", "rotations", "root_path", "heading", "contacts", "phase", "phase_rate", "affective", "movement")
CHECKPOINT = "ab" * 32
RECIPE = json.dumps({"kind": "constant", "emotion": [0.0, 0.0, 1.0, 0.0]})


def _real_sample(table: pa.Table) -> tuple[pa.Table, dict]:
    """Two labelled and two unlabelled real gaits, from different sources (the annotated table, with a split)."""
    if "split" not in table.column_names:
        table = table.append_column("split", pa.array(["train"] * table.num_rows, pa.string()))
    labelled = np.flatnonzero(pc.is_valid(table.column("emotion")).to_numpy(zero_copy_only=False))
    unlabelled = np.flatnonzero(pc.is_null(table.column("emotion")).to_numpy(zero_copy_only=False))
    sources = table.column("source").to_pylist()
    rows = [labelled[0], next(i for i in labelled if sources[i] != sources[labelled[0]]),
            unlabelled[0], next(i for i in unlabelled if sources[i] != sources[unlabelled[0]])]
    return table.take(rows), json.loads(table.schema.metadata[b"emogait"])


def strings(real_values: list, synthetic_values: list) -> pa.Array:
    return pa.array(list(real_values) + list(synthetic_values), pa.string())


def _published_table(annotated_table: pa.Table) -> tuple[pa.Table, dict]:
    """Real gaits plus two synthetic ones (arrays borrowed from real gaits, lineage of a generator)."""
    real, meta = _real_sample(annotated_table)
    n_real, n_synth = real.num_rows, 2
    shapes = meta["shapes"]
    arrays = {name: column_array(real, name, shapes[name]) for name in ARRAYS}
    emotion = column_array(real, "emotion", shapes["emotion"])
    labelled = ~np.isnan(emotion).any(1)
    synthetic_emotion = np.eye(4, dtype=np.float32)[[2, 1]]
    all_emotion = np.concatenate([np.nan_to_num(emotion), synthetic_emotion])
    unlabelled = np.concatenate([~labelled, np.zeros(n_synth, bool)])
    window = shapes["positions"][0]
    columns = {
        "gait_id": strings(real.column("gait_id").to_pylist(), ["synthetic/000000", "synthetic/000001"]),
        "kind": strings(["real"] * n_real, ["synthetic"] * n_synth),
        "split": strings(real.column("split").to_pylist(), ["synthetic"] * n_synth),
        "source": strings(real.column("source").to_pylist(), ["generator"] * n_synth),
        "content": strings(real.column("content").to_pylist(), ["walk"] * n_synth),
        "label_method": strings(real.column("label_method").to_pylist(), ["conditioned"] * n_synth),
        "emotion": array_column(all_emotion, unlabelled),
        "emotion_per_frame": array_column(np.repeat(all_emotion[:, None], window, 1), unlabelled),
        **{name: array_column(np.concatenate([values, values[:n_synth]])) for name, values in arrays.items()},
        "source_file": strings(real.column("file").to_pylist(), [None] * n_synth),
        "source_sha256": strings(real.column("sha256").to_pylist(), [None] * n_synth),
        "t_start": pa.array(real.column("t_start").to_pylist() + [None] * n_synth, pa.float64()),
        "t_end": pa.array(real.column("t_end").to_pylist() + [None] * n_synth, pa.float64()),
        "checkpoint_sha256": strings([None] * n_real, [CHECKPOINT] * n_synth),
        "seed_gait_id": strings([None] * n_real, real.column("gait_id").to_pylist()[:n_synth]),
        "trajectory_id": strings([None] * n_real, ["line/0", "circle/1"]),
        "trajectory_family": strings([None] * n_real, ["line", "circle"]),
        "emotion_recipe": strings([None] * n_real, [RECIPE] * n_synth),
        "plan_seed": pa.array([None] * n_real + [11, 12], pa.int64()),
    }
    meta = {**meta, "shapes": {**shapes, "emotion_per_frame": [window, 4]}}
    table = pa.table(columns).replace_schema_metadata({b"emogait": json.dumps(meta, sort_keys=True).encode()})
    return table, meta


def _describe(table: pa.Table) -> dict:
    return dict(name="emogait-test", description="Real and synthetic emotive gaits (test sample).", version="0.1.0",
                license="https://creativecommons.org/licenses/by/4.0/", citation="@misc{emogait, title={emogait}}",
                url="https://example.org/emogait", date_published="2025-01-01",
                creators=[{"@type": "sc:Organization", "name": "emogait"}],
                rai={"dataCollection": "Public motion capture, retargeted and cut into 60-frame windows.",
                     "dataAnnotationProtocol": "Emotion labels from each source's file-name rule; synthetic "
                                               "gaits carry the emotion they were conditioned on.",
                     "dataAnnotationPlatform": "none (rule-based)", "annotationsPerItem": "1",
                     "dataBiases": "Few actors; staged emotions.", "dataUseCases": "Training and evaluation."},
                column_descriptions={name: f"The gait's {name.replace('_', ' ')}." for name in table.column_names})


def _publish(directory: Path, table: pa.Table, meta: dict, shards: int = 1) -> dict:
    directory.mkdir(parents=True, exist_ok=True)
    if shards == 1:
        write_parquet(table, directory / "gaits.parquet")
    else:
        bounds = np.linspace(0, table.num_rows, shards + 1).astype(int)
        for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            write_parquet(table.slice(a, b - a), directory / f"gaits-{k:05d}.parquet")
    write_hdf5_atomic(table, {}, directory / "gaits.h5", meta)
    (directory / "README.md").write_text("# emogait test sample\n", encoding="utf-8")
    (directory / "previews").mkdir(exist_ok=True)
    (directory / "previews" / "gait_0.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(32)))
    doc = croissant_metadata(directory, **_describe(table))
    write_croissant(directory, doc)
    return doc


@pytest.fixture(scope="module")
def sample(annotated) -> tuple[pa.Table, dict]:
    return _published_table(annotated[0])


@pytest.fixture(scope="module")
def published(sample, tmp_path_factory) -> tuple[Path, dict]:
    directory = tmp_path_factory.mktemp("published") / "synthesized_emotive_gaits"
    doc = _publish(directory, *sample)
    write_provenance(directory / PROVENANCE_NAME, prov_document(stage_graph(REPO, LOCK), REPO, directory))
    write_sha256sums(directory)
    return directory, doc


def _sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _validate(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(MLCROISSANT), "validate", "--jsonld", str(path)], capture_output=True, text=True,
                          timeout=300)


def _issues(output: str) -> list[str]:
    """absl's warning/error lines (W..., E..., F...) and mlcroissant's issue report."""
    return [line for line in output.splitlines() if re.match(r"[WEF]\d{4} ", line) or "Found the following" in line]


# ---------------------------------------------------------------------------------------------- Croissant

def test_the_fixture_is_a_sound_published_directory(published, sample):
    directory, _ = published
    assert verify(directory) == []
    table, _ = read_table(directory)
    assert table.column("kind").to_pylist().count("synthetic") == 2
    assert table.column("emotion").null_count == 2  # the two unlabelled real gaits


def test_mlcroissant_validate_passes_without_errors_or_warnings(published):
    directory, _ = published
    result = _validate(directory / CROISSANT_NAME)
    assert result.returncode == 0, result.stderr
    assert _issues(result.stdout + result.stderr) == []


def test_mlcroissant_reads_the_records_the_parquet_file_holds(published, sample):
    directory, _ = published
    table, meta = sample
    dataset = mlc.Dataset(jsonld=directory / CROISSANT_NAME)
    assert not dataset.metadata.ctx.issues.errors and not dataset.metadata.ctx.issues.warnings
    records = list(dataset.records("gaits"))
    assert [r["gaits/gait_id"].decode() for r in records] == table.column("gait_id").to_pylist()
    assert [r["gaits/kind"].decode() for r in records] == table.column("kind").to_pylist()
    assert [r["gaits/plan_seed"] for r in records][-2:] == [11, 12]
    positions = column_array(table, "positions", meta["shapes"]["positions"])
    for i, record in enumerate(records):
        np.testing.assert_array_equal(np.asarray(record["gaits/positions"], np.float32).reshape(60, 21, 3),
                                      positions[i])
    emotion = table.column("emotion").to_pylist()
    assert [r["gaits/emotion"] is None for r in records] == [e is None for e in emotion]
    for record, expected in zip(records, emotion):
        if expected is not None:
            np.testing.assert_allclose(record["gaits/emotion"], expected, rtol=0, atol=1e-7)


def test_every_parquet_column_is_one_field_with_its_type_shape_and_units(published, sample):
    directory, doc = published
    table, meta = sample
    fields = {f["@id"].removeprefix("gaits/"): f for f in doc["recordSet"][0]["field"]}
    assert list(fields) == table.column_names
    assert all(f["source"]["extract"]["column"] == name for name, f in fields.items())
    for name, shape in meta["shapes"].items():
        assert fields[name]["isArray"] is True
        assert fields[name]["arrayShape"] == ",".join(map(str, shape))
        assert fields[name]["dataType"] == "sc:Float"
    assert fields["positions"]["arrayShape"] == "60,21,3"
    assert fields["emotion_per_frame"]["arrayShape"] == "60,4"
    assert {fields[c]["dataType"] for c in ("gait_id", "kind", "emotion_recipe")} == {"sc:Text"}
    assert (fields["t_start"]["dataType"], fields["plan_seed"]["dataType"]) == ("sc:Float", "sc:Integer")
    assert "isArray" not in fields["t_start"]
    assert fields["positions"]["description"].endswith("Units: m.")
    assert doc["recordSet"][0]["key"] == {"@id": "gaits/gait_id"}
    assert doc["conformsTo"] == "http://mlcommons.org/croissant/1.1"
    assert doc["rai:dataAnnotationProtocol"].startswith("Emotion labels")


def test_file_checksums_are_the_files_and_the_document_agrees_with_them(published):
    directory, doc = published
    objects = {o["@id"]: o for o in doc["distribution"]}
    assert set(objects) == {"gaits.parquet", "gaits.h5"}
    sums = dict(line.split("  ")[::-1] for line in (directory / "SHA256SUMS").read_text().splitlines())
    for name, item in objects.items():
        assert item["sha256"] == sums[name] == _sha256_of(directory / name) and item["contentUrl"] == name
    assert (objects["gaits.parquet"]["encodingFormat"], objects["gaits.h5"]["encodingFormat"]) == (
        "application/x-parquet", "application/x-hdf5")
    assert croissant_problems(directory, doc) == []


def test_the_same_directory_gives_the_same_bytes(published, sample):
    directory, doc = published
    first = (directory / CROISSANT_NAME).read_bytes()
    write_croissant(directory, croissant_metadata(directory, **_describe(sample[0])))
    assert (directory / CROISSANT_NAME).read_bytes() == first
    assert first.endswith(b"}\n") and json.loads(first.decode("utf-8")) == doc


def test_shards_are_a_file_set_read_in_order(sample, tmp_path):
    table, meta = sample
    doc = _publish(tmp_path, table, meta, shards=2)
    kinds = {o["@id"]: o["@type"] for o in doc["distribution"]}
    assert kinds == {"gaits-00000.parquet": "cr:FileObject", "gaits-00001.parquet": "cr:FileObject",
                     "gaits-parquet-shards": "cr:FileSet", "gaits.h5": "cr:FileObject"}
    assert doc["recordSet"][0]["field"][0]["source"]["fileSet"] == {"@id": "gaits-parquet-shards"}
    result = _validate(tmp_path / CROISSANT_NAME)
    assert result.returncode == 0 and _issues(result.stdout + result.stderr) == [], result.stderr
    records = mlc.Dataset(jsonld=tmp_path / CROISSANT_NAME).records("gaits")
    assert [r["gaits/gait_id"].decode() for r in records] == table.column("gait_id").to_pylist()
    assert croissant_problems(tmp_path, doc) == []


def test_parts_are_record_sets_of_their_own(sample, tmp_path):
    """Shards of the real gaits and of each generator family (``gaits-<n>-<part>.parquet``): one FileSet and one
    record set per part beside ``gaits``; mlcroissant validates them and reads each part's gaits alone."""
    table, meta = sample
    n_real = table.column("kind").to_pylist().count("real")
    generator = pa.array([None] * n_real + ["fam_a", "fam_b"], pa.string())
    table = table.append_column("generator", generator)
    parts = {"real": (0, n_real), "fam_a": (n_real, 1), "fam_b": (n_real + 1, 1)}
    shards = {}
    for k, (part, (first, rows)) in enumerate(parts.items()):
        shards[part] = [f"gaits-{k:03d}-{part}.parquet"]
        write_parquet(table.slice(first, rows), tmp_path / shards[part][0])
    write_hdf5_atomic(table, {}, tmp_path / "gaits.h5", meta)
    doc = croissant_metadata(tmp_path, **_describe(table), parts=shards)
    write_croissant(tmp_path, doc)
    assert [rs["@id"] for rs in doc["recordSet"]] == ["gaits", "real", "fam_a", "fam_b"]
    assert {o["@id"]: o["includes"] for o in doc["distribution"] if o["@type"] == "cr:FileSet"} == {
        "gaits-parquet-shards": "gaits-*.parquet", "gaits-real": "gaits-*-real.parquet",
        "gaits-fam_a": "gaits-*-fam_a.parquet", "gaits-fam_b": "gaits-*-fam_b.parquet"}
    assert croissant_problems(tmp_path, doc) == []
    result = _validate(tmp_path / CROISSANT_NAME)
    assert result.returncode == 0 and _issues(result.stdout + result.stderr) == [], result.stderr
    dataset = mlc.Dataset(jsonld=tmp_path / CROISSANT_NAME)
    ids = table.column("gait_id").to_pylist()
    assert [r["fam_b/gait_id"].decode() for r in dataset.records("fam_b")] == ids[n_real + 1:]
    assert [r["real/gait_id"].decode() for r in dataset.records("real")] == ids[:n_real]
    # a part's record set that lost a field is a problem
    del doc["recordSet"][2]["field"][1]
    assert any("record set 'fam_a'" in p for p in croissant_problems(tmp_path, doc))


def _missing_column(doc):
    doc["recordSet"][0]["field"][3]["source"]["extract"]["column"] = "emotion_label"


def _wrong_shape(doc):
    next(f for f in doc["recordSet"][0]["field"] if f["name"] == "positions")["arrayShape"] = "60,21,4"


def _stale_checksum(doc):
    doc["distribution"][0]["sha256"] = "0" * 64


def _unlisted_file(doc):
    doc["distribution"] = [o for o in doc["distribution"] if o["@id"] != "gaits.h5"]


@pytest.mark.parametrize("plant, words", [
    (_missing_column, ["gaits/source", "'emotion_label' is not in the Parquet file", "'source' has 0 fields"]),
    (_wrong_shape, ["gaits/positions", "holds 5040 values, the Parquet list 3780"]),
    (_stale_checksum, ["FileObject 'gaits.parquet': sha256 " + "0" * 64]),
    (_unlisted_file, ["gaits.h5 has no FileObject"]),
])
def test_a_document_that_disagrees_with_the_files_is_named(published, plant, words, tmp_path):
    directory, doc = published
    planted = json.loads(json.dumps(doc))
    plant(planted)
    problems = " | ".join(croissant_problems(directory, planted))
    assert all(w in problems for w in words), problems
    if plant is _missing_column:  # the validator reads the document only: this is why croissant_problems exists
        (tmp_path / CROISSANT_NAME).write_text(json.dumps(planted), encoding="utf-8")
        assert _validate(tmp_path / CROISSANT_NAME).returncode == 0


def test_undocumented_columns_and_unknown_rai_properties_are_refused(published, sample):
    directory, _ = published
    described = _describe(sample[0])
    del described["column_descriptions"]["plan_seed"]
    with pytest.raises(ValueError, match=r"undocumented: \['plan_seed'\]"):
        croissant_metadata(directory, **described)
    described = _describe(sample[0])
    described["rai"]["dataColection"] = "typo"
    with pytest.raises(ValueError, match="dataColection"):
        croissant_metadata(directory, **described)


# ---------------------------------------------------------------------------------------------- PROV-JSON

def _lock() -> dict:
    return yaml.safe_load(LOCK.read_text(encoding="utf-8"))


def _edges(doc: dict, kind: str, a: str, b: str) -> set[tuple[str, str]]:
    return {(r[a], r[b]) for r in doc.get(kind, {}).values()}


def test_every_stage_is_an_activity_and_every_path_an_entity_with_its_edges(published):
    directory, _ = published
    doc = prov_document(stage_graph(REPO, LOCK), REPO, directory)
    lock = _lock()
    assert set(lock["stages"]) >= {"ingest", "annotate", "validate_contacts", "split", "train", "evaluate"}
    assert set(doc["activity"]) == {f"stage:{name}" for name in lock["stages"]}
    used, generated = _edges(doc, "used", "prov:activity", "prov:entity"), set()
    spec = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    measured = {next(iter(i)) for st in spec.values() for key in ("metrics", "plots") for i in st.get(key, [])}
    assert "reports/train.json" in measured
    for name, stage in lock["stages"].items():
        activity = doc["activity"][f"stage:{name}"]
        assert activity["dvc:cmd"] == stage["cmd"] and json.loads(activity["dvc:params"]) == stage.get("params", {})
        for dep in stage.get("deps", []):
            assert (f"stage:{name}", f"path:{dep['path']}") in used
            assert doc["entity"][f"path:{dep['path']}"]["dvc:path"] == dep["path"]
        for out in stage.get("outs", []):
            entity = doc["entity"][f"path:{out['path']}"]
            if out["path"] in measured:  # metrics and plots: measurements, named without digests
                assert "dvc:md5" not in entity and "dvc:size" not in entity
            else:
                assert (entity["dvc:md5"], entity["dvc:size"]) == (out["md5"], out["size"])
            generated.add((f"path:{out['path']}", f"stage:{name}"))
    assert _edges(doc, "wasGeneratedBy", "prov:entity", "prov:activity") == generated  # no publish stage: no more
    assert _edges(doc, "wasAssociatedWith", "prov:activity", "prov:agent") == {
        (a, "emogait:software") for a in doc["activity"]}
    assert doc["agent"]["emogait:software"]["prov:label"] == "emogait"
    # nothing generates the published files in this lock: they are entities with their checksums, unrelated
    published_files = {k: v for k, v in doc["entity"].items() if "emogait:sha256" in v}
    assert {v["prov:label"] for v in published_files.values()} == {
        "README.md", "croissant.json", "gaits.h5", "gaits.parquet", "previews/gait_0.png"}
    assert "wasDerivedFrom" not in doc


def test_prov_json_is_well_formed_serialisable_and_deterministic(published):
    directory, _ = published
    doc = prov_document(stage_graph(REPO, LOCK), REPO, directory)
    text = json.dumps(doc, indent=2)
    assert json.dumps(prov_document(stage_graph(REPO, LOCK), REPO, directory), indent=2) == text
    allowed = {"prefix", "entity", "activity", "agent", "used", "wasGeneratedBy", "wasAssociatedWith",
               "wasDerivedFrom", "hadMember"}
    assert set(doc) <= allowed and set(doc["prefix"]) >= {"emogait", "dvc", "stage", "path"}
    declared = set(doc["entity"]) | set(doc["activity"]) | set(doc["agent"])
    for kind in allowed - {"prefix", "entity", "activity", "agent"}:
        for relation in doc.get(kind, {}).values():
            ends = [v for k, v in relation.items() if k.startswith("prov:")]
            assert ends and set(ends) <= declared, (kind, relation)
    qualified = [*declared, *(k for node in [*doc["entity"].values(), *doc["activity"].values()] for k in node)]
    assert {q.split(":", 1)[0] for q in qualified} <= set(doc["prefix"]) | {"prov"}
    path = write_provenance(directory.parent / "provenance-copy.json", doc)
    assert path.read_text(encoding="utf-8") == text + "\n"


def test_publish_depends_on_every_input_and_param_its_provenance_records():
    """provenance.json holds the lock entries of the stages upstream of publish, their code md5s included. Each path
    and param they record must be a dep or param of publish itself: else a code change upstream whose outputs
    come out byte-identical (a tidy-up) does not rerun publish, the published provenance keeps naming code that is
    gone, and a clean clone's `dvc repro` rewrites dvc.lock."""
    graph = stage_graph(REPO, LOCK, running="publish")
    own = graph["stages"].pop("publish")
    upstream = graph["stages"]
    assert {"ingest", "annotate", "split", "train", "synthesize", "synthesize_motion_graph"} <= set(upstream)
    deps = [r["path"] for r in own["deps"]]
    recorded = {r["path"] for stage in upstream.values() for key in ("deps", "outs") for r in stage[key] if "md5" in r}
    assert "pipeline/generators/autoregressive/critic.py" in recorded
    assert sorted(p for p in recorded if not any(holds(d, p) for d in deps)) == []
    params = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]["publish"]["params"]
    named = {k for stage in upstream.values() for file in stage.get("params", {}).values() for k in file}
    assert sorted(k for k in named if not any(k == p or k.startswith(p + ".") for p in params)) == []
    # the dvc.yaml dep ${data.mocap_root} is recorded as the path it resolves to, with the digest ingest locked
    mocap = yaml.safe_load((REPO / "params.yaml").read_text())["data"]["mocap_root"]
    ingest = {r["path"]: r for r in upstream["ingest"]["deps"]}
    assert next(r for r in own["deps"] if r["path"] == mocap)["md5"] == ingest[mocap]["md5"]


def _with_publish_stage(tmp_path: Path, outs: list[dict]) -> Path:
    """A copy of the repository's dvc.lock with a publish stage appended (paths relative to the repository)."""
    lock = _lock()
    deps = [{"path": "data/split/gaits.parquet", "hash": "md5", "md5": "0" * 32, "size": 1},
            {"path": "data/models", "hash": "md5", "md5": "1" * 32 + ".dir", "size": 2, "nfiles": 3}]
    lock["stages"]["publish"] = {"cmd": "python -m stages.publish", "deps": deps,
                                 "params": {"params.yaml": {"publish": {"gaits": 6}}}, "outs": outs}
    lock_path = tmp_path / "dvc.lock"
    lock_path.write_text(yaml.safe_dump(lock, sort_keys=False), encoding="utf-8")
    return lock_path


def test_a_publish_stage_generates_the_published_files_from_its_inputs(published, tmp_path):
    directory, _ = published
    out = Path(os.path.relpath(directory, REPO)).as_posix()
    outs = [{"path": out, "hash": "md5", "md5": "2" * 32 + ".dir", "size": 3, "nfiles": 9}]
    doc = prov_document(stage_graph(REPO, _with_publish_stage(tmp_path, outs)), REPO, directory)
    lock = _lock()
    files = {v["prov:label"]: k for k, v in doc["entity"].items() if "emogait:sha256" in v}
    sums = dict(line.split("  ")[::-1] for line in (directory / "SHA256SUMS").read_text().splitlines())
    assert set(files) == set(sums) - {PROVENANCE_NAME}  # provenance.json and SHA256SUMS describe, not are, data
    assert all(doc["entity"][files[rel]]["emogait:sha256"] == sums[rel] for rel in files)
    assert files["gaits.parquet"] == f"path:{out}/gaits.parquet"
    generated = _edges(doc, "wasGeneratedBy", "prov:entity", "prov:activity")
    derived = _edges(doc, "wasDerivedFrom", "prov:generatedEntity", "prov:usedEntity")
    members = _edges(doc, "hadMember", "prov:collection", "prov:entity")
    for entity in files.values():
        assert (entity, "stage:publish") in generated
        assert {(entity, "path:data/split/gaits.parquet"), (entity, "path:data/models")} <= derived
        assert (f"path:{out}", entity) in members
    # the publish stage saw a split file other than the one the split stage locked: both md5s are on record
    seen = {r["dvc:md5"] for r in doc["used"].values() if r["prov:entity"] == "path:data/split/gaits.parquet"}
    assert seen == {"0" * 32, lock["stages"]["split"]["outs"][0]["md5"]}


def test_a_published_file_the_lock_names_keeps_its_dvc_record(published, tmp_path):
    directory, _ = published
    parquet = Path(os.path.relpath(directory / "gaits.parquet", REPO)).as_posix()
    outs = [{"path": parquet, "hash": "md5", "md5": "3" * 32, "size": 4}]
    doc = prov_document(stage_graph(REPO, _with_publish_stage(tmp_path, outs)), REPO, directory)
    entity = doc["entity"][f"path:{parquet}"]
    assert (entity["dvc:md5"], entity["emogait:sha256"]) == ("3" * 32, _sha256_of(directory / "gaits.parquet"))
    generated = [r for r in doc["wasGeneratedBy"].values() if r["prov:entity"] == f"path:{parquet}"]
    assert [r["prov:activity"] for r in generated] == ["stage:publish"]
    readme = f"path:{Path(os.path.relpath(directory / 'README.md', REPO)).as_posix()}"
    assert readme in doc["entity"] and all(r["prov:entity"] != readme for r in doc["wasGeneratedBy"].values())


def test_the_running_publish_stage_records_its_lineage_whatever_ran_after_it(published, tmp_path):
    """Run inside `publish`, the document holds the stages publish depends on (transitively) and publish itself
    from dvc.yaml, so a lock that also holds later stages (audit) or an older publish entry gives the same bytes."""
    directory, _ = published
    doc = prov_document(stage_graph(REPO, LOCK, running="publish"), REPO, directory)
    assert set(doc["activity"]) == {f"stage:{s}" for s in ("ingest", "annotate", "split", "train", "synthesize",
                                                           "fit_pca_gaussian", "synthesize_pca_gaussian",
                                                           "fit_motion_graph", "synthesize_motion_graph", "publish")}
    lock = _lock()
    earlier = {**lock, "stages": {k: v for k, v in lock["stages"].items() if k not in ("publish", "audit")}}
    path = tmp_path / "dvc.lock"
    path.write_text(yaml.safe_dump(earlier, sort_keys=False))
    assert json.dumps(prov_document(stage_graph(REPO, path, running="publish"), REPO, directory)) == json.dumps(doc)
