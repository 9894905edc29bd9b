"""Foot-contact validation: our detector's foot strikes / foot offs against gait events annotated in C3D trials.

For every trial with annotated events: the heel and toe marker trajectories of each foot (by the source
manifest's marker-set rules), in metres and Y up, short gaps filled, the floor moved to y = 0 (a low
quantile of all foot-marker heights of the trial); then ``pipeline.ops.contacts.foot_contacts`` and
``foot_events`` at the trial's native rate on every stretch where both markers of a foot are tracked.
Derived and annotated events are matched one-to-one per (side, kind), nearest pairs first, within a
tolerance. False events are derived events without a match, counted only inside the annotated time
span ± a margin (annotations usually cover only part of a trial), per second of that span.

The same scoring serves any detector that returns (kind, side, time) events, so an established method
(``zeni_events``, Zeni et al. 2008, via the ``gaitalytics`` package) is scored beside ours on the same input.

A library module: manifests, configs and arrays in, trials and numbers out (``annotated_trials`` reads the
C3D files through the file screen ingest uses, ``pipeline.ingest.screen``); the stage reads the params and
writes the report.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.ops.contacts import ContactConfig, foot_contacts, foot_events
from pipeline.ingest.markers import (
    CONTACT_RULES,
    MarkerRuleError,
    contact_points,
    evaluate_rule,
    fill_short_gaps,
    runs,
    select_marker_set,
)
from pipeline.io.files import save_figure
from pipeline.ingest.screen import screen_file
from pipeline.io.manifests import SourceManifest, list_inputs
from pipeline.io.readers.c3d import C3dClip, positions_m_y_up

SIDES = {"left": (0, 1), "right": (2, 3)}  # heel, toe columns in CONTACT_POINTS order
KINDS = ("foot_strike", "foot_off")
TIME_EPS = 1e-6  # s: EVENT:TIMES are float32 (about 0.5 µs resolution at 5 s); a tolerance edge is not a miss


@dataclass(frozen=True)
class ValidationConfig:
    tolerance_s: float = 0.05  # an annotated event counts as matched within this
    span_margin_s: float = 0.5  # false events are counted inside [first annotated - margin, last + margin]
    floor_quantile: float = 0.02  # the floor: this quantile of all foot-marker heights of the trial
    max_gap_seconds: float = 0.1  # interior gaps filled by interpolation
    min_run_seconds: float = 0.5  # shorter tracked stretches of a foot are not analysed


@dataclass(frozen=True)
class Event:
    kind: str  # foot_strike | foot_off
    side: str  # left | right
    time: float  # s, on the trial's clock


@dataclass
class Trial:
    """One C3D trial prepared for validation (all arrays on the trial's native frame grid)."""

    name: str
    fps: float
    times: np.ndarray  # (T,) s
    points: np.ndarray  # (T, 4, 3) heel/toe L/R, metres, Y up, floor at 0, NaN where untracked
    annotated: list[Event]
    marker_set: str
    pelvis: dict[str, np.ndarray] = field(default_factory=dict)  # file-frame (Z-up) metres, for Zeni
    contact_points_zup: np.ndarray | None = None  # (T, 4, 3) file-frame metres, for Zeni
    filled: dict[str, int] = field(default_factory=dict)  # gap samples filled per contact point


def prepare_trial(name: str, clip: C3dClip, marker_sets: Sequence[Mapping[str, Any]], up_axis: str,
                  cfg: ValidationConfig = ValidationConfig()) -> Trial:
    """Heel/toe tracks of one clip in metres, Y up, gaps filled, floor at y = 0. Raises MarkerRuleError."""
    marker_set = select_marker_set(marker_sets, clip.labels)
    if marker_set is None:
        raise MarkerRuleError(f"no marker set of the manifest matches the labels {list(clip.labels)[:12]}...")
    max_frames = int(round(cfg.max_gap_seconds * clip.rate))
    gaps = fill_short_gaps(clip.positions, max_frames)
    raw = contact_points(marker_set, clip.labels, gaps.positions)  # (T, 4, 3) file units and axes
    zup = raw * clip.unit_scale_m
    points = positions_m_y_up(raw, clip.unit_scale_m, up_axis)
    heights = points[..., 1]
    points[..., 1] -= np.nanquantile(heights, cfg.floor_quantile)
    pelvis = {}
    for key, rule in (marker_set.get("pelvis") or {}).items():
        try:
            pelvis[key] = evaluate_rule(rule, clip.labels, gaps.positions, key) * clip.unit_scale_m
        except ValueError:
            continue
    annotated = [Event(e.kind, e.side, e.time) for e in clip.events]
    before = np.isfinite(contact_points(marker_set, clip.labels, clip.positions)).all(-1)
    after = np.isfinite(raw).all(-1)
    filled = {k: int((after[:, i] & ~before[:, i]).sum()) for i, k in enumerate(CONTACT_RULES)}
    return Trial(name=name, fps=clip.rate, times=clip.times(), points=points, annotated=annotated,
                 marker_set=marker_set["name"], pelvis=pelvis, contact_points_zup=zup, filled=filled)


def annotated_trials(manifests: Sequence[SourceManifest], mocap_root: Path,
                     cfg: ValidationConfig = ValidationConfig()) -> tuple[list[Trial], list[dict[str, str]]]:
    """Every C3D trial with annotated foot strikes / foot offs, prepared; and every other input, with the reason.

    The inputs are those ingest accounts for (``list_inputs``: pinned files and unpinned ones the globs find),
    screened as ingest screens them. A manifest's ``max_gap_seconds`` overrides ``cfg.max_gap_seconds``.
    """
    trials, skipped = [], []
    for manifest in manifests:
        if manifest.format != "c3d":
            raise ValueError(f"manifest {manifest.name}: expected a C3D source (annotated gait events), "
                             f"found format {manifest.format!r}")
        source_dir = mocap_root / manifest.name
        gaps = manifest.max_gap_seconds
        trial_cfg = replace(cfg, max_gap_seconds=cfg.max_gap_seconds if gaps is None else gaps)
        for rel, pinned in list_inputs(manifest, source_dir):
            name = f"{manifest.name}/{rel}"
            screened = screen_file(manifest, source_dir, rel, pinned)
            if screened.rejection is not None:
                skipped.append({"file": name, "reason": screened.rejection})
            elif not screened.clip.events:
                skipped.append({"file": name, "reason": "no annotated foot strike / foot off events"})
            else:
                try:
                    trials.append(prepare_trial(name, screened.clip, manifest.marker_sets, manifest.up_axis,
                                                trial_cfg))
                except MarkerRuleError as err:
                    skipped.append({"file": name, "reason": f"no heel/toe markers: {err}"})
    return trials, skipped


def derive_events(points: np.ndarray, fps: float, cfg: ContactConfig) -> list[tuple[str, str, int]]:
    """Our detector on heel/toe tracks (T, 4, 3) with NaN gaps: (kind, side, frame) events.

    Each foot is analysed on every stretch where both its markers are tracked, so a marker dropping out
    never reads as a foot lifting off or landing.
    """
    out: list[tuple[str, str, int]] = []
    frames_needed = 3
    for side, cols in SIDES.items():
        tracked = np.isfinite(points[:, list(cols)]).all(axis=(-1, -2))
        for start, stop in runs(tracked):
            if stop - start < frames_needed:
                continue
            seg = torch.from_numpy(np.ascontiguousarray(points[start:stop][:, list(cols)]))
            contacts = foot_contacts(seg, fps, cfg)  # (S, 2)
            both = torch.zeros(stop - start, 4, dtype=torch.bool)
            both[:, list(cols)] = contacts
            events = foot_events(both, fps, cfg)
            out += [("foot_strike", side, start + f) for f in events[f"{side}_strike"]]
            out += [("foot_off", side, start + f) for f in events[f"{side}_off"]]
    return sorted(out, key=lambda e: (e[2], e[1], e[0]))


def our_events(trial: Trial, cfg: ContactConfig, vcfg: ValidationConfig = ValidationConfig()) -> list[Event]:
    tracked = _long_runs_only(trial.points, trial.fps, vcfg.min_run_seconds)
    return [Event(k, s, float(trial.times[f])) for k, s, f in derive_events(tracked, trial.fps, cfg)]


def _long_runs_only(points: np.ndarray, fps: float, min_seconds: float) -> np.ndarray:
    out = points.copy()
    for cols in SIDES.values():
        tracked = np.isfinite(points[:, list(cols)]).all(axis=(-1, -2))
        for start, stop in runs(tracked):
            if (stop - start) / fps < min_seconds:
                out[start:stop, list(cols)] = np.nan
    return out


def match_events(annotated: Sequence[Event], derived: Sequence[Event],
                 tolerance: float) -> list[tuple[int, int, float]]:
    """One-to-one matches (annotated index, derived index, derived - annotated seconds), nearest pairs first."""
    pairs = sorted((abs(d.time - a.time), i, j) for i, a in enumerate(annotated) for j, d in enumerate(derived)
                   if a.kind == d.kind and a.side == d.side and abs(d.time - a.time) <= tolerance + TIME_EPS)
    used_a: set[int] = set()
    used_d: set[int] = set()
    out = []
    for _, i, j in pairs:
        if i in used_a or j in used_d:
            continue
        used_a.add(i)
        used_d.add(j)
        out.append((i, j, derived[j].time - annotated[i].time))
    return sorted(out)


def evaluable(trial: Trial, cfg: ValidationConfig = ValidationConfig()) -> list[bool]:
    """Per annotated event: were both markers of its foot tracked at the event's frame and the frames either
    side of it, on a stretch long enough to analyse? Where they were not (a marker occluded at that very
    moment) no marker-based method can find the event; such events are reported and counted apart."""
    tracked = np.isfinite(_long_runs_only(trial.points, trial.fps, cfg.min_run_seconds)).all(-1)  # (T, 4)
    out = []
    for e in trial.annotated:
        k = int(np.argmin(np.abs(trial.times - e.time)))
        window = tracked[max(0, k - 1):k + 2][:, list(SIDES[e.side])]
        out.append(bool(window.all()) and 0 < k < len(trial.times) - 1)
    return out


def score(annotated: Sequence[Event], derived: Sequence[Event], cfg: ValidationConfig = ValidationConfig(),
          evaluable_flags: Sequence[bool] | None = None) -> dict:
    """Figures of one trial (or of pooled trials via ``pool``): matched fraction, errors, false events."""
    matches = match_events(annotated, derived, cfg.tolerance_s)
    flags = list(evaluable_flags) if evaluable_flags is not None else [True] * len(annotated)
    matched_a = {i for i, _, _ in matches}
    errors = [abs(e) for _, _, e in matches]
    if annotated:
        lo = min(a.time for a in annotated) - cfg.span_margin_s
        hi = max(a.time for a in annotated) + cfg.span_margin_s
    else:
        lo = hi = 0.0
    matched_d = {j for _, j, _ in matches}
    false = [d for j, d in enumerate(derived) if j not in matched_d and lo <= d.time <= hi]
    return {
        "annotated": len(annotated),
        "matched": len(matches),
        "evaluable": sum(flags),
        "matched_evaluable": sum(1 for i in matched_a if flags[i]),
        "derived_in_span": sum(lo <= d.time <= hi for d in derived),
        "false_events": len(false),
        "span_s": hi - lo,
        "errors_s": errors,
        "signed_errors_s": [e for _, _, e in matches],
        "unmatched": [{"kind": a.kind, "side": a.side, "time": round(a.time, 4), "evaluable": flags[i]}
                      for i, a in enumerate(annotated) if i not in matched_a],
    }


def summarize(raw: Mapping[str, Any]) -> dict:
    """Figures from a ``score`` dict (or several pooled): the report's numbers, rounded for stable JSON."""
    errors = np.asarray(raw["errors_s"], dtype=np.float64)
    signed = np.asarray(raw["signed_errors_s"], dtype=np.float64)
    n = raw["annotated"]
    return {
        "annotated_events": n,
        "matched_events": raw["matched"],
        "matched_fraction": round(raw["matched"] / n, 4) if n else None,
        "evaluable_events": raw["evaluable"],
        "matched_evaluable_fraction": round(raw["matched_evaluable"] / raw["evaluable"], 4) if raw["evaluable"] else None,
        "median_abs_error_ms": round(float(np.median(errors)) * 1000, 2) if errors.size else None,
        "p90_abs_error_ms": round(float(np.percentile(errors, 90)) * 1000, 2) if errors.size else None,
        "mean_signed_error_ms": round(float(signed.mean()) * 1000, 2) if signed.size else None,
        "false_events": raw["false_events"],
        "false_events_per_s": round(raw["false_events"] / raw["span_s"], 4) if raw["span_s"] else None,
        "unmatched": raw["unmatched"],
    }


def pool(raws: Sequence[Mapping[str, Any]]) -> dict:
    keys = ("annotated", "matched", "evaluable", "matched_evaluable", "derived_in_span", "false_events", "span_s")
    out: dict[str, Any] = {k: sum(r[k] for r in raws) for k in keys}
    out["errors_s"] = [e for r in raws for e in r["errors_s"]]
    out["signed_errors_s"] = [e for r in raws for e in r["signed_errors_s"]]
    out["unmatched"] = []
    return out


def zeni_events(trial: Trial, **kwargs: Any) -> list[Event]:
    """Zeni et al. (2008) events by the ``gaitalytics`` package (MarkerEventDetection) on the same tracks.

    Zeni, Richards & Higginson, "Two simple methods for determining gait events during treadmill and
    overground walking using kinematic data", Gait & Posture 27(4):710-714: foot strike at the maximum of
    the heel's anterior distance from the sacrum, foot off at the minimum of the toe's. The package rotates
    the markers into the direction of progression (ASIS midpoint - sacrum) in the horizontal plane of a
    Z-up lab, which is how the files are recorded, so the file frame (in metres) is passed. Raises
    KeyError when the trial has no ASIS/sacrum markers.
    """
    import tempfile
    from pathlib import Path

    import xarray as xr
    import yaml
    from gaitalytics import api as ga_api
    from gaitalytics import mapping as ga_mapping
    from gaitalytics import model as ga_model

    names = {"l_heel": 0, "l_toe": 1, "r_heel": 2, "r_toe": 3}
    pelvis = {"l_ant_hip": "left_asis", "r_ant_hip": "right_asis", "sacrum": "sacrum"}
    missing = [v for v in pelvis.values() if v not in trial.pelvis]
    if missing:
        raise KeyError(f"{trial.name}: no {missing} markers for the Zeni method")
    tracks = [trial.contact_points_zup[:, k] for k in names.values()] + [trial.pelvis[v] for v in pelvis.values()]
    labels = list(names) + list(pelvis)
    data = np.stack(tracks, axis=0).transpose(2, 0, 1)  # (axis, channel, time)
    markers = xr.DataArray(data, dims=("axis", "channel", "time"),
                           coords={"axis": ["x", "y", "z"], "channel": labels, "time": trial.times})
    ga_trial = ga_model.Trial()
    ga_trial.add_data(ga_model.DataCategory.MARKERS, markers)
    config = {"analysis": {"markers": labels}, "mapping": {"markers": {k: k for k in labels}}}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mapping.yaml"
        path.write_text(yaml.safe_dump(config))
        mapping = ga_mapping.MappingConfigs(path)
    table = ga_api.detect_events(ga_trial, mapping, **kwargs)
    kind = {"Foot Strike": "foot_strike", "Foot Off": "foot_off"}
    return sorted((Event(kind[row.label], row.context.lower(), float(row.time)) for row in
                   table.rename(columns=str.lower).itertuples()), key=lambda e: (e.time, e.side, e.kind))


DETECTORS = ("ours", "zeni_gaitalytics")


def validate(trials: Sequence[Trial], cfg: ContactConfig, vcfg: ValidationConfig = ValidationConfig(),
             reference: bool = True) -> tuple[dict, dict[str, dict[str, list[Event]]]]:
    """Score our detector (and the Zeni reference) on every trial.

    Returns (figures, events): figures per detector, overall and per trial; events[detector][trial name].
    """
    events: dict[str, dict[str, list[Event]]] = {d: {} for d in DETECTORS}
    figures: dict[str, Any] = {}
    for detector in DETECTORS:
        if detector == "zeni_gaitalytics" and not reference:
            continue
        raws, per_file, errors = [], {}, {}
        for trial in trials:
            try:
                found = our_events(trial, cfg, vcfg) if detector == "ours" else zeni_events(trial)
            except (KeyError, ImportError) as err:
                errors[trial.name] = f"{type(err).__name__}: {err}"
                found = []
            events[detector][trial.name] = found
            raw = score(trial.annotated, found, vcfg, evaluable(trial, vcfg))
            raws.append(raw)
            per_file[trial.name] = summarize(raw)
        figures[detector] = {"overall": summarize(pool(raws)) | {"trials": len(trials)}, "per_file": per_file}
        figures[detector]["overall"].pop("unmatched")
        if errors:
            figures[detector]["errors"] = errors
    return figures, events


def acceptance(figures: Mapping[str, Any], min_matched: float = 0.95, max_median_ms: float = 20.0) -> dict:
    """The issue's acceptance: >= 95 % of all annotated events matched within tolerance (and of the evaluable
    ones), median error <= 20 ms, and no worse than the reference detector on matched fraction and median error."""
    ours = figures["ours"]["overall"]
    out = {
        "min_matched_fraction": min_matched,
        "max_median_abs_error_ms": max_median_ms,
        "matched": bool(ours["matched_fraction"] is not None and ours["matched_fraction"] >= min_matched
                        and ours["matched_evaluable_fraction"] >= min_matched),
        "median": bool(ours["median_abs_error_ms"] is not None and ours["median_abs_error_ms"] <= max_median_ms),
    }
    ref = figures.get("zeni_gaitalytics", {}).get("overall")
    if ref:
        out["no_worse_than_reference"] = bool(
            ours["matched_fraction"] >= ref["matched_fraction"]
            and ours["matched_evaluable_fraction"] >= ref["matched_evaluable_fraction"]
            and ours["median_abs_error_ms"] <= ref["median_abs_error_ms"])
    out["passed"] = all(v for k, v in out.items() if isinstance(v, bool))
    return out


def contact_report(trials: Sequence[Trial], skipped: Sequence[Mapping[str, str]], figures: Mapping[str, Any],
                   cfg: ContactConfig, vcfg: ValidationConfig) -> dict:
    """The validation report (reports/contacts.json): configs, acceptance, figures, trials and the files not
    validated with their reasons."""
    return {
        "contact_config": cfg.__dict__,
        "validation_config": vcfg.__dict__,
        "acceptance": acceptance(figures),
        "detectors": figures,
        "trials": [{"file": t.name, "marker_set": t.marker_set, "fps": t.fps, "frames": int(len(t.times)),
                    "annotated_events": len(t.annotated), "gap_samples_filled": t.filled} for t in trials],
        "not_validated": list(skipped),
    }


def report_summary(report: Mapping[str, Any]) -> str:
    """One line for people: trials and events, ours and the reference."""
    figures = report["detectors"]
    ours, ref = figures["ours"]["overall"], figures.get("zeni_gaitalytics", {}).get("overall", {})
    return (f"{len(report['trials'])} annotated trials, {ours['annotated_events']} events; ours matched "
            f"{ours['matched_fraction']:.1%} ({ours['matched_evaluable_fraction']:.1%} of evaluable), median "
            f"{ours['median_abs_error_ms']} ms; Zeni {ref.get('matched_fraction', float('nan')):.1%}, median "
            f"{ref.get('median_abs_error_ms')} ms")


def render_contacts(trials: Sequence[Trial], events: Mapping[str, Mapping[str, list[Event]]], path) -> None:
    """Per trial and foot: heel and toe heights, annotated events (lines) and derived events (markers)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(trials), 2, figsize=(15, 2.3 * len(trials) + 0.8), squeeze=False)
    styles = {"ours": ("v", 0.16, "ours"), "zeni_gaitalytics": ("^", 0.145, "Zeni (gaitalytics)")}
    for row, trial in zip(axes, trials):
        for ax, (side, (heel, toe)) in zip(row, SIDES.items()):
            ax.plot(trial.times, trial.points[:, heel, 1] * 100, color="tab:blue", lw=1, label="heel")
            ax.plot(trial.times, trial.points[:, toe, 1] * 100, color="tab:orange", lw=1, label="toe")
            for e in trial.annotated:
                if e.side == side:
                    ax.axvline(e.time, color="tab:green" if e.kind == "foot_strike" else "tab:red", lw=1.2, alpha=0.7)
            for detector, (marker, y, name) in styles.items():
                for e in events.get(detector, {}).get(trial.name, []):
                    if e.side == side:
                        ax.plot(e.time, y * 100, marker, ms=6, linestyle="none",
                                color="tab:green" if e.kind == "foot_strike" else "tab:red",
                                markerfacecolor="none" if detector != "ours" else None)
            ax.set_ylim(-1, 17)
            ax.set_ylabel("height (cm)")
            ax.set_title(f"{trial.name.rsplit('/', 1)[-1]} - {side} foot ({trial.fps:g} Hz, {trial.marker_set})", fontsize=9)
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="tab:blue", label="heel point height (ankle marker where the set has one)"),
               Line2D([], [], color="tab:orange", label="toe height"),
               Line2D([], [], color="tab:green", label="annotated foot strike"),
               Line2D([], [], color="tab:red", label="annotated foot off"),
               Line2D([], [], marker="v", color="k", linestyle="none", label="ours (strike green, off red)"),
               Line2D([], [], marker="^", color="k", markerfacecolor="none", linestyle="none",
                      label="Zeni / gaitalytics")]
    fig.legend(handles=handles, loc="upper center", ncol=6, fontsize=9, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.5 / fig.get_figheight()))
    save_figure(fig, path, dpi=80)
