"""How the published synthetic gaits differ from the real gaits they were learnt from, measured on the table being
published (no recogniser), for the dataset card's "Known limitations" and the Croissant record's collection text.

Fixed prose went stale here: the Croissant fields once said the generator's emotion input changed gaits little and
that seeds came from the test split, long after neither was true. What can be measured is measured at publish:

- contents: per real labelled content (walk, walk-back, run, ...) and per generator family, the gaits per dominant
  emotion, how far the body faces from its direction of travel and the net speed;
- walking speed per dominant emotion: each family's gaits against the real labelled train-split walks
  (``synthesis.walking_figures``, as ``reports/synthesize.json`` reports it for a family);
- trunk and head: per family, how far the spine, neck and head rotations turn within a gait, against real
  train-split walks (the head is a leaf of the skeleton: its rotation moves no joint position, so only a rig on
  the published rotations shows it);
- root paths: per family, how often the root's ground path curls into a small loop or reverses within half a
  second, and how many of its steps point against the direction of travel, against real walks (a hesitating
  generated step can carry the root back: ``generate.forward_steps_only``);
- seeds: the splits and contents of the real gaits the seeded families start from.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.core.emotions import EMOTIONS, dominant_index
from pipeline.io.gait_table import column_array
from pipeline.ops.geometry import facing_off_travel, odd_frames, path_turns
from pipeline.ops.quaternion import qspread
from pipeline.synth.synthesis import net_and_path_speed, walking_figures

TRUNK_JOINTS = ("spine", "neck", "head")
TRAVEL_SECONDS = 1.0  # the direction of travel is the mean step over about a stride (as the generator reads it)
LOOP_SECONDS = 0.5  # a root path turning by more than LOOP_DEG within it curls into a loop (real walks: ~1 in 700)
LOOP_DEG = 270  # a planned trajectory's sharpest corner turns 135 deg
REVERSAL_DEG = 180
CHUNK = 512  # gaits per batch of the pairwise frame angles (CHUNK x joints x T x T)


def _strings(table: pa.Table, name: str) -> np.ndarray:
    return np.array([v if v is not None else "" for v in table.column(name).to_pylist()])


def _median(values: np.ndarray, digits: int) -> float | None:
    return round(float(np.median(values)), digits) if len(values) else None


def trunk_turn_deg(rotations: np.ndarray, joints: list[int]) -> np.ndarray:
    """(N, J) degrees: how far each joint's local rotation turns within each gait (``qspread`` over its frames).
    rotations: (N, T, 21, 4)."""
    out = []
    for first in range(0, len(rotations), CHUNK):
        q = torch.from_numpy(np.ascontiguousarray(rotations[first:first + CHUNK][:, :, joints].transpose(0, 2, 1, 3)))
        out.append(torch.rad2deg(qspread(q.double())).numpy())
    return np.concatenate(out) if out else np.zeros((0, len(joints)))


def root_path_figures(root_path: np.ndarray, frames: int) -> dict[str, float]:
    """Shares of ground root paths (N, T, 2) that loop (the step direction turns by more than ``LOOP_DEG`` within
    ``frames`` frames) or reverse (``REVERSAL_DEG``), and of their steps that point against the displacement over
    ``frames`` frames around them (``geometry.path_turns``)."""
    largest, against = (t.numpy() for t in path_turns(torch.as_tensor(root_path, dtype=torch.float64), frames))
    return {"loops": float((largest > np.deg2rad(LOOP_DEG)).mean()),
            "reversals": float((largest > np.deg2rad(REVERSAL_DEG)).mean()),
            "frames_against_travel": float(against.mean())}


def root_path_row(root_path: np.ndarray, frames: int) -> dict[str, Any]:
    """The card's row of a group of root paths (N, T, 2): its gait count and ``root_path_figures`` to 4 places
    (None for an empty group)."""
    if not len(root_path):
        return {"gaits": 0, "loops": None, "reversals": None, "frames_against_travel": None}
    return {"gaits": int(len(root_path)), **{k: round(v, 4) for k, v in root_path_figures(root_path, frames).items()}}


def measure(table: pa.Table, meta: dict[str, Any]) -> dict[str, Any]:
    """The figures (JSON-ready) of a published table (real and synthetic rows) and its schema metadata."""
    shapes, fps = meta["shapes"], float(meta["fps"])
    kind, split, content, generator, seed = (_strings(table, c) for c in (
        "kind", "split", "content", "generator", "seed_gait_id"))
    gait_id = _strings(table, "gait_id")
    emotion = column_array(table, "emotion", shapes["emotion"])
    root_path = column_array(table, "root_path", shapes["root_path"]).astype(np.float64)
    heading = column_array(table, "heading", shapes["heading"]).astype(np.float64)
    real = kind == "real"
    dominant = dominant_index(emotion)
    labelled = real & (dominant >= 0)
    ground = torch.from_numpy(root_path)
    root = torch.stack((ground[..., 0], torch.zeros_like(ground[..., 0]), ground[..., 1]), -1)
    facing = np.degrees(facing_off_travel(root, torch.from_numpy(heading), odd_frames(TRAVEL_SECONDS, fps))
                        .abs().median(-1).values.numpy())
    net, _ = net_and_path_speed(root_path, fps)
    families = list(meta["generators"])

    def group(mask: np.ndarray) -> dict[str, Any]:
        return {"gaits": int(mask.sum()),
                "per_emotion": {e: int((mask & (dominant == k)).sum()) for k, e in enumerate(EMOTIONS)},
                "facing_off_travel_deg": _median(facing[mask], 1), "net_speed_m_s": _median(net[mask], 3)}

    by_count = [c for c, _ in sorted(Counter(content[labelled]).items(), key=lambda kv: (-kv[1], kv[0]))]
    contents = {"real_labelled": {c: group(labelled & (content == c)) for c in by_count},
                "synthetic": {f: group(generator == f) for f in families}}
    train_walks = real & (split == "train") & (content == "walk")
    labelled_walks = labelled & train_walks
    walking = {"real_labelled_train_walks": walking_figures(root_path[labelled_walks], emotion[labelled_walks], fps),
               **{f: walking_figures(root_path[generator == f], emotion[generator == f], fps) for f in families}}
    joints = [meta["joint_names"].index(j) for j in TRUNK_JOINTS]
    rotations = column_array(table, "rotations", shapes["rotations"])

    def turn(mask: np.ndarray) -> np.ndarray:
        return np.median(trunk_turn_deg(rotations[mask], joints), 0)

    def turn_row(mask: np.ndarray, median: np.ndarray) -> dict[str, Any]:
        return {"gaits": int(mask.sum()), **{j: round(float(median[k]), 1) for k, j in enumerate(TRUNK_JOINTS)}}

    real_turn = turn(train_walks)
    trunk: dict[str, Any] = {"real_train_walks": turn_row(train_walks, real_turn)}
    for f in families:
        own = turn(generator == f)
        trunk[f] = {**turn_row(generator == f, own), "ratio_to_real": {
            j: round(float(own[k] / real_turn[k]), 2) for k, j in enumerate(TRUNK_JOINTS)}}
    loop_frames = max(2, round(LOOP_SECONDS * fps))
    root_paths = {name: root_path_row(root_path[mask], loop_frames) for name, mask in
                  (("real_walks", real & (content == "walk")), *((f, generator == f) for f in families))}
    row_of = {g: i for i, g in enumerate(gait_id)}
    seeds = {}
    for f in families:
        rows = np.array([row_of[s] for s in sorted(set(seed[generator == f]) - {""})], dtype=int)
        if len(rows):
            seeds[f] = {"gaits": len(rows), "splits": sorted(set(split[rows])), "contents": sorted(set(content[rows])),
                        "labelled": bool(labelled[rows].all())}
    return {"how": {"facing_off_travel_deg": "median over gaits of the median over frames of |heading - direction "
                                             "of travel| (the mean step over 1 s)",
                    "net_speed_m_s": "start-to-end ground distance of the root / duration, median over gaits",
                    "trunk_turn_deg": "median over gaits of the largest angle between two frames' local rotations "
                                      "of the joint",
                    "root_path": f"shares of gaits whose root's ground step direction turns by more than {LOOP_DEG} "
                                 f"(loops) or {REVERSAL_DEG} deg (reversals) within {loop_frames} frames, and of "
                                 "steps against the displacement over those frames around them"},
            "contents": contents, "walking": walking, "trunk_turn_deg": trunk, "root_path": root_paths, "seeds": seeds}


def _cell(value: float | None, spec: str, unit: str) -> str:
    return "–" if value is None else f"{value:{spec}}{unit}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|---" * len(header) + "|", *("| " + " | ".join(r) + " |" for r in rows)]


def card_section(figures: dict[str, Any]) -> str:
    """The card's "Known limitations" tables (Markdown) from ``measure``'s figures."""
    contents = [[label.format(key), str(g["gaits"]), *(str(g["per_emotion"][e]) for e in EMOTIONS),
                 _cell(g["facing_off_travel_deg"], ".1f", "°"), _cell(g["net_speed_m_s"], ".2f", " m/s")]
                for label, groups in (("real labelled, {}", figures["contents"]["real_labelled"]),
                                      ("`{}`", figures["contents"]["synthetic"]))
                for key, g in groups.items()]
    walking = [["real labelled train-split walks" if key == "real_labelled_train_walks" else f"`{key}`",
                *(_cell(per[e]["net_speed_m_s"], ".2f", " m/s") if e in per else "–" for e in EMOTIONS)]
               for key, per in figures["walking"].items()]
    trunk = [[f"real train-split walks ({t['gaits']})", *(f"{t[j]:.1f}°" for j in TRUNK_JOINTS)]
             if key == "real_train_walks" else
             [f"`{key}`", *(f"{t[j]:.1f}° ({t['ratio_to_real'][j]:.2f}×)" for j in TRUNK_JOINTS)]
             for key, t in figures["trunk_turn_deg"].items()]
    roots = [["real walks" if key == "real_walks" else f"`{key}`", str(r["gaits"]),
              *(_cell(None if r[k] is None else 100 * r[k], ".2f", " %")
                for k in ("loops", "reversals", "frames_against_travel"))]
             for key, r in figures["root_path"].items()]
    return "\n".join([
        "Measured on these files when they were written, without a recogniser (the pipeline's "
        "`reports/publish.json` holds the same figures).", "",
        "**What the gaits show.** Every content of the real labelled gaits (as its source names it) against "
        "each generator family's gaits: gaits per dominant emotion, how far the body faces from its direction of "
        "travel (median; about 0° walking forwards, 180° walking backwards) and the net speed (start to end over "
        "the 2 s, median). A recogniser trained on synthetic gaits sees the contents they do not show only in "
        "the real ones.", "",
        *_table(["gaits", "count", *EMOTIONS, "facing off travel", "net speed"], contents), "",
        "**Walking speed per dominant emotion** (net speed, median):", "", *_table(["gaits", *EMOTIONS], walking), "",
        "**Trunk and head.** How far each joint's rotation turns within a gait (the largest angle between two of "
        "its frames, median over gaits), against real train-split walks. The head is a leaf of the skeleton: its "
        "rotation moves no published joint position, but a character rigged on the published rotations shows it.",
        "", *_table(["gaits", *TRUNK_JOINTS], trunk), "",
        f"**Root paths.** How often a gait's root path curls into a small loop (its step direction turns by more than "
        f"{LOOP_DEG}° within {LOOP_SECONDS:g} s; a planned trajectory's sharpest corner turns 135°) or reverses "
        f"(more than {REVERSAL_DEG}°), and the share of steps against the direction of travel. Where a generated "
        "step hesitates, the root can circle on the spot for a moment; a character follows the root.", "",
        *_table(["gaits", "count", "loops", "reversals", "steps against travel"], roots), "",
        "Whether adding synthetic gaits to real training data helps an emotion recogniser depends on the recogniser "
        "and on the contents it is tested on: measure it (the pipeline's audit, `emogait audit`) before relying "
        "on it."])


def seed_text(figures: dict[str, Any]) -> dict[str, str]:
    """Words for the card and the Croissant record: the seeded families and their seeds' splits and contents."""
    seeds = figures["seeds"]
    splits = sorted({s for v in seeds.values() for s in v["splits"]})
    contents = sorted({c for v in seeds.values() for c in v["contents"]})
    return {"seeded": ", ".join(seeds) or "none", "seed_splits": "/".join(splits) or "no",
            "seed_contents": ", ".join(contents) or "none"}
