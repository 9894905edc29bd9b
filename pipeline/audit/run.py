"""The audit of a published gait directory, end to end: problems, label distributions, feature distances and
emotion recognisability, as metrics.json, plots and a self-contained index.html in an output folder.

Works on any published directory (ours, or a copy someone downloaded); reads nothing else.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from pipeline.audit.memorisation import memorisation
from pipeline.audit.metrics import (
    AuditConfig,
    all_problems,
    generator_families,
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
    plot_memorisation,
    plot_simplex_faces,
    plot_transitions,
    write_html,
)
from pipeline.core.skeleton import canonical_skeleton
from pipeline.io.files import write_json
from pipeline.recognition import RecognitionInputs


def _every(stride: int) -> str:
    """'every frame', 'every 2nd frame', 'every 3rd frame', 'every 4th frame'."""
    if stride == 1:
        return "every frame"
    suffix = "th" if 10 <= stride % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(stride % 10, "th")
    return f"every {stride}{suffix} frame"


def audit_directory(directory: Path, out: Path, cfg: AuditConfig, progress: bool = False) -> dict[str, Any]:
    """Audit ``directory`` into ``out`` (metrics.json, *.png, index.html); returns the metrics."""
    directory = Path(directory)
    frame, meta = load_for_audit(directory)
    return audit_frame(frame, meta, all_problems(directory, frame), directory.name, out, cfg, progress)


def audit_frame(frame: pd.DataFrame, meta: dict[str, Any], problems: list[dict[str, str]], name: str, out: Path,
                cfg: AuditConfig, progress: bool = False) -> dict[str, Any]:
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
    inputs = RecognitionInputs.from_frame(frame)
    recognition = recognisability(frame, names, cfg, inputs, progress)
    metrics["recognisability"] = recognition
    if "by_recogniser" in recognition:
        figures.append((plot_confusions(recognition, names, out / "confusion.png"),
                        "The two emotion recognisers (rows; confusion matrices summed over seeds): recognisability "
                        "of real held-out and synthetic gaits, and the same recogniser trained with synthetic "
                        f"gaits added (augmentation: {recognition['augmentation']['protocol']})."))
    finite = inputs.finite()  # a gait with a NaN is listed among the problems and left out here
    train = real & (frame["split"] == "train").to_numpy() & finite
    held_out = real & frame["split"].isin(cfg.test_splits).to_numpy() & finite
    if train.any() and (held_out.any() or synthetic.any()):
        metrics["memorisation"], distances = memorisation(
            inputs, train, held_out, synthetic & finite,
            {n: m & finite for n, m in generator_families(frame).items()}, cfg.memorisation_frame_stride,
            cfg.memorisation_candidates)
        metrics["memorisation"]["left_out_not_finite"] = int((~finite).sum())
        figures.append((plot_memorisation(distances, out / "memorisation.png"),
                        "No memorisation: each gait's distance to its nearest real train window (mean joint "
                        "position error of the root-relative poses in the heading frame, on "
                        f"{_every(cfg.memorisation_frame_stride)}), synthetic gaits beside real held-out windows."))
    write_json(metrics, out / "metrics.json")
    write_html(out / "index.html", f"Audit of {name}", metrics, problems, figures, names)
    return metrics
