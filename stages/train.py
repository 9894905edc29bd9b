"""DVC stage `train`: the generator and its two ablations, trained on the train split, checked on val.

data/split/gaits.parquet -> data/models/{full,no_affect,no_root}.pt, reports/train.json (DVC metrics: final
losses, checkpoint sha256, seconds), reports/train_curves.csv (DVC plots: loss per epoch and variant).
The variants (params.yaml ``train.variants``) train in parallel processes, ``train.threads`` torch threads each;
each is seeded and deterministic, so a rerun gives the same checkpoint bytes on the same machine.
"""

from __future__ import annotations

import csv
import io
import multiprocessing
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.io.gait_table import atomic_path, read_gaits, write_json_atomic
from pipeline.generators.autoregressive.network import GeneratorConfig, LossWeights
from pipeline.core.skeleton import load_skeleton
from pipeline.generators.autoregressive.training import (
    GaitTensors,
    TrainConfig,
    checkpoint_bytes,
    config_dicts,
    train_generator,
    write_checkpoint,
)
from stages.common import REPO, SKELETON, load_params

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
OUT_MODELS = REPO / "data" / "models"
OUT_REPORT = REPO / "reports" / "train.json"
OUT_CURVES = REPO / "reports" / "train_curves.csv"


def variant_configs(params: dict[str, Any]) -> dict[str, tuple[GeneratorConfig, TrainConfig, LossWeights]]:
    p = params["train"]
    base_model = dict(p.get("model") or {})
    base_loss = {k: float(v) for k, v in (p.get("loss") or {}).items()}
    train = TrainConfig(**{k: v for k, v in p.items() if k in TrainConfig.__dataclass_fields__})
    out = {}
    for name, change in (p.get("variants") or {"full": {}}).items():
        change = change or {}
        model = GeneratorConfig.from_dict({**base_model, **(change.get("model") or {})})
        loss = LossWeights(**{**base_loss, **{k: float(v) for k, v in (change.get("loss") or {}).items()}})
        out[name] = (model, train, loss)
    return out


def split_tensors(path: Path) -> tuple[GaitTensors, GaitTensors]:
    table, arrays = read_gaits(path)
    split = np.array(table.column("split").to_pylist())
    return (GaitTensors.from_arrays(arrays, np.flatnonzero(split == "train")),
            GaitTensors.from_arrays(arrays, np.flatnonzero(split == "val")))


def _train_variant(job: tuple) -> dict[str, Any]:
    """One variant, in its own process: returns the history and the checkpoint's bytes."""
    name, model_cfg, cfg, weights, in_gaits, every = job
    skeleton = load_skeleton(SKELETON)
    train, val = split_tensors(in_gaits)
    offsets = torch.from_numpy(skeleton.offsets).to(torch.float32)
    start = time.perf_counter()

    def progress(row: dict) -> None:
        if row["epoch"] % every == 0 or row["epoch"] == cfg.epochs:
            val_total = row.get("val_total")
            print(f"train[{name}]: epoch {row['epoch']}/{cfg.epochs}, teacher forcing {row['teacher_forcing']:.3f}, "
                  f"loss {row['train_total']:.3f}" + (f", val {val_total:.3f}" if val_total is not None else "")
                  + f" ({time.perf_counter() - start:.0f} s)", flush=True)

    result = train_generator(train, val, offsets, skeleton.parents, model_cfg, cfg, weights, progress)
    extra = {"variant": name, "configs": config_dicts(model_cfg, cfg, weights), "epochs": cfg.epochs,
             "train_gaits": len(train), "val_gaits": len(val)}
    return {"name": name, "history": result.history, "seconds": time.perf_counter() - start,
            "checkpoint": checkpoint_bytes(result.model, extra)}


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_models: Path = OUT_MODELS,
         out_report: Path = OUT_REPORT, out_curves: Path = OUT_CURVES) -> dict:
    params = load_params(params_path) if params_path else load_params()
    variants = variant_configs(params)
    every = max(1, int(params["train"].get("progress_every", 25)))
    jobs = [(name, m, t, w, in_gaits, every) for name, (m, t, w) in variants.items()]
    workers = max(1, min(int(params["train"].get("parallel", 1)), len(jobs)))
    start = time.perf_counter()
    if workers == 1:
        results = [_train_variant(job) for job in jobs]
    else:
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            results = pool.map(_train_variant, jobs)
    report: dict[str, Any] = {"seconds": round(time.perf_counter() - start, 1), "variants": {}}
    rows = []
    for res in results:
        path = out_models / f"{res['name']}.pt"
        sha = write_checkpoint(res["checkpoint"], path)
        final = res["history"][-1]
        report["variants"][res["name"]] = {
            "checkpoint": str(path.relative_to(REPO) if path.is_relative_to(REPO) else path), "sha256": sha,
            "seconds": round(res["seconds"], 1), "epochs": final["epoch"],
            "final_teacher_forcing": final["teacher_forcing"],
            "train": {k[6:]: round(v, 5) for k, v in final.items() if k.startswith("train_")},
            "val": {k[4:]: round(v, 5) for k, v in final.items() if k.startswith("val_")},
        }
        for row in res["history"]:
            rows.append({"variant": res["name"], "epoch": row["epoch"], "teacher_forcing": row["teacher_forcing"],
                         "train_total": round(row["train_total"], 6),
                         "val_total": round(row["val_total"], 6) if "val_total" in row else ""})
    report["configs"] = {name: config_dicts(*variants[name]) for name in variants}
    write_json_atomic(report, out_report)
    _write_curves(rows, out_curves)
    for name, v in report["variants"].items():
        print(f"train: {name}: val loss {v['val'].get('total', float('nan')):.3f} after {v['epochs']} epochs "
              f"({v['seconds']:.0f} s), sha256 {v['sha256'][:12]}")
    return report


def _write_curves(rows: list[dict], path: Path) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=["variant", "epoch", "teacher_forcing", "train_total", "val_total"],
                            lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(path) as tmp:
        tmp.write_text(buffer.getvalue())


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
