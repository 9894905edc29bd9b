"""Left-right asymmetry of the gaits per emotion: real train, real held-out, the real train gaits' mirror images and
every generator family, on the published directory. No recogniser is involved.

The real walks here are not symmetric: per emotion, the performers lean their head towards one shoulder, bend one
elbow or knee more than the other. The held-out clips share that (same performers), so a generator whose gaits keep
it looks like the data and one that averages it away (or flips it) does not. Mirror images flip it by construction.

Per gait, the mean over its frames of left minus right of the four lateral pairs of affective features
(``LATERAL_PAIRS``, DESIGN.md §5): elbows (7, 8), head-neck-shoulder (9, 10), head-root-knee (11, 12), knees (15, 16).
Per group and emotion (dominant label; synthetic gaits whose label holds in every frame), the mean of those. Each
group's mismatch with the real train gaits: per emotion and pair, the difference of means in units of the real
train gaits' standard deviation (within the emotion), then the root mean square over emotions and pairs.

Printed as JSON and written to benchmarks/out/asymmetry.json. Run from the repository root after ``dvc repro``:
``python benchmarks/asymmetry.py`` (seconds).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from benchmarks.published import published_gaits  # noqa: E402
from pipeline.audit.metrics import augmentation_controls  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "asymmetry.json"
# (left, right) affective feature indices (DESIGN.md §5)
LATERAL_PAIRS = {"elbow": (7, 8), "head_neck_shoulder": (9, 10), "head_root_knee": (11, 12), "knee": (15, 16)}


def asymmetry(affective: np.ndarray) -> np.ndarray:
    """(N, T, 18) -> (N, pairs): per gait, the mean over frames of left minus right (rad) of each lateral pair."""
    return np.stack([(affective[..., l] - affective[..., r]).mean(-1) for l, r in LATERAL_PAIRS.values()], -1)


def main() -> dict:
    gaits = published_gaits()
    names, label, train, held = gaits.names, gaits.label, gaits.train, gaits.held
    values = asymmetry(gaits.inputs.affective)
    groups = {"real_train": (values[train], label[train]), "real_held_out": (values[held], label[held])}
    mirrored = augmentation_controls(gaits.inputs.select(train), ["mirrored"])["mirrored"]
    groups["real_train_mirrored"] = (asymmetry(mirrored.affective), label[train])
    for family, rows in gaits.families.items():
        groups[family] = (values[rows], label[rows])

    reference, reference_label = groups["real_train"]
    out: dict = {"pairs": {k: list(v) for k, v in LATERAL_PAIRS.items()},
                 "unit": "rad, per-gait mean over frames of left minus right", "groups": {}}
    for group, (v, y) in groups.items():
        per_emotion, z = {}, []
        for e, name in enumerate(names):
            mine, theirs = v[y == e], reference[reference_label == e]
            if not len(mine) or len(theirs) < 2:
                continue
            per_emotion[name] = {"gaits": int(len(mine)),
                                 **{p: round(float(m), 4) for p, m in zip(LATERAL_PAIRS, mine.mean(0))}}
            z.append((mine.mean(0) - theirs.mean(0)) / theirs.std(0).clip(1e-6))
        out["groups"][group] = {"per_emotion": per_emotion,
                                "mismatch_sd": round(float(np.sqrt(np.mean(np.square(z)))), 3) if z else None}
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
