"""What every stage shares: the repository layout and params.yaml."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parent.parent
PARAMS = REPO / "params.yaml"
SKELETON = REPO / "manifests" / "skeleton.yaml"
SOURCES = REPO / "manifests" / "sources"


def load_params(path: Path = PARAMS) -> dict[str, Any]:
    return yaml.safe_load(Path(path).read_text())


def mocap_root(params: dict[str, Any]) -> Path:
    root = Path(params["data"]["mocap_root"])
    return root if root.is_absolute() else (REPO / root).resolve()
