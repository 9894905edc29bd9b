"""How much the placed root path is smoothed (``generate.root_smoothing_s``), chosen by how real walks move, never
by the recognisers that grade the generator.

The stance-foot placement carries the root by the lowest foot point; when the stance passes from one foot to the
other that point jumps, and the root speed with it (synthetic root speed varies from frame to frame about twice
as much as real). For each window in ``--seconds`` every ``--every``-th plan row is generated (the synthesize
stage's seeds, trajectory pieces, per-frame emotions and placement, foot locking included) and compared with
the labelled real train walks (the seed pool) on physical figures only: per gait the mean frame-to-frame change
of the root's ground speed, its standard deviation over frames, the mean change of the root's step vector (the
movement feature κ), the net and path speeds; and the stance feet's skating speed. Rule: the shortest window
whose speed change per frame is at most the real walks' (median over gaits).

Printed as JSON and written to benchmarks/out/root_smoothing.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/root_smoothing.py [--seconds 0 0.1 0.2 0.3]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.ops.footlock import skating_speed  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, generate, place_paths  # noqa: E402
from pipeline.generators.autoregressive.training import load_checkpoint  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from pipeline.ops.geometry import odd_frames  # noqa: E402
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from stages.configs import contact_config, placement_config  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "root_smoothing.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"
MODEL = REPO / "data" / "models" / "full.pt"


def root_motion(ground: np.ndarray, fps: float) -> dict[str, float]:
    """Medians over gaits of ground paths (N, T, 2): speed change per frame, speed std over frames (m/s), step
    vector change per frame (m/frame, the movement feature κ), net and path speed (m/s)."""
    step = np.diff(ground, axis=1)
    speed = np.linalg.norm(step, axis=-1) * fps
    seconds = step.shape[1] / fps
    figures = {"speed_change_per_frame_m_s": np.abs(np.diff(speed, axis=1)).mean(1), "speed_std_m_s": speed.std(1),
               "step_change_m": np.linalg.norm(np.diff(step, axis=1), axis=-1).mean(1),
               "net_speed_m_s": np.linalg.norm(ground[:, -1] - ground[:, 0], axis=-1) / seconds,
               "path_speed_m_s": speed.mean(1)}
    return {k: round(float(np.median(v)), 4) for k, v in figures.items()}


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, nargs="+", default=[0.0, 0.1, 0.2, 0.3, 0.4])
    parser.add_argument("--every", type=int, default=5, help="every k-th plan row (1000 of the 5,000 at 5)")
    parser.add_argument("--batch", type=int, default=500)
    args = parser.parse_args()
    torch.set_num_threads(2)
    params = load_params()
    fps = float(params["ingest"]["target_fps"])
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(GAITS), cfg)
    skeleton = load_skeleton(SKELETON)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    model, _, sha = load_checkpoint(MODEL)
    rows = work.plan[:: args.every]
    shapes, per_frame = row_inputs(rows, work.emotions, {t.id: t for t in work.trajectories}, cfg)
    per_frame = torch.from_numpy(per_frame.astype(np.float32))
    walks = np.array([work.row_of[g] for g in work.seed_pools[-1]])
    real = torch.from_numpy(work.arrays["positions"][walks].astype(np.float32))
    contacts = contact_config(params)
    out = {"checkpoint_sha256": sha, "rows": len(rows), "fps": fps,
           "rule": "shortest window whose speed change per frame <= the real walks' (medians over gaits)",
           "real_labelled_train_walks": {"gaits": len(walks), **root_motion(real[:, :, 0, [0, 2]].numpy(), fps),
                                         "skating_m_s": round(skating_speed(real, fps, contacts)[0], 4)},
           "by_window": {}}
    for seconds in args.seconds:
        placement = replace(placement_config(params), root_smoothing_s=seconds)
        started = time.perf_counter()
        positions = []
        for first in range(0, len(rows), args.batch):
            part = slice(first, first + args.batch)
            seeds = Seeds.from_arrays(work.arrays, np.array([work.row_of[r["seed_gait_id"]] for r in rows[part]]),
                                      int(params["train"]["prefix"]))
            positions.append(generate(model, seeds, place_paths(shapes[part], seeds), per_frame[part], offsets,
                                      skeleton.parents, placement).positions)
        positions = torch.cat(positions)
        entry = {"frames": odd_frames(seconds, fps), **root_motion(positions[:, :, 0, [0, 2]].numpy(), fps),
                 "skating_m_s": round(skating_speed(positions, fps, contacts)[0], 4),
                 "seconds": round(time.perf_counter() - started, 2)}
        out["by_window"][str(seconds)] = entry
        print(f"window {seconds} s: {entry}", flush=True)
    limit = out["real_labelled_train_walks"]["speed_change_per_frame_m_s"]
    meeting = [float(s) for s, e in out["by_window"].items() if e["speed_change_per_frame_m_s"] <= limit]
    out["chosen_s"] = min(meeting) if meeting else None
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
