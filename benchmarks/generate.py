"""Generation benchmark: agent-frames per second of batched generation (pipeline.generators.autoregressive.rollout.generate) on this machine.

For each batch size N in ``--agents``: N seed gaits (test-split windows of data/split/gaits.parquet, cycled when
there are fewer), a sharp-turn path each, a per-frame emotion, ``--steps`` generated frames in ONE call. Timed
after one warm-up call; the median of ``--repeats`` is reported as agent-frames per second (N × steps / seconds),
with the torch thread count. Then the synthesize stage's work on the whole 5,000-gait plan (generation and
annotation, in the stage's batches), timed ``--synthesis-repeats`` times (median). The model is
data/models/full.pt when it exists (the sizes in params.yaml otherwise: speed does not depend on the weights).
Printed as JSON and written to benchmarks/out/generate.json.

Run from the repository root:  ``make bench``  or  ``python benchmarks/generate.py [--agents 1 16 64 256]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.evaluation.autoregressive import turn_path  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, generate, place_paths  # noqa: E402
from pipeline.generators.autoregressive.network import EmotiveGaitNet, GeneratorConfig  # noqa: E402
from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.generators.autoregressive.training import load_checkpoint  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from pipeline.generators.autoregressive.family import AutoregressiveFamily  # noqa: E402
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, synthesize  # noqa: E402
from stages.configs import annotate_config, placement_config  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "generate.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"
MODEL = REPO / "data" / "models" / "full.pt"


def synthesis_figures(model_path: Path, params: dict, repeats: int) -> dict:
    """The synthesize stage's work on the whole plan (generation + annotation, no file writes), timed."""
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(GAITS), cfg)
    skeleton = load_skeleton(SKELETON)
    family = AutoregressiveFamily.from_checkpoint(model_path, work.arrays, work.row_of, skeleton,
                                                  placement_config(params), int(params["train"]["prefix"]))
    trajectories = {t.id: t for t in work.trajectories}
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        synthesize(family, work.plan, work.emotions, trajectories, skeleton, annotate_config(params), cfg)
        times.append(time.perf_counter() - start)
    seconds = statistics.median(times)
    return {"gaits": len(work.plan), "frames_per_gait": cfg.frames, "seconds": round(seconds, 2),
            "seconds_all": [round(t, 2) for t in times], "target_seconds": 60,
            "agent_frames_per_s": round(len(work.plan) * cfg.frames / seconds, 1)}


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", type=int, nargs="+", default=[1, 16, 64, 256])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--synthesis-repeats", type=int, default=1,
                        help="times to synthesize the whole default plan (5,000 gaits; 0 skips it)")
    args = parser.parse_args()
    if not GAITS.exists():
        sys.exit(f"{GAITS} is missing: run `make repro` (or `dvc repro split`) first")
    torch.set_num_threads(args.threads)
    params = load_params()
    skeleton = load_skeleton(SKELETON)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    if MODEL.exists():
        model, _, sha = load_checkpoint(MODEL)
        source = f"{MODEL.relative_to(REPO)} (sha256 {sha[:12]})"
    else:
        model = EmotiveGaitNet(GeneratorConfig.from_dict(params["train"]["model"])).eval()
        source = "untrained, params.yaml train.model sizes"
    table, arrays = read_gaits(GAITS)
    test = np.flatnonzero(np.array(table.column("split").to_pylist()) == "test")
    placement = placement_config(params)
    prefix = int(params["train"]["prefix"])
    results = []
    for n in args.agents:
        rows = test[np.arange(n) % len(test)]
        seeds = Seeds.from_arrays(arrays, rows, prefix)
        paths = place_paths(turn_path(), seeds)
        emotions = torch.zeros(n, args.steps, 4)
        emotions[..., 0] = torch.linspace(1.0, 0.0, args.steps)
        emotions[..., 1] = 1.0 - emotions[..., 0]
        generate(model, seeds, paths, emotions, offsets, skeleton.parents, placement)  # warm-up
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            generate(model, seeds, paths, emotions, offsets, skeleton.parents, placement)
            times.append(time.perf_counter() - start)
        seconds = statistics.median(times)
        results.append({"agents": n, "steps": args.steps, "seconds": round(seconds, 4),
                        "agent_frames_per_s": round(n * args.steps / seconds, 1)})
    out = {"model": source, "threads": args.threads, "torch": torch.__version__, "results": results}
    if args.synthesis_repeats and MODEL.exists():
        out["synthesis"] = synthesis_figures(MODEL, params, args.synthesis_repeats)
    write_json(out, OUT, sort_keys=False)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
