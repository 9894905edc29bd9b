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
from pipeline.evaluation.families import (AffectReference, family_sensitivity, markdown, sensitivity_rows,
                                          side_by_side, under_one_hot)
from pipeline.io.files import write_json, write_text
from pipeline.io.gait_table import read_gaits
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs
from pipeline.viz.stick_figures import Motion, render_filmstrip
from stages import synthesize, synthesize_pca_gaussian
from stages.common import REPO, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
REPORTS = REPO / "reports"
SYNTHESIS_REPORTS = {"autoregressive_affect": "synthesize.json", "pca_gaussian": "synthesize_pca_gaussian.json"}
MODEL_REPORTS = {"pca_gaussian": ("pca_gaussian.json", ("emotion_in_pc_space", "novelty"))}


BUILDERS = {"autoregressive_affect": synthesize.family, "pca_gaussian": synthesize_pca_gaussian.family}


def families(params: dict[str, Any], work: SynthesisPlan) -> dict[str, Any]:
    """Every family of ``synthesize.families``, built as its synthesis stage builds it."""
    return {name: BUILDERS[name](params, work) for name in params["synthesize"]["families"]}


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
    audit = json.loads((reports / "audit" / "metrics.json").read_text())
    report = {"sensitivity_rows": len(rows), **side_by_side(list(sensitivity), synthesis, audit, sensitivity,
                                                            model_figures)}
    write_json(report, reports / "families.json")
    write_text(markdown(report), reports / "families.md")
    for name, f in report["families"].items():
        rec = ", ".join(f"{r['name']} {r['synthetic_balanced_accuracy']:.3f}" for r in f["recognition"].values())
        print(f"evaluate_families: {name}: recognised {rec}; condition sensitivity "
              f"{f['condition_sensitivity']['fraction_of_real']:.2f}; skating {f['foot_skating_ratio_to_real']:.2f}x")
    return report


if __name__ == "__main__":
    main()
