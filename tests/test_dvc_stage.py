"""The real DVC pipeline in a fresh copy of the repository: `dvc repro` runs ingest, a second one is a no-op."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from stages.common import REPO
from tests.conftest import MOCAP

COPY = ["dvc.yaml", "params.yaml", "pipeline", "stages", "manifests", ".dvc/config", ".dvcignore"]


def _run(args, cwd, env):
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, check=True)


def test_dvc_repro_then_noop(tmp_path):
    work = tmp_path / "repo"
    for rel in COPY:
        src, dst = REPO / rel, work / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__")) if src.is_dir() else shutil.copy(src, dst)
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["data"]["mocap_root"] = str(MOCAP)
    (work / "params.yaml").write_text(yaml.safe_dump(params))
    env = dict(os.environ, DVC_NO_ANALYTICS="1", PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
    _run(["git", "init", "-q"], work, env)
    dvc = [sys.executable, "-m", "dvc"]
    first = _run(dvc + ["repro"], work, env)
    assert "Running stage 'ingest'" in first.stdout
    report = json.loads((work / "reports/ingest.json").read_text())
    assert report["files_seen"] == 361 and report["gaits"] > 1000
    assert (work / "data/ingested/gaits.parquet").stat().st_size > 1_000_000
    status = _run(dvc + ["status"], work, env)
    assert "up to date" in status.stdout
    second = _run(dvc + ["repro"], work, env)
    assert "Running stage" not in second.stdout and "didn't change" in second.stdout
