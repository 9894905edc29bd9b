"""The published dataset directory: built here from real annotated gaits, loaded with pandas and torch,
verified, and then broken one defect at a time to see that ``verify`` names each one."""

from __future__ import annotations

import hashlib
import json
import re
import time

import h5py
import numpy as np
import pyarrow as pa
import pytest
import torch
from torch.utils.data import DataLoader

from pipeline.dataset import (
    GaitDataset,
    load_dataframe,
    verify,
    write_hdf5_atomic,
    write_sha256sums,
)
from pipeline.io.files import write_parquet
from pipeline.io.gait_table import array_column, column_array


def _pick_rows(table: pa.Table, per_source: int = 3) -> list[int]:
    """Labelled and unlabelled gaits of every source: a few dozen rows of the real data."""
    sources = table.column("source").to_pylist()
    labelled = np.asarray(table.column("emotion").is_valid())
    rows: list[int] = []
    for source in sorted(set(sources)):
        for want in (True, False):
            own = [i for i, s in enumerate(sources) if s == source and labelled[i] == want]
            rows += own[:: max(1, len(own) // per_source)][:per_source]
    return sorted(rows)


def _with_meta(table: pa.Table, meta: dict) -> pa.Table:
    return table.replace_schema_metadata({b"emogait": json.dumps(meta, sort_keys=True).encode()})


def _publish(directory, table: pa.Table, meta: dict, shards: int = 1):
    """What the publish stage will do for the gait files: Parquet (maybe sharded), HDF5, then SHA256SUMS."""
    table = _with_meta(table, meta)
    if shards == 1:
        write_parquet(table, directory / "gaits.parquet")
    else:
        bounds = np.linspace(0, table.num_rows, shards + 1).astype(int)
        for k in range(shards):
            shard = table.slice(bounds[k], bounds[k + 1] - bounds[k])
            write_parquet(shard, directory / f"gaits-{k:05d}.parquet")
    write_hdf5_atomic(table, {}, directory / "gaits.h5", meta)
    write_sha256sums(directory)
    return directory


def _replace_array(table: pa.Table, name: str, values: np.ndarray) -> pa.Table:
    null_rows = ~np.asarray(table.column(name).is_valid())
    return table.set_column(table.column_names.index(name), name, array_column(values, null_rows))


@pytest.fixture(scope="module")
def real(annotated):
    """(table, meta): real annotated gaits with a ``kind`` column, as the publish stage will ship them."""
    table, _ = annotated
    meta = json.loads(table.schema.metadata[b"emogait"])
    subset = table.take(_pick_rows(table))
    subset = subset.append_column("kind", pa.array(["real"] * subset.num_rows, pa.string()))
    return _with_meta(subset, meta), meta


@pytest.fixture(scope="module")
def published(real, tmp_path_factory):
    table, meta = real
    return _publish(tmp_path_factory.mktemp("published"), table, meta)


def test_the_sample_is_real_and_varied(real):
    table, _ = real
    assert 12 <= table.num_rows <= 60
    assert len(set(table.column("source").to_pylist())) >= 3
    assert 0 < table.column("emotion").null_count < table.num_rows


def test_load_dataframe_gives_arrays_of_the_documented_shape(published, real):
    table, meta = real
    frame = load_dataframe(published)
    assert len(frame) == table.num_rows
    assert frame["gait_id"].tolist() == table.column("gait_id").to_pylist()
    assert set(frame["kind"]) == {"real"}
    for name, shape in meta["shapes"].items():
        expected = column_array(table, name, shape)
        valid = np.asarray(table.column(name).is_valid())
        for i, cell in enumerate(frame[name]):
            if valid[i]:
                assert cell.shape == tuple(shape) and cell.dtype == np.float32
                np.testing.assert_array_equal(cell, expected[i])
            else:
                assert cell is None
    assert frame.attrs["emogait"]["joint_names"][0] == "root"


def test_gait_dataset_batches_with_a_dataloader(published, real):
    table, meta = real
    dataset = GaitDataset(published, columns=["gait_id", "kind", "emotion", "positions", "rotations", "t_start"])
    assert len(dataset) == table.num_rows
    batches = list(DataLoader(dataset, batch_size=8, shuffle=False))
    first = batches[0]
    assert first["positions"].shape == (8, 60, 21, 3) and first["positions"].dtype == torch.float32
    assert first["rotations"].shape == (8, 60, 21, 4)
    assert first["emotion"].shape == (8, 4)
    assert first["t_start"].shape == (8,)
    assert first["gait_id"] == table.column("gait_id").to_pylist()[:8]
    positions = torch.cat([b["positions"] for b in batches])
    assert torch.equal(positions, torch.from_numpy(column_array(table, "positions", meta["shapes"]["positions"])))


def test_a_fresh_directory_verifies(published):
    assert verify(published) == []


def test_shards_load_in_order_and_verify(real, tmp_path):
    table, meta = real
    directory = _publish(tmp_path, table, meta, shards=3)
    assert sorted(p.name for p in tmp_path.glob("gaits-*.parquet")) == [f"gaits-{k:05d}.parquet" for k in range(3)]
    assert load_dataframe(directory)["gait_id"].tolist() == table.column("gait_id").to_pylist()
    assert verify(directory) == []


def test_hdf5_is_byte_reproducible_and_documented(real, tmp_path):
    table, meta = real
    write_hdf5_atomic(table, {}, tmp_path / "a.h5", meta)
    time.sleep(1.1)  # a stored timestamp would now differ
    write_hdf5_atomic(table, {}, tmp_path / "b.h5", meta)
    assert (tmp_path / "a.h5").read_bytes() == (tmp_path / "b.h5").read_bytes()
    with h5py.File(tmp_path / "a.h5", "r") as h5:
        assert list(h5.attrs["joint_names"]) == meta["joint_names"]
        assert list(h5.attrs["emotion_order"]) == ["happy", "sad", "angry", "neutral"]
        assert h5.attrs["parents"].tolist() == meta["parents"]
        positions = h5["positions"]
        assert positions.shape == (table.num_rows, 60, 21, 3) and positions.attrs["units"] == "m"
        assert (positions.compression, positions.shuffle, positions.fletcher32) == ("gzip", True, True)
        assert positions.chunks is not None
        assert list(h5["gait_id"].asstr()[()]) == table.column("gait_id").to_pylist()
        assert np.isnan(h5["emotion"][()]).any(axis=1).sum() == table.column("emotion").null_count


def test_sha256sums_is_in_sha256sum_format(published):
    lines = (published / "SHA256SUMS").read_text().splitlines()
    assert [line.split("  ", 1)[1] for line in lines] == ["gaits.h5", "gaits.parquet"]
    for line in lines:
        digest, rel = line.split("  ", 1)
        assert re.fullmatch(r"[0-9a-f]{64}", digest)
        assert hashlib.sha256((published / rel).read_bytes()).hexdigest() == digest


def _emotion_off(table):
    values = column_array(table, "emotion", (4,))
    row = int(np.flatnonzero(np.asarray(table.column("emotion").is_valid()))[0])
    values[row] = values[row] * 0.9
    return _replace_array(table, "emotion", values), row


def _emotion_negative(table):
    values = column_array(table, "emotion", (4,))
    row = int(np.flatnonzero(np.asarray(table.column("emotion").is_valid()))[-1])
    values[row] = [1.25, -0.25, 0.0, 0.0]
    return _replace_array(table, "emotion", values), row


def _duplicate_id(table):
    ids = table.column("gait_id").to_pylist()
    ids[3] = ids[1]
    return table.set_column(table.column_names.index("gait_id"), "gait_id", pa.array(ids, pa.string())), 1


def _nan_position(table):
    values = column_array(table, "positions", (60, 21, 3))
    values[2, 10, 5, 1] = np.nan
    return _replace_array(table, "positions", values), 2


@pytest.mark.parametrize("plant, words", [
    (_emotion_off, ("'emotion'", "do not sum to 1")),
    (_emotion_negative, ("'emotion'", "negative")),
    (_duplicate_id, ("'gait_id'", "more than once")),
    (_nan_position, ("'positions'", "NaN")),
], ids=["emotion-sum", "emotion-negative", "duplicate-id", "nan-position"])
def test_verify_names_each_planted_defect(real, tmp_path, plant, words):
    table, meta = real
    broken, row = plant(table)
    problems = verify(_publish(tmp_path, broken, meta))
    assert len(problems) == 1, problems
    assert all(w in problems[0] for w in words), problems
    assert repr(table.column("gait_id")[row].as_py()) in problems[0]


def test_verify_names_a_changed_byte(real, tmp_path):
    table, meta = real
    directory = _publish(tmp_path, table, meta)
    path = directory / "gaits.parquet"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    problems = verify(directory)
    assert any(p.startswith("gaits.parquet: sha256 mismatch") for p in problems), problems


def test_verify_names_hdf5_that_disagrees_with_parquet(real, tmp_path):
    table, meta = real
    directory = _publish(tmp_path, table, meta)
    positions = column_array(table, "positions", (60, 21, 3))
    positions[4, 0, 0, 0] += 0.01
    write_hdf5_atomic(table, {"positions": positions}, directory / "gaits.h5", meta)
    write_sha256sums(directory)
    problems = verify(directory)
    assert len(problems) == 1 and "gaits.h5:/positions: values differ" in problems[0], problems


def test_verify_names_missing_metadata_and_unlisted_files(real, tmp_path):
    table, meta = real
    directory = _publish(tmp_path, table, meta)
    write_parquet(table.replace_schema_metadata(None), directory / "gaits.parquet")
    (directory / "notes.txt").write_text("not in SHA256SUMS\n")
    problems = verify(directory)
    assert any("schema metadata key 'emogait' missing" in p for p in problems), problems
    assert any(p == "notes.txt: present but not listed in SHA256SUMS" for p in problems), problems
    assert any(p.startswith("gaits.parquet: sha256 mismatch") for p in problems), problems


def _families(real: tuple[pa.Table, dict]) -> tuple[pa.Table, dict, dict[str, list[int]]]:
    """The sample with its last four gaits relabelled as synthetic gaits of two declared families."""
    table, meta = real
    n = table.num_rows
    kind = ["real"] * (n - 4) + ["synthetic"] * 4
    generator = [None] * (n - 4) + ["fam_a", "fam_a", "fam_b", "fam_b"]
    sha = [None] * (n - 4) + ["a" * 64, "a" * 64, "b" * 64, "b" * 64]
    table = table.set_column(table.column_names.index("kind"), "kind", pa.array(kind, pa.string()))
    table = table.append_column("generator", pa.array(generator, pa.string()))
    table = table.append_column("checkpoint_sha256", pa.array(sha, pa.string()))
    meta = {**meta, "generators": {"fam_a": {"model_sha256": "a" * 64}, "fam_b": {"model_sha256": "b" * 64}}}
    parts = {"real": list(range(n - 4)), "fam_a": [n - 4, n - 3], "fam_b": [n - 2, n - 1]}
    return _with_meta(table, meta), meta, parts


def _publish_parts(directory, table: pa.Table, meta: dict, parts: dict[str, list[int]]):
    directory.mkdir(parents=True)
    for k, (part, rows) in enumerate(parts.items()):
        write_parquet(table.take(rows), directory / f"gaits-{k:03d}-{part}.parquet")
    write_hdf5_atomic(table.take([i for rows in parts.values() for i in rows]), {}, directory / "gaits.h5", meta)
    write_sha256sums(directory)
    return directory


def test_verify_checks_every_generator_family(real, tmp_path):
    table, meta, parts = _families(real)
    assert verify(_publish_parts(tmp_path / "sound", table, meta, parts)) == []
    swapped = {"real": parts["real"], "fam_a": parts["fam_b"], "fam_b": parts["fam_a"]}
    problems = verify(_publish_parts(tmp_path / "swapped", table, meta, swapped))
    assert any("gaits-001-fam_a.parquet: expected only fam_a gaits" in p for p in problems), problems
    sha = table.column("checkpoint_sha256").to_pylist()
    sha[-1] = "c" * 64
    other = table.set_column(table.column_names.index("checkpoint_sha256"), "checkpoint_sha256",
                             pa.array(sha, pa.string()))
    problems = verify(_publish_parts(tmp_path / "sha", other, meta, parts))
    assert any("generator 'fam_b': 1 gaits with checkpoint_sha256 other than" in p for p in problems), problems
    declared = {**meta, "generators": {"fam_a": meta["generators"]["fam_a"], "fam_c": {"model_sha256": "c" * 64}}}
    problems = verify(_publish_parts(tmp_path / "undeclared", _with_meta(table, declared), declared, parts))
    assert any("synthetic gaits of ['fam_b']" in p for p in problems), problems
    assert any("generator 'fam_c': declared in the metadata, but no gait has it" in p for p in problems), problems
