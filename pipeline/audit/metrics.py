"""Audit of a published gait directory: value checks, label distributions, feature distributions, whether
synthetic gaits look like their intended emotion, and whether they help an emotion classifier.

Works on any published directory (``pipeline.dataset``). Everything here returns numbers or draws figures; the
`audit` command (stages/audit.py) writes them with a self-contained HTML page. A gait's label for counting and
classifying is its dominant emotion (``core.emotions.dominant_emotion``: ties are reported, never broken). The
classifier's input is a per-gait summary: the mean and standard deviation over the frames of the affective and
movement features. Synthetic gaits are audited per generator family (``generator_families``), alike for every
family.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import torch

from pipeline.io.files import schema_meta
from pipeline.dataset import directory_schema, load_dataframe, verify
from pipeline.core.emotions import dominant_emotion

COLUMNS = ("gait_id", "kind", "split", "source", "label_method", "generator", "emotion", "emotion_per_frame",
           "contacts", "phase", "affective", "movement", "source_file", "source_sha256", "t_start", "t_end",
           "checkpoint_sha256", "seed_gait_id", "trajectory_id", "emotion_recipe")
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

def gait_problems(frame: pd.DataFrame) -> list[dict[str, str]]:
    """Per-gait value checks the loader's ``verify`` does not make: contacts 0/1, phase in [0, 2π), the lineage
    of each kind present, a known kind. One row per gait and check: gait, check, expected, found."""
    rows = []

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
    for kind, fields in LINEAGE.items():
        part = frame[frame["kind"] == kind]
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
    """The loader's verify (checksums, schema, shapes, finite values, emotion rows, unique ids, HDF5) and the
    per-gait checks, as one table."""
    return [{"gait_id": "", "check": "verify", "expected": "", "found": p} for p in verify(directory)] + \
        gait_problems(frame)


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
    """(gaits, 2 x features) mean and standard deviation over the frames of the affective and movement features."""
    features = np.stack([np.concatenate([a, m], axis=-1) for a, m in zip(frame["affective"], frame["movement"])])
    return np.concatenate([features.mean(1), features.std(1)], axis=-1).astype(np.float64)


def feature_distances(real: np.ndarray, synthetic: np.ndarray) -> np.ndarray:
    """Per column: the 1-Wasserstein distance between the real and synthetic values, in real standard deviations."""
    q = np.linspace(0.0, 1.0, 101)
    w = np.abs(np.quantile(real, q, axis=0) - np.quantile(synthetic, q, axis=0)).mean(0)
    return w / np.maximum(real.std(0), 1e-12)


# -------------------------------------------------------------------------------------------- classifier

@dataclass(frozen=True)
class ClassifierConfig:
    hidden: int = 32
    epochs: int = 300
    learning_rate: float = 0.01
    weight_decay: float = 1e-3
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    test_splits: tuple[str, ...] = ("test",)  # the real held-out gaits the recognisers are tested on


def train_classifier(x: np.ndarray, y: np.ndarray, classes: int, cfg: ClassifierConfig, seed: int):
    """A small MLP on standardised summaries (full-batch Adam, class-balanced loss); returns predict(x) -> labels."""
    torch.manual_seed(seed)
    mean, std = x.mean(0), np.maximum(x.std(0), 1e-6)
    xt = torch.from_numpy((x - mean) / std).float()
    yt = torch.from_numpy(y).long()
    model = torch.nn.Sequential(torch.nn.Linear(x.shape[1], cfg.hidden), torch.nn.ELU(),
                                torch.nn.Linear(cfg.hidden, classes))
    counts = torch.bincount(yt, minlength=classes).float()
    weight = counts.sum() / (classes * counts.clamp_min(1.0))
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    for _ in range(cfg.epochs):
        optimiser.zero_grad()
        torch.nn.functional.cross_entropy(model(xt), yt, weight=weight).backward()
        optimiser.step()

    def predict(z: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return model(torch.from_numpy((z - mean) / std).float()).argmax(-1).numpy()
    return predict


def confusion(y: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    out = np.zeros((classes, classes), dtype=int)
    np.add.at(out, (y, predicted), 1)
    return out


SCORES = ("accuracy", "balanced_accuracy", "macro_f1")


def scores(matrix: np.ndarray) -> dict[str, float]:
    """Accuracy, balanced accuracy and macro-F1 of a confusion matrix (rows: truth, columns: predicted).

    Balanced accuracy is the mean recall and macro-F1 the mean F1 over the classes present in the truth (a class
    no tested gait has is left out of both, so neither rewards nor punishes its absence).
    """
    tp = np.diag(matrix).astype(np.float64)
    truth, said = matrix.sum(1), matrix.sum(0)
    present = truth > 0
    f1 = np.where(truth + said > 0, 2 * tp / np.maximum(truth + said, 1), 0.0)
    recall = tp / np.maximum(truth, 1)
    return {"accuracy": round(float(tp.sum() / max(matrix.sum(), 1)), 4),
            "balanced_accuracy": round(float(recall[present].mean()) if present.any() else float("nan"), 4),
            "macro_f1": round(float(f1[present].mean()) if present.any() else float("nan"), 4)}


def majority_baseline(matrix: np.ndarray, names: Sequence[str]) -> dict[str, Any]:
    """The scores of always answering the most frequent true class of the tested gaits, from the confusion
    matrix's row sums: the best accuracy any constant answer reaches on them (its balanced accuracy is 1 / the
    classes present). Returns {"class", "accuracy", "balanced_accuracy", "macro_f1"}."""
    truth = np.asarray(matrix).sum(1)
    top = int(np.argmax(truth))
    constant = np.zeros_like(np.asarray(matrix))
    constant[:, top] = truth
    return {"class": names[top], **scores(constant)}


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


def _summary(matrices: list[np.ndarray], names: Sequence[str]) -> dict[str, Any]:
    """Mean and spread over seeds of each score, the majority baseline and the confusion summed over seeds."""
    per_seed = [scores(m) for m in matrices]
    out: dict[str, Any] = {}
    for s in SCORES:
        out[f"{s}_mean"] = round(float(np.mean([p[s] for p in per_seed])), 4)
        out[f"{s}_std"] = round(float(np.std([p[s] for p in per_seed])), 4)
    summed = np.sum(matrices, axis=0)
    out["gaits"] = int(summed.sum() // len(matrices))
    out["majority_baseline"] = majority_baseline(summed, names)
    out["confusion_summed_over_seeds"] = summed.tolist()
    return out


def _delta(augmented: dict[str, Any], real: dict[str, Any]) -> dict[str, float]:
    return {s: round(augmented[f"{s}_mean"] - real[f"{s}_mean"], 4) for s in SCORES}


def recognisability(frame: pd.DataFrame, names: Sequence[str], cfg: ClassifierConfig = ClassifierConfig()
                    ) -> dict[str, Any]:
    """Emotion classifiers on per-gait summaries, over ``cfg.seeds`` (mean and spread reported):

    * trained on the real train split's labelled gaits, tested on the real held-out gaits (``cfg.test_splits``)
      and on the synthetic gaits against their intended dominant emotion (confusion matrices summed over seeds);
    * augmentation: trained on real train + synthetic gaits, tested on the same real held-out gaits.

    Every test set reports accuracy, balanced accuracy, macro-F1 and its majority-class baseline. The synthetic
    figures are given for all synthetic gaits together (``synthetic``, ``augmented_real_test``,
    ``augmentation_delta``) and per generator family (``families``; one family: the same figures).
    """
    summaries = gait_summaries(frame)
    index = {n: i for i, n in enumerate(names)}
    label = np.array([index.get(d, -1) for d in frame["dominant"]])
    real, synthetic = (frame["kind"] == "real").to_numpy(), (frame["kind"] == "synthetic").to_numpy()
    train = real & (frame["split"] == "train").to_numpy() & (label >= 0)
    test = real & frame["split"].isin(cfg.test_splits).to_numpy() & (label >= 0)
    syn = synthetic & (label >= 0)
    families = {n: m & (label >= 0) for n, m in generator_families(frame).items()}
    separate = len(families) > 1  # one family: its figures are those of all synthetic gaits
    k = len(names)
    if not train.any() or not test.any():
        return {"skipped": "no labelled real train or held-out gaits"}
    runs: dict[str, list[np.ndarray]] = {"real_test": [], "synthetic": [], "augmented_real_test": []}
    family_runs: dict[str, dict[str, list[np.ndarray]]] = {
        n: {"synthetic": [], "augmented_real_test": []} for n in families if separate}
    for seed in cfg.seeds:
        predict = train_classifier(summaries[train], label[train], k, cfg, seed)
        runs["real_test"].append(confusion(label[test], predict(summaries[test]), k))
        for mask, into in [(syn, runs)] + [(families[n], family_runs[n]) for n in family_runs]:
            if mask.any():
                into["synthetic"].append(confusion(label[mask], predict(summaries[mask]), k))
                both = train | mask
                augmented = train_classifier(summaries[both], label[both], k, cfg, seed)
                into["augmented_real_test"].append(confusion(label[test], augmented(summaries[test]), k))
    out: dict[str, Any] = {"features": int(summaries.shape[1]), "seeds": list(cfg.seeds),
                           "test_splits": list(cfg.test_splits),
                           "gaits": {"real_train": int(train.sum()), "real_test": int(test.sum()),
                                     "synthetic": int(syn.sum())}, "classes": list(names)}
    for name, matrices in runs.items():
        if matrices:
            out[name] = _summary(matrices, names)
    out["chance_accuracy"] = round(1.0 / k, 4)
    if "augmented_real_test" in out:
        out["augmentation_delta"] = _delta(out["augmented_real_test"], out["real_test"])
    out["families"] = {}
    for name, mask in families.items():
        entry: dict[str, Any] = {"gaits": int(mask.sum())}
        if not separate:
            entry.update({key: out[key] for key in ("synthetic", "augmented_real_test", "augmentation_delta")
                          if key in out})
        elif family_runs[name]["synthetic"]:
            entry.update({key: _summary(m, names) for key, m in family_runs[name].items()})
            entry["augmentation_delta"] = _delta(entry["augmented_real_test"], out["real_test"])
        out["families"][name] = entry
    return out
