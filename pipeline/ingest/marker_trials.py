"""C3D marker trials for the gait table: canonical joint positions of a trial, or the reason it has none.

A trial goes into the gait table only when its marker set (manifest ``marker_sets``) has ``canonical``
rules and the file has every marker they name; the joint positions then take the same retargeting path
as BVH joints (``pipeline.ingest.run``). Otherwise it is lower-body only (it still serves contact validation)
and is filtered with the joints it lacks. Interior gaps up to the manifest's ``max_gap_seconds`` are
filled and counted; what remains is trimmed to the longest stretch with every joint tracked.

Knows manifests' marker rules and C3D clips; never writes anything.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.ingest.markers import MarkerRuleError, canonical_joints, fill_short_gaps, runs, select_marker_set
from pipeline.io.readers.c3d import C3dClip, positions_m_y_up
from pipeline.io.manifests import SourceManifest


class NotUsable(ValueError):
    """The trial is fine but gives no canonical motion (a policy outcome: the file is filtered)."""


@dataclass(frozen=True)
class MarkerMotion:
    """Canonical joint positions of one trial, trimmed to its usable stretch (metres, Y up)."""

    points: np.ndarray  # (F, J, 3)
    fps: float
    time_offset: float  # s from the clip's first frame to the first frame kept
    filled: dict[str, int]  # gap samples filled per marker used
    marker_set: str

    @property
    def frames(self) -> int:
        return int(self.points.shape[0])

    @property
    def frame_time(self) -> float:
        return 1.0 / self.fps


def canonical_motion(manifest: SourceManifest, clip: C3dClip, joint_names: Sequence[str],
                     min_seconds: float) -> MarkerMotion:
    """Canonical joint positions of a trial, or NotUsable with the reason (lower-body only, gaps, too short)."""
    marker_set = select_marker_set(manifest.doc.get("marker_sets", []), clip.labels)
    if marker_set is None:
        raise NotUsable(f"no marker set of the manifest matches this file's labels "
                        f"({', '.join(list(clip.labels)[:10])}{', ...' if len(clip.labels) > 10 else ''})")
    positions = positions_m_y_up(clip.positions, clip.unit_scale_m, manifest.up_axis)
    rules = marker_set.get("canonical")
    if not rules:
        why = marker_set.get("canonical_note", "no full-body rules")
        raise NotUsable(f"lower-body only (marker set {marker_set['name']}): no full-body rules for the canonical "
                        f"skeleton ({why}); lower-body trials serve foot-contact validation, not the gait table")
    missing = _missing_markers(rules, clip.labels, clip.valid)
    if missing:
        listed = "; ".join(f"{j} ({', '.join(m)})" for j, m in missing.items())
        raise NotUsable(f"lower-body only (marker set {marker_set['name']}): no upper-body markers for the canonical "
                        f"skeleton: the full-body rules need {listed}; lower-body trials serve foot-contact "
                        "validation, not the gait table")
    max_frames = int(round(float(manifest.doc.get("max_gap_seconds", 0.0)) * clip.rate))
    gaps = fill_short_gaps(positions, max_frames)
    try:
        joints = canonical_joints(marker_set, clip.labels, gaps.positions, joint_names)
    except MarkerRuleError as err:
        raise NotUsable(f"marker set {marker_set['name']}: {err}") from None
    tracked = np.isfinite(joints).all(axis=(-1, -2))
    stretches = runs(tracked)
    if not stretches:
        raise NotUsable("no frame with every canonical joint tracked")
    start, stop = max(stretches, key=lambda r: (r[1] - r[0], -r[0]))
    if (stop - start - 1) / clip.rate + 1e-9 < min_seconds:
        raise NotUsable(f"too short after gaps: the longest stretch with every joint tracked is "
                        f"{(stop - start - 1) / clip.rate:.2f} s (frames {start}-{stop - 1}); >= {min_seconds:.2f} s "
                        f"needed (interior gaps up to {max_frames} frames are filled)")
    used = {n for n in _rule_marker_names(rules)}
    filled = {lab: int(n) for lab, n in zip(clip.labels, gaps.filled) if n and lab in used}
    return MarkerMotion(points=joints[start:stop], fps=clip.rate, time_offset=start / clip.rate, filled=filled,
                        marker_set=marker_set["name"])


def _missing_markers(rules: dict, labels: Sequence[str], valid: np.ndarray) -> dict[str, list[str]]:
    """Canonical joints whose every alternative names a marker the file lacks or never tracks."""
    have = {lab for k, lab in enumerate(labels) if valid[:, k].any()}
    missing: dict[str, list[str]] = {}
    for joint, rule in rules.items():
        alternatives = rule if isinstance(rule, list) else [rule]
        lacking = [[n for n in _rule_marker_names({joint: alt}) if n not in have] for alt in alternatives]
        if all(lacking):
            missing[joint] = lacking[0]
    return missing


def _rule_marker_names(rules: dict) -> list[str]:
    names: list[str] = []

    def walk(rule) -> None:
        if isinstance(rule, str):
            names.append(rule)
        elif isinstance(rule, list):
            for alt in rule:
                walk(alt)
        elif isinstance(rule, dict):
            if "lateral" in rule:
                walk(rule["lateral"])
            elif "hip_centre" in rule or "joints" in rule:
                return
            else:
                names.extend(rule)

    for rule in rules.values():
        walk(rule)
    return names
