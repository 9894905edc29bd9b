"""DVC stage `evaluate`: the trained generator and its ablations on the **test split** only.

data/split/gaits.parquet + data/models/*.pt -> reports/eval.json (DVC metrics), reports/eval.md (the tables),
reports/eval_errors.png (error per predicted frame), reports/eval_rollouts.png (rollout paths and speeds),
reports/eval_preview.png (stick figures of generated gaits), reports/eval_controllability.png (condition
sensitivity, style retention per block, transitions, as read by the independent recognisers),
reports/eval_emotions.png (one seed on one plan trajectory under the four emotions) and reports/eval_transition.png
(the same seed in one transition). The protocols: pipeline/evaluation/.
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from pipeline.core.skeleton import load_skeleton
from pipeline.evaluation.controllability import ControllabilityConfig
from pipeline.evaluation.report import (markdown, plot_controllability, plot_errors, plot_rollouts, preview,
                                       preview_gaits)
from pipeline.evaluation.run import ControlSetup, EvaluationConfig, evaluate_generators
from pipeline.generators.autoregressive.training import load_checkpoint
from pipeline.io.files import write_json, write_text
from pipeline.io.gait_table import read_gaits
from pipeline.recognition import RecogniserConfig
from pipeline.synth.synthesis import SynthesisConfig
from stages.common import REPO, SKELETON, load_params
from stages.configs import annotate_config, contact_config, placement_config

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
IN_MODELS = REPO / "data" / "models"
OUT = REPO / "reports"


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, in_models: Path = IN_MODELS,
         out: Path = OUT) -> dict:
    params = load_params(params_path) if params_path else load_params()
    p = params["evaluate"]
    torch.set_num_threads(int(p.get("threads", 2)))
    cfg = EvaluationConfig(prefix=int(params["train"]["prefix"]), **{k: int(p[k]) for k in (
        "rollout_steps", "rollout_agents", "expressiveness_steps", "transition_steps", "transition_agents")})
    c = dict(p["controllability"])
    setup = ControlSetup(
        control=ControllabilityConfig(**{k: int(c[k]) for k in ("steps", "block", "transition_agents", "plan_gaits",
                                                                  "seed")}),
        recognisers=RecogniserConfig.from_dict((params.get("audit") or {}).get("recognisers")),
        annotate=annotate_config(params),
        synthesis=SynthesisConfig.from_dict(params["synthesize"], frames=int(c["steps"])),
        preview_trajectory=str(c["preview_trajectory"]), preview_transition=tuple(c["preview_transition"]))
    models, shas = {}, {}
    for name in params["train"]["variants"]:
        models[name], _, shas[name] = load_checkpoint(in_models / f"{name}.pt")
    skeleton = load_skeleton(SKELETON)
    table, arrays = read_gaits(in_gaits)
    report, rollouts, previews = evaluate_generators(table, arrays, models, shas, skeleton, placement_config(params),
                                                     contact_config(params), cfg, setup)
    write_json(report, out / "eval.json")
    write_text(markdown(report), out / "eval.md")
    plot_errors(report, out / "eval_errors.png")
    plot_rollouts(rollouts, report, out / "eval_rollouts.png")
    preview(rollouts["full"], skeleton, out / "eval_preview.png")
    plot_controllability(report, out / "eval_controllability.png")
    preview_gaits(previews["emotions"], skeleton, out / "eval_emotions.png")
    preview_gaits(previews["transition"], skeleton, out / "eval_transition.png")
    t1 = report["table1"]
    control = report["controllability"]
    print("evaluate: pose error " + ", ".join(f"{k} {v['pose_error']:.4f}" for k, v in t1.items())
          + "; condition sensitivity " + ", ".join(f"{k} {v['fraction_of_real']:.2f}"
                                                   for k, v in control["condition_sensitivity"].items())
          + f"; acceptance {'passed' if report['acceptance']['passed'] else 'NOT passed'}")
    return report


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
