"""The audit's figures (PNG) and its self-contained HTML page (figures embedded, tables inline)."""

from __future__ import annotations

import base64
import html
import math
import textwrap
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


def _wrapped(label: str, width: int) -> str:
    return "\n".join(textwrap.wrap(label, width)) or label


def plot_features(frame: pd.DataFrame, summaries: np.ndarray, feature_labels: Sequence[str], names: Sequence[str],
                  path: Path) -> Path:
    """Per-gait mean of each feature, per dominant emotion, real (blue) beside synthetic (orange); each panel
    titled with the feature's index and what it measures (``metrics.feature_descriptions``)."""
    cols = 5
    rows = -(-len(feature_labels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.0 * rows), squeeze=False)
    kinds = sorted(frame["kind"].unique())
    for f, (ax, feature) in enumerate(zip(axes.flat, feature_labels)):
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
        ax.set_xticks([e * (len(kinds) + 1) + (len(kinds) - 1) / 2 for e in range(len(names))], list(names),
                      fontsize=7)
        ax.set_title(_wrapped(feature, 44), fontsize=7, loc="left")
        ax.tick_params(labelsize=6)
    for ax in list(axes.flat)[len(feature_labels):]:
        ax.axis("off")
    fig.suptitle("per-gait mean of each feature by dominant emotion: real (blue), synthetic (orange)")
    return _save(fig, path)


def plot_feature_distances(distances: np.ndarray, feature_labels: Sequence[str], path: Path) -> Path:
    """Real vs synthetic distance of each feature's per-gait mean and standard deviation, one row per feature
    (``distances``: the means' distances for every feature, then the standard deviations'), log scale."""
    n = len(feature_labels)
    means, stds = np.asarray(distances[:n]), np.asarray(distances[n:2 * n])
    fig, ax = plt.subplots(figsize=(14, 1.5 + 0.36 * n))
    y = np.arange(n)
    floor = 1e-3  # a log axis shows no zero; distances below this are drawn at it
    ax.barh(y - 0.2, np.maximum(means, floor), 0.4, color="tab:purple", label="per-gait mean")
    ax.barh(y + 0.2, np.maximum(stds, floor), 0.4, color="tab:olive", label="per-gait std over frames")
    ax.set_xscale("log")
    ax.axvline(1.0, color="0.4", lw=0.8, ls="--")
    ax.set_yticks(y, [_wrapped(label, 70) for label in feature_labels], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("1-Wasserstein distance, real vs synthetic, in real standard deviations (log; dashed: 1)")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("how far synthetic gaits lie from real ones, per feature")
    return _save(fig, path)


CONFUSION_PANELS = (("real_held_out", "trained on real, tested on real held-out"),
                    ("synthetic", "trained on real, tested on synthetic (intended emotion)"),
                    ("augmented_real_held_out", "trained on real + drawn synthetic, tested on real held-out"))


def plot_confusions(recognition: dict[str, Any], names: Sequence[str], path: Path) -> Path:
    """One row per recogniser, one panel per test (``CONFUSION_PANELS``), rows of each matrix shaded by share."""
    recognisers = list(recognition["by_recogniser"].items())
    cols = max(1, max(sum(k in entry for k, _ in CONFUSION_PANELS) for _, entry in recognisers))
    fig, axes = plt.subplots(len(recognisers), cols, figsize=(5 * cols, 4.6 * len(recognisers)), squeeze=False)
    for row, (_, entry) in enumerate(recognisers):
        panels = [(k, t) for k, t in CONFUSION_PANELS if k in entry]
        for ax in axes[row, len(panels):]:
            ax.axis("off")
        for ax, (key, title) in zip(axes[row], panels):
            matrix = np.asarray(entry[key]["confusion_summed_over_seeds"])
            shares = matrix / np.maximum(matrix.sum(1, keepdims=True), 1)
            ax.imshow(shares, cmap="Greens", vmin=0, vmax=1)
            for (i, j), v in np.ndenumerate(matrix):
                ax.text(j, i, str(v), ha="center", va="center", fontsize=8,
                        color="white" if shares[i, j] > 0.5 else "black")
            ax.set_xticks(range(len(names)), names, fontsize=8)
            ax.set_yticks(range(len(names)), names, fontsize=8)
            ax.set_xlabel("predicted")
            ax.set_ylabel("true")
            r = entry[key]
            ax.set_title(f"{entry['name']}: {title}\naccuracy {percent(r['accuracy_mean'])}, balanced "
                         f"{percent(r['balanced_accuracy_mean'])}, macro-F1 {percent(r['macro_f1_mean'])}", fontsize=8)
    return _save(fig, path)


def plot_memorisation(distances: dict[str, np.ndarray], path: Path) -> Path:
    """Histograms (density) of the distance to the nearest real train window: synthetic gaits, real held-out
    windows; medians dashed."""
    fig, ax = plt.subplots(figsize=(10, 3.8))
    values = [v for v in distances.values() if len(v)]
    top = max(float(np.quantile(v, 0.995)) for v in values) if values else 1.0
    bins = np.linspace(0.0, max(top, 1e-3), 50)
    for key, colour, label in (("synthetic", KIND_COLOURS["synthetic"], "synthetic gaits"),
                               ("real_held_out", KIND_COLOURS["real"], "real held-out windows")):
        v = distances.get(key, np.zeros(0))
        if len(v):
            ax.hist(np.minimum(v, bins[-1]), bins=bins, density=True, alpha=0.55, color=colour,
                    label=f"{label} ({len(v):,}; median {np.median(v):.3f} m)")
            ax.axvline(float(np.median(v)), color=colour, ls="--", lw=1)
    ax.set_xlabel("distance to the nearest real train window: mean joint position error, heading frame (m)")
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    ax.set_title("no memorisation: synthetic gaits should lie no closer to the train windows than real held-out "
                 "ones", fontsize=10)
    return _save(fig, path)


# ------------------------------------------------------------------------------------------- formatting
# Every figure on the page goes through these: percentages, signed points, fixed decimals, "a 1 · b 2" lists.

MINUS = "\u2212"
DASH = "–"  # an absent value


def percent(x: float | None, digits: int = 1) -> str:
    """0.8285 -> '82.9 %'."""
    return DASH if x is None or not math.isfinite(x) else f"{100 * x:.{digits}f} %"


def points(delta: float | None, digits: int = 1) -> str:
    """A change of a fraction in percentage points, always signed: -0.0667 -> '−6.7 pts', 0.01 -> '+1.0 pts'."""
    if delta is None or not math.isfinite(delta):
        return DASH
    text = f"{100 * abs(delta):.{digits}f}"
    return f"{MINUS if delta < 0 and float(text) != 0 else '+'}{text} pts"


def number(x: Any, digits: int = 3) -> str:
    """Integers with thousands separators, floats with ``digits`` decimals, None as a dash."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return DASH
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}"
    text = f"{float(x):.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text  # no '-0.000'


def listing(values: dict[str, Any], digits: int = 3, skip_zero: Sequence[str] = ()) -> str:
    """{'happy': 0.25, 'sad': 0.75} -> 'happy 0.250 · sad 0.750' (keys in ``skip_zero`` left out when 0)."""
    return " · ".join(f"{k} {number(v, digits)}" for k, v in values.items() if not (k in skip_zero and not v)) or DASH


def with_spread(mean: float, std: float) -> str:
    """'82.9 % ± 1.2' (the spread over seeds in percentage points)."""
    return f"{percent(mean)} ± {100 * std:.1f}"


def interval(ci: Sequence[float] | None, as_points: bool = False) -> str:
    """A 95 % interval: [0.407, 0.877] -> 'CI 40.7–87.7 %'; ``as_points`` (a change): 'CI −5.0 to +12.3 pts'."""
    if not ci or any(v is None or not math.isfinite(v) for v in ci):
        return f"CI {DASH}"
    if as_points:
        return f"CI {points(ci[0]).removesuffix(' pts')} to {points(ci[1])}"
    return f"CI {100 * ci[0]:.1f}–{100 * ci[1]:.1f} %"


def with_interval(r: dict[str, Any], score: str) -> str:
    """'59.1 % (CI 40.7–87.7 %)': a score's mean over seeds and its 95 % interval over clips."""
    return f"{percent(r[f'{score}_mean'])} ({interval(r.get(f'{score}_ci95'))})"


# ---------------------------------------------------------------------------------------------- verdicts

def held_out_name(recognition: dict[str, Any]) -> str:
    """'real test' (or 'real val + test'): the real gaits the recognisers were tested on."""
    return "real " + " + ".join(recognition.get("test_splits", ["test"]))


def verdict_lines(recognition: dict[str, Any]) -> list[tuple[str, str]]:
    """One (family, plain sentence) per generator family: for each recogniser, how often the family's gaits are
    recognised as the emotion they were generated for (balanced accuracy and accuracy with 95 % intervals over
    clips), against real held-out gaits, chance and the majority class; and what adding them to the recogniser's
    training does to macro-F1 on real held-out gaits (change and its interval). Without recognisers or synthetic
    gaits, one line that says so."""
    if "by_recogniser" not in recognition:
        return [("no verdict", f"no emotion recogniser: {recognition.get('skipped', 'not run')}")]
    held, chance = held_out_name(recognition), recognition["chance_accuracy"]
    recognisers = recognition["by_recogniser"]
    family_names = list(dict.fromkeys(n for e in recognisers.values() for n, f in e["families"].items()
                                      if "synthetic" in f))
    if not family_names:
        parts = [f"{e['name']} {with_interval(e['real_held_out'], 'balanced_accuracy')}" for e in recognisers.values()]
        return [("no synthetic gaits", f"no labelled synthetic gaits to judge; {held} gaits are recognised with "
                                       f"balanced accuracy {', '.join(parts)} (chance {percent(chance)})")]
    lines = []
    for name in family_names:
        gaits, reads, changes, changes_all = None, [], [], []
        for entry in recognisers.values():
            family = entry["families"].get(name, {})
            if "synthetic" not in family:
                continue
            syn, real = family["synthetic"], entry["real_held_out"]
            gaits = family["gaits"]
            reads.append(f"{entry['name']}: balanced accuracy {with_interval(syn, 'balanced_accuracy')} vs {held} "
                         f"{with_interval(real, 'balanced_accuracy')}, accuracy {percent(syn['accuracy_mean'])} "
                         f"(majority class {percent(syn['majority_baseline']['accuracy'])})")
            for key, found in (("augmentation", changes), ("augmentation_all", changes_all)):
                if f"{key}_delta" in family:
                    found.append(f"{entry['name']} {points(family[f'{key}_delta']['macro_f1'])} "
                                 f"({interval(family[f'{key}_delta_ci95']['macro_f1'], as_points=True)})")
        text = (f"{number(gaits)} synthetic gaits recognised as intended — " + "; ".join(reads)
                + f"; chance {percent(chance)}")
        if changes:
            text += f". Augmentation, macro-F1 on {held}: " + ", ".join(changes)
        if changes_all:
            text += "; with every synthetic gait added at weight one: " + ", ".join(changes_all)
        lines.append((name, text))
    return lines


def control_line(recognition: dict[str, Any]) -> str | None:
    """One sentence: what the augmentation protocol does with real gaits added instead of synthetic ones
    (``augmentation_controls``: macro-F1 change per recogniser with its interval), the yardstick a family's
    augmentation change is read against; None without controls."""
    about = recognition.get("augmentation", {}).get("controls", {})
    recognisers = recognition.get("by_recogniser", {})
    parts = []
    for name, what in about.items():
        changes = [f"{e['name']} {points(c['augmentation_delta']['macro_f1'])} "
                   f"({interval(c['augmentation_delta_ci95']['macro_f1'], as_points=True)})"
                   for e in recognisers.values() if (c := e.get("augmentation_controls", {}).get(name))]
        if changes:
            parts.append(f"{what['added']}: " + ", ".join(changes))
    if not parts:
        return None
    return (f"Controls: the same augmentation with real gaits added instead of synthetic ones, macro-F1 on "
            f"{held_out_name(recognition)} — " + "; ".join(parts))


# -------------------------------------------------------------------------------------------------- page

def _cell(value: Any) -> str:
    """A table cell: text as given, numbers formatted; a list or dict is refused (format it first)."""
    if isinstance(value, (list, tuple, dict, np.ndarray)):
        raise TypeError(f"audit page: a table cell must be formatted text or a number, found {type(value).__name__}")
    return html.escape(value if isinstance(value, str) else number(value))


def _table(rows: Sequence[dict[str, Any]], limit: int | None = None, css: str = "") -> str:
    if not rows:
        return "<p>none</p>"
    shown = rows[:limit] if limit else rows
    keys = list(shown[0])
    head = "".join(f"<th>{html.escape(k)}</th>" for k in keys)
    body = "".join("<tr>" + "".join(f"<td>{_cell(r[k])}</td>" for k in keys) + "</tr>" for r in shown)
    more = f"<p>… and {len(rows) - len(shown)} more (all in metrics.json)</p>" if len(rows) > len(shown) else ""
    return f'<table class="{css}"><tr>{head}</tr>{body}</table>{more}'


# the recognition table's last column; its figures' columns say what they hold in the paragraph above the table
MAJORITY = "majority class: accuracy · balanced · macro-F1"


def _recognition_rows(recognition: dict[str, Any]) -> list[dict[str, str]]:
    if "by_recogniser" not in recognition:
        return []
    held = held_out_name(recognition)
    train = f"{number(recognition['gaits']['real_train'])} real train"

    def row(recogniser: str, tested: str, trained: str, r: dict[str, Any]) -> dict[str, str]:
        m = r["majority_baseline"]
        return {"recogniser": recogniser, "tested on": tested, "trained on": trained,
                "gaits (clips)": f"{number(r['gaits'])} ({number(r['clips'])})",
                **{label: f"{with_spread(r[f'{s}_mean'], r[f'{s}_std'])}\n({interval(r.get(f'{s}_ci95'))})"
                   for s, label in (("accuracy", "accuracy"), ("balanced_accuracy", "balanced accuracy"),
                                    ("macro_f1", "macro-F1"))},
                MAJORITY: f"{m['class']}:\n{percent(m['accuracy'])} · {percent(m['balanced_accuracy'])} · "
                          f"{percent(m['macro_f1'])}"}

    def change_row(recogniser: str, trained: str, r: dict[str, Any]) -> dict[str, str]:
        d, ci = r["augmentation_delta"], r["augmentation_delta_ci95"]
        return {"recogniser": recogniser, "tested on": held, "trained on": trained, "gaits (clips)": "",
                **{label: f"{points(d[s])}\n({interval(ci[s], as_points=True)})"
                   for s, label in (("accuracy", "accuracy"), ("balanced_accuracy", "balanced accuracy"),
                                    ("macro_f1", "macro-F1"))},
                MAJORITY: ""}

    rows = []
    for kind, entry in recognition["by_recogniser"].items():
        who = f"{entry['name']} ({number(len(recognition['seeds'][kind]))} seeds)"
        rows.append(row(who, held, train, entry["real_held_out"]))
        for name, control in entry.get("augmentation_controls", {}).items():
            added = f"{recognition['augmentation']['controls'][name]['added']}, a control"
            rows.append(row(who, held, f"{train} + {added}", control["augmented_real_held_out"]))
            rows.append(change_row(who, f"change from adding {added}", control))
        for name, family in entry.get("families", {}).items():
            if "synthetic" not in family:
                continue
            rows.append(row(who, f"{name}: synthetic, intended emotion", train, family["synthetic"]))
            drawn = recognition.get("augmentation", {}).get("drawn", {})
            drawn = drawn.get(name, drawn.get("all", family["gaits"]))
            for key, added in (("augmentation", f"{number(drawn)} {name} (drawn per seed, steady labels)"),
                               ("augmentation_all", f"all {number(family['gaits'])} {name}")):
                result = family.get("augmented_real_held_out" if key == "augmentation" else "augmented_all_real_held_out")
                if result is None:
                    continue
                rows.append(row(who, held, f"{train} + {added}", result))
                rows.append(change_row(who, f"change from adding {added}",
                                       {"augmentation_delta": family[f"{key}_delta"],
                                        "augmentation_delta_ci95": family[f"{key}_delta_ci95"]}))
    return rows


def content_rows(recognition: dict[str, Any]) -> list[dict[str, str]]:
    """Augmentation's change of macro-F1 on the held-out gaits of the contents the generators make and on the
    others (the same fits as the recognition table, scored on each part)."""
    views = recognition.get("held_out_by_content", {})
    rows = []
    for kind, entry in recognition.get("by_recogniser", {}).items():
        for view, part in entry.get("by_content", {}).items():
            about = views[view]
            base = part["real_held_out"]
            for name, change in part["augmented"].items():
                rows.append({
                    "recogniser": entry["name"],
                    "held-out gaits": f"{view.replace('_', ' ')}: {', '.join(about['contents'])}",
                    "gaits (clips)": f"{number(about['gaits'])} ({number(about['clips'])})",
                    "per emotion": listing(about["per_emotion"]),
                    "synthetic gaits added": "every family, pooled" if name == "all" else name,
                    "macro-F1, real train only": with_interval(base, "macro_f1"),
                    "change of macro-F1 (95 % interval)":
                        f"{points(change['augmentation_delta']['macro_f1'])} "
                        f"({interval(change['augmentation_delta_ci95']['macro_f1'], as_points=True)})"})
    return rows


def _memorisation_rows(memo: dict[str, Any]) -> list[dict[str, str]]:
    rows = []
    for key, label in (("synthetic", "synthetic gaits"), ("real_held_out", "real held-out windows"),
                       *((f, f"synthetic: {f}") for f in memo.get("families", {}))):
        d = memo["families"][key] if key in memo.get("families", {}) else memo.get(key, {})
        if d.get("gaits"):
            rows.append({"gaits": label, "count": number(d["gaits"]), "median (m)": number(d["median"]),
                         "5th percentile (m)": number(d["p5"]), "95th percentile (m)": number(d["p95"])})
    return rows


def _label_rows(labels: dict[str, Any], names: Sequence[str]) -> list[dict[str, str]]:
    groups = {**labels["by_kind"], **labels["by_kind_source"], **labels["by_kind_split"]}
    return [{"group": g, "gaits": number(s["gaits"]), "labelled": number(s["labelled"]),
             "mean emotion": listing(dict(zip(names, s["mean_emotion"])), 2) if s["mean_emotion"] else DASH,
             "gaits per dominant emotion": listing(s["dominant"], skip_zero=("tie", UNLABELLED)),
             "label entropy (0 one-hot, 1 uniform)": number(s["entropy_mean"], 2),
             "imbalance (largest / smallest class)": number(s["imbalance_max_over_min"], 1),
             "classes missing": ", ".join(s["missing_classes"]) or DASH}
            for g, s in groups.items()]


def _feature_rows(metrics: dict[str, Any]) -> list[dict[str, str]]:
    distances = metrics.get("feature_distance_w1_over_real_std", {})
    means = metrics.get("feature_means", {})
    rows = []
    for d in metrics.get("feature_descriptions", []):
        m = means.get(d["name"], {})
        rows.append({"feature": d["index"], "what it measures": d["words"], "joints": d["joints"] or DASH,
                     "real: mean": number(m.get("real")), "synthetic: mean": number(m.get("synthetic")),
                     "distance of per-gait means": number(distances.get(f"{d['name']} (mean)"), 2),
                     "distance of per-gait std": number(distances.get(f"{d['name']} (std)"), 2)})
    return rows


def _content_section(recognition: dict[str, Any]) -> str:
    rows = content_rows(recognition)
    if not rows:
        return ""
    return ("<h3>Augmentation by held-out content</h3><p>The held-out gaits include motions no synthetic gait shows. "
            "The same predictions as above, scored on the held-out gaits of the contents the synthetic gaits have and "
            "on the others: synthetic gaits can only teach what they show.</p>" + _table(rows))


def write_html(path: Path, title: str, metrics: dict[str, Any], problems: list[dict[str, str]],
               figures: Sequence[tuple[Path, str]], names: Sequence[str]) -> Path:
    """One page, read top-down: a verdict per generator family, the overview, the recognition table, the
    problems, the labels, the features in words, and every figure embedded (base64) with its caption. Every
    figure is formatted text (``_cell`` refuses raw lists and dicts)."""
    recognition = metrics.get("recognisability", {})
    verdicts = "".join(f'<li class="verdict"><b>{html.escape(name)}</b>: {html.escape(text)}.</li>'
                       for name, text in verdict_lines(recognition))
    control = control_line(recognition)
    controls = f'<p class="controls">{html.escape(control)}.</p>' if control else ""
    js = metrics["labels"].get("js_distance_real_vs_synthetic")
    overview = [
        {"figure": "gaits", "value": f"{number(metrics['gaits'])} ({listing(metrics['kinds'])})"},
        {"figure": "problems", "value": number(len(problems))},
        {"figure": "label distance, real vs synthetic (Jensen-Shannon, 0 same, 1 disjoint)",
         "value": f"dominant emotions {number(js['dominant_classes'], 3)} · mean soft labels "
                  f"{number(js['mean_soft_labels'], 3)}" if js else DASH},
    ]
    if "by_recogniser" in recognition:
        overview.append({"figure": "emotion recognisers", "value":
                         f"summary MLP on {number(recognition['features'])} per-gait feature summaries; temporal "
                         f"CNN on the frames of the root-relative heading-frame pose; both trained on real train "
                         f"windows and {number(recognition['block_frames'])}-frame blocks of them; seeds "
                         + " · ".join(f"{recognition['by_recogniser'][k]['name']} {number(len(v))}"
                                      for k, v in recognition["seeds"].items())
                         + f"; chance {percent(recognition['chance_accuracy'])}; tested on "
                         f"{number(recognition['gaits']['real_held_out'])} {held_out_name(recognition)} gaits of "
                         f"{number(recognition['gaits']['real_held_out_clips'])} clips"})
    memo = metrics.get("memorisation")
    if memo and "check" in memo:
        ok = memo["check"]["synthetic_median_ge_real_heldout_median"]
        overview.append({"figure": "no memorisation (distance to the nearest real train window, median)",
                         "value": f"synthetic {number(memo['synthetic']['median'])} m, real held-out "
                                  f"{number(memo['real_held_out']['median'])} m: "
                                  + ("passed (synthetic no closer)" if ok else "FAILED (synthetic closer)")})
    if "transitions_by_start_end" in metrics:
        overview.append({"figure": "synthetic transitions",
                         "value": number(int(np.sum(metrics["transitions_by_start_end"])))})
    images = "".join(
        f'<figure><img alt="{html.escape(f.name)}" src="data:image/png;base64,'
        f'{base64.b64encode(f.read_bytes()).decode()}"><figcaption>{html.escape(caption)}</figcaption></figure>'
        for f, caption in figures)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1400px;color:#222}}
table{{border-collapse:collapse;font-size:13px;margin:0.5em 0}}td,th{{border:1px solid #ccc;padding:3px 8px;
text-align:left;vertical-align:top}}th{{background:#f3f3f3}}img{{max-width:100%}}figure{{margin:1.5em 0}}
figcaption{{font-size:13px;color:#333}}ul.verdicts{{font-size:17px;line-height:1.5;padding-left:1.2em}}
li.verdict{{margin:0.3em 0}}p.controls{{font-size:15px}}table.recognition td:nth-child(n+5){{white-space:pre}}</style></head><body>
<h1>{html.escape(title)}</h1>
<h2>Verdict</h2><ul class="verdicts">{verdicts}</ul>{controls}
<h2>Overview</h2>{_table(overview)}
<h2>Emotion recognition</h2>
<p>Accuracy, balanced accuracy (mean recall over the emotions present) and macro-F1: mean ± spread in points over
the seeds, then the 95 % bootstrap interval of that mean resampling clips (a real clip's windows together; a
synthetic gait is its own unit); a change's interval is paired (the same clips drawn for both). The
majority class column is the best any constant answer does on the same gaits.</p>
{_table(_recognition_rows(recognition), css="recognition")}
{_content_section(recognition)}
<h2>No memorisation</h2>
<p>Distance of each gait to its nearest real train-split window: mean joint position error of the root-relative
poses in each frame's heading frame. Real held-out windows come from other clips than any train window, so their
distances say how far a new recording lies; synthetic gaits should lie no closer.</p>
{_table(_memorisation_rows(metrics.get("memorisation", {"families": {}})))}
<h2>Problems ({len(problems)})</h2>{_table(problems, 200)}
<h2>Labels</h2>{_table(_label_rows(metrics["labels"], names))}
<h2>Features</h2>
<p>Per frame: the 18 affective features of the pose and the movement features of the pelvis. Mean: over all
frames of all gaits of a kind. Distance: 1-Wasserstein between the real and synthetic per-gait values, in real
standard deviations.</p>
{_table(_feature_rows(metrics))}
<h2>Figures</h2>{images}
</body></html>
"""
    write_text(page, path)
    return path
