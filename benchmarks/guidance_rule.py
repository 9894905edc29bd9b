"""How strongly the emotion condition is guided at generation (``generate.guidance``), chosen on real data: the
affective features of real gaits, never a recogniser that grades the generator.

Classifier-free guidance moves each generated frame w times as far along the difference between the network with
and without its condition. Too little and the condition barely shows; too much and the gaits become caricatures,
farther from every real gait of their emotion than real gaits of that emotion lie. For each w in ``--guidance``
every labelled val walk (walks, as every published gait is; clips the generator never trained on, not the test
seeds ``evaluate`` reports on) is generated on a straight line under each one-hot emotion (60 frames after its
18-frame prefix), and reported are:
- ``sensitivity``: the separation of one seed's four gaits as a fraction of the real emotion centroids' separation
  (affect summaries: per gait the mean of the 18 affective features in training SD units; the centroids are the
  labelled train walks'), as ``evaluate`` measures it (its centroids are of every labelled train gait);
- ``to_condition_centroid``: the mean distance of every generated gait to its condition's real centroid, beside
  ``real_val_to_own_centroid``, the same for the real val gaits and their own emotion.
The rule (``chosen``): the w whose sensitivity is nearest 1.0, where the condition moves a gait as far as real
emotions differ, neither less (the condition barely shows) nor more (caricature: ``to_condition_centroid`` grows
with w past it). The evaluation recognisers (``pipeline.recognition``) are not used here.

Printed as JSON and written to benchmarks/out/guidance_rule.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/guidance_rule.py [--guidance 0.5 1 2]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.evaluation.autoregressive import (affect_summary, centroid_distances, emotion_centroids,  # noqa: E402
                                               straight_path)
from pipeline.evaluation.controllability import condition_sensitivity, under_each_emotion  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, place_paths  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from stages.common import load_params  # noqa: E402
from stages.configs import placement_config  # noqa: E402

from generator_data import generator, split_gaits  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "guidance_rule.json"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--guidance", type=float, nargs="+", default=[0.5, 0.75, 1.0, 1.5, 2.0, 3.0])
    parser.add_argument("--frames", type=int, default=60, help="generated frames per gait")
    args = parser.parse_args()
    torch.set_num_threads(2)
    params = load_params()
    arrays, split, content, dominant = split_gaits()
    model, sha, skeleton, offsets = generator()
    low, high, scale = model.affective_low, model.affective_high, model.affective_std

    def summary(rows: np.ndarray) -> torch.Tensor:
        return affect_summary(torch.from_numpy(arrays["positions"][rows]), low, high, scale)

    walks = (dominant >= 0) & (content == "walk")  # the published gaits are walks: compared with real walks only
    train = np.flatnonzero((split == "train") & walks)
    centroids = emotion_centroids(summary(train), [EMOTIONS[d] for d in dominant[train]])
    val = np.flatnonzero((split == "val") & walks)
    own = torch.from_numpy(dominant[val])
    real = float(torch.linalg.vector_norm(summary(val) - centroids[own], dim=-1).mean())
    seeds = Seeds.from_arrays(arrays, val, int(params["train"]["prefix"]))
    paths = place_paths(straight_path(), seeds)
    out = {"checkpoint_sha256": sha, "seeds": int(len(val)), "real_val_to_own_centroid": round(real, 4),
           "by_guidance": {}}
    for w in args.guidance:
        started = time.perf_counter()
        generated = under_each_emotion(model, seeds, paths, args.frames, offsets, skeleton.parents,
                                       replace(placement_config(params), guidance=w))
        summaries = torch.stack([affect_summary(g.positions, low, high, scale) for g in generated])  # (4, N, 18)
        entry = {"sensitivity": condition_sensitivity(summaries, centroids)["fraction_of_real"],
                 "to_condition_centroid": centroid_distances(summaries, centroids)["distance_to_same_emotion"],
                 "seconds": round(time.perf_counter() - started, 2)}
        out["by_guidance"][str(w)] = entry
        print(f"guidance {w}: {entry}", flush=True)
    out["chosen"] = min(args.guidance, key=lambda w: abs(out["by_guidance"][str(w)]["sensitivity"] - 1.0))
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
