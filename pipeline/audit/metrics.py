"""Audit of a published gait directory: value checks, label distributions, feature distributions, whether
synthetic gaits look like their intended emotion, and whether they help an emotion classifier.

Works on any published directory (``pipeline.dataset``). Everything here returns numbers or draws figures; the
`audit` command (stages/audit.py) writes them with a self-contained HTML page. A gait's label for counting and
classifying is its dominant emotion (``core.emotions.dominant_emotion``: ties are reported, never broken). The
classifier's input is a per-gait summary: the mean and standard deviation over the frames of the affective and
movement features.
"""

from __future__ import annotations

import json
import math
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

COLUMNS = ("gait_id", "kind", "split", "source", "label_method", "emotion", "emotion_per_frame", "contacts", "phase",
           "affective", "movement", "source_file", "source_sha256", "t_start", "t_end", "checkpoint_sha256",
           "seed_gait_id", "trajectory_id", "emotion_recipe")
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
            add(gait, "contacts", "0 or 1", "missing" if contacts is None else f"{np.unique(contacts)[:4]}")
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


def scores(matrix: np.ndarray) -> dict[str, float]:
    """Accuracy and macro-F1 of a confusion matrix (rows: truth); classes absent from the truth are left out."""
    tp = np.diag(matrix).astype(np.float64)
    truth, said = matrix.sum(1), matrix.sum(0)
    present = truth > 0
    f1 = np.where(truth + said > 0, 2 * tp / np.maximum(truth + said, 1), 0.0)
    return {"accuracy": round(float(tp.sum() / max(matrix.sum(), 1)), 4),
            "macro_f1": round(float(f1[present].mean()) if present.any() else float("nan"), 4)}


def recognisability(frame: pd.DataFrame, names: Sequence[str], cfg: ClassifierConfig = ClassifierConfig()
                    ) -> dict[str, Any]:
    """Emotion classifiers on per-gait summaries, over ``cfg.seeds`` (mean and spread reported):

    * trained on the real train split's labelled gaits, tested on the real test split and on the synthetic
      gaits against their intended dominant emotion (confusion matrices summed over the seeds);
    * augmentation: trained on real train + synthetic gaits, tested on the same real test split.
    """
    summaries = gait_summaries(frame)
    index = {n: i for i, n in enumerate(names)}
    label = np.array([index.get(d, -1) for d in frame["dominant"]])
    real, synthetic = (frame["kind"] == "real").to_numpy(), (frame["kind"] == "synthetic").to_numpy()
    train = real & (frame["split"] == "train").to_numpy() & (label >= 0)
    test = real & (frame["split"] == "test").to_numpy() & (label >= 0)
    syn = synthetic & (label >= 0)
    k = len(names)
    if not train.any() or not test.any():
        return {"skipped": "no labelled real train or test gaits"}
    runs: dict[str, list[np.ndarray]] = {"real_test": [], "synthetic": [], "augmented_real_test": []}
    for seed in cfg.seeds:
        predict = train_classifier(summaries[train], label[train], k, cfg, seed)
        runs["real_test"].append(confusion(label[test], predict(summaries[test]), k))
        if syn.any():
            runs["synthetic"].append(confusion(label[syn], predict(summaries[syn]), k))
            both = train | syn
            augmented = train_classifier(summaries[both], label[both], k, cfg, seed)
            runs["augmented_real_test"].append(confusion(label[test], augmented(summaries[test]), k))
    out: dict[str, Any] = {"features": int(summaries.shape[1]), "seeds": list(cfg.seeds),
                           "gaits": {"real_train": int(train.sum()), "real_test": int(test.sum()),
                                     "synthetic": int(syn.sum())}, "classes": list(names)}
    for name, matrices in runs.items():
        if not matrices:
            continue
        per_seed = [scores(m) for m in matrices]
        out[name] = {
            "accuracy_mean": round(float(np.mean([s["accuracy"] for s in per_seed])), 4),
            "accuracy_std": round(float(np.std([s["accuracy"] for s in per_seed])), 4),
            "macro_f1_mean": round(float(np.mean([s["macro_f1"] for s in per_seed])), 4),
            "macro_f1_std": round(float(np.std([s["macro_f1"] for s in per_seed])), 4),
            "confusion_summed_over_seeds": np.sum(matrices, axis=0).tolist()}
    out["chance_accuracy"] = round(1.0 / k, 4)
    if "augmented_real_test" in out:
        out["augmentation_delta"] = {
            "accuracy": round(out["augmented_real_test"]["accuracy_mean"] - out["real_test"]["accuracy_mean"], 4),
            "macro_f1": round(out["augmented_real_test"]["macro_f1_mean"] - out["real_test"]["macro_f1_mean"], 4)}
    return out
