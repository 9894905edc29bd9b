"""What `emogait preview` draws: gaits of a gait table by id, or a BVH clip of a mocap source on the canonical
skeleton (its first window, exactly as ingest makes it) beside the same instants on the source's own rig.

Paths, manifests and configs in, ``Motion``s out (``stick_figures`` renders them); never the pipeline's params.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from pipeline.core.skeleton import Skeleton
from pipeline.ingest.retarget import bvh_point_positions
from pipeline.ingest.run import IngestConfig, ingest_chunk
from pipeline.io.files import read_meta, sha256_file
from pipeline.io.gait_table import read_gaits
from pipeline.io.manifests import SourceManifest, locate_source_file
from pipeline.io.readers.bvh import read_bvh
from pipeline.viz.stick_figures import Motion


class PreviewError(ValueError):
    """What was asked for cannot be shown: the message names the file or id, what was expected and found."""


def gait_motions(table_path: Path, gait_ids: Sequence[str]) -> list[Motion]:
    """The gaits with these ids from a gait table (Parquet), titled with id and style."""
    meta = read_meta(table_path)
    table, arrays = read_gaits(table_path, columns=["gait_id", "label_method", "style", "positions"])
    ids = table.column("gait_id").to_pylist()
    motions = []
    for gid in gait_ids:
        if gid not in ids:
            raise PreviewError(f"{table_path}: expected a gait with id {gid!r}, found none ({len(ids)} gaits)")
        k = ids.index(gid)
        style = table.column("style")[k].as_py()
        motions.append(Motion(f"{gid}\n({style})", arrays["positions"][k], meta["parents"], meta["joint_names"]))
    return motions


def bvh_motions(path: Path, manifests: Sequence[SourceManifest], skeleton: Skeleton, cfg: IngestConfig,
                source: str | None = None, show_source: bool = True) -> list[Motion]:
    """The clip's first window on the canonical skeleton, and (optionally) the same frames on the source rig.

    path: a BVH file under a source folder of ``cfg.mocap_root`` (the folder names the source unless
    ``source`` does); the root, the folder and the file may be reached through symbolic links. The clip need
    not be a gait (no speed filter) nor pinned: what is shown is what ingest would make of it.
    """
    by_name = {m.name: m for m in manifests}
    if source is not None and source not in by_name:
        raise PreviewError(f"source {source!r}: expected one of the BVH sources {sorted(by_name)}, found no such "
                           "manifest")
    try:
        name, rel = locate_source_file(path, cfg.mocap_root, [source] if source else sorted(by_name))
    except ValueError as err:
        raise PreviewError(str(err)) from None
    manifest = by_name[name]
    file = cfg.mocap_root / name / rel
    sha = sha256_file(file)
    cfg = replace(cfg, min_gait_speed=0.0)
    result = ingest_chunk(manifest, skeleton, [(rel, sha)], cfg)
    if not result.windows:
        raise PreviewError(f"{path}: {result.records[0].status}: {result.records[0].reason}")
    first = result.windows[0]
    motions = [Motion(f"{name}/{Path(rel).name}\ncanonical 21 joints", first["positions"], skeleton.parents,
                      skeleton.names)]
    if show_source:
        clip = read_bvh(file)
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
