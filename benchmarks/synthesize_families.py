"""Synthesis of the 5,000-row plan by every generator family (issue 12: goal ≤ 60 s each, annotation included, on
2 cores): each family's DVC stage (`synthesize`, `synthesize_pca_gaussian`,
`synthesize_motion_graph`) run into a scratch directory and
timed, with the figures of its report that say what was made.

Printed as JSON and written to benchmarks/out/synthesize_families.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/synthesize_families.py``.
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
from stages.synthesize import main as autoregressive_stage  # noqa: E402
from stages.synthesize_motion_graph import main as motion_graph_stage  # noqa: E402
from stages.synthesize_pca_gaussian import main as pca_gaussian_stage  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "synthesize_families.json"
STAGES = {"autoregressive_affect": autoregressive_stage, "pca_gaussian": pca_gaussian_stage,
          "motion_graph": motion_graph_stage}


def main() -> dict:
    out = {}
    for name, stage in STAGES.items():
        with tempfile.TemporaryDirectory() as scratch:
            where = Path(scratch)
            started = time.perf_counter()
            report = stage(out=where / name, out_report=where / "report.json", out_plot=where / "paths.png")
            seconds = time.perf_counter() - started
        out[name] = {"stage_seconds": round(seconds, 1), "gaits": report["gaits"],
                     "model_sha256": report["model_sha256"], "finite": report["finite"],
                     "copied_real_frames": report["copied_real_frames"]}
    out["note"] = ("stage_seconds: the whole stage (plan, model load, generation, annotation, novelty report, files); "
                   "the generation + annotation share is printed by the stage itself")
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
