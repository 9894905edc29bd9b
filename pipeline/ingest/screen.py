"""The file screen: is an input there, is it the file its manifest pins, and does its format's reader accept it?

Ingest and contact validation take every mocap file through ``screen_file``, so a file is turned away for the
same reasons, in the same words, wherever it is read. A reason names the file, what was expected and what was
found. This module knows files, pins and readers; never what the motion in a file means.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pipeline.io.files import sha256_bytes
from pipeline.io.manifests import SourceManifest
from pipeline.io.readers.bvh import BvhClip, BvhError, read_bvh
from pipeline.io.readers.c3d import C3dClip, C3dError, read_c3d

READERS = {  # manifest format -> (reader(path, data), its error, the name reasons use)
    "bvh": (read_bvh, BvhError, "BVH"),
    "c3d": (read_c3d, C3dError, "C3D"),
}


@dataclass(frozen=True)
class Screened:
    """One input after the screen: read, or rejected with the reason (a quarantine: the file is bad)."""

    rel: str  # relative to the source folder
    path: Path  # where it was looked for: the source folder / rel
    sha256: str | None  # of the bytes found; None when no file is there
    clip: BvhClip | C3dClip | None  # the file as its format's reader returns it; None when rejected
    rejection: str | None = None


def screen_file(manifest: SourceManifest, source_dir: Path, rel: str, pinned: str | None) -> Screened:
    """Read ``source_dir / rel`` if it is there, is pinned, matches its pin and parses; else say why not."""
    path = source_dir / rel
    if not path.is_file():
        return Screened(rel, path, None, None,
                        f"missing: the manifest pins {rel} (sha256 {pinned}) but no file is at {path}; "
                        f"obtain it from {manifest.upstream_url(rel)}")
    data = path.read_bytes()
    sha256 = sha256_bytes(data)
    if pinned is None:
        return Screened(rel, path, sha256, None,
                        f"not pinned: the manifest lists no sha256 for this file (found {sha256}); pin it to ingest it")
    if sha256 != pinned:
        return Screened(rel, path, sha256, None, f"sha256 mismatch: expected {pinned} (manifest), found {sha256}")
    read, error, name = READERS[manifest.format]
    try:
        clip = read(path, data)
    except error as err:
        return Screened(rel, path, sha256, None, f"malformed {name}: {err}")
    return Screened(rel, path, sha256, clip)
