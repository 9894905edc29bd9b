"""Synthesis of the planned gaits, family-agnostic: the plan (from the split gaits and plain configs), any
generator family (``pipeline.generators.base``) generating each row's gait in batches along its trajectory piece
with per-frame emotions, then the same annotation as real gaits, and the stage's report (counts, novelty).

Frames a family generates from but does not publish (a seed prefix) are not part of a synthetic gait. The
annotation of contacts and phase runs on those frames + generated frames (strikes before the first generated
frame fix its phase) and is then cut to the generated frames; movement and affective features are computed on
the generated window alone, as for real windows (pipeline.annotate.annotation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.annotate.annotation import AnnotateConfig, annotate_clip, stored_phase
from pipeline.core.emotions import EMOTIONS
from pipeline.core.skeleton import Skeleton
from pipeline.generators.base import GeneratorFamily
from pipeline.ops.contacts import ContactConfig, phase_rate
from pipeline.ops.features import movement_features, pose_affective_features
from pipeline.ops.footlock import skating_speed
from pipeline.ops.geometry import distance_to_polyline, moving_average, odd_frames
from pipeline.synth.novelty import (
    distinct_labels,
    l1_to_labels,
    nearest_training_path,
    novel_emotions,
    training_nearest_distances,
    training_paths,
)
from pipeline.synth.plan import build_plan, frame_emotions, seed_emotion
from pipeline.synth.trajectories import Trajectory, onto, piece_from, start_pose, trajectories_from_spec


@dataclass(frozen=True)
class SynthesisConfig:
    """The plan and its synthesis (the pipeline params' ``synthesize``), with the gait length in frames."""

    seed: int
    emotions: int  # novel emotion vectors from the simplex
    min_l1_to_training: float
    transition_rounds: int
    seed_content: str  # seeds: labelled windows of this content from ``seed_splits`` (plan.build_plan)
    trajectories: dict[str, dict[str, Any]]  # id -> {family, pieces, starts_within_m?}
    start_span_m: float
    novelty: dict[str, float]  # min_mean_distance_m, min_compared_m, piece_close_m
    path_ahead_m: float = 8.0
    batch: int = 1000
    frames: int = 60
    seed_splits: tuple[str, ...] = ("train",)  # leak-free: the recognisers are tested on val + test clips

    @classmethod
    def from_dict(cls, d: dict[str, Any], frames: int) -> SynthesisConfig:
        return cls(seed=int(d["seed"]), emotions=int(d["emotions"]), min_l1_to_training=float(d["min_l1_to_training"]),
                   transition_rounds=int(d["transition_rounds"]), seed_content=str(d["seed_content"]),
                   trajectories=d["trajectories"], start_span_m=float(d["start_span_m"]), novelty=d["novelty"],
                   path_ahead_m=float(d["path_ahead_m"]), batch=int(d["batch"]), frames=int(frames),
                   seed_splits=tuple(d.get("seed_splits", ("train",))))


@dataclass
class SynthesisPlan:
    """Everything the plan needs, from the split gaits: the train labels, the novel emotions, the trajectories,
    the seed pools (labelled gaits by dominant emotion) and one row per synthetic gait."""

    table: pa.Table
    arrays: dict[str, np.ndarray]
    labels: np.ndarray  # the train split's emotion labels
    emotions: np.ndarray
    trajectories: list[Trajectory]
    seed_pools: dict[int, list[str]]  # emotion index (-1: all) -> seed gait ids
    plan: list[dict[str, Any]]

    @classmethod
    def prepare(cls, table: pa.Table, arrays: dict[str, np.ndarray], cfg: SynthesisConfig) -> SynthesisPlan:
        split = np.array(table.column("split").to_pylist())
        content = np.array(table.column("content").to_pylist())
        labels = arrays["emotion"][split == "train"]
        labels = labels[~np.isnan(labels).any(-1)].astype(np.float64)
        emotions = novel_emotions(cfg.emotions, labels, cfg.min_l1_to_training, np.random.default_rng([cfg.seed, 0]))
        trajectories = trajectories_from_spec(cfg.trajectories, cfg.start_span_m)
        gait_ids = table.column("gait_id").to_pylist()
        labelled = ~np.isnan(arrays["emotion"]).any(-1)
        rows = np.flatnonzero(np.isin(split, cfg.seed_splits) & (content == cfg.seed_content) & labelled)
        dominant = np.argmax(arrays["emotion"][rows], axis=-1)
        seed_pools = {k: [gait_ids[i] for i in rows[dominant == k]] for k in range(arrays["emotion"].shape[-1])}
        seed_pools[-1] = [gait_ids[i] for i in rows]
        plan = build_plan(trajectories, emotions, seed_pools, cfg.transition_rounds, cfg.seed)
        return cls(table, arrays, labels, emotions, trajectories, seed_pools, plan)

    @property
    def row_of(self) -> dict[str, int]:
        """Row of the split table by gait id."""
        return {g: i for i, g in enumerate(self.table.column("gait_id").to_pylist())}


def row_inputs(rows: Sequence[dict[str, Any]], emotions: np.ndarray, trajectories: dict[str, Trajectory],
               cfg: SynthesisConfig) -> tuple[torch.Tensor, np.ndarray]:
    """What a family generates plan rows from: each row's trajectory piece (N, K, 2) float32 in its own start
    frame, and its per-frame emotions (N, frames, 4) float64."""
    shapes = torch.from_numpy(np.stack([piece_from(trajectories[r["trajectory_id"]].points, r["start_m"],
                                                   cfg.path_ahead_m) for r in rows]).astype(np.float32))
    return shapes, np.stack([frame_emotions(r["recipe"], emotions, cfg.frames) for r in rows])


def synthesize(family: GeneratorFamily, plan: Sequence[dict[str, Any]], emotions: np.ndarray,
               trajectories: dict[str, Trajectory], skeleton: Skeleton, annotate: AnnotateConfig,
               cfg: SynthesisConfig, progress: Callable[[int, int], None] | None = None) -> dict[str, np.ndarray]:
    """Arrays (gaits, ...) for every plan row, in plan order: positions, rotations, root_path, heading, contacts,
    phase, phase_rate, affective, movement, emotion_per_frame, the per-gait emotion (mean over the frames),
    phase_from_condition (bool per gait) and path_deviation_m (per gait: the mean ground distance of the root to
    the trajectory piece as the family placed it; NaN where the family does not say)."""
    parts: dict[str, list[np.ndarray]] = {}
    for first in range(0, len(plan), cfg.batch):
        rows = plan[first:first + cfg.batch]
        shapes, per_frame = row_inputs(rows, emotions, trajectories, cfg)
        g = family.generate(rows, shapes, torch.from_numpy(per_frame.astype(np.float32)))
        batch = _annotate(g.positions.double(), g.rotations.double(),
                          None if g.context_positions is None else g.context_positions.double(),
                          None if g.conditioned_phase is None else g.conditioned_phase.double(), skeleton, annotate)
        batch.update(positions=g.positions.numpy(), rotations=g.rotations.numpy(),
                     root_path=g.positions[:, :, 0, [0, 2]].numpy(), heading=g.heading.numpy(),
                     emotion_per_frame=per_frame, emotion=per_frame.mean(1),  # rows sum to 1
                     path_deviation_m=np.full(len(rows), np.nan) if g.placed_paths is None else
                     distance_to_polyline(g.positions[:, :, 0, [0, 2]], g.placed_paths).mean(-1).numpy())
        if g.source_segments is not None:
            batch["source_segments"] = np.array(g.source_segments, dtype=object)
        if g.placed_paths is not None:
            batch["piece_placement"] = piece_placement(shapes.double(), g.placed_paths.double())
        for k, v in batch.items():
            parts.setdefault(k, []).append(v if v.dtype in (bool, object) else np.asarray(v, dtype=np.float32))
        if progress:
            progress(first + len(rows), len(plan))
    return {k: np.concatenate(v) for k, v in parts.items()}


def _annotate(positions: torch.Tensor, rotations: torch.Tensor, context_positions: torch.Tensor | None,
              conditioned_phase: torch.Tensor | None, skeleton: Skeleton, cfg: AnnotateConfig) -> dict[str, np.ndarray]:
    """Annotations of generated gaits. Where the contacts give too few strikes to define the stepping phase, the
    phase the family generated with is kept, if it has one (``phase_from_condition`` flags those gaits)."""
    prefix = 0 if context_positions is None else context_positions.shape[1]
    contacts, phase, rate, fallback = [], [], [], []
    for n in range(positions.shape[0]):
        clip = positions[n] if context_positions is None else torch.cat([context_positions[n], positions[n]])
        ann = annotate_clip(clip, skeleton, cfg)
        theta = ann["phase"][prefix:]
        fallback.append(not bool(torch.isfinite(theta).all()))
        if fallback[-1] and conditioned_phase is not None:
            theta = conditioned_phase[n]
        contacts.append(ann["contacts"][prefix:].numpy())
        phase.append(theta.numpy())
        rate.append(phase_rate(theta).numpy())
    return {"contacts": np.stack(contacts), "phase": stored_phase(np.stack(phase)), "phase_rate": np.stack(rate),
            "phase_from_condition": np.array(fallback), **window_features(positions, rotations, skeleton, cfg)}


def window_features(positions: torch.Tensor, rotations: torch.Tensor, skeleton: Skeleton,
                    cfg: AnnotateConfig) -> dict[str, np.ndarray]:
    """Affective (N, T, 18) and movement (N, T, 5) features of generated gaits (N, T, 21, 3 | 4), on the generated
    window alone, as for real windows; also what the evaluation's recognisers read of generated frames."""
    offsets = torch.from_numpy(skeleton.offsets)
    return {"affective": pose_affective_features(positions[..., 0, :], rotations, offsets, skeleton.parents).numpy(),
            "movement": movement_features(positions, cfg.lowpass_frames).numpy()}


def copied_frames(synthetic: np.ndarray, real: np.ndarray, decimals: int = 4) -> int:
    """How many synthetic frames repeat a real frame's body pose: the 20 non-root local rotations of (G, T, 21, 4)
    arrays equal after rounding to ``decimals`` (the root's is left out: a copy turned to another heading is
    still a copy)."""
    def keys(a: np.ndarray) -> list[bytes]:
        flat = np.round(a[..., 1:, :].reshape(-1, (a.shape[-2] - 1) * a.shape[-1]).astype(np.float64), decimals)
        return [row.tobytes() for row in flat + 0.0]  # + 0.0: -0.0 and 0.0 are the same value
    real_keys = set(keys(real))
    return sum(k in real_keys for k in keys(synthetic))


PLAN_COLUMNS = ("gait_id", "trajectory_id", "trajectory_family", "start_m", "seed_gait_id", "plan_seed",
                "emotion_recipe")


def plan_rows(plan: Sequence[dict[str, Any]], recipes: Sequence[str]) -> list[tuple]:
    """One row per synthetic gait (PLAN_COLUMNS), for plan.csv."""
    return [(r["gait_id"], r["trajectory_id"], r["trajectory_family"], r["start_m"], r["seed_gait_id"],
             r["plan_seed"], recipe) for r, recipe in zip(plan, recipes)]


def synthesis_report(work: SynthesisPlan, synthetic: dict[str, np.ndarray], cfg: SynthesisConfig, fps: float,
                     model_sha256: str, phase_from_condition: list[str], seeded: bool = True,
                     contacts: ContactConfig | None = None) -> dict[str, Any]:
    """Counts, the seed pool (a seeded family's), the emotion and trajectory novelty tests (trajectories vs the
    training clips' root paths), how close the pieces single gaits walk come to training paths, copied real
    frames. No timing: the report holds only what the inputs determine, so a rerun gives the same bytes (the
    stage prints its time; benchmarks/ measure it)."""
    table, arrays, plan, trajectories = work.table, work.arrays, work.plan, work.trajectories
    split = np.array(table.column("split").to_pylist())
    clip_ids = table.column("clip_id").to_pylist()
    train = np.flatnonzero(split == "train")
    novelty = cfg.novelty
    emotion_l1 = l1_to_labels(work.emotions, work.labels)
    starts = np.round(table.column("t_start").to_numpy()[train] * fps).astype(int)
    paths = training_paths(arrays["root_path"][train], [clip_ids[i] for i in train], starts, cfg.frames)
    min_compared = float(novelty["min_compared_m"])
    reference = training_nearest_distances(paths, min_compared)
    shapes = {t.id: nearest_training_path(t.points, paths, min_compared) for t in trajectories}
    by_id = {t.id: t for t in trajectories}
    piece_m = float(np.median(np.linalg.norm(np.diff(synthetic["root_path"], axis=1), axis=-1).sum(1)))
    closeness = np.array([nearest_training_path(piece_from(by_id[r["trajectory_id"]].points, r["start_m"], piece_m),
                                                paths, piece_m)["distance_m"]
                          for r in plan[:: max(1, len(plan) // 500)]])
    content = np.array(table.column("content").to_pylist())
    walks = np.flatnonzero((split == "train") & (content == cfg.seed_content)
                           & ~np.isnan(arrays["emotion"]).any(-1))
    single = np.array([r["recipe"]["kind"] == "single" for r in plan])
    sums = synthetic["emotion"].sum(-1)
    frame_sums = synthetic["emotion_per_frame"].sum(-1)
    min_distance = float(novelty["min_mean_distance_m"])
    seed_pool = {"splits": list(cfg.seed_splits), "content": cfg.seed_content, "labelled": True,
                 "rule": "dominant emotion of the seed = dominant emotion the gait starts with",
                 "gaits": len(work.seed_pools[-1]),
                 "gaits_per_emotion": {EMOTIONS[k]: len(v) for k, v in work.seed_pools.items() if k >= 0},
                 "rows_without_matching_seed": sum(not work.seed_pools.get(seed_emotion(r["recipe"], work.emotions))
                                                   for r in plan),
                 "used": len({r["seed_gait_id"] for r in plan})} if seeded else "none: the family needs no seed"
    return {
        "gaits": len(plan),
        "per_trajectory": {t.id: sum(r["trajectory_id"] == t.id for r in plan) for t in trajectories},
        "single_emotion_gaits": sum(r["recipe"]["kind"] == "single" for r in plan),
        "transition_gaits": sum(r["recipe"]["kind"] == "transition" for r in plan),
        "seed_pool": seed_pool,
        "model_sha256": model_sha256,
        "emotion_rows_max_abs_sum_error": float(max(np.abs(sums - 1).max(), np.abs(frame_sums - 1).max())),
        "emotion_novelty": {"test": f"L1 distance to every distinct training label > {cfg.min_l1_to_training}",
                            "training_labels": distinct_labels(work.labels).tolist(),
                            "min_l1": round(float(emotion_l1.min()), 4),
                            "passed": bool((emotion_l1 > cfg.min_l1_to_training).all())},
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
        "walking": {"synthetic": walking_figures(synthetic["root_path"], synthetic["emotion"], fps),
                    "real_labelled_train_walks": walking_figures(arrays["root_path"][walks], arrays["emotion"][walks],
                                                                 fps),
                    "why": "net speed well below path speed: the body steps on the spot or circles"},
        "cycle_frames": {"synthetic_single_emotion": cycle_frames(synthetic["phase_rate"][single],
                                                                  synthetic["emotion"][single]),
                         "real_labelled_train_walks": cycle_frames(arrays["phase_rate"][walks], arrays["emotion"][walks]),
                         "how": "per dominant emotion, median over gaits of 2π / the gait's mean phase rate"},
        "path_deviation_m": path_deviation(synthetic["path_deviation_m"], [r["trajectory_family"] for r in plan],
                                           root_sway(arrays["root_path"][walks], fps)),
        **({"foot_skating": foot_skating(synthetic["positions"], arrays["positions"][walks], fps, contacts,
                                         [r["trajectory_family"] for r in plan])}
           if contacts is not None else {}),
        "copied_real_frames": copied_frames(synthetic["rotations"], arrays["rotations"]),
        "finite": bool(all(np.isfinite(v).all() for k, v in synthetic.items()
                               if k != "path_deviation_m" and v.dtype != object)),
    }


def cycle_frames(phase_rate: np.ndarray, emotions: np.ndarray) -> dict[str, float]:
    """Per dominant emotion, the median stepping-cycle length in frames (2π / mean phase rate per gait)."""
    frames = 2 * np.pi / np.maximum(phase_rate.mean(1), 1e-6)
    dominant = np.argmax(emotions, axis=-1)
    return {name: round(float(np.median(frames[dominant == k])), 2) for k, name in enumerate(EMOTIONS)
            if (dominant == k).any()}


def root_sway(root_paths: np.ndarray, fps: float, seconds: float = 1.0) -> float:
    """The real reference of path deviation: the mean ground distance (m) of real walks' roots (N, T, 2) from their
    own travel line, the root path averaged over about one stride (``seconds``, centred; frames whose window fits),
    measured as path deviation is (``distance_to_polyline``: across the line, not along it). A root that follows a
    path perfectly still sways this much around it."""
    frames = odd_frames(seconds, fps)
    half = frames // 2
    paths = torch.from_numpy(root_paths.astype(np.float64)).transpose(1, 2)  # (N, 2, T)
    line = moving_average(paths, frames)[..., half:-half].transpose(1, 2)
    return float(distance_to_polyline(paths[..., half:-half].transpose(1, 2), line).mean())


def path_deviation(deviation: np.ndarray, families: Sequence[str], real_sway: float | None = None
                   ) -> dict[str, dict[str, float]]:
    """Per trajectory family (and all): mean and 90th percentile over gaits of each gait's mean distance (m) from
    its root to its placed trajectory piece; with ``real_sway`` (``root_sway``) the mean's ratio to it."""
    families = np.array(families)
    groups = {"all": np.ones(len(families), bool), **{f: families == f for f in sorted(set(families))}}
    out = {f: {"mean": round(float(np.nanmean(deviation[m])), 4),
               "p90": round(float(np.nanpercentile(deviation[m], 90)), 4)} for f, m in groups.items()}
    if real_sway is not None:
        for v in out.values():
            v["ratio_to_real_sway"] = round(v["mean"] / real_sway, 3)
        out["real_walk_sway_m"] = {"mean": round(real_sway, 4), "how": "real labelled train walks' roots from their "
                                   "own path averaged over 1 s (about one stride)"}
    return out


def foot_skating(synthetic: np.ndarray, real: np.ndarray, fps: float, contacts: ContactConfig,
                 families: Sequence[str] | None = None) -> dict[str, Any]:
    """Mean horizontal speed of heel/toe points in contact (m/s), synthetic gaits vs real walks, and their ratio;
    with each gait's trajectory family, the ratio per family too."""
    syn = skating_speed(torch.from_numpy(synthetic), fps, contacts)[0]
    ref = skating_speed(torch.from_numpy(real), fps, contacts)[0]
    out: dict[str, Any] = {"synthetic_m_s": round(syn, 4), "real_walks_m_s": round(ref, 4),
                           "ratio_to_real": round(syn / ref, 3)}
    if families is not None:
        families = np.array(families)
        out["ratio_to_real_per_trajectory_family"] = {
            f: round(skating_speed(torch.from_numpy(synthetic[families == f]), fps, contacts)[0] / ref, 3)
            for f in sorted(set(families))}
    return out


def net_and_path_speed(root_paths: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) net speed (start-to-end ground distance / duration) and (N,) path speed (ground distance walked /
    duration), m/s, of root paths (N, T, 2) ground (x, z). A body that steps on the spot or circles has a path speed
    but little net speed."""
    seconds = (root_paths.shape[1] - 1) / fps
    net = np.linalg.norm(root_paths[:, -1] - root_paths[:, 0], axis=-1) / seconds
    walked = np.linalg.norm(np.diff(root_paths, axis=1), axis=-1).sum(1) / seconds
    return net, walked


def walking_figures(root_paths: np.ndarray, emotions: np.ndarray, fps: float) -> dict[str, dict[str, float]]:
    """Per dominant emotion: gaits, median net speed and median path speed (``net_and_path_speed``), m/s.
    root_paths: (N, T, 2) ground (x, z); emotions: (N, 4) labels (no NaN rows)."""
    net, walked = net_and_path_speed(root_paths, fps)
    dominant = np.argmax(emotions, axis=-1)
    return {name: {"gaits": int((dominant == k).sum()),
                   "net_speed_m_s": round(float(np.median(net[dominant == k])), 3),
                   "path_speed_m_s": round(float(np.median(walked[dominant == k])), 3)}
            for k, name in enumerate(EMOTIONS) if (dominant == k).any()}


def piece_placement(pieces: torch.Tensor, placed: torch.Tensor) -> np.ndarray:
    """(N, 3) where a family placed each trajectory piece (N, K, 2) in the world (``placed``, the same points moved
    rigidly): the world origin of the piece's first point and the turn from the piece's frame to the world."""
    def first_direction(p: torch.Tensor) -> torch.Tensor:
        d = p[:, 1] - p[:, 0]
        return torch.atan2(d[:, 0], d[:, 1])

    turn = first_direction(placed) - first_direction(pieces)
    return torch.cat([placed[:, 0], turn[:, None]], 1).numpy()


def placed_root_paths(work: SynthesisPlan, root_paths: np.ndarray, placement: np.ndarray | None = None
                      ) -> list[tuple[str, np.ndarray, list[np.ndarray]]]:
    """Each trajectory with the generated root paths drawn where they start on it (for ``render_trajectories``).
    With the families' ``piece_placement`` (N, 3) a root path is taken into its piece's frame exactly (a piece may
    turn at its very start, as the new-heading trajectories do); without it, by its own initial travel direction."""
    placed: dict[str, list[np.ndarray]] = {t.id: [] for t in work.trajectories}
    by_id = {t.id: t for t in work.trajectories}
    for n, (r, root_path) in enumerate(zip(work.plan, root_paths)):
        points = by_id[r["trajectory_id"]].points
        i, direction = start_pose(points, r["start_m"])
        if placement is None or not np.isfinite(placement[n]).all():
            placed[r["trajectory_id"]].append(onto(root_path, points[i], direction))
            continue
        ox, oz, turn = (float(v) for v in placement[n])
        c, s_ = np.cos(direction - turn), np.sin(direction - turn)
        x, z = root_path[:, 0] - ox, root_path[:, 1] - oz
        # world -> the piece's frame (turn by -turn), -> the trajectory's world (turn by the start direction)
        placed[r["trajectory_id"]].append(np.stack([x * c + z * s_, -x * s_ + z * c], -1) + points[i])
    return [(t.id, t.points, placed[t.id]) for t in work.trajectories]
