"""Fitting the PCA + Gaussian family (issue 12, seed 001): the `fit_pca_gaussian` stage run on the split gaits
into a scratch directory, timed (goal: < 10 s on 2 cores), with the stage's report (cycle counts, cumulative
explained variance, reconstruction errors at 10 components and at the kept number, the emotion models).

Printed as JSON and written to benchmarks/out/pca_gaussian_fit.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/pca_gaussian_fit.py``.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from pipeline.io.files import write_json  # noqa: E402
from stages.fit_pca_gaussian import main as fit_stage  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "pca_gaussian_fit.json"


def main() -> dict:
    with tempfile.TemporaryDirectory() as scratch:
        where = Path(scratch)
        started = time.perf_counter()
        report = fit_stage(out_model=where / "model.pt", out_report=where / "report.json",
                           out_plot=where / "variance.png")
        seconds = time.perf_counter() - started
    out = {"fit_seconds": round(seconds, 2), **{k: v for k, v in report.items() if k != "model"}}
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
