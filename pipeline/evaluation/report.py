"""The evaluation report a person reads: eval.md (the tables) and the plots (error by horizon, rollout paths and
speeds, stick figures of generated gaits), from the report ``pipeline.evaluation.run`` returns."""

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
    lines += ["", "## Acceptance", ""] + [f"- {k}: {v}" for k, v in report["acceptance"].items()]
    return "\n".join(lines) + "\n"


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
