"""Fitting the autoregressive family: the generator and its ablations (``variants``), trained side by side in
parallel processes on the train split and checked on val, each seeded and deterministic (a rerun gives the same
checkpoint bytes on the same machine). Takes the split gait table's path and plain configs; returns what the
stage writes (checkpoint bytes, histories, report rows).
"""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.core.skeleton import Skeleton
from pipeline.generators.autoregressive.critic import CriticConfig
from pipeline.generators.autoregressive.network import GeneratorConfig, LossWeights
from pipeline.generators.autoregressive.training import (
    GaitTensors,
    TrainConfig,
    checkpoint_bytes,
    config_dicts,
    train_generator,
)
from pipeline.io.gait_table import read_gaits
from pipeline.ops.mirror import mirror_gait

Variants = dict[str, tuple[GeneratorConfig, TrainConfig, LossWeights]]


def critic_config(train: dict[str, Any]) -> CriticConfig:
    """The style critic's config from a ``train`` mapping's ``critic`` section (defaults where absent)."""
    return CriticConfig(**{k: v for k, v in (train.get("critic") or {}).items()})


def _loss_weights(loss: dict[str, Any] | None) -> dict[str, Any]:
    """A ``train.loss`` mapping as LossWeights fields: floats, and ``motion_joints`` as joint name -> float."""
    return {k: ({j: float(w) for j, w in v.items()} if k == "motion_joints" else float(v))
            for k, v in (loss or {}).items()}


def variant_configs(train: dict[str, Any]) -> Variants:
    """The configs of every variant from a ``train`` mapping: base ``model``/``loss`` with each variant's changes."""
    p = train
    base_model = dict(p.get("model") or {})
    base_loss = _loss_weights(p.get("loss"))
    train = TrainConfig(**{k: v for k, v in p.items() if k in TrainConfig.__dataclass_fields__})
    out = {}
    for name, change in (p.get("variants") or {"full": {}}).items():
        change = change or {}
        model = GeneratorConfig.from_dict({**base_model, **(change.get("model") or {})})
        loss = LossWeights(**{**base_loss, **_loss_weights(change.get("loss"))})
        out[name] = (model, train, loss)
    return out


MIRRORED = ("positions", "rotations", "heading", "phase", "phase_rate", "affective", "movement", "emotion")


def mirrored(arrays: dict[str, np.ndarray], rows: np.ndarray, skeleton: Skeleton) -> dict[str, np.ndarray]:
    """The mirror images (ops.mirror) of the gaits ``rows``: the arrays GaitTensors reads."""
    gait = mirror_gait({k: torch.from_numpy(np.ascontiguousarray(arrays[k][rows])) for k in MIRRORED}, skeleton)
    return {k: v.numpy() for k, v in gait.items()}


def split_tensors(path: Path, skeleton: Skeleton | None = None, mirror: bool = False
                  ) -> tuple[GaitTensors, GaitTensors]:
    """(train, val) gaits; with ``mirror``, the train gaits followed by their mirror images."""
    table, arrays = read_gaits(path)
    split = np.array(table.column("split").to_pylist())
    train = np.flatnonzero(split == "train")
    if mirror:
        if skeleton is None:
            raise ValueError("mirroring needs the skeleton")
        images = mirrored(arrays, train, skeleton)
        both = {k: np.concatenate([arrays[k][train], images[k]]) for k in MIRRORED}
        train_tensors = GaitTensors.from_arrays(both)
    else:
        train_tensors = GaitTensors.from_arrays(arrays, train)
    return train_tensors, GaitTensors.from_arrays(arrays, np.flatnonzero(split == "val"))


def _train_variant(job: tuple) -> dict[str, Any]:
    """One variant, in its own process: returns the history and the checkpoint's bytes."""
    name, model_cfg, cfg, weights, critic_cfg, in_gaits, skeleton, every = job
    train, val = split_tensors(in_gaits, skeleton, cfg.mirror)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    start = time.perf_counter()

    def progress(row: dict) -> None:
        if row["epoch"] % every == 0 or row["epoch"] == cfg.epochs:
            val_total = row.get("val_total")
            print(f"train[{name}]: epoch {row['epoch']}/{cfg.epochs}, teacher forcing {row['teacher_forcing']:.3f}, "
                  f"loss {row['train_total']:.3f}" + (f", val {val_total:.3f}" if val_total is not None else "")
                  + f" ({time.perf_counter() - start:.0f} s)", flush=True)

    result = train_generator(train, val, offsets, skeleton.parents, model_cfg, cfg, weights, progress, critic_cfg)
    extra = {"variant": name, "configs": config_dicts(model_cfg, cfg, weights), "epochs": cfg.epochs,
             "train_gaits": len(train), "val_gaits": len(val)}
    if result.critic is not None:
        extra["critic"] = {"config": critic_cfg.to_dict(), "figures": result.critic_figures,
                           "state_dict": {k: v.contiguous() for k, v in result.critic.state_dict().items()}}
    return {"name": name, "history": result.history, "seconds": time.perf_counter() - start,
            "critic": result.critic_figures, "checkpoint": checkpoint_bytes(result.model, extra)}


def fit_variants(in_gaits: Path, variants: Variants, skeleton: Skeleton, workers: int, progress_every: int,
                 critic: CriticConfig = CriticConfig()) -> list[dict[str, Any]]:
    """Train every variant (``workers`` processes at most); [{name, history, seconds, checkpoint (bytes)}]."""
    every = max(1, progress_every)
    jobs = [(name, m, t, w, critic, in_gaits, skeleton, every) for name, (m, t, w) in variants.items()]
    workers = max(1, min(workers, len(jobs)))
    if workers == 1:
        results = [_train_variant(job) for job in jobs]
    else:
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            results = pool.map(_train_variant, jobs)
    return results


def variant_summary(result: dict[str, Any]) -> dict[str, Any]:
    """A variant's report entry: epochs, the critic's figures, final teacher forcing and its final train/val losses.
    No seconds: the report holds only what the inputs determine, so a rerun gives the same bytes."""
    final = result["history"][-1]
    return {"epochs": final["epoch"], "critic": result.get("critic"),
            "final_teacher_forcing": final["teacher_forcing"],
            "train": {k[6:]: round(v, 5) for k, v in final.items() if k.startswith("train_")},
            "val": {k[4:]: round(v, 5) for k, v in final.items() if k.startswith("val_")}}


CURVE_COLUMNS = ("variant", "epoch", "teacher_forcing", "train_total", "val_total")


def curve_rows(results: list[dict[str, Any]]) -> list[tuple]:
    """Loss per epoch and variant (CURVE_COLUMNS), for the training-curves plot."""
    return [(res["name"], row["epoch"], row["teacher_forcing"], round(row["train_total"], 6),
             round(row["val_total"], 6) if "val_total" in row else "")
            for res in results for row in res["history"]]
