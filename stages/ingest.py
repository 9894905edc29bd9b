"""DVC stage `ingest`: mocap sources -> data/ingested/gaits.parquet + reports/ingest.json."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from pipeline.io.gait_table import to_table, write_json_atomic, write_parquet_atomic
from pipeline.ingest.run import IngestConfig, missing_data_message, run_ingest
from pipeline.viz.stick_figures import Motion, render_filmstrip
from pipeline.core.skeleton import load_skeleton
from pipeline.io.manifests import load_manifests
from stages.common import REPO, SKELETON, SOURCES, load_params, mocap_root

OUT_GAITS = REPO / "data" / "ingested" / "gaits.parquet"
OUT_REPORT = REPO / "reports" / "ingest.json"
OUT_PREVIEW = REPO / "reports" / "ingest_preview.png"


def preview_gaits(windows: list[dict], skeleton) -> list[Motion]:
    """One gait per source, a labelled walk where the source has one, for a look at the retargeting."""
    picked: dict[str, dict] = {}
    rank = lambda w: (w["emotion"] is not None, w["content"] == "walk")  # noqa: E731
    for w in windows:
        if w["source"] not in picked or rank(w) > rank(picked[w["source"]]):
            picked[w["source"]] = w
    return [Motion(f"{w['gait_id'].split('/')[0]}\n{w['style']} {w['content']}", w["positions"], skeleton.parents,
                   skeleton.names) for w in picked.values()]


def main(params_path: Path | None = None, out_gaits: Path = OUT_GAITS, out_report: Path = OUT_REPORT,
         sources: Path = SOURCES, out_preview: Path = OUT_PREVIEW) -> dict:
    params = load_params(params_path) if params_path else load_params()
    p = params["ingest"]
    cfg = IngestConfig(mocap_root=mocap_root(params), target_fps=float(p["target_fps"]), window=int(p["window"]),
                       stride=int(p["stride"]), min_gait_speed=float(p["min_gait_speed"]),
                       chunk_frames=int(p["chunk_frames"]))
    manifests = load_manifests(sources, formats=("bvh", "c3d"))
    if not cfg.mocap_root.is_dir():
        sys.exit(missing_data_message(manifests, cfg.mocap_root))
    skeleton = load_skeleton(SKELETON)
    windows, report = run_ingest(manifests, skeleton, cfg, scheduler_address=os.environ.get("DASK_SCHEDULER_ADDRESS"),
                                 workers=p.get("workers"))
    write_parquet_atomic(to_table(windows, skeleton, cfg.window), out_gaits)
    write_json_atomic(report, out_report)
    render_filmstrip(preview_gaits(windows, skeleton), out_preview)
    print(f"ingest: {report['files_seen']} files seen, {report['files_ingested']} ingested, "
          f"{report['files_quarantined']} quarantined, {report['files_filtered']} filtered; "
          f"{report['gaits']} gaits from {report['clips']} clips -> {out_gaits.relative_to(REPO)}")
    return report


if __name__ == "__main__":
    main()
