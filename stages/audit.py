"""DVC stage `audit` (and `emogait audit PATH`): label and quality audit of a published gait directory.

data/published/synthesized_emotive_gaits/ (or any published directory) -> reports/audit/: metrics.json (DVC
metrics), *.png (DVC plots) and index.html, which shows them all (pipeline/audit/run.py).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import torch

from pipeline.audit.metrics import AuditConfig
from pipeline.audit.report import control_line, verdict_lines
from pipeline.audit.run import audit_directory
from stages.common import REPO, load_params

PUBLISHED = REPO / "data" / "published" / "synthesized_emotive_gaits"
OUT = REPO / "reports" / "audit"


def main(params_path: Path | None = None, directory: Path = PUBLISHED, out: Path = OUT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    p = params["audit"]
    torch.set_num_threads(int(p.get("threads", 2)))
    print(f"audit: {directory}", flush=True)
    started = time.perf_counter()
    metrics = audit_directory(Path(directory), Path(out), AuditConfig.from_dict(p), progress=True)
    print(f"audit: {metrics['gaits']} gaits, {metrics['problem_count']} problems -> {out} "
          f"({time.perf_counter() - started:.0f} s)")
    for family, verdict in verdict_lines(metrics["recognisability"]):
        print(f"audit: {family}: {verdict}")
    control = control_line(metrics["recognisability"])
    if control:
        print(f"audit: {control}")
    memo = metrics.get("memorisation", {})
    if "check" in memo:
        print(f"audit: nearest train window, median: synthetic {memo['synthetic']['median']:.3f} m, real held-out "
              f"{memo['real_held_out']['median']:.3f} m")
    return metrics


if __name__ == "__main__":
    main(directory=Path(sys.argv[1]) if len(sys.argv) > 1 else PUBLISHED)
