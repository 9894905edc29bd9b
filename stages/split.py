"""DVC stage `split`: data/annotated/gaits.parquet -> data/split/gaits.parquet (+ `split` column) + reports/split.json."""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa

from pipeline.io.files import write_json, write_parquet
from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.io.gait_table import read_gaits
from pipeline.split import assign_splits, split_report
from stages.common import REPO, load_params

IN_GAITS = REPO / "data" / "annotated" / "gaits.parquet"
OUT_GAITS = REPO / "data" / "split" / "gaits.parquet"
OUT_REPORT = REPO / "reports" / "split.json"


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_gaits: Path = OUT_GAITS,
         out_report: Path = OUT_REPORT) -> dict:
    params = load_params(params_path) if params_path else load_params()
    p = params["split"]
    fractions = {k: float(v) for k, v in p["fractions"].items()}
    table, arrays = read_gaits(in_gaits)
    clip_ids = table.column("clip_id").to_pylist()
    strata = [dominant_emotion(None if e[0] != e[0] else e, EMOTIONS) for e in arrays["emotion"]]
    clip_strata = dict(zip(clip_ids, strata))  # all windows of a clip share its label
    assignment = assign_splits(clip_strata, fractions, int(p["seed"]), int(p.get("min_held_out_clips", 0)))
    split = pa.array([assignment[c] for c in clip_ids], type=pa.string())
    write_parquet(table.append_column("split", split), out_gaits)
    report = split_report(clip_ids, table.column("source").to_pylist(), strata, assignment, fractions, int(p["seed"]))
    write_json(report, out_report)
    t = report["totals"]
    print("split: " + ", ".join(f"{s} {t[s]['clips']} clips / {t[s]['gaits']} gaits" for s in t)
          + f"; clips in two splits: {len(report['clips_in_two_splits'])}")
    return report


if __name__ == "__main__":
    main()
