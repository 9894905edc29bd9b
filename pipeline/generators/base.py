"""The interface every generator family implements, so that planning, synthesis, annotation, publishing and the
audit treat every family alike (a new family is a package beside ``autoregressive/``, never a branch elsewhere).

A family is *fitted* on the split gait table (its own stage writes the model under ``data/models/`` and the
model's sha256 identifies it in every gait's lineage) and then *generates* gaits for plan rows: given each row's
trajectory piece (placed in the world) and per-frame emotions, it returns the gaits' motion on the canonical
skeleton. Annotation (contacts, phase, features) is not the family's job: ``pipeline.synth.synthesis`` runs the
same annotation as for real gaits on whatever a family returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pyarrow as pa
import torch

from pipeline.ops.geometry import odd_frames
from pipeline.ops.path_fit import fit_poses


@dataclass
class GeneratedMotion:
    """N generated gaits of T frames on the canonical skeleton (J joints).

    positions (N, T, J, 3) world joint positions, metres; rotations (N, T, J, 4) local unit quaternions;
    heading (N, T) body heading about +Y. context_positions (N, C, J, 3): frames that precede each gait but are
    not part of it (e.g. a seed prefix), which annotation may look at (strikes before the first frame fix its
    phase), or None. conditioned_phase (N, T): the stepping phase the family generated with, kept where the
    contacts give too few strikes to define one, or None. placed_paths (N, K, 2): the trajectory pieces as the
    family placed them in the world (ground x, z), which the gaits were steered along.
    """

    positions: torch.Tensor
    rotations: torch.Tensor
    heading: torch.Tensor
    context_positions: torch.Tensor | None = None
    conditioned_phase: torch.Tensor | None = None
    placed_paths: torch.Tensor | None = None
    source_segments: list[str] | None = None  # per gait, JSON: the real frames it was assembled from (a family
                                              # that re-sequences real motion; published as source_segments)


def fit_placed(positions: torch.Tensor, rotations: torch.Tensor, paths: torch.Tensor, placement: Any
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Every family's last step before foot locking: walks (positions (N, T, J, 3), rotations (N, T, J, 4)) laid
    onto the paths (N, K, 2) they were placed along (``ops.path_fit``) by the placement's ``path_fit_s`` (the
    travel line's averaging time; 0 leaves them as placed), ``path_corner_m`` and ``path_turn_m``
    (``rollout.PlacementConfig``); also the turn (N, T) rad that gave each frame's body."""
    if placement.path_fit_s <= 0:
        return positions, rotations, torch.zeros(positions.shape[:2], dtype=positions.dtype)
    return fit_poses(positions, rotations, paths, odd_frames(placement.path_fit_s, placement.fps),
                     placement.path_corner_m, placement.path_turn_m)


class GeneratorFamily(Protocol):
    """A fitted generator, ready to generate plan rows."""

    name: str  # the published ``generator`` value, e.g. "autoregressive_affect"
    description: str  # one sentence for the dataset card and the published metadata
    model_sha256: str  # of the fitted model's file
    seeded: bool  # whether each gait continues a real seed gait (the plan row's ``seed_gait_id``)

    def lineage(self) -> dict[str, Any]:
        """The model's own lineage, published beside the gaits (e.g. the real cycles a model's statistics came
        from); plain JSON values."""
        ...

    def generate(self, rows: Sequence[dict[str, Any]], paths: torch.Tensor,
                 emotions: torch.Tensor) -> GeneratedMotion:
        """rows: plan rows (dicts; ``seed_gait_id``, ``plan_seed``, ...); paths (N, K, 2): each row's trajectory
        piece as ground (x, z) in its own start frame (from (0, 0) towards +z), which the family places in the
        world where its gait starts; emotions (N, T, 4): the condition per frame, rows summing to 1."""
        ...


@dataclass
class TrainClips:
    """The clips a family is fitted on, rebuilt from their overlapping windows: per clip id its positions
    (T, 21, 3), local rotations (T, 21, 4) and heading (T,), and the split table's row of its first window."""

    positions: dict[str, np.ndarray]
    rotations: dict[str, np.ndarray]
    heading: dict[str, np.ndarray]
    first_row: dict[str, int]


def train_clips(table: pa.Table, arrays: dict[str, np.ndarray], split: str, contents: Sequence[str],
                fps: float) -> TrainClips:
    """The clips of ``split`` whose content is one of ``contents``, of a split gait table (``io.gait_table``)."""
    from pipeline.annotate.annotation import rebuild_clips

    splits = np.array(table.column("split").to_pylist())
    content = np.array(table.column("content").to_pylist())
    rows = np.flatnonzero((splits == split) & np.isin(content, list(contents)))
    clip_ids = [table.column("clip_id")[int(r)].as_py() for r in rows]
    window = arrays["positions"].shape[1]
    starts = np.round(table.column("t_start").to_numpy()[rows] * fps).astype(int)
    positions = rebuild_clips(clip_ids, starts, arrays["positions"][rows], window)
    rotations = rebuild_clips(clip_ids, starts, arrays["rotations"][rows], window)
    heading = rebuild_clips(clip_ids, starts, arrays["heading"][rows], window)
    return TrainClips({c: p for c, (p, _) in positions.items()}, {c: r for c, (r, _) in rotations.items()},
                      {c: h for c, (h, _) in heading.items()},
                      {c: int(rows[members[0][0]]) for c, (_, members) in positions.items()})
