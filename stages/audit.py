"""DVC stage `audit` (and `emogait audit PATH`): label and quality audit of a published gait directory.

data/published/synthesized_emotive_gaits/ (or any published directory) -> reports/audit/: metrics.json (DVC
metrics), *.png (DVC plots) and index.html, which shows them all.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import torch

from pipeline.audit.metrics import (
    ClassifierConfig,
    all_problems,
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
from pipeline.io.gait_table import write_json_atomic
from stages.common import REPO, load_params

PUBLISHED = REPO / "data" / "published" / "synthesized_emotive_gaits"
OUT = REPO / "reports" / "audit"


def main(params_path: Path | None = None, directory: Path = PUBLISHED, out: Path = OUT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    p = params["audit"]
    torch.set_num_threads(int(p.get("threads", 2)))
    directory, out = Path(directory), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"audit: {directory}", flush=True)
    frame, meta = load_for_audit(directory)
    names = list(meta["emotion_order"])
    problems = all_problems(directory, frame)
    labels = label_distributions(frame, names)
    summaries = gait_summaries(frame)
    feature_names = [*meta["affective_names"], *meta["movement_names"]]
    summary_names = [f"{n} (mean)" for n in feature_names] + [f"{n} (std)" for n in feature_names]
    real, synthetic = (frame["kind"] == "real").to_numpy(), (frame["kind"] == "synthetic").to_numpy()
    metrics: dict[str, Any] = {"directory": directory.name, "gaits": int(len(frame)),
                               "kinds": {k: int(v) for k, v in frame["kind"].value_counts().sort_index().items()},
                               "problem_count": len(problems), "problems": problems, "labels": labels}
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
        figures.append((plot_feature_distances(distances, summary_names, out / "feature_distances.png"),
                        "How far the synthetic per-gait feature summaries lie from the real ones (1-Wasserstein "
                        "distance in real standard deviations)."))
    figures.append((plot_features(frame, summaries, feature_names, names, out / "features.png"),
                    "Affective and movement features (per-gait mean) by dominant emotion."))
    c = p["classifier"]
    recognition = recognisability(frame, names, ClassifierConfig(hidden=int(c["hidden"]), epochs=int(c["epochs"]),
                                                                  learning_rate=float(c["learning_rate"]),
                                                                  weight_decay=float(c["weight_decay"]),
                                                                  seeds=tuple(int(s) for s in c["seeds"])))
    metrics["recognisability"] = recognition
    if "real_test" in recognition:
        figures.append((plot_confusions(recognition, names, out / "confusion.png"),
                        "Emotion classifier on per-gait feature summaries (confusion matrices summed over seeds): "
                        "recognisability of real and synthetic gaits, and the same classifier trained with the "
                        "synthetic gaits added (augmentation)."))
    write_json_atomic(metrics, out / "metrics.json")
    write_html(out / "index.html", f"Audit of {directory.name}", metrics, problems, figures)
    r = recognition
    print(f"audit: {len(frame)} gaits, {len(problems)} problems; "
          + (f"real test accuracy {r['real_test']['accuracy_mean']:.2f}" if "real_test" in r else "no classifier")
          + (f", synthetic {r['synthetic']['accuracy_mean']:.2f}, augmentation delta "
             f"{r['augmentation_delta']['accuracy']:+.3f}" if "augmentation_delta" in r else "")
          + f" -> {out}")
    return metrics


if __name__ == "__main__":
    main(directory=Path(sys.argv[1]) if len(sys.argv) > 1 else PUBLISHED)
