"""What the generator benchmarks read after ``dvc repro`` (guidance_rule.py, stride.py, seed_contents.py): the split
gaits with their split, content and dominant emotion, the trained network with the skeleton's offsets, and the
placement without what is laid over the legs' own walk."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.emotions import dominant_index  # noqa: E402
from pipeline.core.skeleton import Skeleton, load_skeleton  # noqa: E402
from pipeline.generators.autoregressive.network import EmotiveGaitNet  # noqa: E402
from pipeline.generators.autoregressive.rollout import PlacementConfig  # noqa: E402
from pipeline.generators.autoregressive.training import load_checkpoint  # noqa: E402
from pipeline.io.gait_table import read_gaits  # noqa: E402
from stages.common import SKELETON  # noqa: E402
from stages.configs import placement_config  # noqa: E402

GAITS = REPO / "data" / "split" / "gaits.parquet"
MODEL = REPO / "data" / "models" / "full.pt"


def split_gaits(path: Path = GAITS) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """(arrays, split (N,), content (N,), dominant emotion index (N,), -1 where unlabelled)."""
    table, arrays = read_gaits(path)
    return (arrays, np.array(table.column("split").to_pylist()), np.array(table.column("content").to_pylist()),
            dominant_index(arrays["emotion"]))


def generator(path: Path = MODEL) -> tuple[EmotiveGaitNet, str, Skeleton, torch.Tensor]:
    """(the network in eval mode, its checkpoint's sha256, the skeleton, its offsets as float32)."""
    model, _, sha = load_checkpoint(path)
    skeleton = load_skeleton(SKELETON)
    return model, sha, skeleton, torch.from_numpy(skeleton.offsets).to(torch.float32)


def legs_placement(params: dict[str, Any]) -> PlacementConfig:
    """The synthesis placement (params ``generate``) without root smoothing, path fit or foot locking: where the
    generated legs alone carry the root."""
    return replace(placement_config(params), root_smoothing_s=0.0, path_fit_s=0.0, foot_lock=False)
