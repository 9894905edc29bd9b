"""DVC stage `annotate`: data/ingested/gaits.parquet -> data/annotated/gaits.parquet + reports/annotate.json
(per-clip figures) + reports/annotate.png (contacts and phase of a walk per source)."""

from __future__ import annotations

from pathlib import Path

from pipeline.annotate.annotation import ANNOTATION_META, annotate_windows, annotation_report
from pipeline.core.skeleton import load_skeleton
from pipeline.io.files import write_json, write_parquet
from pipeline.io.gait_table import read_gaits, with_arrays
from pipeline.ops.contacts import CONTACT_POINTS
from pipeline.viz.stick_figures import annotation_examples
from stages.common import REPO, SKELETON, load_params
from stages.configs import annotate_config

IN_GAITS = REPO / "data" / "ingested" / "gaits.parquet"
OUT_GAITS = REPO / "data" / "annotated" / "gaits.parquet"
OUT_REPORT = REPO / "reports" / "annotate.json"
OUT_PLOT = REPO / "reports" / "annotate.png"


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_gaits: Path = OUT_GAITS,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict:
    params = load_params(params_path) if params_path else load_params()
    cfg = annotate_config(params)
    table, arrays = read_gaits(in_gaits)
    skeleton = load_skeleton(SKELETON)
    annotations, clips = annotate_windows(table.column("clip_id").to_pylist(), table.column("t_start").to_numpy(),
                                          arrays["positions"], arrays["rotations"], skeleton, cfg)
    write_parquet(with_arrays(table, annotations, ANNOTATION_META), out_gaits)
    report = annotation_report(table, clips)
    write_json(report, out_report)
    annotation_examples(table, arrays, annotations, skeleton, CONTACT_POINTS, cfg.fps, out_plot)
    print(f"annotate: {report['gaits']} gaits from {report['clips']} clips; walk stance fraction median "
          f"{report['stance_fraction']['walk_median']:.2f}; {len(report['clips_without_phase'])} clips without phase")
    return report


if __name__ == "__main__":
    main()
