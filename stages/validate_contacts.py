"""DVC stage `validate_contacts`: our foot-contact detector vs annotated gait events in the C3D trials.

Reads every C3D source manifest, checks each pinned file's sha256, takes the trials with annotated foot
strikes / foot offs and writes reports/contacts.json (figures of our detector and of the Zeni et al. 2008
reference, overall and per file) and reports/contacts.png (heel/toe heights with annotated and derived
events). Contact thresholds come from params.yaml ``annotate.contacts`` (the ones annotation uses);
validation settings from ``validate_contacts`` (defaults in pipeline.annotate.contact_validation.ValidationConfig).
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path
from typing import Any

from pipeline.annotate.contact_validation import (
    ValidationConfig,
    acceptance,
    prepare_trial,
    render_contacts,
    validate,
)
from pipeline.ops.contacts import ContactConfig
from pipeline.io.gait_table import write_json_atomic
from pipeline.ingest.markers import MarkerRuleError
from pipeline.io.readers.c3d import C3dError, read_c3d
from pipeline.io.manifests import load_manifests
from stages.common import REPO, SOURCES, load_params, mocap_root

OUT_REPORT = REPO / "reports" / "contacts.json"
OUT_PLOT = REPO / "reports" / "contacts.png"


def contact_config(params: dict[str, Any]) -> ContactConfig:
    return ContactConfig(**{k: float(v) for k, v in params["annotate"]["contacts"].items()})


def validation_config(params: dict[str, Any]) -> ValidationConfig:
    return ValidationConfig(**{k: float(v) for k, v in (params.get("validate_contacts") or {}).items()})


def load_trials(root: Path, sources: Path, vcfg: ValidationConfig) -> tuple[list, list[dict[str, str]]]:
    """Every annotated C3D trial, prepared; and every C3D file not validated, with the reason."""
    trials, skipped = [], []
    for manifest in load_manifests(sources, formats=("c3d",)):
        for entry in manifest.files:
            rel = f"{manifest.name}/{entry.path}"
            path = root / manifest.name / entry.path
            if not path.is_file():
                skipped.append({"file": rel, "reason": f"missing: no file at {path}"})
                continue
            data = path.read_bytes()
            found = hashlib.sha256(data).hexdigest()
            if found != entry.sha256:
                skipped.append({"file": rel, "reason": f"sha256 mismatch: expected {entry.sha256}, found {found}"})
                continue
            try:
                clip = read_c3d(path, data)
            except C3dError as err:
                skipped.append({"file": rel, "reason": f"malformed C3D: {err.expected} expected, {err.found} found"})
                continue
            if not clip.events:
                skipped.append({"file": rel, "reason": "no annotated foot strike / foot off events"})
                continue
            cfg = ValidationConfig(**{**vcfg.__dict__, "max_gap_seconds": float(
                manifest.doc.get("max_gap_seconds", vcfg.max_gap_seconds))})
            try:
                trials.append(prepare_trial(rel, clip, manifest.doc.get("marker_sets", []), manifest.up_axis, cfg))
            except MarkerRuleError as err:
                skipped.append({"file": rel, "reason": f"no heel/toe markers: {err}"})
    return trials, skipped


def main(params_path: Path | None = None, out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT,
         sources: Path = SOURCES) -> dict:
    params = load_params(params_path) if params_path else load_params()
    root = mocap_root(params)
    if not root.is_dir():
        sys.exit(f"The mocap root {root} does not exist (params.yaml data.mocap_root)")
    cfg, vcfg = contact_config(params), validation_config(params)
    trials, skipped = load_trials(root, sources, vcfg)
    figures, events = validate(trials, cfg, vcfg)
    report = {
        "contact_config": cfg.__dict__,
        "validation_config": vcfg.__dict__,
        "acceptance": acceptance(figures),
        "detectors": figures,
        "trials": [{"file": t.name, "marker_set": t.marker_set, "fps": t.fps, "frames": int(len(t.times)),
                    "annotated_events": len(t.annotated), "gap_samples_filled": t.filled} for t in trials],
        "not_validated": skipped,
    }
    write_json_atomic(report, out_report)
    render_contacts(trials, events, out_plot)
    ours, ref = figures["ours"]["overall"], figures.get("zeni_gaitalytics", {}).get("overall", {})
    print(f"validate_contacts: {len(trials)} annotated trials, {ours['annotated_events']} events; ours matched "
          f"{ours['matched_fraction']:.1%} ({ours['matched_evaluable_fraction']:.1%} of evaluable), median "
          f"{ours['median_abs_error_ms']} ms; Zeni {ref.get('matched_fraction', float('nan')):.1%}, median "
          f"{ref.get('median_abs_error_ms')} ms -> "
          f"{out_report.relative_to(REPO) if out_report.is_relative_to(REPO) else out_report}")
    return report


if __name__ == "__main__":
    main()
