"""DVC stage `evaluate_families`: every generator family side by side on the shared plan (pipeline/evaluation/
families.py), after the audit of the published directory.

data/split/gaits.parquet + each family's model + reports/synthesize*.json + reports/pca_gaussian.json +
reports/audit/metrics.json -> reports/families.json (DVC metrics), reports/families.md (the table) and, per
family, reports/families_emotions_<family>.png (one plan row under the four one-hot emotions) and
reports/families_transition_<family>.png (the same row in one transition).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.evaluation.autoregressive import one_hot_transition
from pipeline.evaluation.families import (AffectReference, constraint_ablation, family_sensitivity, markdown,
                                          sensitivity_rows, side_by_side, under_one_hot)
from pipeline.io.files import write_json, write_text
from pipeline.io.gait_table import read_gaits
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs
from pipeline.viz.stick_figures import Motion, render_filmstrip
from stages import synthesize, synthesize_motion_graph, synthesize_pca_gaussian
from stages.common import REPO, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
REPORTS = REPO / "reports"
SYNTHESIS_REPORTS = {"autoregressive_affect": "synthesize.json", "pca_gaussian": "synthesize_pca_gaussian.json",
                     "motion_graph": "synthesize_motion_graph.json"}
MODEL_REPORTS = {"pca_gaussian": ("pca_gaussian.json", ("emotion_in_pc_space", "novelty")),
                 "motion_graph": ("motion_graph.json", ("table", "key_state_share", "nodes_per_emotion"))}
SEARCH_FIGURES = ("search", "synthetic_transitions_per_gait", "frames_of_planned_dominant_emotion",
                  "warp_deg_per_frame", "longest_unbroken_real_segment_frames", "real_frames_by_design")


BUILDERS = {"autoregressive_affect": synthesize.family, "pca_gaussian": synthesize_pca_gaussian.family,
            "motion_graph": synthesize_motion_graph.family}


def families(params: dict[str, Any], work: SynthesisPlan) -> dict[str, Any]:
    """Every family of ``synthesize.families``, built as its synthesis stage builds it."""
    return {name: BUILDERS[name](params, work) for name in params["synthesize"]["families"]}


def ablation(params: dict[str, Any], work: SynthesisPlan, trajectories: dict[str, Any], cfg: SynthesisConfig,
             count: int) -> dict[str, Any]:
    """The motion graph's constraints switched off in turn on ``count`` single-emotion plan rows, read by the
    audit's summary MLP fitted here on the real labelled train gaits (the audit's settings, its first seed)."""
    from pipeline.core.skeleton import load_skeleton
    from pipeline.recognition import RecognitionInputs, RecogniserConfig, fit_recogniser
    from pipeline.synth.synthesis import window_features
    from stages.common import SKELETON
    from stages.configs import annotate_config, contact_config

    a = work.arrays
    split = np.array(work.table.column("split").to_pylist())
    content = np.array(work.table.column("content").to_pylist())
    train = np.flatnonzero((split == "train") & ~np.isnan(a["emotion"]).any(-1))
    inputs = RecognitionInputs(positions=a["positions"][train], heading=a["heading"][train],
                               affective=a["affective"][train], movement=a["movement"][train])
    audit = params["audit"]
    recogniser = fit_recogniser("summary_mlp", inputs, a["emotion"][train].argmax(-1),
                                RecogniserConfig.from_dict(audit["recognisers"]), int(audit["seeds"]["summary_mlp"][0]))
    skeleton, annotate = load_skeleton(SKELETON), annotate_config(params)

    def features(positions, rotations):
        f = window_features(positions, rotations, skeleton, annotate)
        return f["affective"], f["movement"]

    walks = np.flatnonzero((split == "train") & (content == "walk") & ~np.isnan(a["emotion"]).any(-1))
    rows = sensitivity_rows(work.plan, count)
    return constraint_ablation(lambda **search: synthesize_motion_graph.family(params, work, **search), rows,
                               work.emotions, trajectories, cfg, recogniser, features, a["positions"][walks],
                               float(params["ingest"]["target_fps"]), contact_config(params))


def main(params_path: Path | None = None, reports: Path = REPORTS) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    p = params["evaluate_families"]
    torch.set_num_threads(2)
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(IN_GAITS), cfg)
    split = np.array(work.table.column("split").to_pylist())
    labelled = ~np.isnan(work.arrays["emotion"]).any(-1)
    train = np.flatnonzero((split == "train") & labelled)
    reference = AffectReference(work.arrays["positions"][train], work.arrays["emotion"][train])
    trajectories = {t.id: t for t in work.trajectories}
    rows = sensitivity_rows(work.plan, int(p["sensitivity_rows"]))
    preview_row = next(r for r in work.plan if r["recipe"]["kind"] == "single"
                       and r["trajectory_id"] == p["preview_trajectory"])
    start, end = (EMOTIONS.index(e) for e in p["preview_transition"])
    sensitivity = {}
    for name, family in families(params, work).items():
        print(f"evaluate_families: {name}: {len(rows)} plan rows under the four one-hot emotions", flush=True)
        sensitivity[name] = family_sensitivity(under_one_hot(family, rows, work.emotions, trajectories, cfg),
                                               reference)
        shown = under_one_hot(family, [preview_row], work.emotions, trajectories, cfg)
        parents, names = family.skeleton.parents, family.skeleton.names
        render_filmstrip([Motion(f"{name}: {e} ({preview_row['trajectory_id']})", g.positions[0].numpy(), parents,
                                 names) for e, g in zip(EMOTIONS, shown)],
                         reports / f"families_emotions_{name}.png")
        shapes, _ = row_inputs([preview_row], work.emotions, trajectories, cfg)
        g = family.generate([preview_row], shapes, one_hot_transition(start, end, cfg.frames, 1))
        render_filmstrip([Motion(f"{name}: {EMOTIONS[start]} -> {EMOTIONS[end]} ({preview_row['trajectory_id']})",
                                 g.positions[0].numpy(), parents, names)], reports / f"families_transition_{name}.png")
    synthesis = {n: json.loads((reports / SYNTHESIS_REPORTS[n]).read_text()) for n in sensitivity}
    model_figures = {}
    for name, (file, keys) in MODEL_REPORTS.items():
        if name in sensitivity:
            figures = json.loads((reports / file).read_text())
            model_figures[name] = {k: figures[k] for k in keys}
    for name in sensitivity:
        if name == "motion_graph":
            model_figures[name].update({k: synthesis[name][k] for k in SEARCH_FIGURES if k in synthesis[name]})
    audit = json.loads((reports / "audit" / "metrics.json").read_text())
    report = {"sensitivity_rows": len(rows), **side_by_side(list(sensitivity), synthesis, audit, sensitivity,
                                                            model_figures)}
    if "motion_graph" in sensitivity:
        report["motion_graph_ablation"] = ablation(params, work, trajectories, cfg, int(p["ablation_rows"]))
        for variant, v in report["motion_graph_ablation"]["variants"].items():
            print(f"evaluate_families: motion_graph, {variant}: balanced accuracy {v['balanced_accuracy']:.3f}, "
                  f"path deviation {v['path_deviation_m']:.3f} m, skating {v['foot_skating_ratio_to_real']:.2f}x")
    write_json(report, reports / "families.json")
    write_text(markdown(report), reports / "families.md")
    for name, f in report["families"].items():
        rec = ", ".join(f"{r['name']} {r['synthetic_balanced_accuracy']:.3f}" for r in f["recognition"].values())
        print(f"evaluate_families: {name}: recognised {rec}; condition sensitivity "
              f"{f['condition_sensitivity']['fraction_of_real']:.2f}; skating {f['foot_skating_ratio_to_real']:.2f}x")
    return report


if __name__ == "__main__":
    main()
