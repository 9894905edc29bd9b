"""Stochastic beam search of the motion graph for plan rows (seed 002 §7.1, with gait's constraints).

For each row, a node path of ``frames`` nodes (the gait's context frames, then its published frames) that starts
at one of ``n_save`` random nodes and advances one frame per step along a kept edge: the natural successor (cost 0)
or, at a key state, one of its synthetic edges (cost c). After every step the ``n_save`` partial paths with the
lowest costs are kept, sampled without replacement (Gumbel top-k at ``temperature`` cost units: the paper's
"n_save low-cost candidate segments are sampled and preserved"), each row with its own seeded draws (``plan_seed``),
so a row's path depends on nothing but the row. The cheapest surviving path wins.

**Constraints** (each can be switched off for the ablation):

* *emotion*: every node carries the emotion its frame is asked for: the dominant emotion of the row's per-frame
  emotion (a novel mixture walks as its dominant emotion's real clips; the gait's lineage records the clips), and
  within ``switch_slack`` frames of a change of the dominant emotion (a transition) either emotion may be walked,
  so the switch happens where the graph has an edge between them, and so may the ``bridge`` emotion (neutral):
  some pairs of emotions have no edge between them at all (the few happy and sad clips share none), and a
  transition through a few neutral frames is still a transition from one to the other.
* *trajectory*: the root, steered along the planned path, stays within ``corridor_m`` of it. Steering is the
  placement's own rule (``place``): the body turns as its frames turn, plus a yaw warp of at most
  ``max_warp_deg`` per frame towards the path point ``lookahead_m`` ahead (pure pursuit). The search places each
  partial path as ``place`` will (ground position and heading), with the closest path point found near the last
  one (the path sampled every 2 cm; the placement searches the whole path, so the two can differ where a path
  crosses itself), and each degree of warp costs ``warp_cost``.

A row whose search ends with no surviving path is searched again with the corridor widened ``relax`` times, then
without the trajectory constraint, then without either; the level each row needed is returned (none is dropped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.generators.motion_graph.graph import MotionGraph

LEVELS = ("constrained", "relaxed_corridor", "no_trajectory_constraint", "no_constraint")


@dataclass(frozen=True)
class SearchConfig:
    """The search (the pipeline params' ``motion_graph.search``)."""

    n_save: int = 32  # partial paths kept per step (the paper: 200, over whole segments)
    temperature: float = 1.0  # cost units of the Gumbel noise that makes the choice stochastic
    corridor_m: float = 0.35
    relax: float = 2.0  # the corridor's widening for a row the first search could not satisfy
    lookahead_m: float = 0.6
    max_warp_deg: float = 8.0  # per frame (240 deg/s, the other families' turn limit)
    warp_cost: float = 0.5  # per degree of warp
    switch_slack: int = 10  # frames around a change of dominant emotion where either may be walked ...
    bridge: str = "neutral"  # ... and this one
    emotion: bool = True  # the constraints (the ablation switches them off)
    trajectory: bool = True

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> SearchConfig:
        return cls(**{k: type(getattr(cls, k))(v) for k, v in dict(d or {}).items()})


@dataclass
class PathGrid:
    """Each row's path sampled every ``spacing`` m of arc length: points (R, G, 2) and unit tangents (R, G, 2)."""

    spacing: float
    point: np.ndarray
    tangent: np.ndarray

    @classmethod
    def of(cls, paths: np.ndarray, spacing: float = 0.02) -> PathGrid:
        """paths (R, K, 2) polylines (x, z) from (0, 0)."""
        seg = np.linalg.norm(np.diff(paths, axis=1), axis=-1)
        cum = np.concatenate([np.zeros((len(paths), 1)), np.cumsum(seg, 1)], 1)
        grid = np.arange(0.0, float(cum[:, -1].min()) + 1e-9, spacing)
        point = np.stack([np.stack([np.interp(grid, c, p[:, d]) for d in (0, 1)], -1) for c, p in zip(cum, paths)])
        ahead = np.diff(point, axis=1)
        ahead = np.concatenate([ahead, ahead[:, -1:]], 1)
        return cls(spacing, point, ahead / np.maximum(np.linalg.norm(ahead, axis=-1, keepdims=True), 1e-12))

    def take(self, rows: np.ndarray) -> PathGrid:
        return PathGrid(self.spacing, self.point[rows], self.tangent[rows])

    def closest_near(self, rows: np.ndarray, index: np.ndarray, position: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """The sample closest to ``position`` (..., 2) near the last one ``index``: projected along the tangent
        there, twice (a corner turns the tangent), then the best of that sample and its five neighbours either
        side; and the distance to it."""
        last = self.point.shape[1] - 1
        for _ in range(2):
            offset = position - self.point[rows, index]
            t = self.tangent[rows, index]
            along = (offset[..., 0] * t[..., 0] + offset[..., 1] * t[..., 1]) / self.spacing
            index = np.clip(index + np.rint(along).astype(np.int64), 0, last)
        best, best_d2 = None, None
        for shift in range(-5, 6):
            i = np.clip(index + shift, 0, last)
            d = position - self.point[rows, i]
            d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]
            if best is None:
                best, best_d2 = i, d2
            else:
                closer = d2 < best_d2
                best, best_d2 = np.where(closer, i, best), np.where(closer, d2, best_d2)
        return best, np.sqrt(best_d2)

    def point_at(self, rows: np.ndarray, index: np.ndarray) -> np.ndarray:
        return self.point[rows, np.clip(index, 0, self.point.shape[1] - 1)]


def world_step(step: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """A frame's ground step (..., 2) (sideways, ahead of the previous heading psi) in the world (x, z)."""
    side, fwd = step[..., 0], step[..., 1]
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([side * c + fwd * s, -side * s + fwd * c], -1)


def emotion_reach(g: MotionGraph) -> np.ndarray:
    """(F, 4) the fewest frames from each node to a node of each emotion, walking labelled kept nodes only (the
    only ones an emotion-constrained walk can use); a large number where it cannot. The search prunes partial
    paths that could not reach the emotion the next frames demand in time (a transition's switch must find an
    edge between the emotions within its window)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    src, dst = g.edges()
    labelled = g.frames.dominant >= 0
    keep = labelled[src] & labelled[dst]
    n = len(g.kept)
    reverse = coo_matrix((np.ones(int(keep.sum())), (dst[keep], src[keep])), shape=(n + 1, n + 1)).tocsr()
    out = np.full((n, 4), 10 ** 6, dtype=np.int64)
    for e in range(4):
        targets = np.flatnonzero((g.frames.dominant == e) & g.kept)
        if len(targets) == 0:
            continue
        virtual = coo_matrix((np.full(len(targets), 1e-9), (np.full(len(targets), n), targets)), shape=(n + 1, n + 1))
        dist = dijkstra(reverse + virtual.tocsr(), indices=n, unweighted=False)[:n]
        out[:, e] = np.where(np.isfinite(dist), np.round(dist), 10 ** 6).astype(np.int64)
    return out


def next_demand(allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, L) for each frame t: the first later frame whose allowed set is a single emotion, and that emotion
    (the last frame and its own where none is)."""
    R, L, _ = allowed.shape
    single = allowed.sum(-1) == 1
    frame = np.full((R, L), L - 1)
    emotion = np.tile(allowed[:, -1].argmax(-1)[:, None], (1, L))
    for t in range(L - 2, -1, -1):
        here = single[:, t + 1]
        frame[:, t] = np.where(here, t + 1, frame[:, t + 1])
        emotion[:, t] = np.where(here, allowed[:, t + 1].argmax(-1), emotion[:, t + 1])
    return frame, emotion


def _search(g: MotionGraph, allowed: np.ndarray, grid: PathGrid, seeds: list[int], cfg: SearchConfig,
            corridor: float, emotion: bool, trajectory: bool, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node paths (R, L) and whether each row found one (R,)."""
    R, L = allowed.shape[:2]
    W = cfg.n_save
    dominant = g.frames.dominant
    if emotion:
        demand_frame, demand_emotion = next_demand(allowed)
    kept = np.flatnonzero(g.kept)
    options = 1 + g.out.shape[1]
    # each row's own draws, all steps at once (float32: the noise only orders candidates)
    noise = np.stack([np.random.default_rng([seed, 2]).gumbel(size=(L, W * options)).astype(np.float32)
                      for seed in seeds], 1)
    rngs = [np.random.default_rng([seed, 1]) for seed in seeds]
    rows = np.arange(R)[:, None]
    # start nodes: W random kept nodes the first frame may walk
    node = np.empty((R, W), dtype=np.int64)
    for r in range(R):
        pool = kept[allowed[r, 0, dominant[kept]] & (dominant[kept] >= 0)] if emotion else kept
        node[r] = rngs[r].choice(pool if len(pool) else kept, W, replace=len(pool) < W)
    cost = np.zeros((R, W))
    index = np.zeros((R, W), dtype=np.int64)  # the closest path sample
    position = np.zeros((R, W, 2))
    psi = np.zeros((R, W))
    lookahead = int(round(cfg.lookahead_m / grid.spacing))
    alive = np.ones((R, W), dtype=bool)
    parents = np.zeros((L, R, W), dtype=np.int64)
    nodes = np.zeros((L, R, W), dtype=np.int64)
    nodes[0] = node
    max_warp = math.radians(cfg.max_warp_deg)
    for t in range(1, L):
        cand = np.concatenate([g.natural[node][..., None], g.out[node]], -1)  # (R, W, O)
        step_cost = np.concatenate([np.zeros((R, W, 1)), g.out_cost[node]], -1)
        valid = (cand >= 0) & alive[..., None]
        c = np.maximum(cand, 0)
        if emotion:
            d = dominant[c]
            valid &= (d >= 0) & allowed[rows[..., None], t, np.maximum(d, 0)]
            valid &= reach[c, demand_emotion[:, t][:, None, None]] <= (demand_frame[:, t] - t)[:, None, None]
        # the placement of each option the emotion allows (the others are never kept)
        live = np.flatnonzero(valid.ravel())
        row_of = live // (W * options)
        beam_of = (live // options) % W
        node_of = c.ravel()[live]
        turn = g.frames.turn[node_of]
        moved = position[row_of, beam_of] + world_step(g.frames.step[node_of], psi[row_of, beam_of])
        near, distance = grid.closest_near(row_of, index[row_of, beam_of], moved)
        target = grid.point_at(row_of, near + lookahead) - moved
        wanted = np.arctan2(target[..., 0], target[..., 1])
        natural = psi[row_of, beam_of] + turn
        warp = np.clip(np.remainder(wanted - natural + np.pi, 2 * np.pi) - np.pi, -max_warp, max_warp)
        ok = distance <= corridor if trajectory else np.ones(len(live), dtype=bool)
        flat = np.full(R * W * options, np.inf)
        flat[live[ok]] = (cost.ravel()[live // options] + step_cost.ravel()[live]
                          + cfg.warp_cost * np.degrees(np.abs(warp)))[ok]
        flat = flat.reshape(R, W * options)
        slot = np.zeros(R * W * options, dtype=np.int64)  # where each live option's placement is kept
        slot[live] = np.arange(len(live))
        key = np.where(np.isfinite(flat), -flat / cfg.temperature + noise[t], -np.inf)
        pick = np.argpartition(-key, W - 1, axis=1)[:, :W]
        pick = np.take_along_axis(pick, np.argsort(-np.take_along_axis(key, pick, 1), axis=1, kind="stable"), 1)
        alive = np.isfinite(np.take_along_axis(key, pick, 1))
        beam = pick // options
        node = cand.reshape(R, -1)[rows, pick]
        cost = flat[rows, pick]
        kept = slot.reshape(R, -1)[rows, pick]
        index = np.where(alive, near[kept] if len(live) else 0, 0)
        position = np.where(alive[..., None], moved[kept] if len(live) else 0.0, 0.0)
        psi = np.where(alive, (natural + warp)[kept] if len(live) else 0.0, 0.0)
        parents[t], nodes[t] = beam, node
    cost = np.where(alive, cost, np.inf)
    best = np.argmin(cost, axis=1)
    found = np.isfinite(cost[np.arange(R), best])
    path = np.zeros((R, L), dtype=np.int64)
    b = best
    for t in range(L - 1, -1, -1):
        path[:, t] = nodes[t, np.arange(R), b]
        b = parents[t, np.arange(R), b]
    return path, found


def allowed_emotions(emotions: np.ndarray, context: int, slack: int, bridge: int) -> np.ndarray:
    """(R, context + T, 4) which emotions each frame may walk: the dominant one of its frame (context frames: the
    first frame's), and within ``slack`` frames of a change, the dominant emotions on both sides and ``bridge``;
    the last frame only its own."""
    dominant = np.concatenate([np.repeat(emotions[:, :1], context, 1), emotions], 1).argmax(-1)
    R, L = dominant.shape
    out = np.zeros((R, L, emotions.shape[-1]), dtype=bool)
    for shift in range(-slack, slack + 1):
        idx = np.clip(np.arange(L) + shift, 0, L - 1)
        out[np.arange(R)[:, None], np.arange(L)[None], dominant[:, idx]] = True
    near_change = out.sum(-1) > 1  # outside a change every shift names the same emotion
    out[..., bridge] |= near_change
    # a gait ends in the emotion its last frame names (a change near the end must be complete by then)
    out[:, -1] = False
    out[np.arange(R), -1, dominant[:, -1]] = True
    return out


def search(g: MotionGraph, emotions: np.ndarray, paths: np.ndarray, seeds: list[int], context: int,
           cfg: SearchConfig) -> tuple[np.ndarray, list[str]]:
    """Node paths (R, context + T) for rows with per-frame emotions (R, T, 4) and trajectory pieces (R, K, 2) from
    (0, 0) towards +Z; and the level of ``LEVELS`` each row was found at."""
    from pipeline.core.emotions import EMOTIONS

    allowed = allowed_emotions(emotions, context, cfg.switch_slack, EMOTIONS.index(cfg.bridge))
    grid = PathGrid.of(paths)
    reach = emotion_reach(g)
    R = len(emotions)
    path = np.zeros((R, allowed.shape[1]), dtype=np.int64)
    level = [""] * R
    todo = np.arange(R)
    attempts = [(cfg.corridor_m, cfg.emotion, cfg.trajectory), (cfg.corridor_m * cfg.relax, cfg.emotion,
                                                                  cfg.trajectory),
                (cfg.corridor_m, cfg.emotion, False), (cfg.corridor_m, False, False)]
    for name, (corridor, emotion, trajectory) in zip(LEVELS, attempts):
        if len(todo) == 0:
            break
        sub = grid.take(todo)
        found_path, found = _search(g, allowed[todo], sub, [seeds[i] for i in todo], cfg, corridor, emotion,
                                    trajectory, reach)
        for i, p, ok in zip(todo, found_path, found):
            if ok or name == LEVELS[-1]:
                path[i] = p
                level[i] = name
        todo = todo[~found]
    return path, level
