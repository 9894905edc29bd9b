"""Left-right mirroring of gaits across the body's sagittal plane: a label-preserving augmentation (a mirrored
happy walk is a happy walk), in torch, batched over leading dimensions.

The canonical frame has the body's left on +X (manifests/skeleton.yaml), so mirroring is the reflection
M = diag(-1, 1, 1) of world space with every joint swapped for its counterpart σ(j) (``left_*`` <-> ``right_*``,
found by name; a joint on the midline is its own). Each stored array follows from M and its own definition:

* positions (..., J, 3): X'_j = M X_σ(j).
* rotations (..., J, 4), per bone: q'_j = M q_σ(j) M. Conjugating a rotation by a reflection keeps its angle and
  maps its axis n to det(M) M n = (n_x, -n_y, -n_z), so [w, x, y, z] -> [w, x, -y, -z], then joints swap. Forward
  kinematics of q' gives the mirrored positions: the rest offsets are mirror-symmetric (o_σ(j) = M o_j, checked
  by ``check_mirror_symmetric``) and σ commutes with the parent map, so G'_j = M G_σ(j) M and
  X'_j = X'_parent(j) + G'_j o_j = M (X_σ(parent(j)) + G_σ(j) o_σ(j)) = M X_σ(j).
* root_path (..., T, 2) as (x, z): x negated.
* heading (..., T), about +Y, 0 facing +Z (atan2 of the forward vector's x and z): negated, since M negates the
  forward vector's x.
* contacts (..., T, 4) in ``CONTACT_POINTS`` order (left heel, left toe, right heel, right toe): each column
  swapped with its counterpart's, giving (right heel, right toe, left heel, left toe) of the original. Contacts
  are decided from a point's speed and height, which M keeps.
* phase (..., T), 0 at a left strike and π at a right strike: the mirrored gait's left strikes are the original's
  right strikes, so θ' = θ + π, wrapped to [0, 2π). The phase rate is unchanged.
* affective (..., T, 18): angles, distance ratios and area ratios of joints, each unchanged by a reflection; the
  mirrored gait's feature i is the original's feature whose definition is feature i's with every joint replaced
  by its counterpart (``affective_counterparts``; for the paper's 18: 2<->3, 7<->8, 9<->10, 11<->12, 15<->16, the
  other 8 are their own).
* movement (..., T, 5): root height, speed and low-passed speed are unchanged. The heading-to-path angle as
  defined (``features.movement_features``) is unsigned, |angle| between heading and path tangent, and the path
  curvature is the norm of the tangent's change; M turns a signed angle or turn into its negative, so these two,
  being magnitudes, are unchanged too. (A signed version of either would change sign.)
* emotion, emotion_per_frame: unchanged. Text naming a side (a clip's content 'walk-turn-left') swaps left and
  right (``mirror_side_name``).

Mirroring is its own inverse: positions, rotations, contacts, features and heading exactly, the phase to float
rounding. This module knows arrays and joint names, never files or tables.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import numpy as np
import torch

from pipeline.core.skeleton import Skeleton
from pipeline.ops.contacts import CONTACT_POINTS
from pipeline.ops.features import AFFECTIVE_FEATURES
from pipeline.ops.geometry import wrap_phase

_SIDE = re.compile(r"(?<![a-z])(left|right)(?![a-z])")

# Per-gait arrays that mirroring leaves as they are (see the module docstring for why).
UNCHANGED = ("emotion", "emotion_per_frame", "phase_rate", "movement")


def mirror_side_name(name: str) -> str:
    """'left_hip' -> 'right_hip', 'walk-turn-left' -> 'walk-turn-right'; a name naming no side is unchanged."""
    return _SIDE.sub(lambda m: "right" if m.group(1) == "left" else "left", name)


def counterparts(names: Sequence[str]) -> tuple[int, ...]:
    """σ: for each name, the index of its left/right counterpart (itself on the midline)."""
    index = {n: i for i, n in enumerate(names)}
    out = []
    for n in names:
        other = mirror_side_name(n)
        if other not in index:
            raise ValueError(f"mirroring: '{n}' has no counterpart; expected a name '{other}' among {list(names)}")
        out.append(index[other])
    return tuple(out)


def check_mirror_symmetric(skeleton: Skeleton) -> None:
    """Raise unless the skeleton is its own mirror image: σ(parent(j)) = parent(σ(j)) and o_σ(j) = M o_j."""
    sigma = counterparts(skeleton.names)
    reflected = skeleton.offsets * np.array([-1.0, 1.0, 1.0])
    for j, s in enumerate(sigma):
        p, ps = skeleton.parents[j], skeleton.parents[s]
        if (p < 0) != (ps < 0) or (p >= 0 and sigma[p] != ps):
            raise ValueError(f"mirroring: joint '{skeleton.names[j]}' has parent "
                             f"'{skeleton.names[p] if p >= 0 else None}', its counterpart '{skeleton.names[s]}' "
                             f"has '{skeleton.names[ps] if ps >= 0 else None}'; expected counterparts")
        if not np.allclose(skeleton.offsets[s], reflected[j], atol=1e-9):
            raise ValueError(f"mirroring: rest offset of '{skeleton.names[s]}' is {skeleton.offsets[s].tolist()}, "
                             f"expected the mirror of '{skeleton.names[j]}''s, {reflected[j].tolist()}")


def _take(x: torch.Tensor, index: Sequence[int], dim: int) -> torch.Tensor:
    return x.index_select(dim, torch.as_tensor(index, device=x.device))


def mirror_positions(positions: torch.Tensor, sigma: Sequence[int]) -> torch.Tensor:
    """positions (..., J, 3) -> (..., J, 3): X'_j = M X_σ(j), M negating x."""
    return _take(positions, sigma, -2) * positions.new_tensor([-1.0, 1.0, 1.0])


def mirror_rotations(rotations: torch.Tensor, sigma: Sequence[int]) -> torch.Tensor:
    """Local rotations (..., J, 4) [w, x, y, z] -> (..., J, 4): q'_j = M q_σ(j) M = [w, x, -y, -z] of q_σ(j)."""
    return _take(rotations, sigma, -2) * rotations.new_tensor([1.0, 1.0, -1.0, -1.0])


def mirror_root_path(root_path: torch.Tensor) -> torch.Tensor:
    """Ground path (..., T, 2) as (x, z) -> (..., T, 2): x negated."""
    return root_path * root_path.new_tensor([-1.0, 1.0])


def mirror_heading(heading: torch.Tensor) -> torch.Tensor:
    """Headings (...) about +Y, 0 facing +Z -> (...): negated."""
    return -heading


def mirror_contacts(contacts: torch.Tensor, points: Sequence[str] = CONTACT_POINTS) -> torch.Tensor:
    """Contact flags (..., T, P), columns named ``points`` -> (..., T, P): each column swapped with its
    counterpart's (left heel, left toe, right heel, right toe -> the original's right heel, right toe, left heel,
    left toe)."""
    return _take(contacts, counterparts(points), -1)


def mirror_phase(phase: torch.Tensor) -> torch.Tensor:
    """Stepping phase (...) in [0, 2π), 0 at a left strike -> (...): θ + π wrapped to [0, 2π) (the mirrored gait's
    left strikes are the original's right strikes). A value that rounds up to 2π in the tensor's precision is 0."""
    out = wrap_phase(phase + math.pi)
    return torch.where(out >= 2 * math.pi, torch.zeros_like(out), out)


def _definition_key(kind: str, joints: Sequence[int]) -> tuple:
    """What a feature measures, independent of the order its definition lists symmetric joints in."""
    if kind == "angle":  # (a, v, b): the angle at v between a and b
        return kind, joints[1], frozenset((joints[0], joints[2]))
    if kind == "distance_ratio":  # d(a, b) / d(c, d)
        return kind, frozenset(joints[:2]), frozenset(joints[2:])
    if kind == "area_ratio":  # area(a, b, c) / area(d, e, f)
        return kind, frozenset(joints[:3]), frozenset(joints[3:])
    raise ValueError(f"mirroring: unknown affective feature kind {kind!r}")


def affective_counterparts(sigma: Sequence[int],
                           features: Sequence[tuple[str, Sequence[int]]] = AFFECTIVE_FEATURES) -> tuple[int, ...]:
    """For each affective feature, the index of the feature that measures the same on the mirrored body (its
    definition with every joint replaced by its counterpart); raises if the feature set is not closed under
    mirroring."""
    keys = {_definition_key(kind, joints): i for i, (kind, joints) in enumerate(features)}
    out = []
    for i, (kind, joints) in enumerate(features):
        key = _definition_key(kind, [sigma[j] for j in joints])
        if key not in keys:
            raise ValueError(f"mirroring: affective feature {i} ({kind} {tuple(joints)}) has no mirror-image feature; "
                             f"expected one on joints {tuple(sigma[j] for j in joints)}")
        out.append(keys[key])
    return tuple(out)


def mirror_affective(affective: torch.Tensor, sigma: Sequence[int],
                     features: Sequence[tuple[str, Sequence[int]]] = AFFECTIVE_FEATURES) -> torch.Tensor:
    """Affective features (..., F) -> (..., F) of the mirrored pose: the original's, mirror-paired features swapped."""
    return _take(affective, affective_counterparts(sigma, features), -1)


def mirror_gait(gait: Mapping[str, torch.Tensor], skeleton: Skeleton,
                contact_points: Sequence[str] = CONTACT_POINTS) -> dict[str, torch.Tensor]:
    """The mirror image of a gait (or a batch: every array with the same leading dimensions) given as its
    per-gait arrays by column name (``core.schema``): positions (..., T, J, 3), rotations (..., T, J, 4),
    root_path (..., T, 2), heading (..., T), contacts (..., T, 4), phase (..., T), affective (..., T, 18), and
    the unchanged ``UNCHANGED``. A column with no rule here is refused rather than passed through unmirrored."""
    check_mirror_symmetric(skeleton)
    sigma = counterparts(skeleton.names)
    rules = {
        "positions": lambda x: mirror_positions(x, sigma),
        "rotations": lambda x: mirror_rotations(x, sigma),
        "root_path": mirror_root_path,
        "heading": mirror_heading,
        "contacts": lambda x: mirror_contacts(x, contact_points),
        "phase": mirror_phase,
        "affective": lambda x: mirror_affective(x, sigma),
        **{name: (lambda x: x) for name in UNCHANGED},
    }
    unknown = sorted(set(gait) - set(rules))
    if unknown:
        raise KeyError(f"mirroring: no rule for {unknown}; expected columns among {sorted(rules)}")
    return {name: rules[name](x) for name, x in gait.items()}
