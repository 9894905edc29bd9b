"""Does the generator keep a rare content when it sees it more often? Real data and the generator only, no recogniser.

``seed_contents.py`` found that the network turns a backward-walk seed into a forward walk from the first generated
frame (a network trained on the paper's losses alone does too): the train split's backward walks are 70 of its
1,490 gaits. This trains the default generator (params.yaml ``train``, the ``full`` variant) with the train
split's gaits of one content (default ``walk-back``, labelled or not) repeated K times, and measures each checkpoint
as ``seed_contents.py`` does (every labelled train gait of each walking content continued 60 frames on a straight
line under its own emotion: facing against the direction of travel, net speed, travel against the path). K = 1 is
the default training; its checkpoint is the pipeline's own when it ran on this machine.

A probe for a later change, not a pipeline setting: each K is a training run (~5 min on 2 cores).
Printed as JSON and written to benchmarks/out/content_repeats.json (checkpoints under benchmarks/out/content_repeats/).
Run from the repository root after ``dvc repro``:  ``python benchmarks/content_repeats.py [--repeats 4 8]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.generators.autoregressive.fit import critic_config, split_tensors, variant_configs  # noqa: E402
from pipeline.generators.autoregressive.training import checkpoint_bytes, config_dicts, train_generator  # noqa: E402
from pipeline.io.files import write_bytes, write_json  # noqa: E402
from stages.common import SKELETON, load_params  # noqa: E402

from generator_data import GAITS, MODEL, split_gaits  # noqa: E402
from seed_contents import contents_kept  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "content_repeats.json"
CHECKPOINTS = REPO / "benchmarks" / "out" / "content_repeats"


def train_with_repeats(content: str, repeats: int) -> Path:
    """The default generator trained with the train split's gaits of ``content`` repeated ``repeats`` times."""
    params = load_params()
    model_cfg, cfg, weights = variant_configs(params["train"])["full"]
    skeleton = load_skeleton(SKELETON)
    train, val = split_tensors(GAITS, skeleton, cfg.mirror)
    _, split, contents, _ = split_gaits()
    rows = np.flatnonzero(contents[split == "train"] == content)
    order = np.concatenate([np.arange(len(train)), np.repeat(rows, repeats - 1)])
    print(f"content_repeats: {content} x{repeats}: {len(rows)} of {len(train)} train gaits", flush=True)
    def progress(row: dict) -> None:
        if row["epoch"] % 50 == 0:
            print(f"content_repeats: x{repeats} epoch {row['epoch']}/{cfg.epochs}", flush=True)

    result = train_generator(train.select(torch.from_numpy(order)), val, torch.from_numpy(skeleton.offsets).float(),
                             skeleton.parents, model_cfg, cfg, weights, progress, critic_config(params["train"]))
    extra = {"variant": f"full, {content} x{repeats}", "configs": config_dicts(model_cfg, cfg, weights)}
    path = CHECKPOINTS / f"{content}_x{repeats}.pt"
    write_bytes(checkpoint_bytes(result.model, extra), path)
    return path


def summary(figures: dict) -> dict:
    """Per content: seeds, and facing vs travel / net speed of the real windows, the published placement and the
    stance-foot placement (with its travel vs path over the first and last ten frames)."""
    return {name: {"seeds": e["seeds"], "real": e["real_window"], "published": e["published"],
                   "stance_foot": e["stance_foot"]} for name, e in figures["by_content"].items()}


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--content", default="walk-back")
    parser.add_argument("--repeats", type=int, nargs="+", default=[4, 8])
    args = parser.parse_args()
    out = {"content": args.content, "by_repeats": {}}
    for repeats in [1, *(k for k in args.repeats if k > 1)]:
        path = MODEL if repeats == 1 else train_with_repeats(args.content, repeats)
        figures = contents_kept(path, verbose=False)
        out["by_repeats"][str(repeats)] = {"checkpoint_sha256": figures["checkpoint_sha256"], **summary(figures)}
        print(f"x{repeats}: {json.dumps(out['by_repeats'][str(repeats)][args.content])}", flush=True)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
