"""DVC stage `validate_contacts`: our foot-contact detector vs annotated gait events in the C3D trials ->
reports/contacts.json (ours and the Zeni et al. 2008 reference, overall and per file; the files not validated,
with the reason) + reports/contacts.png. Thresholds: params.yaml ``annotate.contacts`` (as annotation uses them)
and ``validate_contacts`` (defaults in pipeline.annotate.contact_validation.ValidationConfig).
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.annotate.contact_validation import (
    ValidationConfig,
    annotated_trials,
    contact_report,
    render_contacts,
    report_summary,
    validate,
)
from pipeline.io.files import write_json
from pipeline.io.manifests import load_manifests
from stages.common import REPO, SOURCES, load_params, mocap_root
from stages.configs import contact_config, validation_config

OUT_REPORT = REPO / "reports" / "contacts.json"
OUT_PLOT = REPO / "reports" / "contacts.png"


def load_trials(root: Path, sources: Path, vcfg: ValidationConfig) -> tuple[list, list[dict[str, str]]]:
    """The annotated trials of every C3D source manifest in ``sources``, and the files not validated."""
    return annotated_trials(load_manifests(sources, formats=("c3d",)), root, vcfg)


def main(params_path: Path | None = None, out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT,
         sources: Path = SOURCES) -> dict:
    params = load_params(params_path) if params_path else load_params()
    root = mocap_root(params)
    if not root.is_dir():
        sys.exit(f"The mocap root {root} does not exist (params.yaml data.mocap_root)")
    cfg, vcfg = contact_config(params), validation_config(params)
    trials, skipped = load_trials(root, sources, vcfg)
    figures, events = validate(trials, cfg, vcfg)
    report = contact_report(trials, skipped, figures, cfg, vcfg)
    write_json(report, out_report)
    render_contacts(trials, events, out_plot)
    shown = out_report.relative_to(REPO) if out_report.is_relative_to(REPO) else out_report
    print(f"validate_contacts: {report_summary(report)} -> {shown}")
    return report


if __name__ == "__main__":
    main()
