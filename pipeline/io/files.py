"""Every file the pipeline writes goes through here: atomically (a reader never sees half a file, a killed stage
leaves no partial output) and deterministically (no timestamps, sorted keys, fixed row groups), readable by all.

Also the one sha256 helper and the one reader/writer of the ``emogait`` schema metadata that Parquet files carry.
This module knows files and bytes, never gaits, stages or DVC.
"""

from __future__ import annotations

import csv
import hashlib
import glob
import io
import json
import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

META_KEY = b"emogait"  # the schema-metadata key of every gait table (Parquet) we write


def _temporary_name(path: Path, token: str) -> Path:
    """The hidden name of a temporary of ``path``; ``token="*"`` gives the pattern of them all."""
    return path.parent / f".{path.name}.{token}.tmp{path.suffix}"


def _prepare(path: str | Path) -> Path:
    """``path``, its directory made, and the temporaries a killed earlier write of it left removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    for stale in path.parent.glob(_temporary_name(Path(glob.escape(path.name)), "*").name):  # the name, escaped
        stale.unlink(missing_ok=True)
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed onto it when the block succeeds (removed when it fails), for
    writers that need a path (h5py, animations). It ends in ``.tmp`` plus the real suffix, so writers that pick a
    format by extension (Pillow, matplotlib) still can. A process killed mid-write leaves its temporary file; the
    next write of the same path removes it. Whatever can be made in memory goes through ``write_bytes`` instead,
    which leaves nothing behind."""
    path = _prepare(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=f".tmp{path.suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; outputs are for everyone to read
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | Path) -> str:
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def _link_descriptor(fd: int, name: Path) -> None:
    """Give the open unnamed file ``fd`` the name ``name``: through ``/proc/self/fd`` (any user), else
    ``linkat(AT_EMPTY_PATH)`` (where /proc is another mount, e.g. in some sandboxes; needs privilege)."""
    try:
        os.link(f"/proc/self/fd/{fd}", name, follow_symlinks=True)
        return
    except OSError:
        pass
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    at_fdcwd, at_empty_path = -100, 0x1000
    if libc.linkat(fd, b"", at_fdcwd, os.fsencode(name), at_empty_path) != 0:
        errno = ctypes.get_errno()
        raise OSError(errno, os.strerror(errno), str(name))


def _write_unnamed(data: bytes, path: Path) -> bool:
    """Write ``data`` to an unnamed file in ``path``'s directory (Linux ``O_TMPFILE``), then give it a name and
    rename that onto ``path``. A process killed while writing leaves nothing: the file has no name until it is
    whole, and the name exists only between two system calls. False where the file system cannot (the caller then
    uses a named temporary)."""
    try:
        fd = os.open(path.parent, os.O_TMPFILE | os.O_WRONLY, 0o644)
    except (AttributeError, OSError):
        return False
    name = None
    try:
        os.fchmod(fd, 0o644)  # what a named temporary gets too, whatever the umask
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        name = _temporary_name(path, os.urandom(6).hex())
        _link_descriptor(fd, name)
        os.replace(name, path)
        return True
    except OSError:
        if name is not None and os.path.lexists(name):
            os.unlink(name)
        return False
    finally:
        os.close(fd)


def write_bytes(data: bytes, path: str | Path) -> str:
    """Write bytes atomically; return their sha256."""
    path = _prepare(path)
    if not _write_unnamed(data, path):
        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
    return sha256_bytes(data)


def write_text(text: str, path: str | Path) -> None:
    write_bytes(text.encode("utf-8"), path)


def json_text(obj: Any, sort_keys: bool = True, ascii_only: bool = True) -> str:
    """Strict JSON (a NaN is an error: write None), indent 2, newline at the end."""
    return json.dumps(obj, indent=2, sort_keys=sort_keys, ensure_ascii=ascii_only, allow_nan=False) + "\n"


def write_json(obj: Any, path: str | Path, sort_keys: bool = True, ascii_only: bool = True) -> None:
    """Sorted keys by default; ``sort_keys=False`` keeps a document's own order (JSON-LD, PROV-JSON)."""
    write_text(json_text(obj, sort_keys, ascii_only), path)


def write_csv(header: Sequence[str], rows: Iterable[Sequence[Any]], path: str | Path) -> None:
    """A CSV with a header row and ``\\n`` line ends."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    write_text(buffer.getvalue(), path)


def save_figure(fig: Any, path: str | Path, **savefig: Any) -> None:
    """A matplotlib figure (format from the suffix; savefig's own options, e.g. dpi, metadata), atomically; closes
    the figure."""
    import matplotlib.pyplot as plt

    try:
        buffer = io.BytesIO()  # rendered in memory, so a killed stage leaves no temporary beside the figure
        fig.savefig(buffer, **{"format": Path(path).suffix.lstrip("."), **savefig})
        write_bytes(buffer.getvalue(), path)
    finally:
        plt.close(fig)


def write_parquet(table: pa.Table, path: str | Path) -> None:
    """zstd, 512-row groups, statistics, no timestamps: the same table gives the same bytes."""
    sink = pa.BufferOutputStream()  # in memory, as for figures
    pq.write_table(table, sink, compression="zstd", row_group_size=512, write_statistics=True)
    write_bytes(sink.getvalue().to_pybytes(), path)


def schema_meta(schema: pa.Schema) -> dict[str, Any]:
    """The ``emogait`` metadata of a gait table's schema ({} when it has none)."""
    raw = schema.metadata or {}
    return json.loads(raw[META_KEY]) if META_KEY in raw else {}


def with_schema_meta(table: pa.Table, meta: Mapping[str, Any]) -> pa.Table:
    return table.replace_schema_metadata({META_KEY: json.dumps(meta, sort_keys=True).encode()})


def read_meta(path: str | Path) -> dict[str, Any]:
    """The ``emogait`` metadata of a Parquet file, without reading its data."""
    return schema_meta(pq.read_schema(path))
