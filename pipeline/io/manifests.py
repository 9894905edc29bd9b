"""Source manifests: what a mocap source is, which files it has (pinned by sha256) and how to read them.

Adding a mocap source means adding a manifest under ``manifests/sources/``; nothing here names a source.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

AXES_TO_Y_UP = {
    # Rows map source (x, y, z) to canonical (x, y, z), right-handed, Y up.
    "+Y": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "+Z": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
}


@dataclass(frozen=True)
class FileEntry:
    path: str  # relative to the source folder (= the upstream repository path)
    sha256: str


@dataclass(frozen=True)
class Label:
    content: str
    style: str
    emotion: tuple[float, float, float, float] | None
    label_method: str | None
    fields: dict[str, str]


@dataclass(frozen=True)
class SourceManifest:
    name: str
    format: str
    doc: dict[str, Any]
    files: tuple[FileEntry, ...]

    @property
    def globs(self) -> list[str]:
        return list(self.doc["globs"])

    @property
    def unit_scale_m(self) -> float:
        return float(self.doc["unit_scale_m"])

    @property
    def up_axis(self) -> str:
        return self.doc["up_axis"]

    @property
    def root_offset(self) -> str:
        return self.doc.get("root_offset", "add")

    @property
    def min_clip_seconds(self) -> float:
        return float(self.doc.get("min_clip_seconds", 0.0))

    @property
    def gait_contents(self) -> set[str]:
        return set(self.doc.get("gait_contents", []))

    def joint_map(self, rel_path: str) -> dict[str, Any]:
        overrides = self.doc.get("joint_map_overrides") or {}
        return overrides.get(Path(rel_path).name, self.doc["joint_map"])

    def upstream_url(self, rel_path: str) -> str:
        return self.doc["upstream"]["file_url"].format(path=rel_path)

    def label(self, rel_path: str) -> Label:
        """Content, style and emotion from the file name, by the manifest's rule. Raises ValueError."""
        rule = self.doc["label_rule"]
        name = Path(rel_path).name
        match = re.match(rule["pattern"], name)
        if match is None:
            raise ValueError(f"file name {name!r} does not match the label pattern {rule['pattern']!r}")
        fields = {k: v for k, v in match.groupdict().items() if v is not None}
        fields.update(rule.get("fixed", {}))
        content = rule.get("content_map", {}).get(fields.get("content", "unknown"), fields.get("content", "unknown"))
        style = fields.get("style", "unknown")
        emotion = method = None
        for entry in rule.get("emotions", []):
            if all(fields.get(k) == v for k, v in entry["when"].items()):
                emotion = tuple(float(x) for x in entry["emotion"])
                method = entry["label_method"]
                break
        return Label(content=content, style=style, emotion=emotion, label_method=method, fields=fields)


def load_manifest(path: str | Path) -> SourceManifest:
    doc = yaml.safe_load(Path(path).read_text())
    files = tuple(FileEntry(f["path"], f["sha256"]) for f in doc.get("files", []))
    return SourceManifest(name=doc["name"], format=doc["format"], doc=doc, files=files)


def load_manifests(folder: str | Path, formats: tuple[str, ...] = ("bvh",)) -> list[SourceManifest]:
    manifests = [load_manifest(p) for p in sorted(Path(folder).glob("*.yaml"))]
    return [m for m in manifests if m.format in formats]


def list_inputs(manifest: SourceManifest, source_dir: Path) -> list[tuple[str, str | None]]:
    """Every input the run must account for: (relative path, pinned sha256 or None if unpinned).

    The pinned files (present or not) plus any file the globs find that the manifest does not pin.
    """
    pinned = {f.path: f.sha256 for f in manifest.files}
    found: set[str] = set()
    if source_dir.is_dir():
        for pattern in manifest.globs:
            found.update(p.relative_to(source_dir).as_posix() for p in source_dir.glob(pattern) if p.is_file())
    return sorted({**{p: None for p in found}, **pinned}.items())
