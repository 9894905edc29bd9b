"""The motion graph family (issue 13: graph build ≤ 30 s, search of all 5,000 plan rows ≤ 60 s, on 2 cores): the
graph built from the split gaits (frames, costs, thresholds for every reported k, SCC), then the search alone
for every plan row in the synthesis stage's batches, each timed in one run.

Printed as JSON and written to benchmarks/out/motion_graph.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/motion_graph.py``.
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.generators.motion_graph.graph import GraphConfig, build_graph, clip_frames  # noqa: E402
from pipeline.generators.motion_graph.search import search  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from stages.configs import annotate_config, motion_graph_settings  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "motion_graph.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"


def main() -> dict:
    torch.set_num_threads(2)
    params = load_params()
    table, arrays = read_gaits(GAITS)
    cfg = GraphConfig.from_dict(params["motion_graph"]["graph"])
    started = time.perf_counter()
    frames = clip_frames(table, arrays, load_skeleton(SKELETON), cfg, annotate_config(params))
    graph = build_graph(frames, cfg)
    build = time.perf_counter() - started
    synthesis = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(table, arrays, synthesis)
    trajectories = {t.id: t for t in work.trajectories}
    settings, walk = motion_graph_settings(params)
    levels: Counter = Counter()
    seconds = 0.0
    for first in range(0, len(work.plan), synthesis.batch):
        rows = work.plan[first:first + synthesis.batch]
        shapes, per_frame = row_inputs(rows, work.emotions, trajectories, synthesis)
        started = time.perf_counter()
        _, level = search(graph, per_frame, shapes.double().numpy(), [int(r["plan_seed"]) for r in rows],
                          walk.context, settings)
        seconds += time.perf_counter() - started
        levels.update(level)
    out = {"graph_build_seconds": round(build, 1), "graph_build_goal_seconds": 30,
           "states": len(frames), "states_kept": int(graph.kept.sum()),
           "search_seconds_all_rows": round(seconds, 1), "search_goal_seconds": 60, "rows": len(work.plan),
           "search_levels": dict(levels), "n_save": settings.n_save,
           "note": "graph build: frames, annotation of the rebuilt clips, costs, Johnson SB fits and SCC for every "
                   "reported k; search: the beam search alone (no blending, placement or annotation), in the "
                   "stage's batches, fallback levels included"}
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
