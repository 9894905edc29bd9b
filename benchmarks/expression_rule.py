"""How the plan's novel emotion mixtures are fed to the network: the expression rule m -> m^p / sum(m^p)
(``generate.expression_sharpness``), read by the generator's OWN style critic, never by the recognisers that grade it.

The real labels are one-hot, so the network learnt vertices of the emotion simplex; the plan's 100 emotions are
mixtures farther than L1 0.5 from every vertex. For each p in ``--powers`` every ``--every``-th plan row is
generated (the synthesize stage's seeds, trajectory pieces and per-frame emotions; guidance and placement from
params.yaml) and the critic stored in data/models/full.pt reads each gait's frames; reported is its balanced
accuracy against the row's intended dominant emotion (that of the mean per-frame emotion, as the audit labels
it), for single-emotion rows and transitions, and the seconds per setting. The evaluation recognisers
(``pipeline.recognition``) are not used here: choosing p by them would tune the generator against its graders.

Printed as JSON and written to benchmarks/out/expression_rule.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/expression_rule.py [--powers 1 2 4 8]``.
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

from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.generators.autoregressive.critic import StyleCritic  # noqa: E402
from pipeline.generators.autoregressive.network import travel_frame_positions  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, generate, place_paths  # noqa: E402
from pipeline.generators.autoregressive.training import load_checkpoint  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from pipeline.recognition import confusion, scores  # noqa: E402
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402
from stages.configs import placement_config  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "expression_rule.json"
GAITS = REPO / "data" / "split" / "gaits.parquet"
MODEL = REPO / "data" / "models" / "full.pt"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--powers", type=float, nargs="+", default=[1.0, 2.0, 4.0, 8.0])
    parser.add_argument("--every", type=int, default=5, help="every k-th plan row (1000 of the 5,000 at 5)")
    parser.add_argument("--batch", type=int, default=500)
    args = parser.parse_args()
    torch.set_num_threads(2)
    params = load_params()
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    work = SynthesisPlan.prepare(*read_gaits(GAITS), cfg)
    skeleton = load_skeleton(SKELETON)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    model, extra, sha = load_checkpoint(MODEL)
    critic = StyleCritic()
    critic.load_state_dict(extra["critic"]["state_dict"])
    critic.eval()
    rows = work.plan[:: args.every]
    shapes, per_frame = row_inputs(rows, work.emotions, {t.id: t for t in work.trajectories}, cfg)
    per_frame = torch.from_numpy(per_frame.astype(np.float32))
    intended = per_frame.mean(1).argmax(-1).numpy()
    kinds = np.array([r["recipe"]["kind"] for r in rows])
    out = {"checkpoint_sha256": sha, "rows": len(rows), "reader": "the generator's own style critic (critic.py)",
           "label": "dominant emotion of the mean per-frame emotion", "by_power": {}}
    for power in args.powers:
        placement = replace(placement_config(params), expression_sharpness=power)
        started = time.perf_counter()
        said = []
        for first in range(0, len(rows), args.batch):
            part = slice(first, first + args.batch)
            seeds = Seeds.from_arrays(work.arrays, np.array([work.row_of[r["seed_gait_id"]] for r in rows[part]]),
                                      int(params["train"]["prefix"]))
            g = generate(model, seeds, place_paths(shapes[part], seeds), per_frame[part], offsets, skeleton.parents,
                         placement)
            with torch.no_grad():
                said.append(critic(travel_frame_positions(g.versors, offsets, skeleton.parents)).argmax(-1).numpy())
        said = np.concatenate(said)
        entry = {kind: round(scores(confusion(intended[kinds == kind], said[kinds == kind], 4))["balanced_accuracy"], 4)
                 for kind in ("single", "transition")}
        entry["all"] = round(scores(confusion(intended, said, 4))["balanced_accuracy"], 4)
        entry["seconds"] = round(time.perf_counter() - started, 2)
        out["by_power"][str(power)] = entry
        print(f"p = {power}: {entry}", flush=True)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
