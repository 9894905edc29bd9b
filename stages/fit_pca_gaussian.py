"""DVC stage `fit_pca_gaussian`: the PCA + Gaussian family (seed 001; pipeline/generators/pca_gaussian/) fitted on
the train split's forward walks.

data/split/gaits.parquet -> data/pca_gaussian/model.pt (basis, emotion models, the cycles they came from; its
sha256 identifies the family's gaits), reports/pca_gaussian.json (DVC metrics: cycle counts per style and emotion,
the cumulative explained variance, reconstruction errors at 10 components and at the kept number, the emotion
models' sizes and durations; no timings, which are printed), reports/pca_gaussian.png (the variance curve, paper
Fig. 2).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.core.emotions import EMOTIONS
from pipeline.core.skeleton import load_skeleton
from pipeline.generators.pca_gaussian.cycles import CycleConfig
from pipeline.generators.pca_gaussian.family import fit, model_bytes
from pipeline.generators.pca_gaussian.model import (ModelConfig, cycle_novelty, leave_one_clip_out_reading,
                                                    reconstruction_errors)
from pipeline.io.files import save_figure, write_bytes, write_json
from pipeline.io.gait_table import read_gaits
from stages.common import REPO, SKELETON, load_params
from stages.configs import annotate_config

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
OUT_MODEL = REPO / "data" / "pca_gaussian" / "model.pt"
OUT_REPORT = REPO / "reports" / "pca_gaussian.json"
OUT_PLOT = REPO / "reports" / "pca_gaussian.png"


def plot_variance(cumulative: np.ndarray, kept: int, goal: float, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    shown = cumulative[: min(len(cumulative), 60)]
    ax.plot(np.arange(1, len(shown) + 1), 100 * shown, marker=".", color="tab:blue")
    ax.axhline(100 * goal, color="0.5", ls="--", lw=0.8)
    ax.axvline(kept, color="tab:red", lw=0.8, label=f"kept: {kept} components")
    ax.set_xlabel("principal components")
    ax.set_ylabel("cumulative explained variance (%)")
    ax.set_title("walk cycles in PC space (first 60 of %d components)" % len(cumulative))
    ax.legend(loc="lower right")
    save_figure(fig, out)
    return out


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_model: Path = OUT_MODEL,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    p = params["pca_gaussian"]
    cycle_cfg, cfg = CycleConfig.from_dict(p.get("cycles")), ModelConfig.from_dict(p.get("model"))
    skeleton = load_skeleton(SKELETON)
    started = time.perf_counter()
    f = fit(*read_gaits(in_gaits), skeleton, cycle_cfg, cfg, annotate_config(params))
    sha = write_bytes(model_bytes(f, cycle_cfg, cfg), out_model)
    seconds = time.perf_counter() - started
    cumulative = np.cumsum(f.basis.explained)
    errors = [reconstruction_errors(f.cycles.flat(), f.basis, n, skeleton.offsets, skeleton.parents, cycle_cfg.frames)
              for n in sorted({min(10, len(cumulative)), f.components})]
    scores = f.basis.scores(f.cycles.flat(), f.components)
    clips = np.asarray(f.cycles.clip_id)
    report = {"model": str(out_model.relative_to(REPO) if out_model.is_relative_to(REPO) else out_model),
              "sha256": sha, "cycles": f.cycles.counts(), "basis_cycles": int(len(f.basis.basis_rows)),
              "components_available": int(len(cumulative)), "variance_goal": cfg.variance,
              "components_kept": f.components,
              "components_for_variance": f.basis.components_for(cfg.variance),
              "emotion_features_sd": cfg.emotion_features_sd,
              "emotion_feature_errors_sd": {str(k): dict(zip(EMOTIONS, v))
                                            for k, v in f.emotion_feature_errors.items()},
              "cumulative_variance": [round(float(v), 4) for v in cumulative[:60]],
              "components_for": {f"{v:.2f}": f.basis.components_for(v) for v in (0.8, 0.9, 0.95, 0.99)},
              "reconstruction": errors,
              "models": {name: {"cycles": m.cycles, "duration_frames_mean_std": [round(m.duration_mean, 2),
                                                                                 round(m.duration_std, 2)]}
                         for name, m in zip(EMOTIONS, f.model.models)},
              "emotion_in_pc_space": {**leave_one_clip_out_reading(scores, f.cycles.dominant(), clips),
                                      "how": "each labelled cycle read as the emotion whose centroid of the kept "
                                             "scores, fitted on the other clips' cycles, is nearest"},
              "novelty": cycle_novelty(f.model.models, scores, clips, per_emotion=200, seed=cfg.seed,
                                       values_per_cycle=f.cycles.flat().shape[1])}
    write_json(report, out_report)
    plot_variance(cumulative, f.components, cfg.variance, out_plot)
    counts = report["cycles"]["per_emotion"]
    print(f"fit_pca_gaussian: {report['cycles']['cycles']} cycles ({', '.join(f'{k} {v}' for k, v in counts.items())}), "
          f"{f.components} components ({report['components_for_variance']} for {cfg.variance:.0%}; the emotions' "
          f"features within {cfg.emotion_features_sd:g} SD), {errors[-1]['joint_position_error_m'] * 100:.1f} cm / "
          f"{errors[-1]['rotation_error_deg']:.1f} deg; {seconds:.1f} s; sha256 {sha[:12]}")
    reading, novelty = report["emotion_in_pc_space"], report["novelty"]
    print(f"fit_pca_gaussian: emotion from PC scores, leave one clip out: balanced accuracy "
          f"{reading['balanced_accuracy']:.3f} (majority {reading['majority_baseline_accuracy']:.3f}); drawn cycles to "
          f"the nearest real: median {novelty['drawn_to_nearest_real_deg']['median']:.2f} deg vs real to real "
          f"{novelty['real_to_nearest_real_of_another_clip_deg']['median']:.2f} deg; reproduced {novelty['reproduced']}")
    return report


if __name__ == "__main__":
    main()
