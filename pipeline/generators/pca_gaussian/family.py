"""The PCA + Gaussian model as a generator family (``pipeline.generators.base``): ``fit`` on the split gaits,
``generate`` for plan rows (each gait starts at its trajectory piece's start, facing along it; no seed gait)."""

from __future__ import annotations

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
from pipeline.generators.pca_gaussian.model import (ModelConfig, PCABasis, balanced_rows, components_for_emotions,
                                                    fit_basis, fit_style_models)
from pipeline.generators.pca_gaussian.synthesis import CycleModel, WalkSettings, walk
from pipeline.io.files import sha256_bytes

NAME = "pca_gaussian"


@dataclass
class Fit:
    """A fit: the synthesis model, the basis and the cycles it came from; ``emotion_feature_errors``: per number
    of components tried by the emotion-feature rule, each emotion's largest feature error (real SDs)."""

    model: CycleModel
    basis: PCABasis
    cycles: Cycles
    components: int
    emotion_feature_errors: dict[int, list[float]] = field(default_factory=dict)


def fit(table: pa.Table, arrays: dict[str, np.ndarray], skeleton: Skeleton, cycle_cfg: CycleConfig = CycleConfig(),
        cfg: ModelConfig = ModelConfig(), annotate: AnnotateConfig = AnnotateConfig()) -> Fit:
    """Cycles of the train walks, the style-balanced basis, the kept components (enough for ``cfg.variance`` and,
    where ``cfg.emotion_features_sd`` is set, for the emotions' affective features) and the four emotion models;
    the foot floor is the median over the train walks' frames of their lowest heel/toe point's height."""
    cycles = cut_cycles(table, arrays, skeleton, cycle_cfg, annotate)
    basis = fit_basis(cycles.flat(), balanced_rows(cycles.style, cfg.per_style, cfg.seed))
    k, tried = basis.components_for(cfg.variance), {}
    if cfg.emotion_features_sd > 0:
        k, tried = components_for_emotions(cycles.flat(), cycles.dominant(), basis, cfg.emotion_features_sd, k,
                                           skeleton.offsets, skeleton.parents, cycle_cfg.frames)
    models = fit_style_models(basis.scores(cycles.flat(), k), cycles.durations, cycles.dominant(), cycles.follows,
                              cfg.prior_cycles)
    split = np.array(table.column("split").to_pylist())
    content = np.array(table.column("content").to_pylist())
    walks = (split == cycle_cfg.split) & (content == cycle_cfg.content)
    floor = float(np.median(arrays["positions"][walks][:, :, list(FOOT_JOINTS), 1].min(-1)))
    model = CycleModel(mean=basis.mean, components=basis.components[:k], models=models, frames=cycle_cfg.frames,
                       joints=cycles.rotvec.shape[2], foot_floor_m=floor)
    return Fit(model=model, basis=basis, cycles=cycles, components=k, emotion_feature_errors=tried)


@dataclass
class PCAGaussianFamily:
    """A fitted PCA + Gaussian model, ready for plan rows; ``fields`` are the model file's other fields
    (``load_model``), its lineage."""

    model: CycleModel
    model_sha256: str
    skeleton: Skeleton
    placement: PlacementConfig
    settings: WalkSettings = WalkSettings()
    fields: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    name: str = NAME
    description: str = ("PCA + Gaussian walk cycles (Tilmanne & Dutoit 2010): two-step cycles of real train-split "
                        "walks in a PCA space, one Gaussian per emotion and component, drawn cycle after cycle and "
                        "steered along the trajectory; no seed gait")
    seeded: bool = False

    @classmethod
    def from_file(cls, path, skeleton: Skeleton, placement: PlacementConfig,
                  settings: WalkSettings = WalkSettings()) -> PCAGaussianFamily:
        model, fields, sha = load_model(path)
        return cls(model, sha, skeleton, placement, settings, fields)

    def lineage(self) -> dict[str, Any]:
        """The real cycles (clip @ first frame, 30 fps) whose statistics formed each emotion model."""
        from pipeline.core.emotions import EMOTIONS

        ids, dominant = self.fields.get("cycle_ids", []), self.fields.get("cycle_dominant", [])
        return {"model_sha256": self.model_sha256, "components": int(self.model.components.shape[0]),
                "cycles": len(ids),
                "cycles_per_emotion_model": {e: [c for c, d in zip(ids, dominant) if d == k]
                                             for k, e in enumerate(EMOTIONS)},
                "basis_cycles": "every cycle of every style (other styles, unlabelled walks included) may enter the "
                                "style-balanced basis; see the model file's cycle_ids"}

    def generate(self, rows: Sequence[dict[str, Any]], paths: torch.Tensor, emotions: torch.Tensor) -> GeneratedMotion:
        motion, counts = walk(self.model, rows, paths, emotions, torch.from_numpy(self.skeleton.offsets),
                              self.skeleton.parents, self.placement, self.settings)
        for k, v in counts.items():
            self.counts[k] = self.counts.get(k, 0) + v
        return motion


FORMAT = "emogait-pca-gaussian/1"


def model_bytes(f: Fit, cycle_cfg: CycleConfig, cfg: ModelConfig) -> bytes:
    """The fitted model as bytes (torch's zip format, deterministic for the same numbers): the basis mean and kept
    components, the four emotion models, the settings, and the cycles it was fitted on (clip @ first frame, with
    their dominant emotion index or -1): the family's lineage."""
    import dataclasses
    import io

    from pipeline.core.emotions import EMOTIONS

    models = f.model.models
    blob = {"format": FORMAT, "cycles_config": dataclasses.asdict(cycle_cfg), "model_config": dataclasses.asdict(cfg),
            "emotions": list(EMOTIONS), "mean": torch.from_numpy(f.model.mean),
            "components": torch.from_numpy(np.ascontiguousarray(f.model.components)),
            "score_mean": torch.from_numpy(np.stack([m.mean for m in models])),
            "score_std": torch.from_numpy(np.stack([m.std for m in models])),
            "score_max_change": torch.from_numpy(np.stack([m.max_change for m in models])),
            "duration": torch.tensor([[m.duration_mean, m.duration_std, m.duration_max_change] for m in models],
                                     dtype=torch.float64),
            "model_cycles": [int(m.cycles) for m in models], "frames": int(f.model.frames),
            "joints": int(f.model.joints), "foot_floor_m": float(f.model.foot_floor_m),
            "cycle_ids": [f"{c}@{int(s)}" for c, s in zip(f.cycles.clip_id, f.cycles.start_frame)],
            "cycle_dominant": [int(d) for d in f.cycles.dominant()]}
    buffer = io.BytesIO()
    torch.save(blob, buffer)
    return buffer.getvalue()


def load_model(path) -> tuple[CycleModel, dict[str, Any], str]:
    """(the synthesis model, the file's other fields, sha256 of the file) of ``model_bytes`` written to ``path``."""
    import io
    from pathlib import Path

    from pipeline.generators.pca_gaussian.model import StyleModel

    data = Path(path).read_bytes()
    blob = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    if blob.get("format") != FORMAT:
        raise ValueError(f"{path}: expected a {FORMAT} model, found {blob.get('format')!r}")
    models = [StyleModel(mean=blob["score_mean"][k].numpy(), std=blob["score_std"][k].numpy(),
                         max_change=blob["score_max_change"][k].numpy(), duration_mean=float(blob["duration"][k, 0]),
                         duration_std=float(blob["duration"][k, 1]), duration_max_change=float(blob["duration"][k, 2]),
                         cycles=int(blob["model_cycles"][k])) for k in range(len(blob["emotions"]))]
    model = CycleModel(mean=blob["mean"].numpy(), components=blob["components"].numpy(), models=models,
                       frames=int(blob["frames"]), joints=int(blob["joints"]), foot_floor_m=float(blob["foot_floor_m"]))
    return model, {k: v for k, v in blob.items() if k not in ("mean", "components")}, sha256_bytes(data)
