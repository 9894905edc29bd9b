"""The real DVC pipeline in a fresh copy of the repository, and the stages' declared dependencies."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from stages.common import REPO
from tests.conftest import MOCAP

COPY = ["dvc.yaml", "params.yaml", "pipeline", "stages", "manifests", ".dvc/config", ".dvcignore"]
DVC = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]


def _run(args, cwd, env):
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, check=True)


def test_dvc_repro_runs_every_stage_then_is_a_noop(tmp_path):
    work = tmp_path / "repo"
    for rel in COPY:
        src, dst = REPO / rel, work / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__")) if src.is_dir() else shutil.copy(src, dst)
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["data"]["mocap_root"] = str(MOCAP)
    # The real stages, sized to a test: a few epochs, few agents (the full sizes are measured by `make repro`).
    params["train"].update(epochs=3, validate_every=3, progress_every=1, batch_size=32)
    params["train"]["model"].update(gru_hidden=32, versor_hidden=32)
    params["evaluate"].update(rollout_steps=50, rollout_agents=3, expressiveness_steps=20, transition_steps=20,
                              transition_agents=2)
    (work / "params.yaml").write_text(yaml.safe_dump(params))
    env = dict(os.environ, DVC_NO_ANALYTICS="1", PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
    _run(["git", "init", "-q"], work, env)
    dvc = [sys.executable, "-m", "dvc"]
    first = _run(dvc + ["repro"], work, env)
    for stage in DVC:
        assert f"Running stage '{stage}'" in first.stdout
    report = json.loads((work / "reports/ingest.json").read_text())
    assert report["files_seen"] >= 361 and report["gaits"] > 1000
    split = json.loads((work / "reports/split.json").read_text())
    assert split["clips_in_two_splits"] == [] and split["totals"]["test"]["gaits"] > 0
    assert json.loads((work / "reports/contacts.json").read_text())["acceptance"]["passed"]
    trained = json.loads((work / "reports/train.json").read_text())
    assert set(trained["variants"]) == {"full", "no_affect", "no_root"}
    for name, v in trained["variants"].items():
        assert hashlib.sha256((work / v["checkpoint"]).read_bytes()).hexdigest() == v["sha256"]
    evaluation = json.loads((work / "reports/eval.json").read_text())
    assert evaluation["split"] == "test" and evaluation["table1_gaits"] == split["totals"]["test"]["gaits"]
    assert set(evaluation["table1"]) == {"zero_velocity", "constant_velocity", "full", "no_affect", "no_root"}
    assert (work / "reports/eval.md").read_text().startswith("# Generator evaluation")
    assert "up to date" in _run(dvc + ["status"], work, env).stdout
    second = _run(dvc + ["repro"], work, env)
    assert "Running stage" not in second.stdout and "didn't change" in second.stdout


@pytest.mark.parametrize("stage", sorted(DVC))
def test_stage_deps_cover_every_library_module_it_imports(stage):
    code = (f"import sys, stages.{stage}; print('\\n'.join(sorted(m.__file__ for n, m in sys.modules.items() "
            "if n.split('.')[0] in ('pipeline', 'stages') and getattr(m, '__file__', None))))")
    files = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    deps = [REPO / d for d in DVC[stage]["deps"] if not d.startswith("$")]
    for f in files.split():
        path = Path(f)
        if path.name == "__init__.py" or path.suffix == ".so":
            continue
        assert any(path == d or d in path.parents for d in deps), f"stage {stage}: {path.relative_to(REPO)} not in deps"
