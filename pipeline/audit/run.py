"""The audit of a published gait directory, end to end: problems, label distributions, feature distances and
emotion recognisability, as metrics.json, plots and a self-contained index.html in an output folder.

Works on any published directory (ours, or a copy someone downloaded); reads nothing else.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from pipeline.audit.metrics import (
    ClassifierConfig,
    all_problems,
    feature_descriptions,
    feature_distances,
    gait_summaries,
    label_distributions,
    load_for_audit,
    recognisability,
    transition_counts,
)
from pipeline.audit.report import (
    plot_confusions,
    plot_feature_distances,
    plot_features,
    plot_labels,
    plot_simplex_faces,
    plot_transitions,
    write_html,
)
from pipeline.core.skeleton import canonical_skeleton
from pipeline.io.files import write_json


def audit_directory(directory: Path, out: Path, classifier: ClassifierConfig) -> dict[str, Any]:
    """Audit ``directory`` into ``out`` (metrics.json, *.png, index.html); returns the metrics."""
    directory = Path(directory)
    frame, meta = load_for_audit(directory)
    return audit_frame(frame, meta, all_problems(directory, frame), directory.name, out, classifier)


def audit_frame(frame: pd.DataFrame, meta: dict[str, Any], problems: list[dict[str, str]], name: str, out: Path,
                classifier: ClassifierConfig) -> dict[str, Any]:
    """The audit of gaits already loaded (``metrics.load_for_audit``: one row per gait, the directory's schema
    metadata) and checked (``problems``), into ``out``; returns the metrics."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = list(meta["emotion_order"])
    labels = label_distributions(frame, names)
    summaries = gait_summaries(frame)
    feature_names = [*meta["affective_names"], *meta["movement_names"]]
    summary_names = [f"{n} (mean)" for n in feature_names] + [f"{n} (std)" for n in feature_names]
    descriptions = feature_descriptions(meta["affective_names"], meta["movement_names"],
                                        meta.get("joint_names") or canonical_skeleton().names)
    feature_labels = [f"{d['index']} {d['words']}" for d in descriptions]
    real, synthetic = (frame["kind"] == "real").to_numpy(), (frame["kind"] == "synthetic").to_numpy()
    metrics: dict[str, Any] = {"directory": name, "gaits": int(len(frame)),
                               "kinds": {k: int(v) for k, v in frame["kind"].value_counts().sort_index().items()},
                               "problem_count": len(problems), "problems": problems, "labels": labels,
                               "feature_descriptions": descriptions,
                               "feature_means": {n: {k: round(float(summaries[mask, i].mean()), 4)
                                                     for k, mask in (("real", real), ("synthetic", synthetic))
                                                     if mask.any()} for i, n in enumerate(feature_names)}}
    figures = [(plot_labels(frame, names, out / "labels.png"),
                "Gaits per dominant emotion (ties and unlabelled shown), how labels were obtained, and label "
                "entropy (0: one-hot, 1: uniform), real vs synthetic."),
               (plot_simplex_faces(frame, names, out / "simplex_faces.png"),
                "Emotion vectors on the four faces of the 4-emotion simplex (log density).")]
    counts = transition_counts(frame, names)
    if counts is not None:
        metrics["transitions_by_start_end"] = counts.tolist()
        figures.append((plot_transitions(counts, names, out / "transitions.png"),
                        "Synthetic emotion transitions by the dominant emotion of their start and end."))
    if real.any() and synthetic.any():
        distances = feature_distances(summaries[real], summaries[synthetic])
        metrics["feature_distance_w1_over_real_std"] = {n: round(float(d), 4) for n, d in zip(summary_names, distances)}
        figures.append((plot_feature_distances(distances, feature_labels, out / "feature_distances.png"),
                        "How far the synthetic per-gait feature summaries lie from the real ones (1-Wasserstein "
                        "distance in real standard deviations)."))
    figures.append((plot_features(frame, summaries, feature_labels, names, out / "features.png"),
                    "Affective and movement features (per-gait mean) by dominant emotion."))
    recognition = recognisability(frame, names, classifier)
    metrics["recognisability"] = recognition
    if "real_test" in recognition:
        figures.append((plot_confusions(recognition, names, out / "confusion.png"),
                        "Emotion classifier on per-gait feature summaries (confusion matrices summed over seeds): "
                        "recognisability of real and synthetic gaits, and the same classifier trained with the "
                        "synthetic gaits added (augmentation)."))
    write_json(metrics, out / "metrics.json")
    write_html(out / "index.html", f"Audit of {name}", metrics, problems, figures, names)
    return metrics
