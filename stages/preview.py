"""Load what `emogait preview` shows: gaits from a gait table, or a BVH clip before and after retargeting."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.io.gait_table import read_gaits, read_metadata
from pipeline.ingest.run import IngestConfig, ingest_chunk
from pipeline.viz.stick_figures import Motion
from pipeline.io.readers.bvh import read_bvh
from pipeline.ingest.retarget import bvh_point_positions
from pipeline.core.skeleton import load_skeleton
from pipeline.io.manifests import load_manifest
from stages.common import SKELETON, SOURCES, mocap_root


def gait_motions(table_path: Path, gait_ids: list[str]) -> list[Motion]:
    meta = read_metadata(table_path)
    table, arrays = read_gaits(table_path, columns=["gait_id", "label_method", "style", "positions"])
    ids = table.column("gait_id").to_pylist()
    motions = []
    for gid in gait_ids:
        if gid not in ids:
            raise SystemExit(f"gait {gid!r} is not in {table_path}")
        k = ids.index(gid)
        style = table.column("style")[k].as_py()
        motions.append(Motion(f"{gid}\n({style})", arrays["positions"][k], meta["parents"], meta["joint_names"]))
    return motions


def bvh_motions(path: Path, source: str | None, params: dict[str, Any], show_source: bool = True) -> list[Motion]:
    """The clip's first window on the canonical skeleton, and (optionally) the same frames on the source rig."""
    root = mocap_root(params)
    path = path.resolve()
    rel_to_root = path.relative_to(root)
    source = source or rel_to_root.parts[0]
    manifest = load_manifest(SOURCES / f"{source}.yaml")
    rel = path.relative_to(root / source).as_posix()
    p = params["ingest"]
    cfg = IngestConfig(mocap_root=root, target_fps=float(p["target_fps"]), window=int(p["window"]),
                       stride=int(p["stride"]), min_gait_speed=0.0)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    result = ingest_chunk(manifest, load_skeleton(SKELETON), [(rel, sha)], cfg)
    if not result.windows:
        raise SystemExit(f"{path}: {result.records[0].status}: {result.records[0].reason}")
    first = result.windows[0]
    skeleton = load_skeleton(SKELETON)
    motions = [Motion(f"{source}/{Path(rel).name}\ncanonical 21 joints", first["positions"], skeleton.parents,
                      skeleton.names)]
    if show_source:
        clip = read_bvh(path)
        s = clip.skeleton
        pts = bvh_point_positions([clip], list(s.names), manifest.root_offset, manifest.up_axis).numpy()
        pts = pts * manifest.unit_scale_m
        # The same instants as the canonical window (its first 60 frames at the target rate).
        times = np.arange(cfg.window) / cfg.target_fps
        idx = np.clip(np.round(times / clip.frame_time).astype(int), 0, clip.frames - 1)
        pts = pts[idx]
        pts[..., 1] -= pts[..., 1].min()
        pelvis = manifest.joint_map(rel)["root"]
        motions.append(Motion(f"source rig ({len(s.names)} points)", pts, s.parents, s.names, s.index(pelvis)))
    return motions
