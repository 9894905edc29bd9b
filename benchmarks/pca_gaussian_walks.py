"""Walks of the PCA + Gaussian family (issue 12) on a sample of the shared plan, measured as the autoregressive
family's are: recognised as their intended dominant emotion by the two independent recognisers (fitted here on the
real labelled train gaits only, the audit's settings and seed 0) of the model the `fit_pca_gaussian` stage wrote, foot skating against the real train walks, net
and path speed per emotion, redrawn and clamped scores, and seconds. Also the plan's single rows with their
emotion replaced by its dominant vertex (one-hot), which says what the emotion models carry before any blending.

Printed as JSON and written to benchmarks/out/pca_gaussian_walks.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/pca_gaussian_walks.py [--every 10]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from benchmarks.root_smoothing import root_motion  # noqa: E402
from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.ops.footlock import skating_speed  # noqa: E402
from pipeline.generators.pca_gaussian.family import PCAGaussianFamily, load_model  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from pipeline.recognition import RECOGNISERS, RecogniserConfig, confusion, fit_recogniser, scores  # noqa: E402
from pipeline.recognition.inputs import RecognitionInputs  # noqa: E402
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, synthesize, walking_figures  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from stages.configs import annotate_config, contact_config, placement_config, walk_settings  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "pca_gaussian_walks.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"
MODEL = REPO / "data" / "pca_gaussian" / "model.pt"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--every", type=int, default=10, help="every k-th plan row (500 of the 5,000 at 10)")
    args = parser.parse_args()
    torch.set_num_threads(2)
    params = load_params()
    skeleton = load_skeleton(SKELETON)
    table, arrays = read_gaits(GAITS)
    model, _, sha = load_model(MODEL)
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    fps = float(params["ingest"]["target_fps"])
    work = SynthesisPlan.prepare(table, arrays, cfg)
    family = PCAGaussianFamily(model, sha, skeleton, placement_config(params), walk_settings(params))
    trajectories = {t.id: t for t in work.trajectories}
    split = np.array(table.column("split").to_pylist())
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    train = np.flatnonzero((split == "train") & labelled)
    recognisers = {kind: fit_recogniser(kind, RecognitionInputs.from_arrays(arrays, train),
                                        arrays["emotion"][train].argmax(-1),
                                        RecogniserConfig.from_dict(params["audit"]["recognisers"]), 0)
                   for kind in RECOGNISERS}
    walks = np.array([work.row_of[g] for g in work.seed_pools[-1]])
    contacts = contact_config(params)
    real_skating = skating_speed(torch.from_numpy(arrays["positions"][walks]), fps, contacts)[0]
    plan = work.plan[:: args.every]
    one_hot = [{**r, "recipe": {"kind": "single", "emotion": int(np.argmax(work.emotions[r["recipe"]["emotion"]]))}}
               for r in plan if r["recipe"]["kind"] == "single"]
    out = {"model_sha256": family.model_sha256, "components": int(model.components.shape[0]),
           "real_walks_skating_m_s": round(real_skating, 4),
           "real_walks_root_motion": root_motion(arrays["positions"][walks][:, :, 0, [0, 2]], fps), "sets": {}}
    for name, rows, emotions in (("plan_sample", plan, work.emotions), ("one_hot_single_rows", one_hot, np.eye(4))):
        family.counts.clear()
        started = time.perf_counter()
        syn = synthesize(family, rows, emotions, trajectories, skeleton, annotate_config(params), cfg)
        seconds = time.perf_counter() - started
        intended = syn["emotion"].argmax(-1)
        entry = {"gaits": len(rows), "seconds": round(seconds, 2), "scores_redrawn_clamped": dict(family.counts),
                 "skating_ratio_to_real": round(skating_speed(torch.from_numpy(syn["positions"]), fps,
                                                              contacts)[0] / real_skating, 3),
                 "walking": walking_figures(syn["root_path"], syn["emotion"], fps),
                 "root_motion": root_motion(syn["root_path"], fps),
                 "phase_from_condition": int(syn["phase_from_condition"].sum())}
        for kind, recogniser in recognisers.items():
            matrix = confusion(intended, recogniser.predict(RecognitionInputs.from_arrays(syn)), len(EMOTIONS))
            entry[kind] = {"balanced_accuracy": round(scores(matrix)["balanced_accuracy"], 4),
                           "confusion": matrix.tolist()}
        out["sets"][name] = entry
        print(f"{name}: {json.dumps({k: v for k, v in entry.items() if k != 'walking'})}", flush=True)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
