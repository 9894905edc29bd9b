"""The published gait table: real annotated gaits and synthetic gaits in one schema, with lineage.

Columns, one row per gait:
    gait_id, kind ("real" | "synthetic"), split (train/val/test; "synthetic"), source, content, label_method;
    emotion (4; the gait's label: a real gait's annotated vector, null when unlabelled; a synthetic gait's mean
    per-frame condition), emotion_per_frame (T x 4); positions, rotations, root_path, heading, contacts, phase,
    phase_rate, affective, movement (as in the annotated table);
    lineage of real gaits: source_file, source_sha256, t_start, t_end (seconds in the source clip);
    lineage of synthetic gaits: generator (the family), checkpoint_sha256 (its model file), seed_gait_id (seeded
    families), trajectory_id, trajectory_family, emotion_recipe (JSON), plan_seed, source_segments (families that
    re-sequence real frames).

Every family generates the same plan rows; the named dataset's family (``publish.named_family``) keeps the plan's
gait ids, another family's ids carry its name (``family_gait_id``) so that ids stay unique side by side.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np
import pyarrow as pa

from pipeline.core.emotions import GENERATOR_LABEL_METHOD
from pipeline.core.schema import PUBLISHED, columns, descriptions, units
from pipeline.io.files import schema_meta, with_schema_meta
from pipeline.io.gait_table import array_column

ARRAYS = tuple(c.name for c in columns(PUBLISHED) if c.is_array)


def _columns(n: int, scalars: dict[str, Sequence[Any]], arrays: dict[str, np.ndarray],
             null_arrays: dict[str, np.ndarray]) -> dict[str, pa.Array]:
    out: dict[str, pa.Array] = {}
    for c in columns(PUBLISHED):
        if c.is_array:
            out[c.name] = array_column(arrays[c.name], null_arrays.get(c.name))
        else:
            out[c.name] = pa.array(scalars.get(c.name, [None] * n), c.arrow_type)
    return out


def _meta(base: dict[str, Any], arrays: dict[str, np.ndarray], annotated: pa.Table) -> dict[str, Any]:
    """The published metadata: the annotated table's, the shapes of the published arrays, and the frame rate
    every gait shares (the annotated table's ``fps`` column)."""
    rates = set(annotated.column("fps").to_pylist())
    if len(rates) != 1:
        raise ValueError(f"expected one frame rate for all gaits, found {sorted(rates)}")
    meta = {**base, "fps": rates.pop()}
    meta["shapes"] = {name: list(arrays[name].shape[1:]) for name in ARRAYS}
    meta["units"] = {**base.get("units", {}), **units(("emotion_per_frame",))}
    return meta


def family_gait_id(plan_gait_id: str, generator: str, named_family: str) -> str:
    """A plan row's gait id in ``generator``'s table: the plan's own for the named dataset's family,
    ``syn-<generator>-...`` for another (the plan's ids start ``syn-``)."""
    if generator == named_family:
        return plan_gait_id
    return f"syn-{generator}-{plan_gait_id.removeprefix('syn-')}"


def synthetic_table(plan: Sequence[dict[str, Any]], recipes: Sequence[str], arrays: dict[str, np.ndarray],
                    generator: dict[str, Any], real: pa.Table, named_family: str) -> pa.Table:
    """One family's synthetic gaits in the published schema; ``real`` lends its schema metadata (skeleton, names).

    generator: the family's entry of the metadata's ``generators`` (``generator_entry``): its name, model sha256
    and whether its gaits are seeded (then each row's ``seed_gait_id`` is kept)."""
    n = len(plan)
    name = generator["name"]
    scalars = {"gait_id": [family_gait_id(r["gait_id"], name, named_family) for r in plan],
               "kind": ["synthetic"] * n, "generator": [name] * n, "split": ["synthetic"] * n,
               "source": ["generator"] * n, "content": ["walk"] * n, "label_method": [GENERATOR_LABEL_METHOD] * n,
               "checkpoint_sha256": [generator["model_sha256"]] * n,
               "seed_gait_id": [r.get("seed_gait_id") if generator["seeded"] else None for r in plan],
               "trajectory_id": [r["trajectory_id"] for r in plan],
               "trajectory_family": [r["trajectory_family"] for r in plan], "emotion_recipe": list(recipes),
               "plan_seed": [int(r["plan_seed"]) for r in plan]}
    if "source_segments" in generator["lineage"]:
        scalars["source_segments"] = [str(s) for s in arrays["source_segments"]]
    table = pa.table(_columns(n, scalars, arrays, {}))
    meta = _meta(schema_meta(real.schema), arrays, real)
    meta["generators"] = {name: generator}
    return with_schema_meta(table, meta)


def generator_entry(name: str, description: str, model_sha256: str, seeded: bool,
                    extra_lineage: Sequence[str] = ()) -> dict[str, Any]:
    """A family's entry of the published metadata's ``generators``, and the synthetic lineage its gaits must
    carry (the audit checks it: a seeded family's gaits name their seed; a family that re-sequences real motion
    names the real frames, ``extra_lineage``)."""
    lineage = ["generator", "checkpoint_sha256", *(["seed_gait_id"] if seeded else []), "trajectory_id",
               "emotion_recipe", "plan_seed", *extra_lineage]
    return {"name": name, "description": description, "model_sha256": model_sha256, "seeded": bool(seeded),
            "lineage": lineage}


def real_table(table: pa.Table, arrays: dict[str, np.ndarray]) -> pa.Table:
    """The annotated real gaits (all splits) in the published schema."""
    n = table.num_rows
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    window = arrays["positions"].shape[1]
    per_frame = np.repeat(np.nan_to_num(arrays["emotion"])[:, None], window, axis=1)
    arrays = {**arrays, "emotion_per_frame": per_frame}
    scalars = {name: table.column(name).to_pylist() for name in ("gait_id", "split", "source", "content",
                                                                   "label_method", "t_start", "t_end")}
    scalars.update(kind=["real"] * n, source_file=table.column("file").to_pylist(),
                   source_sha256=table.column("sha256").to_pylist())
    out = pa.table(_columns(n, scalars, arrays, {"emotion": ~labelled, "emotion_per_frame": ~labelled}))
    return with_schema_meta(out, _meta(schema_meta(table.schema), arrays, table))


def published_parts(real: pa.Table, families: Sequence[pa.Table]) -> list[tuple[str, pa.Table]]:
    """("real", real gaits), then (family name, its gaits) in the given order, all with one schema metadata: the
    families' (which adds nothing real lacks) with every family in ``generators``, in order."""
    if not families:
        raise ValueError("expected at least one generator family's synthetic table, found none")
    generators: dict[str, Any] = {}
    for table in families:
        generators.update(schema_meta(table.schema)["generators"])
    meta = {**schema_meta(families[0].schema), "generators": generators}
    meta["kinds"] = {"real": "annotated motion capture",
                     "synthetic": "generated by one of the generator families in 'generators' (column generator)"}
    parts = [("real", real), *((next(iter(schema_meta(t.schema)["generators"])), t) for t in families)]
    return [(name, with_schema_meta(t.combine_chunks(), meta)) for name, t in parts]



COLUMN_DESCRIPTIONS = descriptions(PUBLISHED)


def composition(table: pa.Table) -> dict[str, Any]:
    """Gait counts: all, per kind, per kind and split, real per source, synthetic per generator and per trajectory
    family."""
    kind, split, source, family, generator = (table.column(c).to_pylist() for c in (
        "kind", "split", "source", "trajectory_family", "generator"))

    def count(values) -> dict[str, int]:
        return dict(sorted(Counter(values).items()))

    return {"gaits": table.num_rows, "real": kind.count("real"), "synthetic": kind.count("synthetic"),
            "by_kind_split": count(f"{k} / {sp}" for k, sp in zip(kind, split)),
            "real_by_source": count(sr for k, sr in zip(kind, source) if k == "real"),
            "synthetic_by_generator": count(g for k, g in zip(kind, generator) if k == "synthetic"),
            "synthetic_by_family": count(f for k, f in zip(kind, family) if k == "synthetic")}
