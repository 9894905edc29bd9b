"""Every generator family side by side, on the shared plan: what each family's own reports, the audit and a
controlled generation say, in one table.

* **Condition sensitivity** (generated here, the same for every family): ``rows`` single-emotion plan rows (their
  trajectory, seed and plan seed) each generated under the four one-hot emotions; the mean pairwise distance of
  the four gaits' affect summaries as a fraction of the real emotion centroids' (``controllability``).
* **Recognisability, augmentation, memorisation**: the audit's figures per family (independent recognisers,
  real train only; ``pipeline.audit``).
* **Walking**: foot skating vs real, path deviation per trajectory family, stepping-cycle length and speed per
  emotion vs real: the synthesis stage's report of each family.
* **Model figures** a family reports of itself (the PCA family: emotion in PC space, novelty of drawn cycles).

Reports in, numbers and a Markdown table out; generation takes a family (``pipeline.generators.base``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.evaluation.autoregressive import affect_summary, emotion_centroids
from pipeline.evaluation.controllability import condition_sensitivity, one_hot
from pipeline.generators.base import GeneratedMotion, GeneratorFamily
from pipeline.ops.features import affective_features
from pipeline.synth.synthesis import SynthesisConfig, row_inputs
from pipeline.synth.trajectories import Trajectory


class AffectReference:
    """Real emotion centroids of affect summaries: the 18 features of the labelled train gaits, clipped to the
    train range and divided by the train standard deviation, averaged per gait and per dominant emotion."""

    def __init__(self, train_positions: np.ndarray, train_emotions: np.ndarray):
        features = affective_features(torch.from_numpy(train_positions)).reshape(-1, 18)
        self.low, self.high = features.min(0).values, features.max(0).values
        self.scale = features.std(0).clamp_min(1e-6)
        summaries = self.summary(torch.from_numpy(train_positions))
        self.centroids = emotion_centroids(summaries, [EMOTIONS[k] for k in np.argmax(train_emotions, -1)])

    def summary(self, positions: torch.Tensor) -> torch.Tensor:
        return affect_summary(positions, self.low, self.high, self.scale)


def sensitivity_rows(plan: Sequence[dict[str, Any]], count: int) -> list[dict[str, Any]]:
    """``count`` single-emotion plan rows spread evenly over the plan (every trajectory is met)."""
    single = [r for r in plan if r["recipe"]["kind"] == "single"]
    picks = np.linspace(0, len(single) - 1, min(count, len(single))).round().astype(int)
    return [single[i] for i in picks]


def under_one_hot(family: GeneratorFamily, rows: Sequence[dict[str, Any]], emotions: np.ndarray,
                  trajectories: dict[str, Trajectory], cfg: SynthesisConfig) -> list[GeneratedMotion]:
    """The rows generated under each one-hot emotion (EMOTIONS order): same trajectory piece, seed and plan seed."""
    shapes, _ = row_inputs(rows, emotions, trajectories, cfg)
    return [family.generate(rows, shapes, one_hot(k, len(rows), cfg.frames)) for k in range(len(EMOTIONS))]


def family_sensitivity(generated: list[GeneratedMotion], reference: AffectReference) -> dict[str, Any]:
    summaries = torch.stack([reference.summary(g.positions.double()) for g in generated])
    return condition_sensitivity(summaries, reference.centroids)


def _recognition(audit: dict[str, Any], family: str) -> dict[str, Any]:
    """The audit's recognisability and augmentation of one family, per recogniser."""
    out = {}
    for kind, entry in audit.get("recognisability", {}).get("by_recogniser", {}).items():
        fam = entry.get("families", {}).get(family, {})
        if "synthetic" not in fam:
            continue
        syn, real = fam["synthetic"], entry["real_held_out"]
        out[kind] = {"name": entry["name"],
                     "synthetic_balanced_accuracy": syn["balanced_accuracy_mean"],
                     "synthetic_balanced_accuracy_ci95": syn["balanced_accuracy_ci95"],
                     "real_held_out_balanced_accuracy": real["balanced_accuracy_mean"],
                     "augmentation_macro_f1_delta": fam.get("augmentation_delta", {}).get("macro_f1"),
                     "augmentation_macro_f1_delta_ci95": fam.get("augmentation_delta_ci95", {}).get("macro_f1")}
    return out


def side_by_side(families: Sequence[str], synthesis: dict[str, dict[str, Any]], audit: dict[str, Any],
                 sensitivity: dict[str, dict[str, Any]], model_figures: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """One entry per family from its synthesis report, the audit, the condition sensitivity and its own model
    figures; and the real reference beside them."""
    memo = audit.get("memorisation", {})
    out: dict[str, Any] = {"families": {}}
    for name in families:
        s = synthesis[name]
        out["families"][name] = {
            "gaits": s["gaits"], "model_sha256": s["model_sha256"],
            "recognition": _recognition(audit, name),
            "condition_sensitivity": sensitivity[name],
            "foot_skating_ratio_to_real": s["foot_skating"]["ratio_to_real"],
            "foot_skating_per_trajectory_family": s["foot_skating"].get("ratio_to_real_per_trajectory_family", {}),
            "path_deviation_m": s["path_deviation_m"],
            "cycle_frames": s["cycle_frames"]["synthetic_single_emotion"],
            "speed_m_s": {e: v["path_speed_m_s"] for e, v in s["walking"]["synthetic"].items()},
            "nearest_train_window_median_m": memo.get("families", {}).get(name, {}).get("median",
                                                                                         memo.get("synthetic", {}).get("median")),
            "copied_real_frames": s["copied_real_frames"],
            "real_frames_by_design_share": s.get("real_frames_by_design", {}).get("share", 0.0),
            **({"model": model_figures[name]} if name in model_figures else {})}
    s = synthesis[families[0]]  # the real reference is the same in every family's report
    out["real"] = {"cycle_frames": s["cycle_frames"]["real_labelled_train_walks"],
                   "speed_m_s": {e: v["path_speed_m_s"] for e, v in s["walking"]["real_labelled_train_walks"].items()},
                   "foot_skating_m_s": s["foot_skating"]["real_walks_m_s"],
                   "nearest_train_window_median_m": memo.get("real_held_out", {}).get("median")}
    return out


def _ci(values: Sequence[float] | None, points: bool = False) -> str:
    if not values:
        return "–"
    f = (lambda v: f"{100 * v:+.1f}") if points else (lambda v: f"{v:.3f}")
    return f"[{f(values[0])}, {f(values[1])}]"


def markdown(report: dict[str, Any]) -> str:
    """The side-by-side table a person reads, then the per-family details."""
    fams = report["families"]
    names = list(fams)
    real = report["real"]
    head = "| figure | " + " | ".join(f"`{n}`" for n in names) + " | real |"
    rows = [head, "|---|" + "---|" * (len(names) + 1)]

    def row(label: str, values: Sequence[str], real_value: str = "") -> None:
        rows.append(f"| {label} | " + " | ".join(values) + f" | {real_value} |")

    kinds = list(dict.fromkeys(k for f in fams.values() for k in f["recognition"]))
    for kind in kinds:
        rec = [f["recognition"].get(kind) for f in fams.values()]
        held = next((r["real_held_out_balanced_accuracy"] for r in rec if r), None)
        label = next(r["name"] for r in rec if r)
        row(f"recognised as intended, balanced accuracy ({label}; 95 % CI)",
            [f"{r['synthetic_balanced_accuracy']:.3f} {_ci(r['synthetic_balanced_accuracy_ci95'])}" if r else "–"
             for r in rec], f"{held:.3f} (val + test)" if held is not None else "")
        row(f"augmentation, macro-F1 on real val + test ({label}; 95 % CI)",
            [f"{100 * r['augmentation_macro_f1_delta']:+.1f} pts {_ci(r['augmentation_macro_f1_delta_ci95'], True)}"
             if r and r["augmentation_macro_f1_delta"] is not None else "–" for r in rec])
    row("condition sensitivity (fraction of the real between-emotion separation)",
        [f"{f['condition_sensitivity']['fraction_of_real']:.2f}" for f in fams.values()], "1.00")
    row("foot skating (× real)", [f"{f['foot_skating_ratio_to_real']:.2f}" for f in fams.values()],
        f"1.00 ({real['foot_skating_m_s']:.3f} m/s)")
    row("path deviation, mean (m)", [f"{f['path_deviation_m']['all']['mean']:.3f}" for f in fams.values()])
    row("nearest train window, median (m)", [f"{f['nearest_train_window_median_m']:.3f}"
                                             if f["nearest_train_window_median_m"] is not None else "–"
                                             for f in fams.values()],
        f"{real['nearest_train_window_median_m']:.3f} (val + test)" if real.get("nearest_train_window_median_m")
        else "")
    for e in EMOTIONS:
        row(f"{e}: stepping cycle (frames) / speed along the path (m/s)",
            [f"{f['cycle_frames'].get(e, float('nan')):.1f} / {f['speed_m_s'].get(e, float('nan')):.2f}"
             for f in fams.values()],
            f"{real['cycle_frames'].get(e, float('nan')):.1f} / {real['speed_m_s'].get(e, float('nan')):.2f}")
    row("copied real frames (20 non-root rotations equal a real frame's)",
        [str(f["copied_real_frames"]) for f in fams.values()])
    row("frames that play a real frame as it is, by design (share)",
        [f"{f['real_frames_by_design_share']:.2f}" for f in fams.values()])
    lines = ["# Generator families side by side", "",
             "Every family generated the same 5,000 plan rows. Recognisability and augmentation: the audit's "
             "independent recognisers (trained on real train gaits only, never in a generator's loss), mean over "
             "seeds with 95 % intervals resampling clips. Real: labelled real gaits (walks of the train split for "
             "cycles and speeds, held-out val + test clips for recognition and nearest windows).", "", *rows, "",
             "## Per trajectory family: path deviation (mean m, × real sway) / foot skating (× real)", "",
             "| trajectory family | " + " | ".join(f"`{n}`" for n in names) + " |",
             "|---|" + "---|" * len(names)]
    first = next(iter(fams.values()))["path_deviation_m"]
    for t in sorted(k for k in first if k not in ("all", "real_walk_sway_m")):
        cells = []
        for f in fams.values():
            d = f["path_deviation_m"][t]
            skating = f.get("foot_skating_per_trajectory_family", {}).get(t)
            cells.append(f"{d['mean']:.3f} ({d['ratio_to_real_sway']:.1f}×)" if "ratio_to_real_sway" in d else
                         f"{d['mean']:.3f}")
            cells[-1] += f" / {skating:.2f}" if skating is not None else ""
        lines.append(f"| {t} | " + " | ".join(cells) + " |")
    if "real_walk_sway_m" in first:
        lines += ["", f"Real reference of path deviation: real labelled train walks' roots lie a mean "
                      f"{first['real_walk_sway_m']['mean']:.3f} m from their own path averaged over 1 s (about one "
                      "stride); a root that follows its path perfectly still sways this much around it."]
    for name, f in fams.items():
        if "model" not in f:
            continue
        m = f["model"]
        lines += ["", f"## `{name}`: the model's own figures", ""]
        if "emotion_in_pc_space" in m:
            r = m["emotion_in_pc_space"]
            lines.append(f"- Emotion from the PC scores of one clip's cycles, centroids of the other clips: balanced "
                         f"accuracy {r['balanced_accuracy']:.3f} (accuracy {r['accuracy']:.3f}, majority "
                         f"{r['majority_baseline_accuracy']:.3f}; {r['cycles']} labelled cycles of {r['clips']} "
                         f"clips; clips per emotion {r['clips_per_emotion']}).")
        if "novelty" in m:
            n = m["novelty"]
            lines.append(f"- Novelty: {n['drawn_cycles']} drawn cycles lie a median "
                         f"{n['drawn_to_nearest_real_deg']['median']:.2f}° (RMS per value) from their nearest real "
                         f"cycle, real cycles {n['real_to_nearest_real_of_another_clip_deg']['median']:.2f}° from the "
                         f"nearest of another clip; reproduced cycles: {n['reproduced']}.")
        if "table" in m:
            lines += ["", "| k | threshold (Johnson SB / empirical) | states before → after SCC | edges before → "
                          "after SCC |", "|---|---|---|---|"]
            for t in m["table"]:
                lines.append(f"| {t['k']} | {t['threshold']['johnson_sb']:.3f} / {t['threshold']['empirical']:.3f} | "
                             f"{t['before_scc']['states']:,} → {t['after_scc']['states']:,} | "
                             f"{t['before_scc']['edges']:,} → {t['after_scc']['edges']:,} |")
            lines += ["", f"- Key states (foot events): {100 * m['key_state_share']:.1f} % of the states (paper: "
                          "22.25 %). Nodes per emotion after the SCC: " + ", ".join(
                              f"{e} {v['after_scc']} ({v['clips']} clips)" for e, v in m["nodes_per_emotion"].items())
                      + "."]
        if "search" in m:
            sr = m["search"]
            lines.append(f"- Search: {100 * sr['success_rate']:.1f} % of the 5,000 rows found with every constraint "
                         f"(paper: 69.8 %); levels {sr['levels']}. Per trajectory family: " + ", ".join(
                             f"{k} {100 * v['success_rate']:.0f} %" for k, v in sr["per_trajectory_family"].items())
                         + "; per starting emotion: " + ", ".join(
                             f"{k} {100 * v['success_rate']:.0f} %" for k, v in sr["per_emotion"].items()) + ".")
            runs = m["longest_unbroken_real_segment_frames"]
            lines.append(f"- Re-sequenced real motion: {m['synthetic_transitions_per_gait']:.2f} synthetic "
                         f"transitions per gait; the longest unbroken real segment of a gait is a median "
                         f"{runs['median']:.0f} of 60 frames ({100 * runs['whole_gait_share']:.1f} % of the gaits are "
                         f"one real segment); yaw warp {m['warp_deg_per_frame']['mean']:.2f}°/frame (mean); "
                         f"{100 * m['frames_of_planned_dominant_emotion']:.1f} % of the frames walk the planned "
                         "dominant emotion.")
    if "motion_graph_ablation" in report:
        a = report["motion_graph_ablation"]
        lines += ["", f"## `motion_graph`: the search's constraints (paper Fig. 6; {a['rows']} single-emotion rows, "
                      f"read by the {a['recogniser']})", "",
                  "| constraints | balanced accuracy | path deviation (m) | foot skating (× real) |", "|---|---|---|---|"]
        for variant, v in a["variants"].items():
            lines.append(f"| {variant} | {v['balanced_accuracy']:.3f} | {v['path_deviation_m']:.3f} | "
                         f"{v['foot_skating_ratio_to_real']:.2f} |")
    return "\n".join(lines) + "\n"


ABLATIONS = {"all constraints": {}, "no emotion constraint": {"emotion": False},
             "no trajectory constraint": {"trajectory": False},
             "none": {"emotion": False, "trajectory": False}}


def constraint_ablation(make_family, rows: Sequence[dict[str, Any]], emotions: np.ndarray,
                        trajectories: dict[str, Trajectory], cfg: SynthesisConfig, recogniser, features,
                        real_positions: np.ndarray, fps: float, contacts) -> dict[str, Any]:
    """A search family's constraints switched off in turn (paper Fig. 6: all / no emotion / no trajectory / none),
    each variant generating the same single-emotion ``rows``: balanced accuracy of the dominant emotion by
    ``recogniser`` (fitted on real train gaits only), path deviation and foot skating vs real walks.

    make_family(**search overrides) -> a family; features(positions, rotations) -> (affective, movement)."""
    from pipeline.ops.geometry import distance_to_polyline
    from pipeline.recognition import RecognitionInputs, confusion, scores
    from pipeline.synth.synthesis import foot_skating

    shapes, per_frame = row_inputs(rows, emotions, trajectories, cfg)
    intended = per_frame.mean(1).argmax(-1)
    out = {}
    for name, overrides in ABLATIONS.items():
        g = make_family(**overrides).generate(rows, shapes, torch.from_numpy(per_frame.astype(np.float32)))
        affective, movement = features(g.positions.double(), g.rotations.double())
        inputs = RecognitionInputs(positions=g.positions.numpy().astype(np.float32),
                                   heading=g.heading.numpy().astype(np.float32),
                                   affective=affective.astype(np.float32), movement=movement.astype(np.float32))
        predicted = recogniser.predict(inputs)
        deviation = distance_to_polyline(g.positions[:, :, 0, [0, 2]], g.placed_paths).mean(-1)
        out[name] = {"balanced_accuracy": round(scores(confusion(intended, predicted, len(EMOTIONS)))
                                                ["balanced_accuracy"], 4),
                     "path_deviation_m": round(float(deviation.mean()), 4),
                     "foot_skating_ratio_to_real": foot_skating(g.positions.numpy(), real_positions, fps,
                                                                contacts)["ratio_to_real"]}
    return {"rows": len(rows), "recogniser": recogniser.kind, "variants": out}
