"""Whether the summary MLP's augmentation loss is the generators' doing: the audit's augmentation protocol, run
with real gaits and with recognisers that have seen mirror images, on the published directory. No generator is
trained or changed here, and no figure feeds back into one.

The audit (``audit.augmentation.controls``) already reports two controls: the real train gaits added again, and
their mirror images. A mirrored sad walk is a sad walk, yet the summary MLP loses from it as it does from every
generator family. This asks what is left of each family's change once the recogniser's training already holds
the mirror images, i.e. once the cue mirroring removes is gone before the synthetic gaits arrive:

- ``real_only`` / ``real_and_mirrored``: macro-F1 on the real held-out gaits of a recogniser trained on the real
  train gaits, and on them plus their mirror images (``augmentation_controls``);
- per family, the change from adding the protocol's synthetic draw (one steady-label synthetic gait per real train
  gait, the audit's seeds and draws) to each of the two.

Per recogniser, the mean over the audit's seeds; changes in macro-F1 points, also on the held-out gaits of the
contents the generators make (forward walks) and on the others. Printed as JSON and written to
benchmarks/out/augmentation_controls.json. Run from the repository root after ``dvc repro``:
``python benchmarks/augmentation_controls.py`` (about 1 min on 2 idle cores).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.audit.metrics import (  # noqa: E402
    AuditConfig,
    augmentation_controls,
    augmentation_draw,
    held_out_by_content,
)
from pipeline.io.files import write_json  # noqa: E402
from pipeline.recognition import RECOGNISERS, RecognitionInputs, confusion, fit_recogniser, scores  # noqa: E402
from stages.common import load_params  # noqa: E402

from published import published_gaits  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "augmentation_controls.json"


def main() -> dict:
    torch.set_num_threads(2)
    cfg = AuditConfig.from_dict(load_params()["audit"])
    published = published_gaits()
    names, inputs, label, train, test = (published.names, published.inputs, published.label, published.train,
                                         published.held)
    views = {"all": np.ones(int(test.sum()), bool), **held_out_by_content(published.frame, test)}
    families = published.families
    real_train, held, y = inputs.select(train), inputs.select(test), label[test]
    mirrored = augmentation_controls(real_train, ["mirrored"])["mirrored"]
    bases = {"real_only": (real_train, label[train]),
             "real_and_mirrored": (RecognitionInputs.concatenate([real_train, mirrored]),
                                   np.concatenate([label[train], label[train]]))}

    def macro_f1(predicted: np.ndarray) -> dict[str, float]:
        return {v: scores(confusion(y[m], predicted[m], len(names)))["macro_f1"] for v, m in views.items()}

    out: dict = {"protocol": "audit.augmentation: per seed, one steady-label synthetic gait per labelled real train "
                             "gait; macro-F1 on the real held-out gaits, mean over the audit's seeds",
                 "real_train": int(train.sum()), "held_out": {v: int(m.sum()) for v, m in views.items()},
                 "recognisers": {}}
    for kind in RECOGNISERS:
        started = time.perf_counter()
        figures: dict[str, list[dict[str, float]]] = {}
        for seed in cfg.seeds[kind]:
            for base, (x, labels) in bases.items():
                before = macro_f1(fit_recogniser(kind, x, labels, cfg.recognisers, seed).predict(held))
                figures.setdefault(base, []).append(before)
                for family, mask in families.items():
                    drawn = augmentation_draw(np.flatnonzero(mask), int(train.sum()), seed)
                    both = RecognitionInputs.concatenate([x, inputs.select(drawn)])
                    after = macro_f1(fit_recogniser(kind, both, np.concatenate([labels, label[drawn]]),
                                                    cfg.recognisers, seed).predict(held))
                    figures.setdefault(f"{base} + {family}", []).append(
                        {v: after[v] - before[v] for v in views})
        mean = {k: {v: round(float(np.mean([f[v] for f in runs])), 4) for v in views} for k, runs in figures.items()}
        entry = {"macro_f1": {b: mean[b] for b in bases},
                 "mirror_images_change": {v: round(mean["real_and_mirrored"][v] - mean["real_only"][v], 4)
                                          for v in views},
                 "augmentation_change": {b: {f: mean[f"{b} + {f}"] for f in families}
                                         for b in bases},
                 "seconds": round(time.perf_counter() - started, 1)}
        out["recognisers"][kind] = entry
        print(f"{kind}: {json.dumps(entry)}", flush=True)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
