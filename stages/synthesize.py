"""DVC stage `synthesize`: the 5,000-gait plan and its gaits (pipeline/synth/synthesis.py).

data/split/gaits.parquet + data/models/full.pt -> data/synthesized/gaits.parquet (synthetic gaits with lineage),
data/synthesized/plan.csv (one row per gait), reports/synthesize.json (counts, novelty tests), reports/synthesize.png.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import torch

from pipeline.core.skeleton import load_skeleton
from pipeline.generators.autoregressive.family import AutoregressiveFamily
from pipeline.io.files import write_csv, write_json, write_parquet
from pipeline.io.gait_table import read_gaits
from pipeline.publish.table import synthetic_table
from pipeline.synth.plan import recipe_json
from pipeline.synth.synthesis import (PLAN_COLUMNS, SynthesisConfig, SynthesisPlan, placed_root_paths, plan_rows,
                                      synthesis_report, synthesize)
from pipeline.viz.stick_figures import render_trajectories
from stages.common import REPO, SKELETON, load_params
from stages.configs import annotate_config, placement_config

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
IN_MODEL = REPO / "data" / "models" / "full.pt"
OUT = REPO / "data" / "synthesized"
OUT_REPORT = REPO / "reports" / "synthesize.json"
OUT_PLOT = REPO / "reports" / "synthesize.png"


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, in_model: Path = IN_MODEL, out: Path = OUT,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    torch.set_num_threads(2)
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(in_gaits), cfg)
    family = AutoregressiveFamily.from_checkpoint(in_model, work.arrays, work.row_of, load_skeleton(SKELETON),
                                                  placement_config(params), int(params["train"]["prefix"]))
    started = time.perf_counter()
    synthetic = synthesize(family, work.plan, work.emotions, {t.id: t for t in work.trajectories}, family.skeleton,
                           annotate_config(params), cfg,
                           progress=lambda done, total: print(f"synthesize: {done}/{total} gaits", flush=True))
    seconds = time.perf_counter() - started
    fallback = [r["gait_id"] for r, f in zip(work.plan, synthetic.pop("phase_from_condition")) if f]
    recipes = [recipe_json(r["recipe"], work.emotions) for r in work.plan]
    write_parquet(synthetic_table(work.plan, recipes, synthetic, family.model_sha256, work.table), out / "gaits.parquet")
    write_csv(PLAN_COLUMNS, plan_rows(work.plan, recipes), out / "plan.csv")
    report = synthesis_report(work, synthetic, cfg, float(params["ingest"]["target_fps"]), family.model_sha256,
                              fallback)
    write_json(report, out_report)
    render_trajectories(placed_root_paths(work, synthetic["root_path"]), out_plot)
    print(f"synthesize: {report['gaits']} gaits in {seconds:.1f} s "
          f"({report['gaits'] * cfg.frames / seconds:.0f} agent-frames/s); "
          f"emotions novel {report['emotion_novelty']['passed']}, "
          f"trajectories novel {report['trajectory_novelty']['passed']}, copied frames {report['copied_real_frames']}")
    return report


if __name__ == "__main__":
    main()
