"""The gait table: one row per 60-frame window, stored as Parquet with fixed-size list columns.

Array columns are flattened row-major into ``fixed_size_list<float32>``; their shapes, the joint names,
parents, rest offsets, the emotion order and units are in the schema metadata (key ``emogait``), so a
reader needs nothing but the file. Writes are atomic (temporary file + rename) and deterministic.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.skeleton import Skeleton

EMOTIONS = ("happy", "sad", "angry", "neutral")

SCALAR_COLUMNS: dict[str, pa.DataType] = {
    "gait_id": pa.string(),
    "clip_id": pa.string(),
    "source": pa.string(),
    "file": pa.string(),
    "sha256": pa.string(),
    "t_start": pa.float64(),
    "t_end": pa.float64(),
    "source_fps": pa.float64(),
    "fps": pa.float64(),
    "scale": pa.float64(),
    "source_leg_m": pa.float64(),
    "content": pa.string(),
    "style": pa.string(),
    "label_method": pa.string(),
}


def array_shapes(window: int, joints: int) -> dict[str, tuple[int, ...]]:
    return {
        "emotion": (len(EMOTIONS),),
        "positions": (window, joints, 3),
        "rotations": (window, joints, 4),
        "root_path": (window, 2),
        "heading": (window,),
    }


def array_column(values: np.ndarray, null_rows: np.ndarray | None = None) -> pa.FixedSizeListArray:
    """(rows, *shape) numbers -> a fixed_size_list<float32> column (row-major), rows masked null if given."""
    rows = values.shape[0]
    size = int(np.prod(values.shape[1:]))
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).reshape(-1), type=pa.float32())
    mask = None if null_rows is None or not null_rows.any() else pa.array(null_rows)
    return pa.FixedSizeListArray.from_arrays(flat, size, mask=mask) if rows else pa.array([], pa.list_(pa.float32(), size))


def with_arrays(table: pa.Table, arrays: dict[str, np.ndarray], meta_update: dict[str, Any]) -> pa.Table:
    """Add (or replace) array columns and merge their shapes and any other keys into the schema metadata."""
    meta = json.loads(table.schema.metadata[b"emogait"]) if table.schema.metadata else {}
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
    return table.replace_schema_metadata({b"emogait": json.dumps(meta, sort_keys=True).encode()})


def to_table(windows: Sequence[dict[str, Any]], skeleton: Skeleton, window: int) -> pa.Table:
    shapes = array_shapes(window, skeleton.joint_count)
    columns: dict[str, pa.Array] = {}
    for name, dtype in SCALAR_COLUMNS.items():
        columns[name] = pa.array([w[name] for w in windows], type=dtype)
    for name, shape in shapes.items():
        values = np.zeros((len(windows), *shape), dtype=np.float32)
        null_rows = np.array([w[name] is None for w in windows], dtype=bool)
        for i, w in enumerate(windows):
            if w[name] is not None:
                values[i] = w[name]
        columns[name] = array_column(values, null_rows)
    meta = {
        "shapes": {k: list(v) for k, v in shapes.items()},
        "joint_names": list(skeleton.names),
        "parents": list(skeleton.parents),
        "rest_offsets_m": skeleton.offsets.round(6).tolist(),
        "emotion_order": list(EMOTIONS),
        "units": {"positions": "m", "root_path": "m", "heading": "rad", "t_start": "s", "t_end": "s"},
        "axes": "right-handed, Y up, +Z forward at rest, the body's left on +X",
        "rotations": "per-bone local unit quaternions [w, x, y, z]; FK: G_j = G_parent q_j, X_j = X_parent + G_j o_j",
    }
    table = pa.table(columns)
    return table.replace_schema_metadata({b"emogait": json.dumps(meta, sort_keys=True).encode()})


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed onto it when the block succeeds (removed when it fails), so a
    reader never sees half a file. Every output of the pipeline is written through this."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; outputs are for everyone to read
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_parquet_atomic(table: pa.Table, path: str | Path) -> None:
    """Write deterministically (no timestamps; fixed row groups) and atomically."""
    with atomic_path(Path(path)) as tmp:
        pq.write_table(table, tmp, compression="zstd", row_group_size=512, write_statistics=True)


def write_json_atomic(obj: Any, path: str | Path) -> None:
    """Sorted keys, strict JSON (a NaN is an error: write None), atomic."""
    text = json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"
    with atomic_path(Path(path)) as tmp:
        tmp.write_text(text)


def read_metadata(path: str | Path) -> dict[str, Any]:
    return json.loads(pq.read_schema(path).metadata[b"emogait"])


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
    meta = read_metadata(path)
    table = pq.read_table(path, columns=list(columns) if columns else None)
    arrays = {
        name: column_array(table, name, shape)
        for name, shape in meta["shapes"].items()
        if name in table.column_names
    }
    return table, arrays
