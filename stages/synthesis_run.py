"""What the synthesis stages of every generator family share (``stages/synthesize*.py``): the plan from the split
gaits, one family's gaits for every plan row with the same annotation as real gaits, and the files.

data/synthesized/<family>/: gaits.parquet (the family's synthetic gaits in the published schema, with lineage),
plan.csv (one row per gait), lineage.json (the family's model lineage, published beside its gaits);
reports/<stage>.json (counts, novelty tests; no timings, which are printed) and reports/<stage>.png (the placed
root paths on every trajectory).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from pipeline.generators.base import GeneratorFamily
from pipeline.io.files import write_csv, write_json, write_parquet
from pipeline.io.gait_table import read_gaits
from pipeline.publish.table import generator_entry, synthetic_table
from pipeline.synth.plan import recipe_json
from pipeline.synth.synthesis import (PLAN_COLUMNS, SynthesisConfig, SynthesisPlan, placed_root_paths, plan_rows,
                                      synthesis_report, synthesize)
from pipeline.viz.stick_figures import render_trajectories
from stages.common import REPO
from stages.configs import annotate_config

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
SYNTHESIZED = REPO / "data" / "synthesized"


def run_synthesis(stage: str, params: dict[str, Any], make_family: Callable[[SynthesisPlan], GeneratorFamily],
                  in_gaits: Path = IN_GAITS, out: Path | None = None, out_report: Path | None = None,
                  out_plot: Path | None = None) -> dict[str, Any]:
    """Synthesize the plan with the family ``make_family`` builds from the prepared plan (its split gaits are
    the seeds' source); outputs default to data/synthesized/<family>/ and reports/<stage>.{json,png}."""
    torch.set_num_threads(2)
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(in_gaits), cfg)
    family = make_family(work)
    annotate = annotate_config(params)
    out = out or SYNTHESIZED / family.name
    out_report = out_report or REPO / "reports" / f"{stage}.json"
    out_plot = out_plot or REPO / "reports" / f"{stage}.png"
    started = time.perf_counter()
    synthetic = synthesize(family, work.plan, work.emotions, {t.id: t for t in work.trajectories}, family.skeleton,
                           annotate, cfg,
                           progress=lambda done, total: print(f"{stage}: {done}/{total} gaits", flush=True))
    seconds = time.perf_counter() - started
    fallback = [r["gait_id"] for r, f in zip(work.plan, synthetic.pop("phase_from_condition")) if f]
    recipes = [recipe_json(r["recipe"], work.emotions) for r in work.plan]
    entry = generator_entry(family.name, family.description, family.model_sha256, family.seeded,
                            getattr(family, "extra_lineage", ()))
    named = str(params["synthesize"]["named_family"])
    write_parquet(synthetic_table(work.plan, recipes, synthetic, entry, work.table, named), out / "gaits.parquet")
    write_csv(PLAN_COLUMNS, plan_rows(work.plan, recipes), out / "plan.csv")
    write_json({**entry, "model_lineage": family.lineage()}, out / "lineage.json")
    report = {"generator": family.name,
              **synthesis_report(work, synthetic, cfg, float(params["ingest"]["target_fps"]), family.model_sha256,
                                 fallback, seeded=family.seeded, contacts=annotate.contacts)}
    if counts := getattr(family, "counts", None):
        report["generator_counts"] = dict(sorted(counts.items()))
    if hasattr(family, "report"):
        report.update(family.report())
    write_json(report, out_report)
    render_trajectories(placed_root_paths(work, synthetic["root_path"], synthetic.get("piece_placement")), out_plot)
    skating = report["foot_skating"]
    print(f"{stage}: foot skating {skating['ratio_to_real']:.2f}x real, path deviation "
          f"{report['path_deviation_m']['all']['mean']:.3f} m (mean)")
    print(f"{stage}: {report['gaits']} {family.name} gaits in {seconds:.1f} s "
          f"({report['gaits'] * cfg.frames / seconds:.0f} agent-frames/s); "
          f"emotions novel {report['emotion_novelty']['passed']}, "
          f"trajectories novel {report['trajectory_novelty']['passed']}, copied frames {report['copied_real_frames']}")
    return report
