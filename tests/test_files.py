"""Atomic writes: a file appears whole under its name or not at all, and a killed write's leftover goes with the
next write of the same path (the kill test in test_dvc_stage.py does this to every stage)."""

import json

import pytest

from pipeline.io.files import atomic_path, write_json


def test_a_failed_write_leaves_neither_the_file_nor_a_temporary(tmp_path):
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "report.json") as tmp:
        tmp.write_text("{half")
        raise RuntimeError("killed")
    assert list(tmp_path.iterdir()) == []


def test_the_next_write_removes_a_killed_writes_temporary_and_no_other_file(tmp_path):
    stale = tmp_path / ".report.json.k1ll3d.tmp.json"  # what mkstemp left when the writer was SIGKILLed
    stale.write_text("{half")
    other = tmp_path / ".other.json.k1ll3d.tmp.json"
    other.write_text("{half")
    write_json({"a": 1}, tmp_path / "report.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.json.k1ll3d.tmp.json", "report.json"]
    assert json.loads((tmp_path / "report.json").read_text()) == {"a": 1}
