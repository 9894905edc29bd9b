"""The affect-based autoregressive network (paper §4) as a generator family (``pipeline.generators.base``): each
plan row's gait continues the first ``prefix`` frames of a real seed gait along its trajectory piece, which is
placed at the seed's last root position and direction of travel."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.core.skeleton import Skeleton
from pipeline.generators.autoregressive.network import EmotiveGaitNet
from pipeline.generators.autoregressive.rollout import PlacementConfig, Seeds, generate, place_paths
from pipeline.generators.autoregressive.training import load_checkpoint
from pipeline.generators.base import GeneratedMotion

NAME = "autoregressive_affect"


class AutoregressiveFamily:
    """A trained network with the real gaits its seeds come from (``arrays``; rows by ``gait_id`` in ``row_of``)."""

    name = NAME
    description = ("affect-based autoregressive network (Bhattacharya et al. 2020): each gait continues the first "
                   "frames of a real labelled walk, conditioned per frame on its emotion, along its trajectory")
    seeded = True

    def __init__(self, model: EmotiveGaitNet, model_sha256: str, arrays: dict[str, np.ndarray],
                 row_of: dict[str, int], skeleton: Skeleton, placement: PlacementConfig, prefix: int):
        self.model, self.model_sha256 = model, model_sha256
        self.arrays, self.row_of, self.skeleton = arrays, row_of, skeleton
        self.placement, self.prefix = placement, prefix
        self.offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)

    @classmethod
    def from_checkpoint(cls, path: Path, arrays: dict[str, np.ndarray], row_of: dict[str, int], skeleton: Skeleton,
                        placement: PlacementConfig, prefix: int) -> AutoregressiveFamily:
        model, _, sha = load_checkpoint(path)
        return cls(model, sha, arrays, row_of, skeleton, placement, prefix)

    def lineage(self) -> dict[str, Any]:
        return {"checkpoint_sha256": self.model_sha256, "prefix_frames": self.prefix,
                "seeds": "the first prefix frames of each gait's seed_gait_id (a labelled real train-split walk); "
                         "not published as synthetic frames"}

    def generate(self, rows: Sequence[dict[str, Any]], paths: torch.Tensor, emotions: torch.Tensor) -> GeneratedMotion:
        seed_rows = np.array([self.row_of[r["seed_gait_id"]] for r in rows])
        seeds = Seeds.from_arrays(self.arrays, seed_rows, self.prefix)
        placed = place_paths(paths, seeds)
        g = generate(self.model, seeds, placed, emotions, self.offsets, self.skeleton.parents, self.placement)
        return GeneratedMotion(g.positions, g.rotations, g.heading,
                               context_positions=torch.from_numpy(self.arrays["positions"][seed_rows, :self.prefix]),
                               conditioned_phase=g.theta, placed_paths=placed)
