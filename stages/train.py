"""DVC stage `train`: the autoregressive generator and its ablation(s), trained on the train split, checked on val.

data/split/gaits.parquet -> data/models/{full,no_affect}.pt (one per params variant), reports/train.json (DVC
metrics: final losses, the style critic's figures, checkpoint sha256; no timings, which are printed), reports/train_curves.csv (DVC
plots: loss per epoch and variant).
The variants (params.yaml ``train.variants``) train in parallel processes, ``train.threads`` torch threads each
(pipeline/generators/autoregressive/fit.py).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from pipeline.core.skeleton import load_skeleton
from pipeline.generators.autoregressive.fit import (
    CURVE_COLUMNS,
    critic_config,
    curve_rows,
    fit_variants,
    variant_configs,
    variant_summary,
)
from pipeline.generators.autoregressive.training import config_dicts
from pipeline.io.files import write_bytes, write_csv, write_json
from stages.common import REPO, SKELETON, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
OUT_MODELS = REPO / "data" / "models"
OUT_REPORT = REPO / "reports" / "train.json"
OUT_CURVES = REPO / "reports" / "train_curves.csv"


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_models: Path = OUT_MODELS,
         out_report: Path = OUT_REPORT, out_curves: Path = OUT_CURVES) -> dict:
    params = load_params(params_path) if params_path else load_params()
    p = params["train"]
    variants = variant_configs(p)
    start = time.perf_counter()
    results = fit_variants(in_gaits, variants, load_skeleton(SKELETON), int(p.get("parallel", 1)),
                           int(p.get("progress_every", 25)), critic_config(p))
    seconds = time.perf_counter() - start
    report: dict[str, Any] = {"variants": {}}
    for res in results:
        path = out_models / f"{res['name']}.pt"
        report["variants"][res["name"]] = {
            "checkpoint": str(path.relative_to(REPO) if path.is_relative_to(REPO) else path),
            "sha256": write_bytes(res["checkpoint"], path), **variant_summary(res)}
    report["configs"] = {name: config_dicts(*variants[name]) for name in variants}
    write_json(report, out_report)
    write_csv(CURVE_COLUMNS, curve_rows(results), out_curves)
    for res in results:
        v = report["variants"][res["name"]]
        print(f"train: {res['name']}: val loss {v['val'].get('total', float('nan')):.3f} after {v['epochs']} epochs "
              f"({res['seconds']:.0f} s), sha256 {v['sha256'][:12]}")
    print(f"train: {len(results)} variant(s) in {seconds:.0f} s")
    return report


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
