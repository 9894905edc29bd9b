"""The gait table: one row per 60-frame window, stored as Parquet with fixed-size list columns.

Array columns are flattened row-major into ``fixed_size_list<float32>``; their shapes, the joint names,
parents, rest offsets, the emotion order and units are in the schema metadata (key ``emogait``, read and written
by ``pipeline.io.files``), so a reader needs nothing but the file.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.emotions import EMOTIONS
from pipeline.core.schema import INGESTED, columns, units
from pipeline.core.skeleton import Skeleton
from pipeline.io.files import read_meta, schema_meta, with_schema_meta


def array_shapes(window: int, joints: int) -> dict[str, tuple[int, ...]]:
    """Per-gait shapes of the ingested table's array columns."""
    return {c.name: c.gait_shape(window, joints) for c in columns(INGESTED) if c.is_array}


def array_column(values: np.ndarray, null_rows: np.ndarray | None = None) -> pa.FixedSizeListArray:
    """(rows, *shape) numbers -> a fixed_size_list<float32> column (row-major), rows masked null if given."""
    rows = values.shape[0]
    size = int(np.prod(values.shape[1:]))
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).reshape(-1), type=pa.float32())
    mask = None if null_rows is None or not null_rows.any() else pa.array(null_rows)
    return pa.FixedSizeListArray.from_arrays(flat, size, mask=mask) if rows else pa.array([], pa.list_(pa.float32(), size))


def with_arrays(table: pa.Table, arrays: dict[str, np.ndarray], meta_update: dict[str, Any]) -> pa.Table:
    """Add (or replace) array columns and merge their shapes and any other keys into the schema metadata."""
    meta = schema_meta(table.schema)
    for name, values in arrays.items():
        column = array_column(values)
        if name in table.column_names:
            table = table.set_column(table.column_names.index(name), name, column)
        else:
            table = table.append_column(name, column)
        meta.setdefault("shapes", {})[name] = list(values.shape[1:])
    for key, value in meta_update.items():
        if isinstance(value, dict) and isinstance(meta.get(key), dict):
            meta[key] = {**meta[key], **value}
        else:
            meta[key] = value
    return with_schema_meta(table, meta)


def to_table(windows: Sequence[dict[str, Any]], skeleton: Skeleton, window: int) -> pa.Table:
    shapes = array_shapes(window, skeleton.joint_count)
    arrays: dict[str, pa.Array] = {}
    for c in columns(INGESTED):
        if not c.is_array:
            arrays[c.name] = pa.array([w[c.name] for w in windows], type=c.arrow_type)
    for name, shape in shapes.items():
        values = np.zeros((len(windows), *shape), dtype=np.float32)
        null_rows = np.array([w[name] is None for w in windows], dtype=bool)
        for i, w in enumerate(windows):
            if w[name] is not None:
                values[i] = w[name]
        arrays[name] = array_column(values, null_rows)
    meta = {
        "shapes": {k: list(v) for k, v in shapes.items()},
        "joint_names": list(skeleton.names),
        "parents": list(skeleton.parents),
        "rest_offsets_m": skeleton.offsets.round(6).tolist(),
        "emotion_order": list(EMOTIONS),
        "units": units(INGESTED),
        "axes": "right-handed, Y up, +Z forward at rest, the body's left on +X",
        "rotations": "per-bone local unit quaternions [w, x, y, z]; FK: G_j = G_parent q_j, X_j = X_parent + G_j o_j",
    }
    table = pa.table({name: arrays[name] for name in INGESTED})
    return with_schema_meta(table, meta)


def column_array(table: pa.Table, name: str, shape: Sequence[int]) -> np.ndarray:
    """A fixed-size list column as a (rows, *shape) float32 array; null rows come back as NaN."""
    col = table.column(name).combine_chunks()
    size = int(np.prod(shape))
    # .values keeps the slots of null rows (flatten() would drop them and misalign the rest)
    flat = col.values.slice(col.offset * size, len(col) * size).to_numpy(zero_copy_only=False).reshape(len(col), size)
    out = flat.astype(np.float32, copy=True)
    if col.null_count:
        out[~np.asarray(col.is_valid())] = np.nan
    return out.reshape((len(col), *shape))


def read_gaits(path: str | Path, columns: Sequence[str] | None = None) -> tuple[pa.Table, dict[str, np.ndarray]]:
    """The table and its array columns as numpy arrays with their recorded shapes."""
    meta = read_meta(path)
    table = pq.read_table(path, columns=list(columns) if columns else None)
    arrays = {
        name: column_array(table, name, shape)
        for name, shape in meta["shapes"].items()
        if name in table.column_names
    }
    return table, arrays
