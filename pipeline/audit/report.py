"""The audit's figures (PNG) and its self-contained HTML page (figures embedded, tables inline)."""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline.audit.metrics import UNLABELLED, normalised_entropy  # noqa: E402
from pipeline.io.files import save_figure, write_text  # noqa: E402

KIND_COLOURS = {"real": "tab:blue", "synthetic": "tab:orange"}


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    save_figure(fig, path, dpi=80, metadata={"Software": None})
    return path


def plot_labels(frame: pd.DataFrame, names: Sequence[str], path: Path) -> Path:
    """Dominant-emotion counts, label methods and label entropy, real vs synthetic."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    kinds = sorted(frame["kind"].unique())
    categories = [*names, "tie", UNLABELLED]
    width = 0.8 / len(kinds)
    for i, kind in enumerate(kinds):
        part = frame[frame["kind"] == kind]
        counts = [int((part["dominant"] == c).sum()) for c in categories]
        axes[0].bar(np.arange(len(categories)) + i * width, counts, width, label=kind, color=KIND_COLOURS.get(kind))
        methods = part["label_method"].fillna("(none)").value_counts()
        axes[1].barh([f"{kind}: {m}" for m in methods.index], methods.to_numpy(), color=KIND_COLOURS.get(kind))
        labelled = [e for e in part["emotion"] if e is not None]
        if labelled:
            axes[2].hist(normalised_entropy(np.stack(labelled)), bins=20, range=(0, 1), alpha=0.6, label=kind,
                         color=KIND_COLOURS.get(kind), density=True)
    axes[0].set_xticks(np.arange(len(categories)) + 0.4 - width / 2, categories, rotation=30)
    axes[0].set_title("gaits per dominant emotion")
    axes[0].legend()
    axes[1].set_title("label method")
    axes[2].set_title("label entropy / log 4 (0 = one-hot)")
    axes[2].legend()
    return _save(fig, path)


def _ternary(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric (n, 3) -> plane coordinates of the triangle with corners (0, 0), (1, 0), (0.5, √3/2)."""
    return points[:, 1] + 0.5 * points[:, 2], points[:, 2] * math.sqrt(3) / 2


def plot_simplex_faces(frame: pd.DataFrame, names: Sequence[str], path: Path) -> Path:
    """Density of the emotion vectors on each face of the 4-emotion simplex (the fourth emotion dropped and the
    other three renormalised), real above, synthetic below."""
    kinds = sorted(frame["kind"].unique())
    fig, axes = plt.subplots(len(kinds), len(names), figsize=(4 * len(names), 3.6 * len(kinds)), squeeze=False)
    for row, kind in enumerate(kinds):
        labelled = [e for e in frame.loc[frame["kind"] == kind, "emotion"] if e is not None]
        emotions = np.stack(labelled) if labelled else np.zeros((0, len(names)))
        for col, dropped in enumerate(names):
            keep = [i for i in range(len(names)) if names[i] != dropped]
            face = emotions[:, keep]
            total = face.sum(1)
            face = face[total > 1e-9] / total[total > 1e-9, None]
            ax = axes[row, col]
            ax.plot([0, 1, 0.5, 0], [0, 0, math.sqrt(3) / 2, 0], color="0.3", lw=1)
            if len(face):
                x, y = _ternary(face)
                ax.hexbin(x, y, gridsize=25, extent=(0, 1, 0, math.sqrt(3) / 2), mincnt=1, cmap="viridis", bins="log")
            for (cx, cy), i in zip([(0, 0), (1, 0), (0.5, math.sqrt(3) / 2)], keep):
                ax.annotate(names[i], (cx, cy), ha="center", va="top" if cy == 0 else "bottom", fontsize=9)
            ax.set_title(f"{kind}: without {dropped} ({len(face)} gaits)", fontsize=9)
            ax.set_aspect("equal")
            ax.axis("off")
    return _save(fig, path)


def plot_transitions(counts: np.ndarray, names: Sequence[str], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(5, 4))
    image = ax.imshow(counts, cmap="Blues")
    for (i, j), v in np.ndenumerate(counts):
        ax.text(j, i, str(v), ha="center", va="center", fontsize=9)
    ax.set_xticks(range(len(names)), names)
    ax.set_yticks(range(len(names)), names)
    ax.set_xlabel("end emotion (dominant)")
    ax.set_ylabel("start emotion (dominant)")
    ax.set_title("synthetic transitions")
    fig.colorbar(image, ax=ax)
    return _save(fig, path)


def plot_features(frame: pd.DataFrame, summaries: np.ndarray, feature_names: Sequence[str], names: Sequence[str],
                  path: Path) -> Path:
    """Per-gait mean of each feature, per dominant emotion, real (blue) beside synthetic (orange)."""
    cols = 6
    rows = -(-len(feature_names) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    kinds = sorted(frame["kind"].unique())
    for f, (ax, feature) in enumerate(zip(axes.flat, feature_names)):
        data, positions, colours = [], [], []
        for e, emotion in enumerate(names):
            for k, kind in enumerate(kinds):
                mask = ((frame["kind"] == kind) & (frame["dominant"] == emotion)).to_numpy()
                if mask.any():
                    data.append(summaries[mask, f])
                    positions.append(e * (len(kinds) + 1) + k)
                    colours.append(KIND_COLOURS.get(kind))
        if data:
            parts = ax.boxplot(data, positions=positions, widths=0.8, showfliers=False, patch_artist=True)
            for patch, colour in zip(parts["boxes"], colours):
                patch.set_facecolor(colour)
        ax.set_xticks([e * (len(kinds) + 1) + (len(kinds) - 1) / 2 for e in range(len(names))],
                      [n[:3] for n in names], fontsize=7)
        ax.set_title(feature, fontsize=7)
        ax.tick_params(labelsize=6)
    for ax in list(axes.flat)[len(feature_names):]:
        ax.axis("off")
    fig.suptitle("per-gait mean of each feature by dominant emotion: real (blue), synthetic (orange)")
    return _save(fig, path)


def plot_feature_distances(distances: np.ndarray, feature_names: Sequence[str], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(12, 3.5))
    ax.bar(range(len(distances)), distances, color="tab:purple")
    ax.set_xticks(range(len(distances)), feature_names, rotation=90, fontsize=6)
    ax.set_ylabel("W1 distance / real std")
    ax.set_title("real vs synthetic, per feature summary")
    return _save(fig, path)


def plot_confusions(recognition: dict[str, Any], names: Sequence[str], path: Path) -> Path:
    panels = [(k, t) for k, t in (("real_test", "trained on real, tested on real test"),
                                  ("synthetic", "trained on real, tested on synthetic (intended emotion)"),
                                  ("augmented_real_test", "trained on real + synthetic, tested on real test"))
              if k in recognition]
    fig, axes = plt.subplots(1, max(1, len(panels)), figsize=(5 * max(1, len(panels)), 4.2), squeeze=False)
    for ax, (key, title) in zip(axes.flat, panels):
        matrix = np.asarray(recognition[key]["confusion_summed_over_seeds"])
        ax.imshow(matrix / np.maximum(matrix.sum(1, keepdims=True), 1), cmap="Greens", vmin=0, vmax=1)
        for (i, j), v in np.ndenumerate(matrix):
            ax.text(j, i, str(v), ha="center", va="center", fontsize=8)
        ax.set_xticks(range(len(names)), names, fontsize=8)
        ax.set_yticks(range(len(names)), names, fontsize=8)
        ax.set_xlabel("predicted")
        ax.set_ylabel("true")
        r = recognition[key]
        ax.set_title(f"{title}\naccuracy {r['accuracy_mean']:.2f}±{r['accuracy_std']:.2f}, "
                     f"macro-F1 {r['macro_f1_mean']:.2f}", fontsize=8)
    return _save(fig, path)


def _table(rows: Sequence[dict[str, Any]], limit: int | None = None) -> str:
    if not rows:
        return "<p>none</p>"
    shown = rows[:limit] if limit else rows
    keys = list(shown[0])
    head = "".join(f"<th>{html.escape(k)}</th>" for k in keys)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r[k]))}</td>" for k in keys) + "</tr>" for r in shown)
    more = f"<p>… and {len(rows) - len(shown)} more (all in metrics.json)</p>" if len(rows) > len(shown) else ""
    return f"<table><tr>{head}</tr>{body}</table>{more}"


def write_html(path: Path, title: str, metrics: dict[str, Any], problems: list[dict[str, str]],
               figures: Sequence[tuple[Path, str]]) -> Path:
    """One page: key figures, the problems table, every figure embedded (base64) with its caption."""
    summary_rows = [{"group": g, **{k: (json.dumps(v) if isinstance(v, (dict, list)) else v)
                                    for k, v in s.items() if k in ("gaits", "labelled", "mean_emotion", "dominant",
                                                                   "entropy_mean", "imbalance_max_over_min")}}
                    for g, s in {**metrics["labels"]["by_kind"], **metrics["labels"]["by_kind_source"],
                                 **metrics["labels"]["by_kind_split"]}.items()]
    recognition = metrics.get("recognisability", {})
    key_rows = [{"figure": k, "value": json.dumps(v)} for k, v in (
        ("gaits", metrics["gaits"]), ("problems", len(problems)),
        ("JS distance real vs synthetic", metrics["labels"].get("js_distance_real_vs_synthetic")),
        *((f"{k}: accuracy / macro-F1", [recognition[k]["accuracy_mean"], recognition[k]["macro_f1_mean"]])
          for k in ("real_test", "synthetic", "augmented_real_test") if k in recognition),
        ("augmentation delta", recognition.get("augmentation_delta")))]
    images = "".join(
        f'<figure><img alt="{html.escape(f.name)}" src="data:image/png;base64,'
        f'{base64.b64encode(f.read_bytes()).decode()}"><figcaption>{html.escape(caption)}</figcaption></figure>'
        for f, caption in figures)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1400px}}table{{border-collapse:collapse;font-size:12px}}
td,th{{border:1px solid #ccc;padding:2px 6px}}img{{max-width:100%}}figure{{margin:1.5em 0}}
figcaption{{font-size:13px;color:#333}}</style></head><body>
<h1>{html.escape(title)}</h1>
<h2>Key figures</h2>{_table(key_rows)}
<h2>Problems ({len(problems)})</h2>{_table(problems, 200)}
<h2>Labels</h2>{_table(summary_rows)}
<h2>Figures</h2>{images}
</body></html>
"""
    write_text(page, path)
    return path
