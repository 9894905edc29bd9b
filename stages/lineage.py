"""The pipeline's stage graph for provenance, read from dvc.yaml and dvc.lock (the one place that parses them).

``stage_graph`` gives the plain graph ``pipeline.publish.provenance.prov_document`` takes: every locked stage
with its command, params and dep/out records, metrics and plots named without digests (they hold timings, which
differ from run to run), and, for the stage now running, its record from dvc.yaml with the md5 of what its file
deps hold now, after only the stages upstream of it (the lock entries of the others depend on when it ran).
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from pipeline.publish.provenance import holds

RECORD_KEYS = ("path", "md5", "hash", "size", "nfiles")


def _paths(items: list[Any]) -> list[str]:
    return [next(iter(i)) if isinstance(i, dict) else str(i) for i in items]


def _upstream(stages: Mapping[str, Any], deps: list[str]) -> dict[str, Any]:
    """The stages whose outputs the given deps are, directly or through others, in lock order."""
    wanted = set(deps)
    kept: set[str] = set()
    changed = True
    while changed:
        changed = False
        for name, stage in stages.items():
            outs = {o["path"] for o in stage.get("outs", [])}
            if name not in kept and any(holds(o, w) or holds(w, o) for o in outs for w in wanted):
                kept.add(name)
                wanted |= {d["path"] for d in stage.get("deps", [])}
                changed = True
    return {name: stage for name, stage in stages.items() if name in kept}


def _interpolated(path: str, params: Mapping[str, Any]) -> str:
    """A dep written as ``${dotted.param}`` in dvc.yaml -> that param's value (params.yaml), as DVC resolves it."""
    if not (match := re.fullmatch(r"\$\{([\w.]+)\}", path)):
        return path
    value: Any = params
    for key in match.group(1).split("."):
        value = value[key]
    return str(value)


def _running_stage(repo: Path, spec: Mapping[str, Any], stages: Mapping[str, Any]) -> tuple[dict, dict]:
    """The running stage's record from its dvc.yaml spec (its lock entry, if any, is its previous run's) and the
    locked stages upstream of it. A file dep gets the md5 of what it holds now; a directory the record of the
    upstream stage that outputs it, else of one that reads it."""
    params = yaml.safe_load((repo / "params.yaml").read_text(encoding="utf-8"))
    deps = [_interpolated(p, params) for p in _paths(spec.get("deps", []))]
    upstream = _upstream(stages, deps)
    known = {r["path"]: r for st in upstream.values() for r in st.get("deps", [])}
    known.update({r["path"]: r for st in upstream.values() for r in st.get("outs", [])})

    def record(path: str) -> dict[str, Any]:
        file = repo / path
        if file.is_file():
            return {"path": path, "md5": hashlib.md5(file.read_bytes()).hexdigest()}  # DVC's file digest
        return {k: v for k, v in known.get(path, {"path": path}).items() if k in RECORD_KEYS}

    return ({"cmd": spec["cmd"], "deps": [record(p) for p in deps],
             "outs": [{"path": p} for p in _paths(spec.get("outs", []))]}, upstream)


def stage_graph(repo: Path, lock_path: Path, running: str | None = None) -> dict[str, Any]:
    """The graph of ``lock_path`` (paths relative to ``repo``, where dvc.yaml is); see the module docstring."""
    lock = yaml.safe_load(Path(lock_path).read_text(encoding="utf-8"))
    if not isinstance(lock, dict) or not isinstance(lock.get("stages"), dict):
        raise ValueError(f"{lock_path}: expected a dvc.lock mapping with 'stages', found {type(lock).__name__}")
    spec = yaml.safe_load((Path(repo) / "dvc.yaml").read_text(encoding="utf-8"))["stages"]
    stages = lock["stages"]
    if running:
        others = {k: v for k, v in stages.items() if k != running}
        record, upstream = _running_stage(Path(repo), spec[running], others)
        stages = {**upstream, running: record}
    reports = {p for stage in spec.values() for key in ("metrics", "plots") for p in _paths(stage.get(key, []))}
    for stage in stages.values():
        for key in ("deps", "outs"):
            stage[key] = [{"path": r["path"]} if r["path"] in reports else r for r in stage.get(key, [])]
    return {"stages": stages}
