"""Marker trajectories -> what the pipeline uses: gap-filled tracks, heel/toe contact points, joint centres.

Which marker is the left heel, where the hip joint centre lies, which markers make the upper body: all of
that is data, the ``marker_sets`` of a C3D source manifest. A rule is one of
  * ``"LTOE"``                         a marker;
  * ``{"L_MT_1": 0.5, "L_MT_5": 0.5}``  an affine combination of markers (weights sum to 1), e.g. a midpoint;
  * ``["LHEE", "LANK"]``               alternatives, the first one the file has with data wins;
  * ``{"hip_centre": "left"}``         the hip joint centre by the regression of Harrington et al. (2007);
  * ``{"lateral": "LKNE", "medial_offset_m": 0.055}``  a joint centre medial of a lateral marker;
  * ``{"joints": {"root": 0.76, "neck": 0.24}}``       a virtual joint between canonical joints.

Hip joint centre: Harrington, Zavatsky, Lawson, Yuan & Stebbins (2007), "Prediction of the hip joint centre in
adults, children, and patients with cerebral palsy based on magnetic resonance imaging", J. Biomech. 40(3),
595-602: in the pelvis frame (origin mid-ASIS; x anterior, y superior, z right; mm)
    x = -0.24 PD - 9.9,  y = -0.30 PW - 10.9,  z = ±(0.33 PW + 7.3)
with PW the inter-ASIS distance and PD the depth from mid-ASIS to mid-PSIS (or the sacral marker).

A transform: arrays and names in, arrays out; it knows neither files nor sources.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

CONTACT_RULES = ("left_heel", "left_toe", "right_heel", "right_toe")  # pipeline.ops.contacts.CONTACT_POINTS order


class MarkerRuleError(ValueError):
    """A rule cannot be evaluated on this file: the message names the rule and the missing markers."""


@dataclass(frozen=True)
class GapFill:
    positions: np.ndarray  # (F, M, 3) with interior gaps of <= max_frames filled; other gaps still NaN
    filled: np.ndarray  # (M,) samples filled per marker
    long_gaps: np.ndarray  # (M,) interior gaps left open (longer than max_frames) per marker


def fill_short_gaps(positions: np.ndarray, max_frames: int) -> GapFill:
    """Fill interior gaps of at most ``max_frames`` missing frames (NaN) by linear interpolation, per marker.

    positions: (F, M, 3). Gaps at the start or end of a track are never extrapolated (there is nothing to
    interpolate towards); gaps longer than ``max_frames`` stay NaN and are counted.
    """
    out = np.array(positions, dtype=np.float64, copy=True)
    frames, markers = out.shape[:2]
    filled = np.zeros(markers, dtype=np.int64)
    long_gaps = np.zeros(markers, dtype=np.int64)
    ok = np.isfinite(out).all(-1)
    for m in range(markers):
        for start, stop in runs(~ok[:, m]):
            if start == 0 or stop == frames:
                continue  # edge gap: trimmed later, never invented
            if stop - start > max_frames:
                long_gaps[m] += 1
                continue
            a, b = out[start - 1, m], out[stop, m]
            w = (np.arange(start, stop) - (start - 1))[:, None] / (stop - start + 1)
            out[start:stop, m] = a + w * (b - a)
            filled[m] += stop - start
    return GapFill(out, filled, long_gaps)


def runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of every run of True in a (F,) boolean array."""
    padded = np.concatenate([[False], np.asarray(flags, dtype=bool), [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def select_marker_set(marker_sets: Sequence[Mapping[str, Any]], labels: Sequence[str]) -> Mapping[str, Any] | None:
    """The first marker set all of whose ``requires`` labels the file has, or None."""
    have = set(labels)
    for marker_set in marker_sets:
        if all(r in have for r in marker_set["requires"]):
            return marker_set
    return None


def evaluate_rule(rule: Any, labels: Sequence[str], positions: np.ndarray, name: str = "rule") -> np.ndarray:
    """(F, 3) trajectory of a marker rule (see the module docstring); NaN where a marker is missing."""
    columns = {label: k for k, label in enumerate(labels)}
    if isinstance(rule, str):
        if rule not in columns:
            raise MarkerRuleError(f"{name}: marker {rule!r} is not in the file")
        return positions[:, columns[rule]]
    if isinstance(rule, list):
        tried = []
        for alternative in rule:
            try:
                track = evaluate_rule(alternative, labels, positions, name)
            except MarkerRuleError as err:
                tried.append(str(err))
                continue
            if np.isfinite(track).all(-1).any():
                return track
            tried.append(f"{alternative!r} has no valid sample")
        raise MarkerRuleError(f"{name}: no alternative usable ({'; '.join(tried)})")
    if isinstance(rule, Mapping):
        weights = {k: float(v) for k, v in rule.items()}
        if abs(sum(weights.values()) - 1.0) > 1e-9:
            raise MarkerRuleError(f"{name}: weights must sum to 1, found {sum(weights.values())}")
        missing = [k for k in weights if k not in columns]
        if missing:
            raise MarkerRuleError(f"{name}: markers {missing} are not in the file")
        return sum(w * positions[:, columns[k]] for k, w in weights.items())
    raise MarkerRuleError(f"{name}: unknown rule {rule!r}")


def contact_points(marker_set: Mapping[str, Any], labels: Sequence[str], positions: np.ndarray) -> np.ndarray:
    """Heel and toe trajectories (F, 4, 3) in CONTACT_RULES order from the marker set's ``contacts`` rules."""
    rules = marker_set["contacts"]
    return np.stack([evaluate_rule(rules[k], labels, positions, k) for k in CONTACT_RULES], axis=1)


def pelvis_frame(lasi: np.ndarray, rasi: np.ndarray, sacrum: np.ndarray) -> tuple[np.ndarray, ...]:
    """Origin (mid-ASIS) and unit axes (anterior, superior, right) of the pelvis, each (F, 3); Y-up metres."""
    origin = 0.5 * (lasi + rasi)
    right = rasi - lasi
    right = right / np.linalg.norm(right, axis=-1, keepdims=True)
    anterior = origin - sacrum
    anterior = anterior - (anterior * right).sum(-1, keepdims=True) * right
    anterior = anterior / np.linalg.norm(anterior, axis=-1, keepdims=True)
    superior = np.cross(right, anterior)  # x anterior, y superior, z right: z = x × y
    return origin, anterior, superior, right


def harrington_hip_centres(lasi: np.ndarray, rasi: np.ndarray, sacrum: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left and right hip joint centres (F, 3) by Harrington et al. (2007); inputs in metres, Y up."""
    origin, anterior, superior, right = pelvis_frame(lasi, rasi, sacrum)
    width = np.linalg.norm(rasi - lasi, axis=-1, keepdims=True) * 1000.0  # mm, as the regression is stated
    depth = np.linalg.norm(0.5 * (lasi + rasi) - sacrum, axis=-1, keepdims=True) * 1000.0
    x = (-0.24 * depth - 9.9) / 1000.0
    y = (-0.30 * width - 10.9) / 1000.0
    z = (0.33 * width + 7.3) / 1000.0
    base = origin + x * anterior + y * superior
    return base - z * right, base + z * right


def canonical_joints(marker_set: Mapping[str, Any], labels: Sequence[str], positions: np.ndarray,
                     joint_names: Sequence[str]) -> np.ndarray:
    """Canonical joint positions (F, J, 3) from the marker set's ``canonical`` rules; positions in metres, Y up.

    Raises MarkerRuleError naming the first joint whose rule cannot be evaluated on this file.
    """
    rules = marker_set.get("canonical")
    if not rules:
        raise MarkerRuleError("the marker set declares no canonical (full-body) rules")
    pelvis = marker_set.get("pelvis") or {}
    out: dict[str, np.ndarray] = {}
    hips: tuple[np.ndarray, np.ndarray] | None = None
    right_axis: np.ndarray | None = None
    pending = []
    for joint in joint_names:
        if joint not in rules:
            raise MarkerRuleError(f"no rule for canonical joint {joint!r}")
        rule = rules[joint]
        if isinstance(rule, Mapping) and "hip_centre" in rule:
            if hips is None:
                lasi, rasi, sacrum = (evaluate_rule(pelvis[k], labels, positions, f"pelvis {k}")
                                      for k in ("left_asis", "right_asis", "sacrum"))
                hips = harrington_hip_centres(lasi, rasi, sacrum)
            out[joint] = hips[0] if rule["hip_centre"] == "left" else hips[1]
        elif isinstance(rule, Mapping) and "lateral" in rule:
            if right_axis is None:
                lasi, rasi = (evaluate_rule(pelvis[k], labels, positions, f"pelvis {k}")
                              for k in ("left_asis", "right_asis"))
                right_axis = rasi - lasi
                right_axis = right_axis / np.linalg.norm(right_axis, axis=-1, keepdims=True)
            lateral = evaluate_rule(rule["lateral"], labels, positions, joint)
            medial = right_axis if joint.startswith("left") else -right_axis  # towards the body's midline
            out[joint] = lateral + float(rule["medial_offset_m"]) * medial
        elif isinstance(rule, Mapping) and "joints" in rule:
            pending.append(joint)
        else:
            out[joint] = evaluate_rule(rule, labels, positions, joint)
    for joint in pending:  # virtual joints between canonical joints, once those exist
        weights = {k: float(v) for k, v in rules[joint]["joints"].items()}
        if abs(sum(weights.values()) - 1.0) > 1e-9 or any(k not in out for k in weights):
            raise MarkerRuleError(f"{joint}: joint weights must sum to 1 over marker-based joints, found {weights}")
        out[joint] = sum(w * out[k] for k, w in weights.items())
    return np.stack([out[j] for j in joint_names], axis=1)
