"""DVC stage `annotate`: data/ingested/gaits.parquet -> data/annotated/gaits.parquet + reports/annotate.json."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.annotate.annotation import ANNOTATION_META, AnnotateConfig, annotate_windows
from pipeline.ops.contacts import CONTACT_POINTS, ContactConfig
from pipeline.io.gait_table import read_gaits, with_arrays, write_json_atomic, write_parquet_atomic
from pipeline.viz.stick_figures import AnnotatedClip, render_annotation
from pipeline.core.skeleton import load_skeleton
from stages.common import REPO, SKELETON, load_params

IN_GAITS = REPO / "data" / "ingested" / "gaits.parquet"
OUT_GAITS = REPO / "data" / "annotated" / "gaits.parquet"
OUT_REPORT = REPO / "reports" / "annotate.json"
OUT_PLOT = REPO / "reports" / "annotate.png"


def plot_examples(table, arrays: dict, annotations: dict, skeleton, cfg: AnnotateConfig, out: Path) -> None:
    """Contacts and phase of the first labelled walk of each source that has walks."""
    chosen: dict[str, str] = {}
    for cid, src, content, method in zip(table.column("clip_id").to_pylist(), table.column("source").to_pylist(),
                                         table.column("content").to_pylist(), table.column("label_method").to_pylist()):
        if content == "walk" and (src not in chosen or (method and not chosen[src][1])):
            chosen[src] = (cid, method)
    clip_ids = table.column("clip_id").to_pylist()
    starts = np.round(table.column("t_start").to_numpy() * cfg.fps).astype(int)
    points = [skeleton.index(n) for n in CONTACT_POINTS]
    examples = []
    for src, (cid, _) in sorted(chosen.items())[:3]:
        rows = [r for r, c in enumerate(clip_ids) if c == cid]
        frames = starts[rows[-1]] + arrays["positions"].shape[1]
        heights, contacts, phase = np.zeros((frames, 4)), np.zeros((frames, 4)), np.zeros(frames)
        for r in rows:
            s = slice(starts[r], starts[r] + arrays["positions"].shape[1])
            heights[s] = arrays["positions"][r][:, points, 1]
            contacts[s] = annotations["contacts"][r]
            phase[s] = annotations["phase"][r]
        examples.append(AnnotatedClip(cid, cfg.fps, heights, contacts, phase, CONTACT_POINTS))
    render_annotation(examples, out)


def config(params: dict) -> AnnotateConfig:
    p = params["annotate"]
    return AnnotateConfig(fps=float(params["ingest"]["target_fps"]), contacts=ContactConfig(**p["contacts"]),
                          lowpass_seconds=float(p["lowpass_seconds"]))


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_gaits: Path = OUT_GAITS,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict:
    params = load_params(params_path) if params_path else load_params()
    cfg = config(params)
    table, arrays = read_gaits(in_gaits)
    skeleton = load_skeleton(SKELETON)
    annotations, clips = annotate_windows(table.column("clip_id").to_pylist(), table.column("t_start").to_numpy(),
                                          arrays["positions"], arrays["rotations"], skeleton, cfg)
    write_parquet_atomic(with_arrays(table, annotations, ANNOTATION_META), out_gaits)
    stance = np.array([c["stance_fraction"] for c in clips.values()])
    contents = dict(zip(table.column("clip_id").to_pylist(), table.column("content").to_pylist()))
    walk_stance = np.array([c["stance_fraction"] for cid, c in clips.items() if contents[cid] == "walk"])
    report = {
        "gaits": table.num_rows,
        "clips": len(clips),
        "clips_without_phase": sorted(cid for cid, c in clips.items() if not c["phase_defined"]),
        "stance_fraction": {"all_median": float(np.median(stance)),
                            "walk_median": float(np.median(walk_stance)) if walk_stance.size else None,
                            "walk_p05": float(np.percentile(walk_stance, 5)) if walk_stance.size else None,
                            "walk_p95": float(np.percentile(walk_stance, 95)) if walk_stance.size else None},
        "per_clip": clips,
    }
    write_json_atomic(report, out_report)
    plot_examples(table, arrays, annotations, skeleton, cfg, out_plot)
    print(f"annotate: {report['gaits']} gaits from {report['clips']} clips; walk stance fraction median "
          f"{report['stance_fraction']['walk_median']:.2f}; {len(report['clips_without_phase'])} clips without phase")
    return report


if __name__ == "__main__":
    main()
