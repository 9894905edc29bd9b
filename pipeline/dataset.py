"""The published dataset directory: its loaders, its verifier, and the writers the publish
stage uses for the files this module reads.

A published directory holds
    gaits.parquet, or shards gaits-*.parquet (read in name order; the publish stage names each shard for the one
        part it holds, ``gaits-<n>-<part>.parquet``: ``real`` or a generator family, and verify checks that)
        one row per gait; array columns are fixed_size_list<float32> (row-major) with their per-gait shapes,
        joint names, parents, emotion order and units in the schema metadata key ``emogait``
        (see ``pipeline.io.gait_table``); a null array row means "absent" (e.g. an unlabelled gait's emotion);
    gaits.h5
        the same columns stacked along axis 0, the gait axis, in the same row order: numeric datasets chunked
        with gzip + shuffle + fletcher32, null array rows stored as NaN; string columns as variable-length
        UTF-8 datasets (chunked but unfiltered: HDF5 refuses checksums on variable-length data), nulls as "";
        root attributes ``emogait`` (the Parquet metadata, JSON), ``joint_names``, ``parents``,
        ``emotion_order``, ``rest_offsets_m`` and ``units`` (JSON); per dataset ``units`` where known;
    SHA256SUMS
        ``sha256sum`` lines "<hex>  <relative path>" for every other (non-hidden) file, sorted by path,
        so ``sha256sum -c SHA256SUMS`` checks a download;
beside the Croissant JSON-LD, the dataset card, the PROV-JSON lineage and generators.json (each generator family's
entry and model lineage), which the publish stage writes. Where the schema metadata declares ``generators``, every
synthetic gait names one of them in its ``generator`` column with that family's model sha256.

This module knows the directory's files, not how gaits are made.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import torch
from torch.utils.data import Dataset

from pipeline.core.emotions import EMOTIONS
from pipeline.io.files import META_KEY, atomic_path, read_meta, schema_meta, sha256_file, write_text
from pipeline.io.gait_table import column_array

ID_COLUMN = "gait_id"
REQUIRED_COLUMNS = (ID_COLUMN, "kind", "positions", "rotations")  # present, and never null
REQUIRED_META = ("shapes", "joint_names", "parents", "emotion_order", "units")
PARQUET_NAME = "gaits.parquet"
SHARD_GLOB = "gaits-*.parquet"
HDF5_NAME = "gaits.h5"
SUMS_NAME = "SHA256SUMS"
EMOTION_TOLERANCE = 1e-5
QUATERNION_TOLERANCE = 1e-3
CHUNK_BYTES = 1 << 20  # about 1 MiB of raw data per HDF5 chunk
_STRING = h5py.string_dtype("utf-8")
_FILTERS = {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True}


# ---------------------------------------------------------------------------------------------- reading

def parquet_files(directory: str | Path) -> list[Path]:
    """The Parquet file (or its shards, in name order) of a published directory."""
    directory = Path(directory)
    single, shards = directory / PARQUET_NAME, sorted(directory.glob(SHARD_GLOB))
    if single.is_file() and shards:
        raise ValueError(f"{directory}: expected {PARQUET_NAME} or {SHARD_GLOB} shards, found both")
    if not single.is_file() and not shards:
        raise FileNotFoundError(f"{directory}: expected {PARQUET_NAME} or {SHARD_GLOB} shards, found neither")
    return [single] if single.is_file() else shards


def directory_schema(directory: str | Path) -> pa.Schema:
    """The Parquet schema of a published directory (its first Parquet file's)."""
    return pq.read_schema(parquet_files(directory)[0])


def directory_metadata(directory: str | Path) -> dict[str, Any]:
    """The ``emogait`` schema metadata of a published directory."""
    return schema_meta(directory_schema(directory))


def read_table(directory: str | Path, columns: Sequence[str] | None = None) -> tuple[pa.Table, dict[str, Any]]:
    """All gaits as one table (shards concatenated in order) and the ``emogait`` metadata of the first file."""
    files = parquet_files(directory)
    meta = directory_metadata(directory)
    tables = [pq.read_table(f, columns=list(columns) if columns else None) for f in files]
    return pa.concat_tables(tables).combine_chunks(), meta


def _valid_rows(table: pa.Table, name: str) -> np.ndarray:
    return pc.is_valid(table.column(name)).to_numpy(zero_copy_only=False)


def _scalar_values(table: pa.Table, name: str) -> np.ndarray | list:
    """A scalar column as a list of str/None (strings) or a numpy array (numbers; nulls become NaN)."""
    column = table.column(name)
    if pa.types.is_string(column.type) or pa.types.is_large_string(column.type):
        return column.to_pylist()
    return column.to_numpy()


def load_dataframe(directory: str | Path, columns: Sequence[str] | None = None) -> pd.DataFrame:
    """The gaits as a DataFrame: one row per gait, each array cell a numpy array of its documented shape.

    A null array row (e.g. an unlabelled gait's emotion) is None, not an array of NaN, so "no label" cannot
    be mistaken for a label. The ``emogait`` metadata is in ``df.attrs["emogait"]``.
    """
    table, meta = read_table(directory, columns)
    shapes = meta["shapes"]
    data: dict[str, Any] = {}
    for name in table.column_names:
        if name in shapes:
            values, valid = column_array(table, name, shapes[name]), _valid_rows(table, name)
            data[name] = pd.Series([v if ok else None for v, ok in zip(values, valid)], dtype=object)
        else:
            data[name] = table.column(name).to_pandas()
    frame = pd.DataFrame(data)
    frame.attrs["emogait"] = meta
    return frame


def gaits_by_id(directory: str | Path, ids: Sequence[str], columns: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Selected gaits, read without loading the rest: {gait id: {column: value, arrays shaped}}; an unknown id
    raises KeyError naming it."""
    files = parquet_files(directory)
    meta = directory_metadata(directory)
    wanted = list(dict.fromkeys([ID_COLUMN, *columns]))
    table = pa.concat_tables([pq.read_table(f, columns=wanted, filters=[(ID_COLUMN, "in", list(ids))]) for f in files])
    found = {}
    for name in wanted:
        values = (column_array(table, name, meta["shapes"][name]) if name in meta["shapes"]
                  else table.column(name).to_pylist())
        for row, gait_id in enumerate(table.column(ID_COLUMN).to_pylist()):
            found.setdefault(gait_id, {})[name] = values[row]
    if missing := [i for i in ids if i not in found]:
        raise KeyError(f"{directory}: no gait with id {', '.join(missing)}")
    return found


class GaitDataset(Dataset):
    """The gaits of a published directory for torch: item i is a dict column -> value.

    columns: which columns to load (default: every array column and the gait id). Array columns come as
    float32 tensors of their per-gait shape (a null row as NaN, so batches stack); numeric columns as 0-d
    tensors; string columns as str (``default_collate`` makes them lists). Everything is read into memory
    once, so DataLoader workers share it and never open files.
    """

    def __init__(self, directory: str | Path, columns: Sequence[str] | None = None):
        meta = read_meta(parquet_files(directory)[0])
        wanted = list(columns) if columns else [ID_COLUMN, *meta["shapes"]]
        table, meta = read_table(directory, wanted)
        self.meta = meta
        self.columns: dict[str, np.ndarray | list] = {
            name: column_array(table, name, meta["shapes"][name]) if name in meta["shapes"]
            else _scalar_values(table, name)
            for name in wanted
        }
        self._rows = table.num_rows

    def __len__(self) -> int:
        return self._rows

    def __getitem__(self, index: int) -> dict[str, Any]:
        item: dict[str, Any] = {}
        for name, values in self.columns.items():
            value = values[index]
            item[name] = value if isinstance(value, str) or value is None else torch.as_tensor(value)
        return item


# ---------------------------------------------------------------------------------------------- writing

def _chunk_rows(rows: int, row_bytes: int) -> int:
    return max(1, min(rows, CHUNK_BYTES // max(row_bytes, 1)))


def _write_scalar(h5: h5py.File, table: pa.Table, name: str) -> None:
    column = table.column(name)
    rows = table.num_rows
    if pa.types.is_string(column.type) or pa.types.is_large_string(column.type):
        values = np.array(["" if v is None else v for v in column.to_pylist()], dtype=object)
        h5.create_dataset(name, data=values, dtype=_STRING, chunks=(_chunk_rows(rows, 64),),
                          maxshape=(None,), track_times=False)
        return
    if not (pa.types.is_integer(column.type) or pa.types.is_floating(column.type) or pa.types.is_boolean(column.type)):
        raise TypeError(f"column {name!r}: expected a string, number or boolean column, found {column.type}")
    values = column.to_numpy()
    h5.create_dataset(name, data=values, chunks=(_chunk_rows(rows, values.itemsize),), maxshape=(None,),
                      track_times=False, **_FILTERS)


def _write_array(h5: h5py.File, name: str, values: np.ndarray, units: str | None) -> None:
    values = np.ascontiguousarray(values, dtype=np.float32)
    shape = values.shape[1:]
    rows = _chunk_rows(values.shape[0], values[:1].nbytes or 4 * int(np.prod(shape)))
    ds = h5.create_dataset(name, data=values, chunks=(rows, *shape), maxshape=(None, *shape),
                           track_times=False, **_FILTERS)
    if units is not None:
        ds.attrs["units"] = units


def _write_root_attrs(h5: h5py.File, meta: dict[str, Any]) -> None:
    h5.attrs["emogait"] = json.dumps(meta, sort_keys=True)
    for key in ("joint_names", "emotion_order"):
        if key in meta:
            h5.attrs[key] = np.array(meta[key], dtype=_STRING)
    if "parents" in meta:
        h5.attrs["parents"] = np.asarray(meta["parents"], dtype=np.int32)
    if "rest_offsets_m" in meta:
        h5.attrs["rest_offsets_m"] = np.asarray(meta["rest_offsets_m"], dtype=np.float64)
    if "units" in meta:
        h5.attrs["units"] = json.dumps(meta["units"], sort_keys=True)


def write_hdf5_atomic(table: pa.Table, arrays: dict[str, np.ndarray], path: str | Path, meta: dict[str, Any]) -> None:
    """The HDF5 twin of a gait table, written atomically and byte-for-byte reproducibly.

    table: the gaits (its scalar columns become 1-D datasets; its array columns are taken from ``arrays`` or,
    when absent there, decoded with the shapes in ``meta["shapes"]``); arrays: name -> (rows, *shape);
    meta: the ``emogait`` metadata. No timestamps are stored (``track_times=False``), so the same content gives
    the same bytes and the same SHA256SUMS line.
    """
    shapes = meta.get("shapes", {})
    arrays = {**{n: column_array(table, n, shapes[n]) for n in table.column_names if n in shapes}, **arrays}
    for name, values in arrays.items():
        if values.shape[0] != table.num_rows:
            raise ValueError(f"array {name!r}: expected {table.num_rows} rows (the table's), found {values.shape[0]}")
        if name in table.column_names and table.column(name).null_count:
            values = np.array(values, dtype=np.float32)
            values[~_valid_rows(table, name)] = np.nan  # null rows are NaN, as the Parquet reader returns them
            arrays[name] = values
    units = meta.get("units", {})
    with atomic_path(Path(path)) as tmp, h5py.File(tmp, "w") as h5:
        for name in table.column_names:
            if name in arrays:
                _write_array(h5, name, arrays[name], units.get(name))
            else:
                _write_scalar(h5, table, name)
        for name in sorted(set(arrays) - set(table.column_names)):
            _write_array(h5, name, arrays[name], units.get(name))
        _write_root_attrs(h5, meta)


def listed_files(directory: Path) -> list[str]:
    """Relative paths of the files SHA256SUMS covers: every non-hidden file but itself, sorted."""
    rels = (p.relative_to(directory).as_posix() for p in directory.rglob("*") if p.is_file())
    return sorted(r for r in rels if r != SUMS_NAME and not any(part.startswith(".") for part in r.split("/")))


def write_sha256sums(directory: str | Path) -> Path:
    """Write SHA256SUMS for the directory's files (run last, after every other file is in place)."""
    directory = Path(directory)
    lines = [f"{sha256_file(directory / rel)}  {rel}\n" for rel in listed_files(directory)]
    path = directory / SUMS_NAME
    write_text("".join(lines), path)
    return path


# ---------------------------------------------------------------------------------------------- verifying

def verify(directory: str | Path) -> list[str]:
    """Every problem found in a published directory, in words; an empty list means it is sound.

    Checks: SHA256SUMS (format, order, every file listed and matching), the Parquet schema metadata and the
    declared shape of every array column, required columns, finite values and unit quaternions, emotion rows
    (where not null) non-negative and summing to 1, unique gait ids, and that gaits.h5 holds the same ids in
    the same order and the same values.
    """
    directory = Path(directory)
    problems = _check_sums(directory)
    try:
        table, meta, parquet_problems = _read_checked(directory)
    except (OSError, ValueError, KeyError, pa.ArrowException) as err:
        return problems + [f"Parquet: unreadable ({err})"]
    problems += parquet_problems
    if table is None:
        return problems
    arrays, array_problems = _check_arrays(table, meta)
    problems += array_problems + _check_ids(table) + _check_generators(directory, table, meta)
    return problems + _check_hdf5(directory / HDF5_NAME, table, meta, arrays)


def _check_sums(directory: Path) -> list[str]:
    path = directory / SUMS_NAME
    if not path.is_file():
        return [f"{SUMS_NAME}: missing; expected one '<sha256>  <path>' line per file"]
    problems, listed = [], {}
    for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        digest, sep, rel = line.partition("  ")
        if not sep or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest) or not rel:
            problems.append(f"{SUMS_NAME}:{lineno}: expected '<64 hex digits>  <relative path>', found {line[:80]!r}")
        elif rel.startswith("/") or ".." in rel.split("/"):
            problems.append(f"{SUMS_NAME}:{lineno}: expected a path inside the directory, found {rel!r}")
        else:
            listed[rel] = digest
    if list(listed) != sorted(listed):
        problems.append(f"{SUMS_NAME}: expected lines sorted by path, found them unsorted")
    for rel, digest in listed.items():
        file = directory / rel
        if not file.is_file():
            problems.append(f"{rel}: listed in {SUMS_NAME} but missing")
        elif (found := sha256_file(file)) != digest:
            problems.append(f"{rel}: sha256 mismatch: expected {digest} ({SUMS_NAME}), found {found}")
    unlisted = [rel for rel in listed_files(directory) if rel not in listed]
    return problems + [f"{rel}: present but not listed in {SUMS_NAME}" for rel in unlisted]


def _read_checked(directory: Path) -> tuple[pa.Table | None, dict[str, Any], list[str]]:
    """The gait table, its metadata, and problems with the metadata (every shard must carry the same)."""
    problems, metas = [], []
    for file in parquet_files(directory):
        raw = pq.read_schema(file).metadata or {}
        if META_KEY not in raw:
            problems.append(f"{file.name}: schema metadata key 'emogait' missing")
            continue
        meta = json.loads(raw[META_KEY])
        missing = [k for k in REQUIRED_META if k not in meta]
        if missing:
            problems.append(f"{file.name}: schema metadata 'emogait' lacks {missing}")
        metas.append((file.name, meta))
    if problems:
        return None, {}, problems
    first_name, first = metas[0]
    problems += [f"{name}: schema metadata differs from {first_name}'s" for name, m in metas[1:] if m != first]
    table, _ = read_table(directory)
    return table, first, problems


def _first(mask: np.ndarray, table: pa.Table) -> str:
    """'gait <id> at <index>' for the first True entry of a (rows, ...) mask."""
    index = tuple(int(i) for i in np.argwhere(mask)[0])
    gait = table.column(ID_COLUMN)[index[0]].as_py() if ID_COLUMN in table.column_names else index[0]
    return f"gait {gait!r} (row {index[0]}" + (f", element {index[1:]})" if len(index) > 1 else ")")


def _check_arrays(table: pa.Table, meta: dict[str, Any]) -> tuple[dict[str, np.ndarray], list[str]]:
    """Decoded array columns (null rows NaN) and problems with shapes, nulls, values and emotion rows."""
    problems = [f"column {c!r}: required but missing" for c in REQUIRED_COLUMNS if c not in table.column_names]
    problems += [f"column {c!r}: {table.column(c).null_count} null rows; expected none"
                 for c in REQUIRED_COLUMNS if c in table.column_names and table.column(c).null_count]
    arrays: dict[str, np.ndarray] = {}
    for name, shape in meta["shapes"].items():
        if name not in table.column_names:
            problems.append(f"column {name!r}: declared in the schema metadata (shape {shape}) but missing")
            continue
        kind = table.column(name).type
        size = int(np.prod(shape))
        if not pa.types.is_fixed_size_list(kind) or kind.list_size != size:
            problems.append(f"column {name!r}: expected fixed_size_list of {size} values (shape {shape}), found {kind}")
            continue
        values = column_array(table, name, shape)
        valid = _valid_rows(table, name)
        arrays[name] = values
        bad = ~np.isfinite(values) & valid.reshape((-1,) + (1,) * len(shape))
        if bad.any():
            rows = int(bad.reshape(len(bad), -1).any(1).sum())
            problems.append(f"column {name!r}: {rows} gaits have NaN or infinite values (first: {_first(bad, table)})")
        problems += _check_values(name, values, valid, meta, table)
    return arrays, problems


def _check_values(name: str, values: np.ndarray, valid: np.ndarray, meta: dict[str, Any], table: pa.Table) -> list[str]:
    """Unit quaternions in 'rotations'; non-negative emotion rows summing to 1 in every emotion column."""
    if name == "rotations":
        off = np.abs(np.linalg.norm(values.astype(np.float64), axis=-1) - 1.0) > QUATERNION_TOLERANCE
        return [f"column 'rotations': quaternions not of unit norm (first: {_first(off, table)})"] if off.any() else []
    if not name.startswith("emotion") or values.shape[-1] != len(meta.get("emotion_order", EMOTIONS)):
        return []
    rows = values[valid].astype(np.float64)
    problems = []
    negative = np.zeros(values.shape[:-1], dtype=bool)
    negative[valid] = (rows < 0).any(-1)
    off = np.zeros(values.shape[:-1], dtype=bool)
    off[valid] = np.abs(rows.sum(-1) - 1.0) > EMOTION_TOLERANCE
    if negative.any():
        problems.append(f"column {name!r}: {int(negative.sum())} emotion rows have negative entries "
                        f"(first: {_first(negative, table)})")
    if off.any():
        total = values[tuple(np.argwhere(off)[0])].sum(dtype=np.float64)
        problems.append(f"column {name!r}: {int(off.sum())} emotion rows do not sum to 1 within "
                        f"{EMOTION_TOLERANCE} (first: {_first(off, table)} sums to {total:.6f})")
    return problems


def _check_generators(directory: Path, table: pa.Table, meta: dict[str, Any]) -> list[str]:
    """Where the metadata declares generator families: every synthetic gait names one of them, every family has
    gaits carrying its model's sha256, and a shard named for a part (``gaits-<n>-<part>.parquet``) holds only
    that part's gaits (``real``, or the family's)."""
    generators = meta.get("generators")
    if not generators or "generator" not in table.column_names:
        return []
    kind = np.array(table.column("kind").to_pylist(), dtype=object)
    generator = np.array(table.column("generator").to_pylist(), dtype=object)
    sha = np.array(table.column("checkpoint_sha256").to_pylist(), dtype=object) \
        if "checkpoint_sha256" in table.column_names else None
    problems = []
    undeclared = sorted({str(g) for g in generator[kind == "synthetic"] if g not in generators})
    if undeclared:
        problems.append(f"column 'generator': synthetic gaits of {undeclared}; expected one of {sorted(generators)} "
                        "(the metadata's 'generators')")
    for name, entry in generators.items():
        rows = generator == name
        if not rows.any():
            problems.append(f"generator {name!r}: declared in the metadata, but no gait has it")
        elif sha is not None and (bad := int((sha[rows] != entry.get("model_sha256")).sum())):
            problems.append(f"generator {name!r}: {bad} gaits with checkpoint_sha256 other than the declared "
                            f"{entry.get('model_sha256')}")
    first = 0
    for file in parquet_files(directory):  # the table holds the shards in this order: slice it by their row counts
        rows = slice(first, first + pq.read_metadata(file).num_rows)
        first = rows.stop
        part = file.stem.split("-", 2)[2] if file.stem.count("-") >= 2 else None
        if part is None:
            continue
        kinds, gens = set(kind[rows]), set(generator[rows])
        expected = ({"real"}, {None}) if part == "real" else ({"synthetic"}, {part})
        if (kinds, gens) != expected:
            problems.append(f"{file.name}: expected only {part} gaits, found kinds {sorted(map(str, kinds))} and "
                            f"generators {sorted(map(str, gens))}")
    return problems


def _check_ids(table: pa.Table) -> list[str]:
    if ID_COLUMN not in table.column_names:
        return []
    ids = pd.Series(table.column(ID_COLUMN).to_pylist(), dtype=object)
    repeated = ids[ids.duplicated(keep=False) & ids.notna()]
    if repeated.empty:
        return []
    names = sorted(set(repeated))
    return [f"column {ID_COLUMN!r}: {len(names)} ids occur more than once (e.g. {names[0]!r} at rows "
            f"{list(repeated.index[repeated == names[0]])}); expected unique ids"]


def _check_hdf5(path: Path, table: pa.Table, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> list[str]:
    """Problems where gaits.h5 differs from the Parquet gaits (ids, order, values, attributes, filters)."""
    if not path.is_file():
        return [f"{path.name}: missing"]
    try:
        with h5py.File(path, "r") as h5:
            problems = [f"{path.name}: root attribute {key!r} missing"
                        for key in ("emogait", "joint_names", "parents", "emotion_order") if key not in h5.attrs]
            for name in table.column_names:
                problems += _compare_dataset(h5, name, table, arrays)
            return problems
    except OSError as err:  # includes a fletcher32 checksum failure while reading
        return [f"{path.name}: unreadable ({err})"]


def _compare_dataset(h5: h5py.File, name: str, table: pa.Table, arrays: dict[str, np.ndarray]) -> list[str]:
    where = f"{HDF5_NAME}:/{name}"
    if name not in h5:
        return [f"{where}: missing; the Parquet file has this column"]
    ds = h5[name]
    if name in arrays:
        expected = arrays[name]
        if ds.shape != expected.shape:
            return [f"{where}: expected shape {expected.shape} (the Parquet column's), found {ds.shape}"]
        problems = []
        if (ds.compression, ds.shuffle, ds.fletcher32) != ("gzip", True, True):
            problems.append(f"{where}: expected chunks with gzip + shuffle + fletcher32, found "
                            f"compression={ds.compression}, shuffle={ds.shuffle}, fletcher32={ds.fletcher32}")
        found = ds[()]
        differ = ~((found == expected) | (np.isnan(found) & np.isnan(expected)))
        if differ.any():
            problems.append(f"{where}: values differ from the Parquet file's (first: {_first(differ, table)})")
        return problems
    expected = _scalar_values(table, name)
    if isinstance(expected, list):
        found = list(ds.asstr()[()]) if ds.dtype.kind == "O" else None
        expected = ["" if v is None else v for v in expected]
        if found != expected:
            what = "ids" if name == ID_COLUMN else "values"
            return [f"{where}: {what} differ from the Parquet file's (same ids in the same order expected)"]
        return []
    found = ds[()]
    if found.shape != expected.shape or not np.array_equal(found, expected, equal_nan=found.dtype.kind == "f"):
        return [f"{where}: values differ from the Parquet file's"]
    return []
