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

import torch


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
