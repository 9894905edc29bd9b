"""The evaluation report a person reads: eval.md (the tables) and the plots (error by horizon, rollout paths and
speeds, controllability, stick figures of generated gaits), from the report ``pipeline.evaluation.run`` returns."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.io.files import save_figure  # noqa: E402
from pipeline.ops.geometry import arc_lengths, to_local_frame, travel_direction, unit_direction  # noqa: E402
from pipeline.viz.stick_figures import Motion, render_filmstrip  # noqa: E402


def markdown(report: dict) -> str:
    t1 = report["table1"]
    lines = ["# Generator evaluation (test split)", "",
             f"Table-1 protocol: {report['prefix']} frames in, the rest predicted on the ground-truth path, "
             f"{report['table1_gaits']} test gaits. Pose error: root-frame joint position error / the character's "
             "bounding-box diagonal; rotation error: geodesic angle of the 20 non-root versors; affective error: mean "
             "|error| of the 18 affective features (clipped to the training range). Paper (its own data, 31 joints): "
             "0.12 pose error.", "",
             "| method | pose error | rotation error (deg) | affective error | root distance to truth (m) |",
             "|---|---|---|---|---|"]
    for name, v in t1.items():
        lines.append(f"| {name} | {v['pose_error']:.4f} | {v['rotation_error_deg']:.2f} | {v['affective_error']:.4f} "
                     f"| {v.get('root_distance_m', '')} |")
    real = report["real_reference"]
    lines += ["", f"## {report['rollout_steps']}-step rollouts", "",
              f"Root placement: {report['placement']['root_advance']} (the `generate` params; Table 1 places the root "
              "by the predicted speed on the ground-truth path).", "",
              f"Real test walks: speed 5-95 % {real['speed_m_s_p5_p95'][0]:.2f}-{real['speed_m_s_p5_p95'][1]:.2f} m/s, "
              f"foot skating {real['foot_skating_m_s']:.3f} m/s (heel/toe horizontal speed while in contact).", "",
              "| model | path | mean speed (m/s) | speed per 50 frames | frozen agents | foot skating (m/s, x real) "
              "| trajectory deviation (m, mean / max) |", "|---|---|---|---|---|---|---|"]
    for name, paths in report["long_horizon"].items():
        for path, f in paths.items():
            lines.append(f"| {name} | {path} | {f['speed_m_s_mean']:.2f} | "
                         f"{' '.join(f'{v:.2f}' for v in f['speed_m_s_by_50_frames'])} | {f['frozen_agents']}/{f['agents']} "
                         f"| {_num(f['foot_skating_m_s'], '.3f')} ({_num(f['foot_skating_ratio_to_real'], '.2f')}x) | "
                         f"{f['trajectory_deviation_m']:.3f} / {f['trajectory_deviation_m_max']:.3f} |")
    ref = report["emotion_reference"]
    lines += ["", "## Emotions", "",
              f"Affect summaries (per gait: mean of the 18 features, in training standard deviations) compared with the "
              f"real emotion centroids of {ref['train_labelled_gaits']} labelled train gaits. Real labelled test gaits "
              f"are nearest to their own emotion's centroid {ref['real_test_nearest_centroid_accuracy']:.0%} of the "
              f"time.", "",
              "| model | distance to intended emotion | to the others | intended nearest (chance 25 %) |",
              "|---|---|---|---|"]
    for name, e in report["expressiveness"].items():
        lines.append(f"| {name} | {e['distance_to_same_emotion']:.3f} | {e['distance_to_other_emotions']:.3f} | "
                     f"{e['nearest_centroid_accuracy']:.0%} |")
    lines += ["", "| model | transitions rising A -> B | monotone over 4 blocks | mean rise (A->B axis = 1) |",
              "|---|---|---|---|"]
    for name, t in report["transitions"].items():
        lines.append(f"| {name} | {t['rising_fraction']:.0%} | {t['monotone_fraction']:.0%} | {t['mean_rise']:.3f} |")
    if "controllability" in report:
        lines += controllability_markdown(report["controllability"])
    lines += ["", "## Acceptance", ""] + [f"- {k}: {v}" for k, v in report["acceptance"].items()]
    return "\n".join(lines) + "\n"


READERS = {"summary_mlp": "summary MLP", "temporal_cnn": "temporal CNN", "nearest_centroid": "nearest centroid"}


def _pct(values) -> str:
    return " / ".join(f"{v:.0%}" for v in values)


def controllability_markdown(c: dict) -> list[str]:
    kinds = c["recognisers"]
    cfg = c["config"]
    real = c["real_test"]
    lines = ["", "## Controllability (issue 11)", "",
             f"Seeds: {real['gaits']} labelled test gaits ({cfg['steps']} frames generated on a straight line "
             f"after the prefix, read in blocks of {cfg['block']} frames). Readers: the independent recognisers "
             f"({', '.join(READERS[k] for k in kinds)}; fitted on {c['train_labelled_gaits']} labelled train gaits, "
             f"seed {cfg['seed']}, never in a generator's loss) and the nearest real emotion centroid of the affect "
             "summary.", "",
             "Condition sensitivity: per seed, the mean distance between the affect summaries of its four gaits "
             "(one per one-hot emotion), as a fraction of the mean distance between the real emotion centroids "
             "(goal >= 0.8).", "",
             "| model | fraction of real separation | generated | real | per seed p10 / p50 / p90 |",
             "|---|---|---|---|---|"]
    for name, v in c["condition_sensitivity"].items():
        lines.append(f"| {name} | {v['fraction_of_real']:.3f} | {v['generated_between_conditions']:.3f} | "
                     f"{v['real_between_emotion_centroids']:.3f} | "
                     f"{' / '.join(f'{x:.2f}' for x in v['per_seed_fraction_p10_p50_p90'])} |")
    blocks = " / ".join(f"{a}-{b - 1}" for a, b in next(iter(c["style_retention"].values()))["blocks"])
    cont = " / ".join(f"{a}-{b - 1}" for a, b in real["continuation_blocks"])
    lines += ["", f"Style retention: seeds of emotion e generated under e, recognised as e per block of generated "
              f"frames ({blocks}; goal >= 70 % in the last). Real reference: the real test windows' own blocks, and "
              f"the real continuation after the prefix (window frames {cont}). Recognised as the condition: every "
              "seed under every emotion (mismatched: the condition differs from the seed's emotion; chance 25 %).", "",
              "| model | reader | recognised as seed emotion | balanced | as condition | as condition, mismatched |",
              "|---|---|---|---|---|---|"]
    for name, v in c["style_retention"].items():
        for reader, kept in v["recognised_as_seed_emotion"].items():
            lines.append(f"| {name} | {READERS.get(reader, reader)} | {_pct(kept['fraction'])} | "
                         f"{_pct(kept['balanced'])} | {_pct(v['recognised_as_condition'][reader])} | "
                         f"{_pct(v['recognised_as_condition_mismatched'][reader])} |")
    for reader in real["window"]:
        lines.append(f"| real | {READERS.get(reader, reader)} | window {_pct(real['window'][reader]['fraction'])}; "
                     f"continuation {_pct(real['continuation'][reader]['fraction'])} | "
                     f"{_pct(real['window'][reader]['balanced'])} | | |")
    lines += ["", "Recognisability: accuracy, balanced accuracy, macro-F1 against the intended dominant emotion; "
              "plan-like gaits are single-emotion rows of the synthesis plan (novel emotions, the plan's trajectories "
              "and seeds), synthesized and annotated as the synthesize stage does; the same rows under the one-hot of "
              "their dominant emotion tell how much of a miss the plan's mixtures cause.", "",
              "| gaits | recogniser | accuracy | balanced accuracy | macro-F1 | majority baseline (acc / bal / F1) |",
              "|---|---|---|---|---|---|"]
    rows = ([("real test", real["scores"])] + [(f"plan-like, {k}", v) for k, v in c["plan_like"].items()]
            + [(f"plan-like under the dominant one-hot, {k}", v)
               for k, v in c.get("plan_like_dominant_one_hot", {}).items()])
    for label, sc in rows:
        m = sc["majority_baseline"]
        for kind in kinds:
            r = sc[kind]
            lines.append(f"| {label} ({sc['gaits']}) | {READERS[kind]} | {r['accuracy']:.3f} | "
                         f"{r['balanced_accuracy']:.3f} | {r['macro_f1']:.3f} | {m['class']}: {m['accuracy']:.3f} / "
                         f"{m['balanced_accuracy']:.3f} / {m['macro_f1']:.3f} |")
    lines += ["", "Transitions (60 frames, one-hot A -> B from seeds of A): the recognisers' probability of B per "
              "block, and the fraction of gaits where it rises from the first block to the last (goal >= 80 %); "
              "control: the same seeds under a constant A.", "",
              "| model | recogniser | P(B) by block | rising | control P(B) by block | control rising |",
              "|---|---|---|---|---|---|"]
    for name, t in c["transitions"].items():
        for kind in kinds:
            r = t[kind]
            lines.append(f"| {name} | {READERS[kind]} | "
                         f"{' / '.join(f'{v:.2f}' for v in r['end_probability_by_block'])} | "
                         f"{r['rising_fraction']:.0%} | "
                         f"{' / '.join(f'{v:.2f}' for v in r['control_end_probability_by_block'])} | "
                         f"{r['control_rising_fraction']:.0%} |")
    return lines


def plot_controllability(report: dict, path: Path) -> None:
    c = report["controllability"]
    kinds = c["recognisers"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    names = list(c["condition_sensitivity"])
    ax = axes[0]
    ax.bar(names, [c["condition_sensitivity"][n]["fraction_of_real"] for n in names], color="tab:blue")
    ax.axhline(1.0, color="tab:green", ls="--", label="real between-emotion separation")
    ax.axhline(0.8, color="tab:red", ls=":", label="goal 0.8")
    ax.set_ylabel("separation between conditions / real")
    ax.set_title("condition sensitivity (same seed, four emotions)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1]
    styles = {"summary_mlp": "-", "temporal_cnn": "--", "nearest_centroid": ":"}
    for k, (name, v) in enumerate(c["style_retention"].items()):
        x = np.arange(len(v["blocks"]))
        for reader, kept in v["recognised_as_seed_emotion"].items():
            ax.plot(x, kept["fraction"], styles.get(reader, "-"), marker="o", color=f"C{k}",
                    label=f"{name}, {READERS.get(reader, reader)}")
    real = c["real_test"]["window"]
    for reader in kinds:
        ax.plot(np.arange(len(real[reader]["fraction"])), real[reader]["fraction"], styles[reader], color="black",
                marker="s", label=f"real windows, {READERS[reader]}")
    ax.axhline(0.7, color="tab:red", ls=":")
    ax.axhline(0.25, color="0.6", lw=0.8)
    ax.set_xticks(x, [f"{a}-{b - 1}" for a, b in v["blocks"]])
    ax.set_xlabel("generated frames")
    ax.set_ylim(0, 1)
    ax.set_ylabel("recognised as the seed's emotion")
    ax.set_title("style retention (seed of e under e)", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    ax = axes[2]
    for k, (name, t) in enumerate(c["transitions"].items()):
        for kind in kinds:
            x = np.arange(len(t["blocks"]))
            ax.plot(x, t[kind]["end_probability_by_block"], styles[kind], marker="o", color=f"C{k}",
                    label=f"{name}, {READERS[kind]} ({t[kind]['rising_fraction']:.0%} rising)")
            ax.plot(x, t[kind]["control_end_probability_by_block"], styles[kind], color=f"C{k}", alpha=0.35,
                    label=f"{name}, {READERS[kind]}, constant A")
        ax.set_xticks(x, [f"{a}-{b - 1}" for a, b in t["blocks"]])
    ax.set_xlabel("generated frames")
    ax.set_ylabel("recogniser's P(end emotion B)")
    ax.set_title("transitions A -> B", fontsize=9)
    ax.legend(fontsize=6)
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle("Controllability on the test split (independent recognisers fitted on real train gaits)")
    fig.tight_layout()
    save_figure(fig, path, dpi=80, metadata={"Software": None})


def preview_gaits(gaits, skeleton, path: Path) -> None:
    """Generated gaits given as (title, positions (T, 21, 3)), one filmstrip row each."""
    render_filmstrip([Motion(title=t, positions=np.asarray(p), parents=skeleton.parents, names=skeleton.names)
                      for t, p in gaits], path, frames=10, dpi=70)


def _num(value, spec: str) -> str:
    return "none" if value is None else format(value, spec)


def plot_errors(report: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for name, v in report["table1"].items():
        frames = np.arange(1, len(v["pose_error_by_frame"]) + 1)
        axes[0].plot(frames, v["pose_error_by_frame"], label=name)
        axes[1].plot(frames, v["rotation_error_deg_by_frame"], label=name)
    axes[0].set_ylabel("pose error / bounding-box diagonal")
    axes[1].set_ylabel("rotation error (deg)")
    for ax in axes:
        ax.set_xlabel("predicted frame (30 fps)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle("Test split: error by prediction horizon (18 frames given)")
    fig.tight_layout()
    save_figure(fig, path, dpi=80, metadata={"Software": None})


def plot_rollouts(rollouts: dict, report: dict, path: Path) -> None:
    names = list(rollouts)
    fig, axes = plt.subplots(2, len(names) + 1, figsize=(4.2 * (len(names) + 1), 8))
    for col, name in enumerate(names):
        for row, kind in enumerate(("straight", "sharp_turn")):
            ax = axes[row, col]
            r = rollouts[name][kind]
            root = r.generated.positions[:, :, 0][..., [0, 2]]
            start = r.path[:, :1]
            # every agent in its own start frame (facing +z), the path drawn as far as the agents got
            along = unit_direction(travel_direction(r.path, 1)[:, None])

            def local(points):
                return to_local_frame(points, along, start).numpy()

            reach = float(torch.linalg.vector_norm(root - start, dim=-1).max()) + 1.0
            target = local(r.path)
            dense = np.concatenate([np.linspace(target[0, k], target[0, k + 1], 200)
                                    for k in range(target.shape[1] - 1)])
            dense = dense[arc_lengths(torch.from_numpy(dense)).numpy() <= reach]
            ax.plot(dense[:, 0], dense[:, 1], color="0.75", lw=6, zorder=0, label="target path")
            for track in local(root):
                ax.plot(track[:, 0], track[:, 1], lw=0.8)
            f = report["long_horizon"][name][kind]
            ax.set_title(f"{name}, {kind}: deviation {f['trajectory_deviation_m']:.2f} m", fontsize=9)
            ax.set_aspect("equal", "datalim")
            ax.set_xlabel("x (m, agent's start frame)")
            ax.set_ylabel("z (m)")
        for row, kind in enumerate(("straight", "sharp_turn")):
            speed = rollouts[name][kind].generated.advance.numpy() * report["fps"]
            axes[row, -1].plot(np.median(speed, 0), label=name)
    lo, hi = report["real_reference"]["speed_m_s_p5_p95"]
    for row, kind in enumerate(("straight", "sharp_turn")):
        ax = axes[row, -1]
        ax.axhspan(lo, hi, color="tab:green", alpha=0.15, label="real walks 5-95 %")
        ax.set_title(f"median speed, {kind}", fontsize=9)
        ax.set_xlabel("generated frame")
        ax.set_ylabel("m/s")
        ax.legend(fontsize=8)
    fig.suptitle(f"{report['rollout_steps']}-step rollouts from test-split walks (grey: target path; "
                 "lines: generated root paths)")
    fig.tight_layout()
    save_figure(fig, path, dpi=70, metadata={"Software": None})


def preview(rollouts: dict, skeleton, path: Path) -> None:
    motions = []
    for kind in ("straight", "sharp_turn"):
        g = rollouts[kind].generated
        for n in range(min(2, g.positions.shape[0])):
            motions.append(Motion(title=f"generated, {kind}, agent {n}", positions=g.positions[n].numpy(),
                                  parents=skeleton.parents, names=skeleton.names))
    render_filmstrip(motions, path, frames=10)
