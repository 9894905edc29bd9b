"""Fitting the PCA + Gaussian family (issue 12, seed 001) on the split gaits: cycle counts, the basis' cumulative
explained variance (paper Fig. 2), reconstruction errors at 10 components and at the chosen number, the emotion
models' sizes and durations, and the seconds of each step (goal: the whole fit < 10 s on 2 cores).

Printed as JSON and written to benchmarks/out/pca_gaussian_fit.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/pca_gaussian_fit.py``.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.generators.pca_gaussian.cycles import CycleConfig, cut_cycles  # noqa: E402
from pipeline.generators.pca_gaussian.model import (  # noqa: E402
    ModelConfig, balanced_rows, fit_basis, fit_style_models, reconstruction_errors)
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from stages.configs import annotate_config  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "pca_gaussian_fit.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"


def main() -> dict:
    skeleton = load_skeleton(SKELETON)
    table, arrays = read_gaits(GAITS)
    cycle_cfg, cfg = CycleConfig(), ModelConfig()
    seconds = {}
    started = time.perf_counter()
    cycles = cut_cycles(table, arrays, skeleton, cycle_cfg, annotate_config(load_params()))
    seconds["cycles"] = time.perf_counter() - started
    started = time.perf_counter()
    basis = fit_basis(cycles.flat(), balanced_rows(cycles.style, cfg.per_style, cfg.seed))
    k = basis.components_for(cfg.variance)
    models = fit_style_models(basis.scores(cycles.flat(), k), cycles.durations, cycles.dominant(), cycles.follows,
                              cfg.prior_cycles)
    seconds["basis_and_models"] = time.perf_counter() - started
    cumulative = np.cumsum(basis.explained)
    errors = [reconstruction_errors(cycles.flat(), basis, n, skeleton.offsets, skeleton.parents, cycle_cfg.frames)
              for n in sorted({min(10, len(cumulative)), k})]
    out = {"cycles": cycles.counts(), "basis_cycles": int(len(basis.basis_rows)),
           "components_available": int(len(cumulative)), "variance_goal": cfg.variance, "components_kept": k,
           "cumulative_variance_first_30": [round(float(v), 4) for v in cumulative[:30]],
           "components_for": {f"{v:.2f}": basis.components_for(v) for v in (0.8, 0.9, 0.95, 0.99)},
           "reconstruction": errors,
           "models": {name: {"cycles": m.cycles, "duration_frames_mean_std": [round(m.duration_mean, 2),
                                                                              round(m.duration_std, 2)]}
                      for name, m in zip(EMOTIONS, models)},
           "seconds": {k2: round(v, 2) for k2, v in seconds.items()},
           "fit_seconds": round(sum(seconds.values()), 2)}
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
