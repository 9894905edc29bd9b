"""The canonical 21-joint skeleton (the paper's pose tree), loaded from ``manifests/skeleton.yaml``."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property
from pathlib import Path

import numpy as np
import yaml

CANONICAL_SKELETON = Path(__file__).resolve().parents[2] / "manifests" / "skeleton.yaml"


@dataclass(frozen=True)
class Skeleton:
    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray  # (J, 3) rest offsets in metres, row 0 zero
    leg_bones: tuple[tuple[int, int], ...]
    foot_joints: tuple[int, ...]

    @property
    def joint_count(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    @cached_property
    def bone_lengths(self) -> np.ndarray:
        return np.linalg.norm(self.offsets, axis=1)

    @cached_property
    def leg_length(self) -> float:
        """Mean over both legs of hip->knee + knee->ankle, in metres."""
        return float(sum(self.bone_lengths[c] for _, c in self.leg_bones) / 2.0)

    @cached_property
    def depth_levels(self) -> tuple[tuple[int, ...], ...]:
        """Joints grouped by depth below the root (level 0 is the root)."""
        depth = [0] * len(self.parents)
        for j, p in enumerate(self.parents):
            depth[j] = 0 if p < 0 else depth[p] + 1
        return tuple(tuple(j for j in range(len(depth)) if depth[j] == d) for d in range(max(depth) + 1))


def load_skeleton(path: str | Path) -> Skeleton:
    doc = yaml.safe_load(Path(path).read_text())
    names = tuple(j["name"] for j in doc["joints"])
    parents = tuple(-1 if j["parent"] is None else names.index(j["parent"]) for j in doc["joints"])
    if any(p >= j for j, p in enumerate(parents)) or parents[0] != -1:
        raise ValueError(f"{path}: joints must be listed parents first, with the root first")
    offsets = np.asarray([j["offset"] for j in doc["joints"]], dtype=np.float64)
    leg = tuple((names.index(a), names.index(b)) for a, b in doc["leg_bones"])
    feet = tuple(names.index(n) for n in doc["foot_joints"])
    return Skeleton(names, parents, offsets, leg, feet)


@cache
def canonical_skeleton() -> Skeleton:
    """The canonical skeleton, loaded once: for code that needs joint indices without being handed a Skeleton
    (the generator's network takes its heel and toe joints from here, by name)."""
    return load_skeleton(CANONICAL_SKELETON)
