"""The motion graph as a generator family (``pipeline.generators.base``; seed 002): ``fit`` builds the graph of the
train walks, ``generate`` searches it for plan rows (``search.py``), blends the synthetic transitions and places
the walk along the row's trajectory. Its frames are real frames re-sequenced, so its lineage lists, per gait, the
clip and frame ranges it was assembled from.

* **Blending** (paper §7): at every synthetic transition i -> j the ``blend_frames`` frames from j on are SLERPed
  from the frames that naturally followed i (i + 1, i + 2, ...; its clip's last frame where the clip ends) into the
  new ones with a cosine weight; the root's ground step, turn and height blend linearly with the same weight.
  Transitions sit at foot events (the key states), where a foot starts or ends its stance.
* **Placement:** the walk starts at its trajectory piece's start facing along it. Each frame moves the root by its
  source frame's ground step (in the heading frame) and turns the body by its source frame's turn; the root height
  is the source frame's. Then the walk is laid onto its path (``generate.path_fit_s``, ``ops.path_fit``: its
  travel line bent onto the path, the sway kept) and the same foot locking as the other families
  (``generate.foot_lock``). Without the path fit, a warp of at most ``max_warp_deg`` per frame turns the body
  towards the point ``lookahead_m`` ahead on the path (``ops.geometry.pursue``, the search's model of placement);
  with it that warp would only add wiggles (the pursuit steers on the swaying root). The turning added to the
  frames' own (warp and fit) is reported, as is the skating.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.core.skeleton import Skeleton
from pipeline.generators.autoregressive.rollout import PlacementConfig
from pipeline.generators.base import GeneratedMotion, fit_placed
from pipeline.generators.motion_graph.graph import MotionGraph, load_graph
from pipeline.generators.motion_graph.search import LEVELS, SearchConfig, search
from pipeline.ops.footlock import lock_feet
from pipeline.ops.geometry import arc_lengths, heading_angle, pursue, wrap_angle
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import qmul, qslerp, yaw

NAME = "motion_graph"


@dataclass(frozen=True)
class WalkConfig:
    """How a searched node path becomes a gait (the pipeline params' ``motion_graph.walk``)."""

    context: int = 18  # frames walked before a gait's first frame (never published; annotation reads them)
    blend_frames: int = 8

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> WalkConfig:
        return cls(**{k: type(getattr(cls, k))(v) for k, v in dict(d or {}).items()})


def segments(path: np.ndarray, g: MotionGraph) -> list[tuple[int, int, int]]:
    """Runs of consecutive source frames in a node path: (clip index, first frame, last frame) each."""
    f = g.frames
    out: list[list[int]] = []
    for n in path.tolist():
        c, fr = int(f.clip[n]), int(f.frame[n])
        if out and out[-1][0] == c and out[-1][2] + 1 == fr:
            out[-1][2] = fr
        else:
            out.append([c, fr, fr])
    return [tuple(s) for s in out]


def blended(path: np.ndarray, g: MotionGraph, frames: int) -> tuple[torch.Tensor, np.ndarray, np.ndarray,
                                                                     np.ndarray, int, np.ndarray]:
    """One node path -> local rotations (L, J, 4) (pelvis without heading), ground steps (L, 2), turns (L,),
    heights (L,), with every synthetic transition cross-faded over ``frames`` frames; how many there were, and
    which frames (L,) a cross-fade touched (the others play their source frame as it is)."""
    f = g.frames
    rot = torch.from_numpy(f.rotations[path].astype(np.float64))
    step, turn, height = f.step[path].copy(), f.turn[path].copy(), f.height[path].copy()
    # the last frame of each node's clip (frames are stored clip after clip)
    last_of_clip = np.searchsorted(f.clip, f.clip[path], side="right") - 1
    transitions = 0
    faded = np.zeros(len(path), dtype=bool)
    for t0 in range(1, len(path)):
        i, last = path[t0 - 1], last_of_clip[t0 - 1]
        if path[t0] == i + 1 and i < last:  # the natural successor
            continue
        transitions += 1
        span = min(frames, len(path) - t0)
        old = np.minimum(i + 1 + np.arange(span), last)
        w = 0.5 - 0.5 * np.cos(math.pi * (np.arange(span) + 1) / (frames + 1))
        window = slice(t0, t0 + span)
        faded[window] = True
        rot[window] = qslerp(torch.from_numpy(f.rotations[old].astype(np.float64)), rot[window],
                             torch.from_numpy(w)[:, None, None])
        step[window] = (1 - w)[:, None] * f.step[old] + w[:, None] * step[window]
        turn[window] = (1 - w) * f.turn[old] + w * turn[window]
        height[window] = (1 - w) * f.height[old] + w * height[window]
    return rot, step, turn, height, transitions, faded


def place(local: torch.Tensor, step: torch.Tensor, turn: torch.Tensor, height: torch.Tensor, paths: torch.Tensor,
          lookahead_m: float, max_warp: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Walks (N, L) along paths (N, K, 2) from (0, 0) facing +Z, each frame turning by its own ``turn`` and a
    pursuit warp of at most ``max_warp``: (pelvis world rotations put into ``local``'s first joint -> rotations
    (N, L, J, 4), root positions (N, L, 3), warps (N, L) rad)."""
    n, length = step.shape[:2]
    cumulative = arc_lengths(paths)
    psi = torch.zeros(n, dtype=step.dtype)
    ground = torch.zeros(n, 2, dtype=step.dtype)
    grounds, headings, warps = [ground], [psi], [torch.zeros(n, dtype=step.dtype)]
    for t in range(1, length):
        side, ahead = step[:, t, 0], step[:, t, 1]
        c, s = torch.cos(psi), torch.sin(psi)
        ground = ground + torch.stack([side * c + ahead * s, -side * s + ahead * c], -1)
        natural = psi + turn[:, t]
        new = pursue(natural, ground, paths, cumulative, lookahead_m, max_warp)
        warps.append(new - natural)
        psi = new
        grounds.append(ground)
        headings.append(psi)
    ground = torch.stack(grounds, 1)
    heading = torch.stack(headings, 1)
    pelvis = qmul(yaw(heading), local[:, :, 0])
    rotations = torch.cat([pelvis[:, :, None], local[:, :, 1:]], 2)
    root = torch.stack([ground[..., 0], height, ground[..., 1]], -1)
    return rotations, root, torch.stack(warps, 1)


def _per_frame(turns: torch.Tensor) -> torch.Tensor:
    """Headings added (N, L) -> the turn each frame adds (N, L) (0 at the first)."""
    return torch.cat([torch.zeros_like(turns[:, :1]), wrap_angle(turns.diff(dim=1))], 1)


def source_phase(g: MotionGraph, nodes: np.ndarray) -> torch.Tensor:
    """(N, T) the stepping phase the source clips' annotation gave the frames a path plays (a clip's frames
    before its first strikes have none: the nearest frame's that has one), kept by annotation only where the gait's
    own contacts give too few strikes to define it."""
    phase = g.frames.phase[nodes]
    out = np.zeros_like(phase)
    for n, p in enumerate(phase):
        known = np.flatnonzero(np.isfinite(p))
        if len(known):
            out[n] = p[known[np.abs(np.arange(len(p))[:, None] - known[None, :]).argmin(1)]]
    return torch.from_numpy(out)


@dataclass
class MotionGraphFamily:
    """A built motion graph, ready for plan rows."""

    graph: MotionGraph
    model_sha256: str
    skeleton: Skeleton
    placement: PlacementConfig
    search_config: SearchConfig = SearchConfig()
    walk: WalkConfig = WalkConfig()
    log: list[dict[str, Any]] = field(default_factory=list)
    name: str = NAME
    description: str = ("statistics-based motion graph (Yang, Yang & Hodgins 2020) of the real train-split walks, "
                        "searched stochastically for paths of the planned emotion along the planned trajectory; "
                        "its frames are real frames re-sequenced, blended at each synthetic transition; no seed gait")
    seeded: bool = False
    extra_lineage: tuple[str, ...] = ("source_segments",)

    @classmethod
    def from_file(cls, path, skeleton: Skeleton, placement: PlacementConfig, search_config: SearchConfig = SearchConfig(),
                  walk: WalkConfig = WalkConfig()) -> MotionGraphFamily:
        graph, sha = load_graph(path)
        return cls(graph, sha, skeleton, placement, search_config, walk)

    def lineage(self) -> dict[str, Any]:
        """The graph's identity and statistics (every gait's own source segments are in its row)."""
        g = self.graph
        return {"model_sha256": self.model_sha256, "threshold": g.threshold, "k": g.config.k,
                "states_kept": int(g.kept.sum()), "clips": len(g.frames.clip_ids),
                "source_segments": "each gait's column source_segments: [clip_id, first frame, last frame] of the "
                                   "rebuilt clip at 30 fps (frame 0 = the clip's first ingested frame), in order"}

    def generate(self, rows: Sequence[dict[str, Any]], paths: torch.Tensor, emotions: torch.Tensor) -> GeneratedMotion:
        c = self.walk.context
        nodes, level = search(self.graph, emotions.double().numpy(), paths.double().numpy(),
                              [int(r["plan_seed"]) for r in rows], c, self.search_config)
        parts = [blended(p, self.graph, self.walk.blend_frames) for p in nodes]
        local = torch.stack([p[0] for p in parts]).to(torch.float32)
        step = torch.from_numpy(np.stack([p[1] for p in parts])).to(torch.float32)
        turn = torch.from_numpy(np.stack([p[2] for p in parts])).to(torch.float32)
        height = torch.from_numpy(np.stack([p[3] for p in parts])).to(torch.float32)
        paths = paths.to(torch.float32)
        offsets = torch.from_numpy(self.skeleton.offsets).to(torch.float32)
        # with the path fit the walk is laid onto its path afterwards, and a pursuit would only add wiggles (it
        # steers on the swaying root); without it, the pursuit's warp is what keeps the walk near its path
        fitted = self.placement.path_fit_s > 0
        rotations, root, warp = place(local, step, turn, height, paths, self.search_config.lookahead_m,
                                      0.0 if fitted else math.radians(self.search_config.max_warp_deg))
        positions = canonical_positions(root, rotations, offsets, self.skeleton.parents)
        positions, rotations, fit_turn = fit_placed(positions, rotations, paths, self.placement)
        warp = warp + _per_frame(fit_turn)  # the turning added to the frames' own
        if self.placement.foot_lock:
            rotations, positions = lock_feet(rotations, positions[..., 0, :], offsets, self.skeleton.parents,
                                             self.placement.fps, self.placement.contacts)
        ids = self.graph.frames.clip_ids
        lineage = []
        dominant = emotions.argmax(-1).numpy()
        for r, (row, p, lv, part) in enumerate(zip(rows, nodes, level, parts)):
            runs = segments(p[c:], self.graph)
            lineage.append(json.dumps([[ids[a], b, e] for a, b, e in runs], separators=(",", ":")))
            walked = self.graph.frames.dominant[p[c:]]
            self.log.append({"trajectory_family": row["trajectory_family"], "kind": row["recipe"]["kind"],
                             "emotion": EMOTIONS[int(dominant[r, 0])], "level": lv, "transitions": part[4],
                             "longest_run": max(e - b + 1 for _, b, e in runs),
                             "source_frames_as_they_are": int((~part[5][c:]).sum()),
                             "frames_of_planned_emotion": float((walked == dominant[r]).mean()),
                             "warp_deg_per_frame": float(np.degrees(warp[r, c:].abs().mean().item()))})
        return GeneratedMotion(positions=positions[:, c:], rotations=rotations[:, c:],
                               heading=heading_angle(rotations[:, c:, 0]), context_positions=positions[:, :c],
                               conditioned_phase=source_phase(self.graph, nodes[:, c:]), placed_paths=paths,
                               source_segments=lineage)

    def report(self) -> dict[str, Any]:
        """The search's outcome over every gait generated so far: levels (success = ``constrained``) per trajectory
        family and per starting emotion, synthetic transitions, warp, and the longest unbroken real segment."""
        if not self.log:
            return {}

        def rates(key: str) -> dict[str, Any]:
            out = {}
            for value in sorted({e[key] for e in self.log}):
                mine = [e for e in self.log if e[key] == value]
                out[value] = {"gaits": len(mine), "success_rate": round(sum(e["level"] == LEVELS[0] for e in mine)
                                                                        / len(mine), 4),
                              "levels": dict(Counter(e["level"] for e in mine))}
            return out

        runs = np.array([e["longest_run"] for e in self.log])
        warp = np.array([e["warp_deg_per_frame"] for e in self.log])
        return {"search": {"gaits": len(self.log), "levels": {lv: sum(e["level"] == lv for e in self.log)
                                                               for lv in LEVELS},
                           "success_rate": round(sum(e["level"] == LEVELS[0] for e in self.log) / len(self.log), 4),
                           "per_trajectory_family": rates("trajectory_family"), "per_emotion": rates("emotion"),
                           "per_kind": rates("kind"),
                           "levels_meaning": {LEVELS[0]: "all constraints held",
                                              LEVELS[1]: "the corridor widened",
                                              LEVELS[2]: "without the trajectory constraint",
                                              LEVELS[3]: "without either constraint (the emotion could not be "
                                                         "walked in time)"}},
                "synthetic_transitions_per_gait": round(float(np.mean([e["transitions"] for e in self.log])), 3),
                "frames_of_planned_dominant_emotion": round(float(np.mean([e["frames_of_planned_emotion"]
                                                                           for e in self.log])), 4),
                "warp_deg_per_frame": {"mean": round(float(warp.mean()), 3),
                                       "p90": round(float(np.percentile(warp, 90)), 3)},
                "real_frames_by_design": {
                    "frames": int(sum(e["source_frames_as_they_are"] for e in self.log)),
                    "share": round(sum(e["source_frames_as_they_are"] for e in self.log) / (60 * len(self.log)), 4),
                    "why": "this family plays real frames: every published frame outside a cross-fade is a real "
                           "train frame's pose (its root turned and moved along the plan). copied_real_frames "
                           "counts frames whose 20 non-root rotations equal a real frame's after foot locking, "
                           "which moves the legs of most frames, so it misses most of these"},
                "longest_unbroken_real_segment_frames": {"median": float(np.median(runs)),
                                                         "p90": float(np.percentile(runs, 90)),
                                                         "whole_gait_share": round(float((runs >= 60).mean()), 4),
                                                         "of_frames": 60}}
