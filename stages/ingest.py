"""DVC stage `ingest`: mocap sources -> data/ingested/gaits.parquet + reports/ingest.json."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from pipeline.io.files import write_json, write_parquet
from pipeline.io.gait_table import to_table
from pipeline.ingest.run import missing_data_message, run_ingest
from pipeline.viz.stick_figures import preview_gaits, render_filmstrip, render_floor_models
from pipeline.core.skeleton import load_skeleton
from pipeline.io.manifests import load_manifests
from stages.common import REPO, SKELETON, SOURCES, load_params
from stages.configs import ingest_config

OUT_GAITS = REPO / "data" / "ingested" / "gaits.parquet"
OUT_REPORT = REPO / "reports" / "ingest.json"
OUT_PREVIEW = REPO / "reports" / "ingest_preview.png"
OUT_FLOOR = REPO / "reports" / "ingest_floor.png"


def main(params_path: Path | None = None, out_gaits: Path = OUT_GAITS, out_report: Path = OUT_REPORT,
         sources: Path = SOURCES, out_preview: Path = OUT_PREVIEW, out_floor: Path = OUT_FLOOR) -> dict:
    params = load_params(params_path) if params_path else load_params()
    cfg = ingest_config(params)
    manifests = load_manifests(sources, formats=("bvh", "c3d"))
    if not cfg.mocap_root.is_dir():
        sys.exit(missing_data_message(manifests, cfg.mocap_root, "params.yaml data.mocap_root"))
    skeleton = load_skeleton(SKELETON)
    windows, report, floors = run_ingest(manifests, skeleton, cfg, workers=params["ingest"].get("workers"),
                                         scheduler_address=os.environ.get("DASK_SCHEDULER_ADDRESS"),
                                         floor_series=True)
    write_parquet(to_table(windows, skeleton, cfg.window), out_gaits)
    write_json(report, out_report)
    render_filmstrip(preview_gaits(windows, skeleton), out_preview)
    render_floor_models(floors, cfg.target_fps, out_floor, skeleton)
    print(f"ingest: {report['files_seen']} files seen, {report['files_ingested']} ingested, "
          f"{report['files_quarantined']} quarantined, {report['files_filtered']} filtered; "
          f"{report['gaits']} gaits from {report['clips']} clips -> {out_gaits.relative_to(REPO)}")
    return report


if __name__ == "__main__":
    main()
