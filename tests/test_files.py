"""Atomic writes: a file appears whole under its name or not at all. Bytes made in memory leave nothing when the
writer is killed; a path-based writer's leftover goes with the next write of the same path (the kill test in
test_dvc_stage.py kills every stage)."""

import json
import subprocess
import sys
import textwrap

import pytest

from pipeline.io.files import _write_unnamed, atomic_path, write_json


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


# A child process that SIGKILLs itself at its first os.write: killed in the middle of writing the file's bytes.
_KILLED_MID_WRITE = textwrap.dedent("""
    import os, signal, sys
    import pipeline.io.files as files
    os.write = lambda fd, data: os.kill(os.getpid(), signal.SIGKILL)
    if sys.argv[2] == "write_bytes":
        files.write_bytes(b"x" * 100_000, sys.argv[1])
    else:  # a writer that needs a path: the named temporary
        with files.atomic_path(sys.argv[1]) as tmp:
            fd = os.open(tmp, os.O_WRONLY)
            os.write(fd, b"x" * 100_000)
""")


def _killed_mid_write(path, how: str) -> int:
    return subprocess.run([sys.executable, "-c", _KILLED_MID_WRITE, str(path), how]).returncode


def test_a_write_killed_mid_way_leaves_no_file_at_all(tmp_path):
    if not _write_unnamed(b"probe", tmp_path / "probe"):
        pytest.skip("this file system cannot write unnamed files (O_TMPFILE); writes use a named temporary")
    (tmp_path / "probe").unlink()
    assert _killed_mid_write(tmp_path / "report.json", "write_bytes") == -9
    assert list(tmp_path.iterdir()) == []
    # a path-based writer killed the same way leaves its temporary (the next write of that path removes it)
    assert _killed_mid_write(tmp_path / "table.h5", "atomic_path") == -9
    assert [p.name.startswith(".table.h5.") for p in tmp_path.iterdir()] == [True]
