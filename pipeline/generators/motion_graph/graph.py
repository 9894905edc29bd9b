"""The motion graph of the third family (seed 002, Yang, Yang & Hodgins §6), built on gait.

**Nodes** are the frames of the train split's rebuilt walk clips (``GraphConfig.contents``: forward and turning
walks; sideways, backwards and running clips stay out). Each carries its clip's emotion and label method, its
foot contacts and stepping phase (``annotate.annotate_clip`` on the rebuilt clip), its local rotations with the
pelvis turned to face +Z, its root height, and the root's motion into it: the ground step from the previous frame
in that frame's heading frame (sideways +x, ahead +z) and the turn (rad) of the heading.

**Edges.** Natural edges i -> i + 1 within a clip (cost 0). A synthetic edge i -> j means "after frame i play
frame j"; its cost (paper Eq. 3-4) compares frame i with frame j - 1, the frame that naturally precedes j:

    c(i, j) = d(p_i, p_{j-1}) + w_v d(ṗ_i, ṗ_{j-1}) + w_s |s_i - s_{j-1}| + w_ω |ω_i - ω_{j-1}|

with d(a, b) = Σ_b ||a[b] - b[b]|| over the 21 joints (every joint weighs 1; the skeleton has no fingers), p the
root-relative joint positions in the heading frame, ṗ their change per frame, s the root's ground step and ω its
turn. Root-relative positions cannot see how fast the body travels or turns (a fast and a slow walk share poses),
hence the last two terms, which the paper's seated conversations did not need. Each extra term is scaled so that
its median over the natural pairs (i, i + k - 1) matches the position term's (the paper: w_v "scales the velocity
term to match the range of the position term").

Synthetic edges are allowed only at **key states**, the foot events (strikes and offs of either foot): i and j - 1
are key states of the same event (a left strike continues from a left strike: any other pairing costs a half step),
never within one clip with |i - j| < k. **Threshold:** the 0.95 quantile of a Johnson SB distribution fitted to the
costs c(i, i + k) of every clip frame (paper §6, k = 3), the empirical quantile reported beside it. Each node keeps
its ``per_class_out`` cheapest synthetic edges below the threshold towards each emotion's nodes and
towards unlabelled nodes (the search's branching; reported). Only the largest
strongly connected component is kept (scipy.sparse.csgraph), so a walk can go on from every kept node; an emotion
with no node in it keeps its own largest component beside it (else that emotion could not be walked at all), which
the statistics report.
"""

from __future__ import annotations

import io
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.annotate.annotation import AnnotateConfig, annotate_clip
from pipeline.core.emotions import EMOTIONS, dominant_index
from pipeline.core.skeleton import Skeleton
from pipeline.generators.base import train_clips
from pipeline.io.files import sha256_bytes
from pipeline.ops.geometry import wrap_angle
from pipeline.ops.quaternion import qmul, yaw

EVENTS = ("left_strike", "left_off", "right_strike", "right_off")
FORMAT = "emogait-motion-graph/1"
# what the graph file keeps of the frames (the cost features, root-relative positions and their velocities, are
# only needed to build it: the file stays a third of the size without them)
STORED = ("clip", "frame", "rotations", "height", "step", "turn", "event", "contacts", "phase")


@dataclass(frozen=True)
class GraphConfig:
    """How the graph is built (the pipeline params' ``motion_graph.graph``)."""

    contents: tuple[str, ...] = ("walk", "walk-turn-left", "walk-turn-right")
    split: str = "train"
    k: int = 3  # threshold from c(i, i + k); no synthetic edge within a clip closer than k frames
    quantile: float = 0.95
    fit_sample: int = 4000  # costs the Johnson SB is fitted to (seeded draw; all go into the empirical quantile)
    per_class_out: int = 3  # cheapest synthetic edges kept per node towards each emotion and towards unlabelled nodes
    seed: int = 0
    table_ks: tuple[int, ...] = (2, 3, 4)  # the Table-2 statistics are reported for these k

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> GraphConfig:
        d = dict(d or {})
        out = {}
        for k, v in d.items():
            default = getattr(cls, k)
            out[k] = tuple(type(default[0])(x) for x in v) if isinstance(default, tuple) else type(default)(v)
        return cls(**out)


@dataclass
class Frames:
    """Every frame of the rebuilt clips (F nodes), in clip order; ``clip`` indexes ``clip_ids``."""

    clip_ids: list[str]
    clip_emotion: np.ndarray  # (clips, 4) NaN rows: unlabelled
    clip_label_method: list[str | None]
    clip_content: list[str]
    clip: np.ndarray  # (F,) int
    frame: np.ndarray  # (F,) frame in the rebuilt clip (the clip's rate, 30 fps)
    rotations: np.ndarray  # (F, J, 4) local; the pelvis turned to face +Z (its heading removed)
    height: np.ndarray  # (F,) root height, m
    step: np.ndarray  # (F, 2) ground step from the previous frame in its heading frame (sideways, ahead), m
    turn: np.ndarray  # (F,) heading change from the previous frame, rad
    relative: np.ndarray | None  # (F, J, 3) root-relative positions in the heading frame (None: not loaded)
    velocity: np.ndarray | None  # (F, J, 3) their change from the previous frame
    event: np.ndarray  # (F,) index into EVENTS of the foot event at this frame, -1: none
    contacts: np.ndarray  # (F, 4)
    phase: np.ndarray  # (F,) stepping phase (NaN where the clip has too few strikes)

    def __len__(self) -> int:
        return len(self.clip)

    @property
    def dominant(self) -> np.ndarray:
        """(F,) the dominant emotion index of each node's clip, -1: unlabelled."""
        return dominant_index(self.clip_emotion)[self.clip]

    def successor(self) -> np.ndarray:
        """(F,) the next frame of the same clip, -1 at a clip's last frame."""
        nxt = np.arange(1, len(self) + 1)
        nxt[:-1][self.clip[1:] != self.clip[:-1]] = -1
        nxt[-1] = -1
        return nxt


def clip_frames(table: pa.Table, arrays: dict[str, np.ndarray], skeleton: Skeleton, cfg: GraphConfig,
                annotate: AnnotateConfig) -> Frames:
    """The rebuilt clips of ``cfg.split`` and ``cfg.contents`` from a split gait table, frame by frame."""
    clips = train_clips(table, arrays, cfg.split, cfg.contents, annotate.fps)
    content = table.column("content").to_pylist()
    methods = table.column("label_method").to_pylist()
    parts: dict[str, list] = {k: [] for k in ("clip", "frame", "rotations", "height", "step", "turn", "relative",
                                               "velocity", "event", "contacts", "phase")}
    ids, emotion, method, contents = [], [], [], []
    for c, cid in enumerate(sorted(clips.positions)):
        pos = clips.positions[cid].astype(np.float64)
        first_row = clips.first_row[cid]
        heading = clips.heading[cid].astype(np.float64)
        rot = torch.from_numpy(clips.rotations[cid].astype(np.float64))
        n = len(pos)
        ids.append(cid)
        emotion.append(arrays["emotion"][first_row])
        method.append(methods[first_row])
        contents.append(str(content[first_row]))
        ann = annotate_clip(torch.from_numpy(pos), skeleton, annotate)
        event = np.full(n, -1)
        for e, name in enumerate(EVENTS):
            event[ann["events"][name]] = e
        h = torch.from_numpy(heading)
        pelvis = qmul(yaw(-h), rot[:, 0])
        local = torch.cat([pelvis[:, None], rot[:, 1:]], 1).numpy()
        c_, s_ = np.cos(heading), np.sin(heading)
        rel = pos - pos[:, :1]
        # into the heading frame: turn by -heading about +Y (heading 0 faces +Z)
        relative = np.stack([c_[:, None] * rel[..., 0] - s_[:, None] * rel[..., 2], rel[..., 1],
                             s_[:, None] * rel[..., 0] + c_[:, None] * rel[..., 2]], -1)
        ground = np.diff(pos[:, 0, [0, 2]], axis=0)
        prev_c, prev_s = c_[:-1], s_[:-1]
        step = np.stack([prev_c * ground[:, 0] - prev_s * ground[:, 1],
                         prev_s * ground[:, 0] + prev_c * ground[:, 1]], -1)
        turn = wrap_angle(torch.from_numpy(np.diff(heading))).numpy()
        velocity = np.diff(relative, axis=0)
        # a clip's first frame has no previous one: it moves as its second does
        parts["step"].append(np.concatenate([step[:1], step]))
        parts["turn"].append(np.concatenate([turn[:1], turn]))
        parts["velocity"].append(np.concatenate([velocity[:1], velocity]))
        parts["clip"].append(np.full(n, c))
        parts["frame"].append(np.arange(n))
        parts["rotations"].append(local)
        parts["height"].append(pos[:, 0, 1])
        parts["relative"].append(relative)
        parts["event"].append(event)
        parts["contacts"].append(ann["contacts"].numpy().astype(np.float32))
        parts["phase"].append(ann["phase"].numpy())
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    return Frames(clip_ids=ids, clip_emotion=np.array(emotion, dtype=np.float64).reshape(len(ids), len(EMOTIONS)),
                  clip_label_method=method, clip_content=contents, clip=cat["clip"], frame=cat["frame"],
                  rotations=cat["rotations"].astype(np.float32), height=cat["height"], step=cat["step"],
                  turn=cat["turn"], relative=cat["relative"], velocity=cat["velocity"], event=cat["event"],
                  contacts=cat["contacts"], phase=cat["phase"])


@dataclass(frozen=True)
class CostWeights:
    """w_v, w_s, w_ω of the transition cost (the position term weighs 1)."""

    velocity: float
    step: float
    turn: float


def cost_terms(f: Frames, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(4, n) the unweighted terms of c between frames a and b (n,): positions, velocities, ground step, turn."""
    return np.stack([np.linalg.norm(f.relative[a] - f.relative[b], axis=-1).sum(-1),
                     np.linalg.norm(f.velocity[a] - f.velocity[b], axis=-1).sum(-1),
                     np.linalg.norm(f.step[a] - f.step[b], axis=-1),
                     np.abs(f.turn[a] - f.turn[b])])


def transition_cost(f: Frames, w: CostWeights, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """c(i, j) of Eq. 3 for "after frame i play frame j": frame i against frame j - 1 (0 for j = i + 1)."""
    return weighted(cost_terms(f, i, j - 1), w)


def natural_pairs(f: Frames, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(i, i + k) for every frame i whose clip has frame i + k - 1 (what c(i, i + k) compares it with)."""
    i = np.arange(len(f) - (k - 1))
    keep = f.clip[i] == f.clip[i + k - 1]
    return i[keep], i[keep] + k


def weights_from(f: Frames, k: int) -> CostWeights:
    """Each extra term scaled to the position term's median over the natural pairs of k."""
    i, j = natural_pairs(f, k)
    terms = cost_terms(f, i, j - 1)
    med = np.median(terms, axis=1)
    scale = [float(med[0] / m) if m > 0 else 0.0 for m in med[1:]]
    return CostWeights(*scale)


def weighted(terms: np.ndarray, w: CostWeights) -> np.ndarray:
    return terms[0] + w.velocity * terms[1] + w.step * terms[2] + w.turn * terms[3]


def johnson_threshold(costs: np.ndarray, quantile: float, sample: int, seed: int) -> dict[str, float]:
    """The ``quantile`` of a Johnson SB fitted (scipy.stats) to a seeded draw of ``sample`` costs, and the
    empirical quantile of all of them."""
    from scipy import stats

    rng = np.random.default_rng(seed)
    drawn = costs if len(costs) <= sample else rng.choice(costs, sample, replace=False)
    drawn = np.sort(drawn)
    a, b, loc, scale = stats.johnsonsb.fit(drawn, loc=0.0, scale=float(drawn.max()) * 1.05)
    fitted = float(stats.johnsonsb.ppf(quantile, a, b, loc=loc, scale=scale))
    return {"johnson_sb": fitted, "empirical": float(np.quantile(costs, quantile)),
            "johnson_sb_params": [float(a), float(b), float(loc), float(scale)], "fitted_on": int(len(drawn))}


@dataclass
class KeyCosts:
    """Per event: the key states i, the key states m = j - 1 that have a next frame j, and c (|i|, |m|): the
    transition costs every k shares (k only masks near pairs and sets the threshold)."""

    sources: list[np.ndarray]
    before: list[np.ndarray]
    costs: list[np.ndarray]


def key_costs(f: Frames, w: CostWeights) -> KeyCosts:
    nxt = f.successor()
    out = KeyCosts([], [], [])
    for e in range(len(EVENTS)):
        keys = np.flatnonzero(f.event == e)
        before = keys[nxt[keys] >= 0]
        rows = []
        for first in range(0, len(keys), 256):
            i = keys[first:first + 256]
            rows.append(weighted(cost_terms(f, np.repeat(i, len(before)), np.tile(before, len(i))), w)
                        .reshape(len(i), len(before)))
        out.sources.append(keys)
        out.before.append(before)
        out.costs.append(np.concatenate(rows) if rows else np.zeros((0, len(before))))
    return out


def synthetic_edges(f: Frames, key: KeyCosts, k: int, threshold: float, per_class: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Edges i -> j below ``threshold`` between key states of the same event (source i, the frame j - 1 before
    the target), never within a clip closer than k. Each source keeps its ``per_class`` cheapest towards each
    emotion's nodes and towards unlabelled nodes: kept by cost alone, the few labelled clips would almost never
    be reached (90 % of the nodes are unlabelled), and an emotion-constrained walk could not branch.
    Returns (sources, targets, costs) sorted by source then cost, and how many were below the threshold."""
    nxt = f.successor()
    dominant = f.dominant
    sources, targets, costs, below = [], [], [], 0
    for i, before, c in zip(key.sources, key.before, key.costs):
        if len(i) == 0 or len(before) == 0:
            continue
        j = nxt[before]
        near = (f.clip[i][:, None] == f.clip[before][None, :]) & (np.abs(i[:, None] - j[None, :]) < k)
        c = np.where(near, np.inf, c)
        ok = c < threshold
        below += int(ok.sum())
        for cls in range(-1, len(EMOTIONS)):
            cols = np.flatnonzero(dominant[j] == cls)
            if len(cols) == 0:
                continue
            sub = c[:, cols]
            order = np.argsort(sub, axis=1, kind="stable")[:, :per_class]
            picked = np.take_along_axis(sub, order, 1)
            r, col = np.nonzero(picked < threshold)
            sources.append(i[r])
            targets.append(j[cols[order[r, col]]])
            costs.append(picked[r, col])
    s = np.concatenate(sources) if sources else np.zeros(0, np.int64)
    t = np.concatenate(targets) if targets else np.zeros(0, np.int64)
    c = np.concatenate(costs) if costs else np.zeros(0)
    order = np.lexsort((c, s))
    return s[order].astype(np.int64), t[order].astype(np.int64), c[order], below


def strongly_connected(n: int, natural: tuple[np.ndarray, np.ndarray], synthetic: tuple[np.ndarray, np.ndarray],
                       dominant: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
    """(n,) bool: the nodes kept (the largest strongly connected component, and for an emotion without a node in
    it, that emotion's largest component); with the component sizes."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    src = np.concatenate([natural[0], synthetic[0]])
    dst = np.concatenate([natural[1], synthetic[1]])
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(n, n)).tocsr()
    count, label = connected_components(graph, directed=True, connection="strong")
    sizes = np.bincount(label, minlength=count)
    largest = int(np.argmax(sizes))
    keep = label == largest
    added = {}
    for e, name in enumerate(EMOTIONS):
        mine = dominant == e
        if mine.any() and not (keep & mine).any():
            own = np.bincount(label[mine], minlength=count)
            comp = int(np.argmax(own))
            keep |= label == comp
            added[name] = int(sizes[comp])
    return keep, {"components": int(count), "largest": int(sizes[largest]), "added_for_emotions": added}


@dataclass
class MotionGraph:
    """The kept graph over ``frames``: ``kept`` (F,) nodes, ``natural`` (F,) next node (-1: none kept), and per
    node its synthetic edges ``out`` (F, 5 per_class_out) / ``out_cost`` (-1 / inf padded)."""

    frames: Frames
    kept: np.ndarray
    natural: np.ndarray
    out: np.ndarray
    out_cost: np.ndarray
    weights: CostWeights
    threshold: float
    config: GraphConfig
    statistics: dict[str, Any] = field(default_factory=dict)

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """All kept edges (sources, targets), natural then synthetic."""
        n = np.flatnonzero(self.natural >= 0)
        s, col = np.nonzero(self.out >= 0)
        return np.concatenate([n, s]), np.concatenate([self.natural[n], self.out[s, col]])


def _graph_at(f: Frames, w: CostWeights, key: KeyCosts, k: int, cfg: GraphConfig) -> tuple[dict[str, Any], tuple]:
    """Threshold, edges and SCC for one k: its Table-2 row and the parts of the graph."""
    costs = transition_cost(f, w, *natural_pairs(f, k))
    threshold = johnson_threshold(costs, cfg.quantile, cfg.fit_sample, cfg.seed)
    s, t, c, below = synthetic_edges(f, key, k, threshold["johnson_sb"], cfg.per_class_out)
    nxt = f.successor()
    nat = (np.flatnonzero(nxt >= 0), nxt[nxt >= 0])
    keep, scc = strongly_connected(len(f), nat, (s, t), f.dominant)
    nat_kept = keep[nat[0]] & keep[nat[1]]
    syn_kept = keep[s] & keep[t]
    row = {"k": k, "threshold": threshold,
           "before_scc": {"states": len(f), "edges": int(len(nat[0]) + len(s)), "synthetic_edges": int(len(s)),
                          "synthetic_below_threshold": below},
           "after_scc": {"states": int(keep.sum()), "edges": int(nat_kept.sum() + syn_kept.sum()),
                         "synthetic_edges": int(syn_kept.sum())},
           "scc": scc}
    return row, (threshold["johnson_sb"], keep, s[syn_kept], t[syn_kept], c[syn_kept])


def build_graph(f: Frames, cfg: GraphConfig = GraphConfig()) -> MotionGraph:
    """The graph at ``cfg.k`` and the statistics (Table 2, key-state share, both thresholds) at every
    ``cfg.table_ks``."""
    w = weights_from(f, cfg.k)
    key = key_costs(f, w)
    table, parts = [], None
    for k in sorted(set(cfg.table_ks) | {cfg.k}):
        row, built = _graph_at(f, w, key, k, cfg)
        table.append(row)
        if k == cfg.k:
            parts = built
    threshold, keep, s, t, c = parts
    natural = f.successor()
    natural = np.where((natural >= 0) & keep & keep[np.maximum(natural, 0)], natural, -1)
    width = cfg.per_class_out * (len(EMOTIONS) + 1)
    out = np.full((len(f), width), -1, dtype=np.int64)
    out_cost = np.full((len(f), width), np.inf)
    slot = Counter()
    for a, b, cost in zip(s.tolist(), t.tolist(), c.tolist()):
        out[a, slot[a]] = b
        out_cost[a, slot[a]] = cost
        slot[a] += 1
    dominant = f.dominant
    stats = {"table": table, "k": cfg.k, "threshold": threshold, "weights": asdict(w),
             "key_state_share": round(float((f.event >= 0).mean()), 4),
             "nodes_per_emotion": {name: {"before_scc": int((dominant == e).sum()),
                                          "after_scc": int(((dominant == e) & keep).sum()),
                                          "clips": int(len(set(f.clip[(dominant == e) & keep].tolist())))}
                                   for e, name in enumerate(EMOTIONS)},
             "unlabelled_nodes": {"before_scc": int((dominant < 0).sum()),
                                  "after_scc": int(((dominant < 0) & keep).sum())},
             "clips": len(f.clip_ids), "contents": dict(sorted(Counter(f.clip_content).items())),
             "synthetic_out_degree_mean": round(float((out >= 0).sum(1)[keep & (f.event >= 0)].mean()), 3)
             if (keep & (f.event >= 0)).any() else 0.0}
    return MotionGraph(f, keep, natural, out, out_cost, w, threshold, cfg, stats)


def graph_bytes(g: MotionGraph) -> bytes:
    """The graph as bytes (torch's zip format: the same numbers give the same bytes)."""
    f = g.frames
    blob = {"format": FORMAT, "config": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(g.config).items()},
            "emotions": list(EMOTIONS), "weights": asdict(g.weights), "threshold": float(g.threshold),
            "clip_ids": list(f.clip_ids), "clip_emotion": torch.from_numpy(f.clip_emotion),
            "clip_label_method": [m or "" for m in f.clip_label_method], "clip_content": list(f.clip_content),
            **{name: torch.from_numpy(np.ascontiguousarray(getattr(f, name)))
               for name in STORED},
            "kept": torch.from_numpy(g.kept), "natural": torch.from_numpy(g.natural), "out": torch.from_numpy(g.out),
            "out_cost": torch.from_numpy(g.out_cost), "statistics": g.statistics}
    buffer = io.BytesIO()
    torch.save(blob, buffer)
    return buffer.getvalue()


def load_graph(path) -> tuple[MotionGraph, str]:
    """(the graph, sha256 of its file) of ``graph_bytes`` written to ``path``."""
    from pathlib import Path

    data = Path(path).read_bytes()
    blob = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    if blob.get("format") != FORMAT:
        raise ValueError(f"{path}: expected a {FORMAT} graph, found {blob.get('format')!r}")
    arrays = {name: blob[name].numpy() for name in STORED}
    f = Frames(clip_ids=list(blob["clip_ids"]), clip_emotion=blob["clip_emotion"].numpy(),
               clip_label_method=[m or None for m in blob["clip_label_method"]],
               clip_content=list(blob["clip_content"]), relative=None, velocity=None, **arrays)
    cfg = GraphConfig.from_dict(blob["config"])
    g = MotionGraph(f, blob["kept"].numpy(), blob["natural"].numpy(), blob["out"].numpy(), blob["out_cost"].numpy(),
                    CostWeights(**blob["weights"]), float(blob["threshold"]), cfg, blob["statistics"])
    return g, sha256_bytes(data)
