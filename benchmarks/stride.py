"""How far a generated walk travels under each emotion, against the real walks it starts from: real data and the
generator only, no recogniser.

The published non-neutral gaits walk slower than the real walks of their emotion (reports/synthesize.json,
``walking``), at the seed's cadence: their strides are shorter. This measures where. Every labelled train walk (the
synthesis seed pool) is generated on a straight line under its own one-hot emotion (60 frames after its 18-frame
prefix), placed three ways, with no root smoothing, path fit or foot locking:
- ``stance_foot``: the default; the root moves so the lowest heel/toe not in its swing phase stays put (the legs'
  stride);
- ``lowest_point``: the same with every foot eligible (``stance_fraction`` 1: the stepping phase plays no part);
- ``predicted_speed``: the root advances by the network's ŝ (the paper's placement).
Reported per emotion: the median speed (m/s) of the real continuation (window frames 18-59) and of each placement,
overall and per whole 20-frame block (the real continuation has two). If the legs' speed is short of the real one while ŝ is not, the legs' stride is
what the condition shrinks.

Printed as JSON and written to benchmarks/out/stride.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/stride.py``.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.evaluation.autoregressive import straight_path  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, generate, place_paths  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from stages.common import load_params  # noqa: E402

from generator_data import generator, legs_placement, split_gaits  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "stride.json"
FRAMES = 60
BLOCK = 20


def _median_speed(advance: np.ndarray) -> dict:
    """advance (N, S) m/s per frame -> median over gaits of the mean, overall and per whole block."""
    return {"m_s": round(float(np.median(advance.mean(1))), 3),
            "by_block_m_s": [round(float(np.median(advance[:, a:a + BLOCK].mean(1))), 3)
                             for a in range(0, advance.shape[1] - BLOCK + 1, BLOCK)]}


def main() -> dict:
    torch.set_num_threads(2)
    params = load_params()
    prefix = int(params["train"]["prefix"])
    arrays, split, content, dominant = split_gaits()
    model, sha, skeleton, offsets = generator()
    plain = legs_placement(params)
    placements = {"stance_foot": replace(plain, root_advance="stance_foot"),
                  "lowest_point": replace(plain, root_advance="stance_foot", stance_fraction=1.0),
                  "predicted_speed": replace(plain, root_advance="predicted_speed")}
    fps = plain.fps
    out = {"checkpoint_sha256": sha, "frames": FRAMES, "by_emotion": {}}
    for k, emotion in enumerate(EMOTIONS):
        rows = np.flatnonzero((split == "train") & (content == "walk") & (dominant == k))
        if len(rows) == 0:
            continue
        seeds = Seeds.from_arrays(arrays, rows, prefix)
        paths = place_paths(straight_path(), seeds)
        condition = torch.zeros(len(rows), FRAMES, len(EMOTIONS))
        condition[..., k] = 1.0
        ground = arrays["positions"][rows][:, prefix - 1:, 0][..., [0, 2]]
        entry = {"seeds": int(len(rows)),
                 "real_continuation": _median_speed(np.linalg.norm(np.diff(ground, axis=1), axis=-1) * fps)}
        for name, placement in placements.items():
            with torch.no_grad():
                generated = generate(model, seeds, paths, condition, offsets, skeleton.parents, placement)
            entry[name] = _median_speed(generated.advance.numpy() * fps)
        out["by_emotion"][emotion] = entry
        print(f"{emotion}: {json.dumps(entry)}", flush=True)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
