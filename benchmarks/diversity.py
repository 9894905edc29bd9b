"""How widely the gaits of one emotion spread, per generator family, against real walks. No recogniser is involved.

A generator that pulls every gait of an emotion towards one point makes a tight cluster: a recogniser trained
with it learns that cluster as the emotion and reads the real walks around it worse. Real walks of one emotion
spread: performers, speeds, contents.

Per gait, the mean and standard deviation over its frames of the 18 affective and 5 movement features (the
audit's feature summaries, ``pipeline.audit.metrics.gait_summaries``), standardised by the labelled real train
gaits. Per group (real train; its walks, the content every generator makes and seeds from; real held-out = the
audit's val + test; each family) and emotion (dominant label; synthetic gaits whose label holds in every frame):
- ``spread``: the median over the 46 summaries of the group's standard deviation over that emotion's gaits,
  divided by the real train gaits' (1: as wide as real train, every content; the real train walks show how much
  of that the walks alone span, the held-out gaits how much real data varies);
- ``to_centroid``: the median over the gaits of their RMS distance (standard units) to the real train centroid of
  that emotion.
Printed as JSON and written to benchmarks/out/diversity.json. Run from the repository root after ``dvc repro``:
``python benchmarks/diversity.py`` (seconds).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from benchmarks.published import published_gaits  # noqa: E402
from pipeline.audit.metrics import gait_summaries  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from stages.common import load_params  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "diversity.json"


def main() -> dict:
    gaits = published_gaits()
    frame, names, label, train = gaits.frame, gaits.names, gaits.label, gaits.train
    summaries = gait_summaries(frame)
    z = (summaries - summaries[train].mean(0)) / summaries[train].std(0).clip(1e-9)
    walks = (frame["content"] == load_params()["synthesize"]["seed_content"]).to_numpy()
    groups = {"real_train": train, "real_train_walks": train & walks, "real_held_out": gaits.held, **gaits.families}
    out: dict = {"unit": "real train standard deviations of the 46 feature summaries", "groups": {}}
    for group, mask in groups.items():
        per_emotion = {}
        for e, name in enumerate(names):
            mine, real = z[mask & (label == e)], z[train & (label == e)]
            if len(mine) < 2 or len(real) < 2:
                continue
            per_emotion[name] = {
                "gaits": int(len(mine)),
                "spread": round(float(np.median(mine.std(0) / real.std(0).clip(1e-9))), 3),
                "to_centroid": round(float(np.median(np.sqrt(((mine - real.mean(0)) ** 2).mean(1)))), 3)}
        out["groups"][group] = {"per_emotion": per_emotion,
                                "mean_spread": round(float(np.mean([v["spread"] for v in per_emotion.values()])), 3)}
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
