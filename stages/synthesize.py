"""DVC stage `synthesize`: the 5,000-gait plan and its gaits.

data/split/gaits.parquet + data/models/full.pt -> data/synthesized/gaits.parquet (synthetic gaits with lineage),
data/synthesized/plan.csv (one row per gait), reports/synthesize.json (counts, novelty tests), reports/synthesize.png.
"""

from __future__ import annotations

import csv
import io
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.io.gait_table import atomic_path, read_gaits, write_json_atomic, write_parquet_atomic
from pipeline.generators.autoregressive.rollout import PlacementConfig
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.synth.novelty import (
    distinct_labels,
    l1_to_labels,
    nearest_training_path,
    novel_emotions,
    training_nearest_distances,
    training_paths,
)
from pipeline.synth.plan import build_plan, recipe_json
from pipeline.synth.trajectories import Trajectory, onto, piece_from, start_pose, trajectories_from_params
from pipeline.viz.stick_figures import render_trajectories
from pipeline.publish.table import synthetic_table
from pipeline.core.skeleton import load_skeleton
from pipeline.synth.synthesis import SynthesisConfig, copied_frames, synthesize
from pipeline.generators.autoregressive.training import load_checkpoint
from stages.annotate import config as annotate_config
from stages.common import REPO, SKELETON, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
IN_MODEL = REPO / "data" / "models" / "full.pt"
OUT = REPO / "data" / "synthesized"
OUT_REPORT = REPO / "reports" / "synthesize.json"
OUT_PLOT = REPO / "reports" / "synthesize.png"


@dataclass
class Synthesis:
    """Everything the plan needs, from params and the split gaits (shared with benchmarks/generate.py)."""

    params: dict[str, Any]
    table: pa.Table
    arrays: dict[str, np.ndarray]
    labels: np.ndarray  # the train split's emotion labels
    emotions: np.ndarray
    trajectories: list[Trajectory]
    seed_pool: list[str]  # test-split gaits whose prefixes seed the synthetic gaits
    plan: list[dict[str, Any]]

    @classmethod
    def prepare(cls, params: dict[str, Any], in_gaits: Path = IN_GAITS) -> Synthesis:
        p = params["synthesize"]
        table, arrays = read_gaits(in_gaits)
        split = np.array(table.column("split").to_pylist())
        content = np.array(table.column("content").to_pylist())
        labels = arrays["emotion"][split == "train"]
        labels = labels[~np.isnan(labels).any(-1)].astype(np.float64)
        emotions = novel_emotions(int(p["emotions"]), labels, float(p["min_l1_to_training"]),
                                  np.random.default_rng([int(p["seed"]), 0]))
        trajectories = trajectories_from_params(p["trajectories"], float(p["start_span_m"]))
        gait_ids = table.column("gait_id").to_pylist()
        seed_pool = [gait_ids[i] for i in np.flatnonzero((split == "test") & (content == p["seed_content"]))]
        plan = build_plan(trajectories, emotions, seed_pool, int(p["transition_rounds"]), int(p["seed"]))
        return cls(params, table, arrays, labels, emotions, trajectories, seed_pool, plan)

    def run(self, model: EmotiveGaitNet, progress: bool = False) -> dict[str, np.ndarray]:
        params, p = self.params, self.params["synthesize"]
        cfg = SynthesisConfig(prefix=int(params["train"]["prefix"]), frames=int(params["ingest"]["window"]),
                              path_ahead_m=float(p["path_ahead_m"]), batch=int(p["batch"]))
        placement = PlacementConfig.from_params(params.get("generate") or {}, params["ingest"]["target_fps"])
        row_of = {g: i for i, g in enumerate(self.table.column("gait_id").to_pylist())}
        return synthesize(model, self.arrays, row_of, self.plan, self.emotions, {t.id: t for t in self.trajectories},
                          load_skeleton(SKELETON), placement, annotate_config(params), cfg,
                          progress=(lambda done, total: print(f"synthesize: {done}/{total} gaits", flush=True))
                          if progress else None)


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, in_model: Path = IN_MODEL, out: Path = OUT,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    p = params["synthesize"]
    torch.set_num_threads(2)
    work = Synthesis.prepare(params, in_gaits)
    table, arrays, plan, emotions, trajectories = work.table, work.arrays, work.plan, work.emotions, work.trajectories
    split = np.array(table.column("split").to_pylist())
    clip_ids = table.column("clip_id").to_pylist()
    fps, window = float(params["ingest"]["target_fps"]), int(params["ingest"]["window"])
    train = np.flatnonzero(split == "train")
    novelty = p["novelty"]
    emotion_l1 = l1_to_labels(emotions, work.labels)

    # trajectories: novel w.r.t. the training clips' root paths
    starts = np.round(table.column("t_start").to_numpy()[train] * fps).astype(int)
    paths = training_paths(arrays["root_path"][train], [clip_ids[i] for i in train], starts, window)
    min_compared = float(novelty["min_compared_m"])
    reference = training_nearest_distances(paths, min_compared)
    shapes = {t.id: nearest_training_path(t.points, paths, min_compared) for t in trajectories}

    model, _, checkpoint_sha = load_checkpoint(in_model)
    started = time.perf_counter()
    synthetic = work.run(model, progress=True)
    seconds = time.perf_counter() - started
    phase_from_condition = [r["gait_id"] for r, f in zip(plan, synthetic.pop("phase_from_condition")) if f]

    # the pieces single gaits walk vs the training paths over the same length (reported, not a test)
    by_id = {t.id: t for t in trajectories}
    piece_m = float(np.median(np.linalg.norm(np.diff(synthetic["root_path"], axis=1), axis=-1).sum(1)))
    closeness = np.array([nearest_training_path(piece_from(by_id[r["trajectory_id"]].points, r["start_m"], piece_m),
                                                paths, piece_m)["distance_m"]
                          for r in plan[:: max(1, len(plan) // 500)]])

    recipes = [recipe_json(r["recipe"], emotions) for r in plan]
    synthetic_rows = synthetic_table(plan, recipes, synthetic, checkpoint_sha, table)
    write_parquet_atomic(synthetic_rows, out / "gaits.parquet")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["gait_id", "trajectory_id", "trajectory_family", "start_m", "seed_gait_id", "plan_seed",
                     "emotion_recipe"])
    for r, recipe in zip(plan, recipes):
        writer.writerow([r["gait_id"], r["trajectory_id"], r["trajectory_family"], r["start_m"], r["seed_gait_id"],
                         r["plan_seed"], recipe])
    with atomic_path(out / "plan.csv") as tmp:
        tmp.write_text(buffer.getvalue())

    sums = synthetic["emotion"].sum(-1)
    frame_sums = synthetic["emotion_per_frame"].sum(-1)
    min_distance = float(novelty["min_mean_distance_m"])
    report = {
        "gaits": len(plan),
        "per_trajectory": {t.id: sum(r["trajectory_id"] == t.id for r in plan) for t in trajectories},
        "single_emotion_gaits": sum(r["recipe"]["kind"] == "single" for r in plan),
        "transition_gaits": sum(r["recipe"]["kind"] == "transition" for r in plan),
        "seed_pool": {"split": "test", "content": p["seed_content"], "gaits": len(work.seed_pool),
                      "used": len({r["seed_gait_id"] for r in plan})},
        "checkpoint_sha256": checkpoint_sha,
        "emotion_rows_max_abs_sum_error": float(max(np.abs(sums - 1).max(), np.abs(frame_sums - 1).max())),
        "emotion_novelty": {"test": f"L1 distance to every distinct training label > {p['min_l1_to_training']}",
                            "training_labels": distinct_labels(work.labels).tolist(),
                            "min_l1": round(float(emotion_l1.min()), 4),
                            "passed": bool((emotion_l1 > float(p["min_l1_to_training"])).all())},
        "trajectory_novelty": {
            "test": (f"mean distance at equal arc length to every training clip root path (aligned at each window "
                     f"start, compared where they share >= {novelty['min_compared_m']} m) > {min_distance} m"),
            "reference_training_nn_distance_m_p50_p90": [round(float(np.percentile(reference, q)), 4)
                                                         for q in (50, 90)],
            "compared_training_paths": len(paths.clip_ids),
            "per_trajectory": {k: {"nearest_m": round(v["distance_m"], 4), "nearest_clip": v["clip_id"],
                                   "compared_m": v["compared_m"], "novel": v["distance_m"] > min_distance}
                               for k, v in shapes.items()},
            "passed": all(v["distance_m"] > min_distance for v in shapes.values()),
            "gait_pieces": {"length_m": round(piece_m, 3), "sampled": len(closeness),
                            f"within_{novelty['piece_close_m']}_m_of_a_training_path": round(float(
                                (closeness <= float(novelty["piece_close_m"])).mean()), 4),
                            "nearest_m_p50": round(float(np.median(closeness)), 4)}},
        "phase_from_condition": {"gaits": phase_from_condition, "why": "too few foot strikes in prefix + generated "
                                 "frames to define the stepping phase; the generator's conditioned phase is kept"},
        "copied_real_frames": copied_frames(synthetic["rotations"], arrays["rotations"]),
        "finite": bool(all(np.isfinite(v).all() for v in synthetic.values())),
        "seconds": round(seconds, 2),
        "agent_frames_per_second": round(len(plan) * window / seconds, 1),
    }
    write_json_atomic(report, out_report)
    placed: dict[str, list[np.ndarray]] = {t.id: [] for t in trajectories}
    for r, root_path in zip(plan, synthetic["root_path"]):
        points = by_id[r["trajectory_id"]].points
        i, direction = start_pose(points, r["start_m"])
        placed[r["trajectory_id"]].append(onto(root_path, points[i], direction))
    render_trajectories([(t.id, t.points, placed[t.id]) for t in trajectories], out_plot)
    print(f"synthesize: {report['gaits']} gaits in {seconds:.1f} s; "
          f"emotions novel {report['emotion_novelty']['passed']}, "
          f"trajectories novel {report['trajectory_novelty']['passed']}, copied frames {report['copied_real_frames']}")
    return report


if __name__ == "__main__":
    main()
