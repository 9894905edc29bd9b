"""Foot-event benchmark: our contact detector and the Zeni et al. (2008) reference side by side, in one run.

Both detectors see the same heel/toe (and, for Zeni, pelvis) tracks of every C3D trial with annotated foot
strikes / foot offs (``stages.validate_contacts.load_trials``), and are scored by the same rules
(``pipeline.annotate.contact_validation``: one-to-one matching per foot and kind within ``tolerance_s``, false events
inside the annotated span). Printed, as JSON: per detector the overall figures (matched fraction of all and of
evaluable annotated events, median / 90th-percentile absolute error, mean signed error, false events per
second), the per-file matched fractions and median errors, and the wall time each detector took over all
trials (median of ``--repeats``). Also written to ``benchmarks/out/contacts.json``.

Thresholds come from params.yaml (``annotate.contacts``, ``validate_contacts``), as for the pipeline.
Run from the repository root:  ``make bench``  or  ``python benchmarks/contacts.py [--repeats N]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from importlib import metadata
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from pipeline.io.files import write_json  # noqa: E402
from pipeline.annotate.contact_validation import DETECTORS, acceptance, our_events, validate, zeni_events  # noqa: E402
from stages.common import SOURCES, load_params, mocap_root  # noqa: E402
from stages.configs import contact_config, validation_config  # noqa: E402
from stages.validate_contacts import load_trials  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "contacts.json"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    params = load_params()
    cfg, vcfg = contact_config(params), validation_config(params)
    trials, skipped = load_trials(mocap_root(params), SOURCES, vcfg)
    detect = {"ours": lambda t: our_events(t, cfg, vcfg), "zeni_gaitalytics": zeni_events}
    seconds = {}
    for name in DETECTORS:
        runs = []
        for _ in range(max(1, args.repeats)):
            start = time.perf_counter()
            for trial in trials:
                detect[name](trial)
            runs.append(time.perf_counter() - start)
        seconds[name] = statistics.median(runs)
    figures, _ = validate(trials, cfg, vcfg)
    frames = sum(len(t.times) for t in trials)
    result = {
        "trials": len(trials),
        "trial_frames": frames,
        "not_validated": len(skipped),
        "contact_config": cfg.__dict__,
        "tolerance_s": vcfg.tolerance_s,
        "gaitalytics_version": metadata.version("gaitalytics"),
        "acceptance": acceptance(figures),
        "detectors": {
            name: {
                "overall": figures[name]["overall"],
                "seconds_all_trials": round(seconds[name], 4),
                "per_file": {k.rsplit("/", 1)[-1]: {"matched_fraction": v["matched_fraction"],
                                                    "median_abs_error_ms": v["median_abs_error_ms"]}
                             for k, v in figures[name]["per_file"].items()},
            }
            for name in DETECTORS
        },
    }
    write_json(result, OUT)
    print(json.dumps(result, indent=2, sort_keys=True))
    return result


if __name__ == "__main__":
    main()
