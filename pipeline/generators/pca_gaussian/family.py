"""The PCA + Gaussian model as a generator family (``pipeline.generators.base``): ``fit`` on the split gaits,
``generate`` for plan rows (each gait starts at its trajectory piece's start, facing along it; no seed gait)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa
import torch

from pipeline.annotate.annotation import AnnotateConfig
from pipeline.core.skeleton import Skeleton
from pipeline.generators.autoregressive.network import FOOT_JOINTS
from pipeline.generators.autoregressive.rollout import PlacementConfig
from pipeline.generators.base import GeneratedMotion
from pipeline.generators.pca_gaussian.cycles import CycleConfig, Cycles, cut_cycles
from pipeline.generators.pca_gaussian.model import ModelConfig, PCABasis, balanced_rows, fit_basis, fit_style_models
from pipeline.generators.pca_gaussian.synthesis import CycleModel, WalkSettings, walk

NAME = "pca_gaussian"


@dataclass
class Fit:
    """A fit: the synthesis model, the basis and the cycles it came from."""

    model: CycleModel
    basis: PCABasis
    cycles: Cycles
    components: int


def fit(table: pa.Table, arrays: dict[str, np.ndarray], skeleton: Skeleton, cycle_cfg: CycleConfig = CycleConfig(),
        cfg: ModelConfig = ModelConfig(), annotate: AnnotateConfig = AnnotateConfig()) -> Fit:
    """Cycles of the train walks, the style-balanced basis, the kept components and the four emotion models; the
    foot floor is the median over the train walks' frames of their lowest heel/toe point's height."""
    cycles = cut_cycles(table, arrays, skeleton, cycle_cfg, annotate)
    basis = fit_basis(cycles.flat(), balanced_rows(cycles.style, cfg.per_style, cfg.seed))
    k = basis.components_for(cfg.variance)
    models = fit_style_models(basis.scores(cycles.flat(), k), cycles.durations, cycles.dominant(), cycles.follows,
                              cfg.prior_cycles)
    split = np.array(table.column("split").to_pylist())
    content = np.array(table.column("content").to_pylist())
    walks = (split == cycle_cfg.split) & (content == cycle_cfg.content)
    floor = float(np.median(arrays["positions"][walks][:, :, list(FOOT_JOINTS), 1].min(-1)))
    model = CycleModel(mean=basis.mean, components=basis.components[:k], models=models, frames=cycle_cfg.frames,
                       joints=cycles.rotvec.shape[2], foot_floor_m=floor)
    return Fit(model=model, basis=basis, cycles=cycles, components=k)


@dataclass
class PCAGaussianFamily:
    """A fitted PCA + Gaussian model, ready for plan rows."""

    model: CycleModel
    model_sha256: str
    skeleton: Skeleton
    placement: PlacementConfig
    settings: WalkSettings = WalkSettings()
    counts: dict[str, int] = field(default_factory=dict)
    name: str = NAME

    def generate(self, rows: Sequence[dict[str, Any]], paths: torch.Tensor, emotions: torch.Tensor) -> GeneratedMotion:
        motion, counts = walk(self.model, rows, paths, emotions, torch.from_numpy(self.skeleton.offsets),
                              self.skeleton.parents, self.placement, self.settings)
        for k, v in counts.items():
            self.counts[k] = self.counts.get(k, 0) + v
        return motion


def model_digest(model: CycleModel) -> str:
    """sha256 of the model's numbers (until the fit stage writes the model file and its digest is the file's)."""
    h = hashlib.sha256()
    for a in (model.mean, model.components, *[np.concatenate([m.mean, m.std, m.max_change,
                                                              [m.duration_mean, m.duration_std, m.duration_max_change]])
                                                for m in model.models]):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()
