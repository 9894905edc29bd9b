"""What `emogait preview` shows, with the settings of params.yaml: gaits by id from a gait table, or BVH clips
before and after retargeting (pipeline.viz.previews)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pipeline.core.skeleton import load_skeleton
from pipeline.ingest.run import IngestConfig
from pipeline.io.manifests import load_manifests
from pipeline.viz import previews
from pipeline.viz.stick_figures import Motion
from stages.common import SKELETON, SOURCES, mocap_root


def gait_motions(table_path: Path, gait_ids: list[str]) -> list[Motion]:
    return previews.gait_motions(table_path, gait_ids)


def bvh_motions(path: Path, source: str | None, params: dict[str, Any], show_source: bool = True) -> list[Motion]:
    """The clip's first window on the canonical skeleton, and (optionally) the same frames on the source rig."""
    p = params["ingest"]
    cfg = IngestConfig(mocap_root=mocap_root(params), target_fps=float(p["target_fps"]), window=int(p["window"]),
                       stride=int(p["stride"]))
    return previews.bvh_motions(path, load_manifests(SOURCES, formats=("bvh",)), load_skeleton(SKELETON), cfg,
                                source=source, show_source=show_source)
