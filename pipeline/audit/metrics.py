"""Audit of a published gait directory: value checks, label distributions, feature distributions, whether
synthetic gaits look like their intended emotion, and whether they help an emotion recogniser.

Works on any published directory (``pipeline.dataset``). Everything here returns numbers or draws figures; the
`audit` command (stages/audit.py) writes them with a self-contained HTML page. A gait's label for counting and
recognising is its dominant emotion (``core.emotions.dominant_emotion``: ties are reported, never broken). The
recognisers are ``pipeline.recognition``'s two independent kinds (a summary MLP, a temporal CNN), trained on the
real train split here; their scores carry 95 % bootstrap intervals over clips. Synthetic gaits are audited per
generator family (``generator_families``), alike for every family; how close they lie to the train windows is
``audit.memorisation``'s.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections import Counter
from collections.abc import Sequence
import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import torch
from pipeline.core.emotions import dominant_emotion
from pipeline.core.skeleton import canonical_skeleton
from pipeline.dataset import directory_metadata, directory_schema, load_dataframe, verify
from pipeline.io.files import schema_meta
from pipeline.ops.mirror import mirror_gait
from pipeline.recognition import (
    RECOGNISER_NAMES,
    RECOGNISERS,
    SCORES,
    RecogniserConfig,
    RecognitionInputs,
    bootstrap_delta_interval,
    bootstrap_interval,
    confusion,
    fit_recogniser,
    majority_baseline,
    scores,
    summary_features,
)

COLUMNS = ("gait_id", "kind", "split", "source", "content", "label_method", "generator", "emotion", "emotion_per_frame",
           "contacts", "phase", "positions", "heading", "affective", "movement", "source_file", "source_sha256", "t_start", "t_end",
           "checkpoint_sha256", "seed_gait_id", "trajectory_id", "emotion_recipe", "plan_seed", "source_segments")
LINEAGE = {"real": ("source_file", "source_sha256", "t_start", "t_end"),
           "synthetic": ("checkpoint_sha256", "seed_gait_id", "trajectory_id", "emotion_recipe")}
UNLABELLED = "unlabelled"


def load_for_audit(directory) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The audited columns that the directory has, one row per gait, plus a ``dominant`` column."""
    schema = directory_schema(directory)
    frame = load_dataframe(directory, [c for c in COLUMNS if c in schema.names])
    meta = schema_meta(schema)
    frame["dominant"] = [dominant_emotion(e, meta["emotion_order"]) for e in frame["emotion"]]
    return frame, meta


# ----------------------------------------------------------------------------------------------- checks

def gait_problems(frame: pd.DataFrame, generators: dict[str, Any] | None = None) -> list[dict[str, str]]:
    """Per-gait value checks the loader's ``verify`` does not make: contacts 0/1, phase in [0, 2π), the lineage
    of each kind present, a known kind. One row per gait and check: gait, check, expected, found.

    generators: the directory metadata's ``generators`` (family -> entry with ``lineage`` columns and
    ``model_sha256``), if it has them: a family's gaits then need its own lineage columns (a family without seeds
    has no ``seed_gait_id``), a declared family and its model's sha256."""
    rows = []
    generators = generators or {}

    def add(gait: str, check: str, expected: str, found: str) -> None:
        rows.append({"gait_id": gait, "check": check, "expected": expected, "found": found})

    for gait, contacts in zip(frame["gait_id"], frame["contacts"]):
        if contacts is None or not np.isin(contacts, (0.0, 1.0)).all():
            add(gait, "contacts", "0 or 1", "missing" if contacts is None else
                "values " + ", ".join(f"{v:g}" for v in np.unique(contacts)[:4]))
    for gait, phase in zip(frame["gait_id"], frame["phase"]):
        if phase is None or not ((phase >= 0) & (phase < 2 * math.pi)).all():
            add(gait, "phase", "in [0, 2π)", "missing" if phase is None else
                f"min {np.nanmin(phase):.4f}, max {np.nanmax(phase):.4f}, NaN {int(np.isnan(phase).sum())}")
    groups = [("real", frame["kind"] == "real", LINEAGE["real"])]
    synthetic = frame["kind"] == "synthetic"
    if generators and "generator" in frame:
        for name, entry in generators.items():
            groups.append((f"{name} synthetic", synthetic & (frame["generator"] == name), entry["lineage"]))
            part = frame[synthetic & (frame["generator"] == name)]
            for gait in part.loc[part["checkpoint_sha256"] != entry["model_sha256"], "gait_id"]:
                add(gait, "lineage checkpoint_sha256", f"{name}'s model {entry['model_sha256'][:12]}…",
                    "another sha256")
        for gait, g in zip(frame.loc[synthetic, "gait_id"], frame.loc[synthetic, "generator"]):
            if g not in generators:
                add(gait, "generator", " or ".join(generators), repr(g))
    else:
        groups.append(("synthetic", synthetic, LINEAGE["synthetic"]))
    for kind, mask, fields in groups:
        part = frame[mask]
        for field in fields:
            if field not in frame:
                add("(all)", f"lineage {field}", f"column for {kind} gaits", "no column")
                continue
            for gait in part.loc[part[field].isna() | (part[field].astype(str) == ""), "gait_id"]:
                add(gait, f"lineage {field}", f"present for {kind} gaits", "missing")
    for gait, kind in zip(frame["gait_id"], frame["kind"]):
        if kind not in LINEAGE:
            add(gait, "kind", " or ".join(LINEAGE), repr(kind))
    return rows


def all_problems(directory, frame: pd.DataFrame) -> list[dict[str, str]]:
    """The loader's verify (checksums, schema, shapes, finite values, emotion rows, unique ids, HDF5, generator
    families) and the per-gait checks, as one table."""
    return [{"gait_id": "", "check": "verify", "expected": "", "found": p} for p in verify(directory)] + \
        gait_problems(frame, directory_metadata(directory).get("generators"))


# ------------------------------------------------------------------------------------------------ labels

def normalised_entropy(emotions: np.ndarray) -> np.ndarray:
    """Entropy of each emotion vector / log(4): 0 for a one-hot label, 1 for the uniform one."""
    p = np.clip(np.asarray(emotions, dtype=np.float64), 0.0, None)
    logs = np.log(np.where(p > 0, p, 1.0))
    return -(p * logs).sum(-1) / math.log(p.shape[-1])


def js_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Jensen-Shannon distance (base 2, in [0, 1]) between two discrete distributions."""
    p, q = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
    p, q = p / p.sum(), q / q.sum()
    m = 0.5 * (p + q)

    def kl(a: np.ndarray) -> float:
        nz = a > 0
        return float((a[nz] * np.log2(a[nz] / m[nz])).sum())

    return math.sqrt(max(0.0, 0.5 * kl(p) + 0.5 * kl(q)))


def label_summary(part: pd.DataFrame, names: Sequence[str]) -> dict[str, Any]:
    """Counts, mean emotion, dominant-emotion counts (ties and unlabelled counted), label methods, entropy and
    imbalance of a group of gaits."""
    labelled = part[part["dominant"] != UNLABELLED]
    emotions = np.stack(labelled["emotion"].to_numpy()) if len(labelled) else np.zeros((0, len(names)))
    dominant = Counter(part["dominant"])
    classes = [dominant.get(n, 0) for n in names]
    present = [c for c in classes if c]
    entropy = normalised_entropy(emotions)
    return {
        "gaits": int(len(part)),
        "labelled": int(len(labelled)),
        "mean_emotion": [round(float(v), 4) for v in emotions.mean(0)] if len(labelled) else None,
        "dominant": {n: dominant.get(n, 0) for n in (*names, "tie", UNLABELLED)},
        "label_method": dict(sorted(Counter(m if isinstance(m, str) else "(none)" for m in part["label_method"]).items())),
        "entropy_mean": round(float(entropy.mean()), 4) if len(labelled) else None,
        "imbalance_max_over_min": round(max(present) / min(present), 3) if present else None,
        "missing_classes": [n for n, c in zip(names, classes) if not c],
    }


def label_distributions(frame: pd.DataFrame, names: Sequence[str]) -> dict[str, Any]:
    """Label summaries per kind, per kind and source, per kind and split; Jensen-Shannon distances between real
    and synthetic labels (dominant-emotion classes, and mean soft labels)."""
    out: dict[str, Any] = {"by_kind": {k: label_summary(g, names) for k, g in frame.groupby("kind")},
                           "by_kind_source": {f"{k} / {s}": label_summary(g, names)
                                              for (k, s), g in frame.groupby(["kind", "source"])},
                           "by_kind_split": {f"{k} / {s}": label_summary(g, names)
                                             for (k, s), g in frame.groupby(["kind", "split"])}}
    kinds = out["by_kind"]
    if {"real", "synthetic"} <= set(kinds) and kinds["real"]["labelled"] and kinds["synthetic"]["labelled"]:
        out["js_distance_real_vs_synthetic"] = {
            "dominant_classes": round(js_distance([kinds["real"]["dominant"][n] for n in names],
                                                  [kinds["synthetic"]["dominant"][n] for n in names]), 4),
            "mean_soft_labels": round(js_distance(kinds["real"]["mean_emotion"], kinds["synthetic"]["mean_emotion"]), 4)}
    return out


def transition_counts(frame: pd.DataFrame, names: Sequence[str]) -> np.ndarray | None:
    """(4, 4) counts of synthetic transitions by the dominant emotion of their start and end vectors (ties on
    the first), or None when the dataset has none."""
    recipes = [json.loads(r) for r in frame.get("emotion_recipe", pd.Series(dtype=object)).dropna()]
    transitions = [r for r in recipes if r.get("kind") == "transition"]
    if not transitions:
        return None
    counts = np.zeros((len(names), len(names)), dtype=int)
    for r in transitions:
        counts[int(np.argmax(r["from_vector"])), int(np.argmax(r["to_vector"]))] += 1
    return counts


# ---------------------------------------------------------------------------------------------- features

# The affective features' published names spell their definitions (``ops.features.AFFECTIVE_FEATURES``):
# <kind>_<joint>_<joint>..., joint indices into the directory's ``joint_names``. The audit reads the words off
# the names the directory was annotated with, so they describe that data and cannot drift from it.
_FEATURE_NAME = re.compile(r"^(angle|distance_ratio|area_ratio)((?:_\d+)+)$")
_JOINT_COUNT = {"angle": 3, "distance_ratio": 4, "area_ratio": 6}
# Where a joint's name is not plain words (manifests/skeleton.yaml says what each joint is).
JOINT_WORDS = {"root": "pelvis", "left_hand_index": "left index finger", "right_hand_index": "right index finger"}
MOVEMENT_WORDS = {
    "root_height": "pelvis height above its mean over the gait (m)",
    "root_speed": "pelvis ground speed (m per frame)",
    "root_speed_lowpass": "pelvis ground speed, low-passed (m per frame)",
    "heading_to_path_angle": "angle between the body's heading and its direction of travel, unsigned (rad)",
    "path_curvature": "path curvature: change of the pelvis's ground step from frame to frame (m per frame)",
}


def joint_words(name: str) -> str:
    """A canonical joint's name in words ('left_shoulder' -> 'left shoulder', the root -> 'pelvis')."""
    return JOINT_WORDS.get(name, name.replace("_", " "))


def _the_two(a: str, b: str) -> str:
    """'the right and left shoulders' for a left/right pair of one body part, else 'the a and the b'."""
    sides = {a.split(" ", 1)[0], b.split(" ", 1)[0]}
    if sides == {"left", "right"} and " " in a and a.split(" ", 1)[1] == b.split(" ", 1)[1]:
        return f"the {a.split(' ', 1)[0]} and {b.split(' ', 1)[0]} {a.split(' ', 1)[1]}s"
    return f"the {a} and the {b}"


def describe_affective_feature(kind: str, joints: Sequence[int], joint_names: Sequence[str]) -> str:
    """What one affective feature measures, in words, from its definition: ``kind`` and joint indices as in
    ``ops.features.AFFECTIVE_FEATURES`` ("angle" (a, v, b): the angle at v between a and b; "distance_ratio"
    (a, b, c, d): d(a, b) / d(c, d); "area_ratio" (a..f): area(a, b, c) / area(d, e, f))."""
    if kind not in _JOINT_COUNT or len(joints) != _JOINT_COUNT[kind]:
        raise ValueError(f"affective feature: expected angle (3 joints), distance_ratio (4) or area_ratio (6), "
                         f"found {kind} with {len(joints)} joints")
    w = [joint_words(joint_names[j]) for j in joints]
    if kind == "angle":
        return f"angle at the {w[1]} between {_the_two(w[0], w[2])}"
    if kind == "distance_ratio":
        return f"ratio of the {w[0]}–{w[1]} distance to the {w[2]}–{w[3]} distance"
    return f"ratio of the area of the triangle {'–'.join(w[:3])} to that of the triangle {'–'.join(w[3:])}"


def parse_affective_name(name: str) -> tuple[str, tuple[int, ...]] | None:
    """('angle', (17, 9, 13)) from 'angle_17_9_13'; None for a name that does not spell a definition."""
    match = _FEATURE_NAME.match(name)
    if not match or len(match.group(2).split("_")[1:]) != _JOINT_COUNT[match.group(1)]:
        return None
    return match.group(1), tuple(int(j) for j in match.group(2).split("_")[1:])


def feature_descriptions(affective_names: Sequence[str], movement_names: Sequence[str],
                         joint_names: Sequence[str]) -> list[dict[str, str]]:
    """Every per-frame feature of a directory in words: [{"index": "affective[0]", "name": "angle_17_9_13",
    "words": "angle at the lower back between the right and left shoulders", "joints": "17, 9, 13"}, ...], the
    affective features first (words from their definitions), then the movement features. A name that spells no
    definition keeps its own words (underscores as spaces)."""
    out = []
    for i, name in enumerate(affective_names):
        parsed = parse_affective_name(name)
        words = describe_affective_feature(*parsed, joint_names) if parsed else name.replace("_", " ")
        out.append({"index": f"affective[{i}]", "name": name, "words": words,
                    "joints": ", ".join(map(str, parsed[1])) if parsed else ""})
    for i, name in enumerate(movement_names):
        out.append({"index": f"movement[{i}]", "name": name,
                    "words": MOVEMENT_WORDS.get(name, name.replace("_", " ")), "joints": ""})
    return out


def gait_summaries(frame: pd.DataFrame) -> np.ndarray:
    """(gaits, 2 x features) mean and standard deviation over the frames of the affective and movement features
    (the summary MLP's input, ``recognition.summary_features``)."""
    return summary_features(np.stack(frame["affective"].to_numpy()), np.stack(frame["movement"].to_numpy()))


def feature_distances(real: np.ndarray, synthetic: np.ndarray) -> np.ndarray:
    """Per column: the 1-Wasserstein distance between the real and synthetic values, in real standard deviations."""
    q = np.linspace(0.0, 1.0, 101)
    w = np.abs(np.quantile(real, q, axis=0) - np.quantile(synthetic, q, axis=0)).mean(0)
    return w / np.maximum(real.std(0), 1e-12)


# ------------------------------------------------------------------------------------------- recognisers

@dataclass(frozen=True)
class AuditConfig:
    """The audit's recognition and memorisation settings (params.yaml ``audit``)."""

    recognisers: RecogniserConfig = dataclasses.field(default_factory=RecogniserConfig)
    seeds: dict[str, tuple[int, ...]] = dataclasses.field(
        default_factory=lambda: {"summary_mlp": (0, 1, 2, 3, 4), "temporal_cnn": (0, 1, 2)})
    test_splits: tuple[str, ...] = ("val", "test")  # the real held-out gaits the recognisers are tested on
    bootstrap_resamples: int = 1000
    memorisation_frame_stride: int = 2
    memorisation_candidates: int = 8
    # augmentation (``recognisability``): per seed, this many synthetic gaits per labelled real train gait, drawn
    # from those whose label holds in every frame; and, beside it, every synthetic gait at weight one
    synthetic_per_real: float = 1.0
    augment_with_all: bool = True
    # beside them, real gaits added in place of synthetic ones (``AUGMENTATION_CONTROLS``), to read a change against
    augmentation_controls: tuple[str, ...] = ("repeated", "mirrored")

    @classmethod
    def from_dict(cls, p: dict[str, Any]) -> "AuditConfig":
        """From params.yaml ``audit`` (recognisers, seeds per recogniser, test_splits, bootstrap_resamples,
        memorisation {frame_stride, candidates}, augmentation {synthetic_per_real, with_all, controls})."""
        seeds = {k: tuple(int(s) for s in v) for k, v in p["seeds"].items()}
        unknown = set(seeds) - set(RECOGNISERS)
        if unknown:
            raise KeyError(f"audit.seeds: expected recognisers among {', '.join(RECOGNISERS)}, found "
                           f"{', '.join(sorted(unknown))}")
        m, a = p.get("memorisation", {}), p.get("augmentation", {})
        controls = tuple(a.get("controls", cls.augmentation_controls))
        if set(controls) - set(AUGMENTATION_CONTROLS):
            raise KeyError(f"audit.augmentation.controls: expected names among {', '.join(AUGMENTATION_CONTROLS)}, "
                           f"found {', '.join(sorted(set(controls) - set(AUGMENTATION_CONTROLS)))}")
        return cls(recognisers=RecogniserConfig.from_dict(p.get("recognisers")), seeds=seeds,
                   test_splits=tuple(p.get("test_splits", cls.test_splits)),
                   bootstrap_resamples=int(p.get("bootstrap_resamples", cls.bootstrap_resamples)),
                   memorisation_frame_stride=int(m.get("frame_stride", cls.memorisation_frame_stride)),
                   memorisation_candidates=int(m.get("candidates", cls.memorisation_candidates)),
                   synthetic_per_real=float(a.get("synthetic_per_real", cls.synthetic_per_real)),
                   augment_with_all=bool(a.get("with_all", cls.augment_with_all)),
                   augmentation_controls=controls)


AUGMENTATION_CONTROLS = {
    "repeated": "the same real train gaits again",
    "mirrored": "the real train gaits' mirror images",
}


def augmentation_controls(inputs: RecognitionInputs, names: Sequence[str] = tuple(AUGMENTATION_CONTROLS)
                          ) -> dict[str, RecognitionInputs]:
    """Real gaits to add to a recogniser's real training gaits (``inputs``, in their order, so their labels are
    the same) in place of synthetic ones, so that a generator's augmentation change is read against what real data
    does under the same protocol: ``repeated``, the same gaits again (nothing new: its change is the refit's own
    noise), and ``mirrored``, their left-right mirror images (``ops.mirror``; a mirrored sad walk is a sad walk,
    so a recogniser that loses from them leans on which side the recorded performers favour, a cue no mirrored or
    newly generated gait keeps)."""
    out: dict[str, RecognitionInputs] = {}
    for name in names:
        if name == "repeated":
            out[name] = inputs
        elif name == "mirrored":
            arrays = {"positions": inputs.positions, "heading": inputs.heading, "affective": inputs.affective,
                      "movement": inputs.movement}
            image = mirror_gait({k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in arrays.items()},
                                canonical_skeleton())
            out[name] = RecognitionInputs.from_arrays({k: v.numpy() for k, v in image.items()})
        else:
            raise KeyError(f"augmentation control: expected one of {', '.join(AUGMENTATION_CONTROLS)}, found {name!r}")
    return out


def clip_identity(frame: pd.DataFrame) -> np.ndarray:
    """One clip identity per gait: a real gait's source and source file (its windows share them), any other gait
    its own id (a synthetic gait is its own unit)."""
    ids = frame["gait_id"].astype(str).to_numpy()
    if "source_file" not in frame:
        return ids
    has_file = frame["source_file"].notna().to_numpy() & (frame["kind"] == "real").to_numpy()
    files = (frame["source"].astype(str) + "/" + frame["source_file"].astype(str)).to_numpy()
    return np.where(has_file, files, ids)


def steady_label(frame: pd.DataFrame) -> np.ndarray:
    """Per gait: True where its whole-gait label holds in every frame, i.e. the dominant emotion of its per-frame
    label (``emotion_per_frame``) is the same throughout. A transition whose dominant emotion changes shows two
    emotions under one whole-gait label, so it is no whole-gait training example. Without per-frame labels, every
    gait is steady."""
    if "emotion_per_frame" not in frame:
        return np.ones(len(frame), bool)
    out = np.ones(len(frame), bool)
    for i, per_frame in enumerate(frame["emotion_per_frame"]):
        if per_frame is None or (isinstance(per_frame, float) and math.isnan(per_frame)):
            continue
        per_frame = np.asarray(per_frame, dtype=np.float64)
        if per_frame.ndim == 2 and len(per_frame) and np.isfinite(per_frame).all():
            dominant = per_frame.argmax(-1)
            out[i] = bool((dominant == dominant[0]).all())
    return out


def augmentation_draw(pool: np.ndarray, count: int, seed: int) -> np.ndarray:
    """``count`` row indices drawn without replacement from ``pool`` (all of it when smaller), sorted; seeded."""
    if count >= len(pool):
        return np.sort(pool)
    return np.sort(np.random.default_rng(seed).choice(pool, size=count, replace=False))


def generator_families(frame: pd.DataFrame) -> dict[str, np.ndarray]:
    """{family name: row mask} of the synthetic gaits, in name order.

    Families are told apart by the ``generator`` column where the table has one (a synthetic gait without a value
    falls in "(unnamed generator)"); without it every synthetic gait is one family, named by its sources and label
    methods ("generator (generator_condition)").
    """
    synthetic = (frame["kind"] == "synthetic").to_numpy()
    if not synthetic.any():
        return {}
    if "generator" in frame:
        named = frame["generator"].where(frame["generator"].notna(), "(unnamed generator)").astype(str).to_numpy()
        return {name: synthetic & (named == name) for name in sorted(set(named[synthetic]))}
    part = frame[synthetic]
    name = " + ".join(sorted({f"{s} ({m if isinstance(m, str) else 'no label method'})"
                              for s, m in zip(part["source"], part["label_method"])}))
    return {name: synthetic}


def held_out_by_content(frame: pd.DataFrame, held_out: np.ndarray) -> dict[str, np.ndarray]:
    """The held-out rows split by content: ``generator_contents`` (a content some synthetic gait has, e.g. forward
    walks) and ``other_contents`` (motions no generator makes: running, sideways walks, ...), as masks over the
    held-out rows. Synthetic gaits can only teach a recogniser the contents they show, so an augmentation figure
    over both hides where it helps or hurts. Empty when the frame has no contents or either part is empty."""
    if "content" not in frame:
        return {}
    content = frame["content"]
    made = set(content[frame["kind"] == "synthetic"].dropna())
    ours = content[held_out].isin(made).to_numpy()
    if not made or ours.all() or not ours.any():
        return {}
    return {"generator_contents": ours, "other_contents": ~ours}


def _summary(matrices: list[np.ndarray], names: Sequence[str], groups: np.ndarray, y: np.ndarray,
             predictions: list[np.ndarray], resamples: int) -> dict[str, Any]:
    """Mean and spread over seeds of each score, the 95 % interval of that mean resampling clips (every seed
    scored on the same drawn clips), the majority baseline and the confusion summed over seeds."""
    per_seed = [scores(m) for m in matrices]
    out: dict[str, Any] = {}
    interval = bootstrap_interval(groups, y, np.stack(predictions), len(names), resamples)
    for s in SCORES:
        out[f"{s}_mean"] = round(float(np.mean([p[s] for p in per_seed])), 4)
        out[f"{s}_std"] = round(float(np.std([p[s] for p in per_seed])), 4)
        out[f"{s}_ci95"] = interval[s]
    summed = np.sum(matrices, axis=0)
    out["gaits"] = int(summed.sum() // len(matrices))
    out["clips"] = int(len(set(groups)))
    out["majority_baseline"] = majority_baseline(summed, names)
    out["confusion_summed_over_seeds"] = summed.tolist()
    return out


def _delta(augmented: dict[str, Any], real: dict[str, Any], groups: np.ndarray, y: np.ndarray,
           before: list[np.ndarray], after: list[np.ndarray], classes: int, resamples: int
           ) -> tuple[dict[str, float], dict[str, list[float]]]:
    """The change of each score's mean over seeds, and its 95 % interval (paired: the same clips drawn for both)."""
    interval = bootstrap_delta_interval(groups, y, np.stack(before), np.stack(after), classes, resamples)
    return {s: round(augmented[f"{s}_mean"] - real[f"{s}_mean"], 4) for s in SCORES}, interval


def _content_breakdown(views: dict[str, np.ndarray], names: Sequence[str], groups: np.ndarray, y: np.ndarray,
                       real: list[np.ndarray], augmented: dict[str, list[np.ndarray]], resamples: int
                       ) -> dict[str, Any]:
    """The held-out predictions (real-only and augmented, the same fits) scored on each content view: the real-only
    figures and, per synthetic set, the augmented figures and their change with its paired interval."""
    k = len(names)
    out: dict[str, Any] = {}
    for view, m in views.items():
        def summary(answers: list[np.ndarray]) -> dict[str, Any]:
            return _summary([confusion(y[m], a[m], k) for a in answers], names, groups[m], y[m],
                            [a[m] for a in answers], resamples)

        base = summary(real)
        sets: dict[str, Any] = {}
        for name, answers in augmented.items():
            result = summary(answers)
            delta, ci = _delta(result, base, groups[m], y[m], [a[m] for a in real], [a[m] for a in answers], k,
                               resamples)
            sets[name] = {"augmented_real_held_out": result, "augmentation_delta": delta,
                          "augmentation_delta_ci95": ci}
        out[view] = {"real_held_out": base, "augmented": sets}
    return out


def labelled_gaits(frame: pd.DataFrame, names: Sequence[str], inputs: RecognitionInputs,
                   test_splits: Sequence[str]) -> tuple[np.ndarray, ...]:
    """(label, usable, real train, real held-out) per gait: the dominant emotion's index in ``names`` (-1: none
    of them), whether the gait has a label and finite values (a gait with a NaN is a problem, listed, not something
    to recognise), and the usable real gaits of the train split and of ``test_splits``."""
    index = {n: i for i, n in enumerate(names)}
    label = np.array([index.get(d, -1) for d in frame["dominant"]])
    usable = (label >= 0) & inputs.finite()
    real = (frame["kind"] == "real").to_numpy()
    train = real & (frame["split"] == "train").to_numpy() & usable
    return label, usable, train, real & frame["split"].isin(test_splits).to_numpy() & usable


def recognisability(frame: pd.DataFrame, names: Sequence[str], cfg: AuditConfig = AuditConfig(),
                    inputs: RecognitionInputs | None = None, progress: bool = False) -> dict[str, Any]:
    """Both independent recognisers (``recognition.RECOGNISERS``), each over its seeds (``cfg.seeds``; mean and
    spread over seeds, 95 % bootstrap intervals over clips):

    * trained on the real train split's labelled gaits, tested on the labelled real held-out gaits
      (``cfg.test_splits``, ``real_held_out``) and on the synthetic gaits against their intended dominant emotion
      (``synthetic``);
    * augmentation: trained on real train + synthetic gaits, tested on the same real held-out gaits. The protocol
      (fixed before it was first measured): per seed, ``cfg.synthetic_per_real`` synthetic gaits per labelled real
      train gait, drawn from those whose label holds in every frame (``steady_label``), so the synthetic gaits
      supplement the real ones instead of outnumbering them 20 to 1 and no transition is taught under one label
      (``augmented_real_held_out``; ``augmentation_delta`` and its paired interval ``augmentation_delta_ci95``).
      Beside it (``cfg.augment_with_all``), the naive use: every synthetic gait at weight one
      (``augmented_all_real_held_out``, ``augmentation_all_delta``, ``augmentation_all_delta_ci95``).
    * augmentation controls (``cfg.augmentation_controls``, ``augmentation_controls``): the same protocol with real
      gaits added instead (``augmentation_controls()``: the real train gaits again; their mirror images), each with
      its change and paired interval: what a generator's change is read against.

    Where the held-out gaits include contents no synthetic gait has (``held_out_by_content``), the same
    predictions are also scored on each part (``by_content``: real-only and augmented, with the change).

    Every test set reports accuracy, balanced accuracy, macro-F1 and its majority-class baseline. The synthetic
    figures are given for all synthetic gaits together and per generator family (``families``; one family: the
    same figures). ``inputs``: the frame's ``RecognitionInputs`` where already built.
    """
    inputs = RecognitionInputs.from_frame(frame) if inputs is None else inputs
    label, usable, train, test = labelled_gaits(frame, names, inputs, cfg.test_splits)
    groups = clip_identity(frame)
    finite = inputs.finite()
    syn = (frame["kind"] == "synthetic").to_numpy() & usable
    families = {n: m & usable for n, m in generator_families(frame).items()}
    separate = len(families) > 1  # one family: its figures are those of all synthetic gaits
    k = len(names)
    if not train.any() or not test.any():
        return {"skipped": "no labelled real train or held-out gaits"}
    out: dict[str, Any] = {"recognisers": list(RECOGNISERS), "seeds": {r: list(cfg.seeds[r]) for r in RECOGNISERS},
                           "test_splits": list(cfg.test_splits), "features": int(2 * (inputs.affective.shape[-1]
                                                                                       + inputs.movement.shape[-1])),
                           "block_frames": cfg.recognisers.block_frames,
                           "gaits": {"real_train": int(train.sum()), "real_held_out": int(test.sum()),
                                     "real_held_out_clips": int(len(set(groups[test]))), "synthetic": int(syn.sum()),
                                     "labelled_left_out_not_finite": int(((label >= 0) & ~finite).sum())},
                           "classes": list(names), "chance_accuracy": round(1.0 / k, 4),
                           "bootstrap_resamples": cfg.bootstrap_resamples, "by_recogniser": {}}
    sets = {"all": syn, **({n: m for n, m in families.items()} if separate else {})}
    steady = steady_label(frame)
    drawn_count = int(round(cfg.synthetic_per_real * train.sum()))
    out["augmentation"] = {
        "protocol": (f"per seed, {cfg.synthetic_per_real:g} synthetic gait(s) per labelled real train gait, drawn "
                     "without replacement from the synthetic gaits whose dominant emotion is the same in every frame"),
        "synthetic_per_real": cfg.synthetic_per_real,
        "eligible": {n: int((m & steady).sum()) for n, m in sets.items()},
        "drawn": {n: min(drawn_count, int((m & steady).sum())) for n, m in sets.items()},
        "also_all_synthetic": cfg.augment_with_all,
        "controls": {n: {"added": f"{AUGMENTATION_CONTROLS[n]} ({int(train.sum())} gaits)", "gaits": int(train.sum())}
                     for n in cfg.augmentation_controls}}
    held = inputs.select(test)
    real_train = inputs.select(train)
    controls = augmentation_controls(real_train, cfg.augmentation_controls)
    r_args = (cfg.bootstrap_resamples,)
    by_content = held_out_by_content(frame, test)
    if by_content:
        content = frame["content"].to_numpy()[test]
        dominant = np.asarray(list(names), dtype=object)[label[test]]
        out["held_out_by_content"] = {
            view: {"contents": sorted({str(c) for c in content[m]}), "gaits": int(m.sum()),
                   "clips": int(len(set(groups[test][m]))),
                   "per_emotion": {n: int((dominant[m] == n).sum()) for n in names}}
            for view, m in by_content.items()}
    for kind in RECOGNISERS:
        seeds = cfg.seeds[kind]
        predicted: dict[str, list[np.ndarray]] = {"real_held_out": []}
        on_synthetic = {n: [] for n, m in sets.items() if m.any()}
        augmented = {n: [] for n in on_synthetic}
        augmented_all = {n: [] for n in on_synthetic}
        controlled: dict[str, list[np.ndarray]] = {n: [] for n in controls}
        for seed in seeds:
            started = time.perf_counter()
            recogniser = fit_recogniser(kind, real_train, label[train], cfg.recognisers, seed)
            predicted["real_held_out"].append(recogniser.predict(held))
            for name, added in controls.items():
                again = fit_recogniser(kind, RecognitionInputs.concatenate([real_train, added]),
                                       np.concatenate([label[train], label[train]]), cfg.recognisers, seed)
                controlled[name].append(again.predict(held))
            for name in on_synthetic:
                on_synthetic[name].append(recogniser.predict(inputs.select(sets[name])))
                both = train.copy()
                both[augmentation_draw(np.flatnonzero(sets[name] & steady), drawn_count, seed)] = True
                again = fit_recogniser(kind, inputs.select(both), label[both], cfg.recognisers, seed)
                augmented[name].append(again.predict(held))
                if cfg.augment_with_all:
                    both = train | sets[name]
                    again = fit_recogniser(kind, inputs.select(both), label[both], cfg.recognisers, seed)
                    augmented_all[name].append(again.predict(held))
            if progress:
                print(f"audit: {kind} seed {seed}: {time.perf_counter() - started:.1f} s", flush=True)

        def summary(mask: np.ndarray, answers: list[np.ndarray]) -> dict[str, Any]:
            return _summary([confusion(label[mask], a, k) for a in answers], names, groups[mask], label[mask],
                            answers, *r_args)

        entry: dict[str, Any] = {"name": RECOGNISER_NAMES[kind],
                                 "real_held_out": summary(test, predicted["real_held_out"])}

        def augmented_by(answers: list[np.ndarray], key: str = "augmentation") -> dict[str, Any]:
            """The held-out figures of recognisers trained with something added, their change from real-only
            and its paired interval, under ``{key}`` names (``augmentation`` -> ``augmented_real_held_out``)."""
            held_out = summary(test, answers)
            delta, ci = _delta(held_out, entry["real_held_out"], groups[test], label[test],
                               predicted["real_held_out"], answers, k, *r_args)
            prefix = "augmented" + key.removeprefix("augmentation")
            return {f"{prefix}_real_held_out": held_out, f"{key}_delta": delta, f"{key}_delta_ci95": ci}

        entry["augmentation_controls"] = {name: augmented_by(answers) for name, answers in controlled.items()}
        per_set: dict[str, dict[str, Any]] = {}
        for name in on_synthetic:
            e = {"synthetic": summary(sets[name], on_synthetic[name]), **augmented_by(augmented[name])}
            if augmented_all[name]:
                e.update(augmented_by(augmented_all[name], "augmentation_all"))
            per_set[name] = e
        if by_content:
            entry["by_content"] = _content_breakdown(by_content, names, groups[test], label[test],
                                                     predicted["real_held_out"], augmented, *r_args)
        entry.update(per_set.get("all", {}))
        entry["families"] = {}
        for name, mask in families.items():
            fam: dict[str, Any] = {"gaits": int(mask.sum())}
            fam.update(per_set.get("all" if not separate else name, {}))
            entry["families"][name] = fam
        out["by_recogniser"][kind] = entry
    return out
