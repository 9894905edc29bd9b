"""DVC stage `evaluate`: the trained generator and its ablations on the **test split** only.

data/split/gaits.parquet + data/models/*.pt -> reports/eval.json (DVC metrics), reports/eval.md (the tables),
reports/eval_errors.png (error per predicted frame), reports/eval_rollouts.png (rollout paths and speeds),
reports/eval_preview.png (stick figures of generated gaits). See pipeline/evaluation/autoregressive.py for the protocols.
"""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.ops.contacts import ContactConfig
from pipeline.evaluation.autoregressive import (
    EMOTION_NAMES,
    affect_summary,
    emotion_centroids,
    expressiveness,
    long_rollouts,
    rollout_figures,
    skating_speed,
    table1,
    transitions,
)
from pipeline.io.gait_table import read_gaits, write_json_atomic
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds
from pipeline.core.skeleton import load_skeleton
from pipeline.split import dominant_emotion
from pipeline.generators.autoregressive.training import GaitTensors, load_checkpoint
from stages.common import REPO, SKELETON, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
IN_MODELS = REPO / "data" / "models"
OUT = REPO / "reports"


def first_window_per_clip(rows: np.ndarray, clip_ids: list[str]) -> np.ndarray:
    seen, out = set(), []
    for r in rows:
        if clip_ids[r] not in seen:
            seen.add(clip_ids[r])
            out.append(r)
    return np.array(out, dtype=np.int64)


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, in_models: Path = IN_MODELS,
         out: Path = OUT) -> dict:
    params = load_params(params_path) if params_path else load_params()
    p = params["evaluate"]
    torch.set_num_threads(int(p.get("threads", 2)))
    placement = PlacementConfig.from_params(params.get("generate") or {}, params["ingest"]["target_fps"])
    contacts = ContactConfig(**{k: float(v) for k, v in params["annotate"]["contacts"].items()})
    prefix = int(params["train"]["prefix"])
    skeleton = load_skeleton(SKELETON)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    parents = skeleton.parents
    table, arrays = read_gaits(in_gaits)
    split = np.array(table.column("split").to_pylist())
    content = np.array(table.column("content").to_pylist())
    clip_ids = table.column("clip_id").to_pylist()
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    dominant = [dominant_emotion(None if not labelled[i] else arrays["emotion"][i], EMOTION_NAMES)
                for i in range(len(split))]
    models, shas = {}, {}
    for name in params["train"]["variants"]:
        models[name], _, shas[name] = load_checkpoint(in_models / f"{name}.pt")
    full = models["full"]
    low, high, scale = full.affective_low, full.affective_high, full.affective_std
    report: dict[str, Any] = {"checkpoints_sha256": shas, "split": "test", "prefix": prefix, "fps": placement.fps,
                              "rollout_steps": int(p["rollout_steps"]), "placement": asdict(placement)}

    # Table 1: every test gait, ground-truth path, its own label.
    test = np.flatnonzero(split == "test")
    gaits = GaitTensors.from_arrays(arrays, test)
    heading = torch.from_numpy(arrays["heading"][test].astype(np.float32))
    emotions = torch.from_numpy(arrays["emotion"][test].astype(np.float32))
    print(f"evaluate: Table-1 protocol on {len(test)} test gaits", flush=True)
    report["table1"] = table1(models, gaits, heading, emotions, offsets, parents, prefix, placement, low, high)
    report["table1_gaits"] = int(len(test))

    # 200-step rollouts from forward-walking test gaits (one window per clip).
    walks = first_window_per_clip(np.flatnonzero((split == "test") & (content == "walk")), clip_ids)
    walks = walks[: int(p["rollout_agents"])]
    seeds = Seeds.from_arrays(arrays, walks, prefix)
    seed_emotion = torch.from_numpy(arrays["emotion"][walks].astype(np.float32))
    real_walks = np.flatnonzero((split == "test") & (content == "walk"))
    real_pos = torch.from_numpy(arrays["positions"][real_walks])
    real_speed = arrays["movement"][real_walks][..., 1].mean(-1) * placement.fps
    speed_range = [float(np.percentile(real_speed, 5)), float(np.percentile(real_speed, 95))]
    real_skate, real_contact = skating_speed(real_pos, placement.fps, contacts)
    report["real_reference"] = {"walk_windows": int(len(real_walks)), "speed_m_s_p5_p95": [round(v, 4) for v in speed_range],
                                "foot_skating_m_s": round(real_skate, 4), "contact_fraction": round(real_contact, 4)}
    steps = int(p["rollout_steps"])
    print(f"evaluate: {steps}-step rollouts of {len(walks)} agents on a straight line and a sharp turn", flush=True)
    rollouts, report["long_horizon"] = {}, {}
    for name, model in models.items():
        rollouts[name] = long_rollouts(model, seeds, seed_emotion, offsets, parents, steps, placement)
        report["long_horizon"][name] = {path: rollout_figures(r, placement.fps, contacts, speed_range)
                                        for path, r in rollouts[name].items()}
        for figures in report["long_horizon"][name].values():
            skate = figures["foot_skating_m_s"]
            figures["foot_skating_ratio_to_real"] = round(skate / real_skate, 3) if skate is not None else None

    # Emotions: real centroids from the labelled train gaits; seeds are the labelled test gaits.
    train_lab = np.flatnonzero((split == "train") & labelled)
    train_summary = affect_summary(torch.from_numpy(arrays["positions"][train_lab]), low, high, scale)
    centroids = emotion_centroids(train_summary, [dominant[i] for i in train_lab])
    test_lab = np.flatnonzero((split == "test") & labelled)
    test_summary = affect_summary(torch.from_numpy(arrays["positions"][test_lab]), low, high, scale)
    nearest = torch.cdist(test_summary.double(), centroids.double()).argmin(-1)
    intended = torch.tensor([EMOTION_NAMES.index(dominant[i]) for i in test_lab])
    report["emotion_reference"] = {
        "train_labelled_gaits": int(len(train_lab)), "test_labelled_gaits": int(len(test_lab)),
        "real_test_nearest_centroid_accuracy": round(float((nearest == intended).double().mean()), 4)}
    emo_seeds = Seeds.from_arrays(arrays, test_lab, prefix)
    print(f"evaluate: expressiveness and transitions from {len(test_lab)} labelled test gaits", flush=True)
    report["expressiveness"] = {name: expressiveness(model, emo_seeds, centroids, offsets, parents,
                                                     int(p["expressiveness_steps"]), placement, low, high, scale)
                                for name, model in models.items()}
    trans_seeds = Seeds.from_arrays(arrays, test_lab[: int(p["transition_agents"])], prefix)
    report["transitions"] = {name: transitions(model, trans_seeds, centroids, offsets, parents,
                                               int(p["transition_steps"]), placement, low, high, scale)
                             for name, model in models.items() if name in ("full", "no_affect")}
    report["acceptance"] = acceptance(report)
    write_json_atomic(report, out / "eval.json")
    (out / "eval.md").write_text(markdown(report))
    plot_errors(report, out / "eval_errors.png")
    plot_rollouts(rollouts, report, out / "eval_rollouts.png")
    preview(rollouts["full"], skeleton, out / "eval_preview.png")
    t1 = report["table1"]
    print("evaluate: pose error " + ", ".join(f"{k} {v['pose_error']:.4f}" for k, v in t1.items())
          + f"; acceptance {'passed' if report['acceptance']['passed'] else 'NOT passed'}")
    return report


def acceptance(report: dict) -> dict:
    t1 = report["table1"]
    full = t1["full"]
    lh = report["long_horizon"]["full"]
    out = {
        "beats_zero_velocity": full["pose_error"] < t1["zero_velocity"]["pose_error"]
        and full["rotation_error_deg"] < t1["zero_velocity"]["rotation_error_deg"],
        "beats_constant_velocity": full["pose_error"] < t1["constant_velocity"]["pose_error"]
        and full["rotation_error_deg"] < t1["constant_velocity"]["rotation_error_deg"],
        "no_affect_worse_on_affective_error": t1["no_affect"]["affective_error"] > full["affective_error"],
        "rollouts_finite_and_moving": all(f["finite"] and f["frozen_agents"] == 0 for f in lh.values()),
        "foot_skating_at_most_1_5x_real": all(f["foot_skating_ratio_to_real"] is not None
                                              and f["foot_skating_ratio_to_real"] <= 1.5 for f in lh.values()),
    }
    out["passed"] = all(out.values())
    return out


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
              f"Root placement: {report['placement']['root_advance']} (params.yaml generate; Table 1 places the root "
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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    fig.savefig(path, dpi=80, metadata={"Software": None})
    plt.close(fig)


def plot_rollouts(rollouts: dict, report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(rollouts)
    fig, axes = plt.subplots(2, len(names) + 1, figsize=(4.2 * (len(names) + 1), 8))
    for col, name in enumerate(names):
        for row, kind in enumerate(("straight", "sharp_turn")):
            ax = axes[row, col]
            r = rollouts[name][kind]
            root = r.generated.positions[:, :, 0][..., [0, 2]]
            start = r.path[:, :1]
            # every agent in its own start frame (facing +z), the path drawn as far as the agents got
            angle = torch.atan2(r.path[:, 1, 0] - r.path[:, 0, 0], r.path[:, 1, 1] - r.path[:, 0, 1])[:, None]
            c, s = torch.cos(angle), torch.sin(angle)

            def local(points):
                d = points - start
                return torch.stack((c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]), dim=-1).numpy()

            reach = float(torch.linalg.vector_norm(root - start, dim=-1).max()) + 1.0
            target = local(r.path)
            dense = np.concatenate([np.linspace(target[0, k], target[0, k + 1], 200)
                                    for k in range(target.shape[1] - 1)])
            dense = dense[np.cumsum(np.r_[0, np.linalg.norm(np.diff(dense, axis=0), axis=1)]) <= reach]
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
    fig.savefig(path, dpi=70, metadata={"Software": None})
    plt.close(fig)


def preview(rollouts: dict, skeleton, path: Path) -> None:
    from pipeline.viz.stick_figures import Motion, render_filmstrip

    motions = []
    for kind in ("straight", "sharp_turn"):
        g = rollouts[kind].generated
        for n in range(min(2, g.positions.shape[0])):
            motions.append(Motion(title=f"generated, {kind}, agent {n}", positions=g.positions[n].numpy(),
                                  parents=skeleton.parents, names=skeleton.names))
    render_filmstrip(motions, path, frames=10)


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
