"""DVC stage `publish`: data/split + data/synthesized/<family>/ (every family of ``synthesize.families``, the
named dataset's first) -> data/published/synthesized_emotive_gaits/ (see pipeline/publish/directory.py), with
lineage from dvc.lock; reports/publish.json."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import json

import pyarrow.parquet as pq
import yaml

from pipeline.io.files import write_json
from pipeline.io.gait_table import read_gaits
from pipeline.publish.directory import PublishConfig, publish_directory
from stages.common import REPO, SOURCES, load_params
from stages.lineage import stage_graph

IN_REAL = REPO / "data" / "split" / "gaits.parquet"
IN_SYNTHETIC = REPO / "data" / "synthesized"
OUT = REPO / "data" / "published" / "synthesized_emotive_gaits"
OUT_REPORT = REPO / "reports" / "publish.json"
LOCK = REPO / "dvc.lock"


def main(params_path: Path | None = None, out: Path = OUT, out_report: Path = OUT_REPORT,
         in_synthetic: Path = IN_SYNTHETIC) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    s = params["synthesize"]
    plan = {"trajectories": len(s["trajectories"]), "emotions": int(s["emotions"]),
            "transitions": int(s["emotions"]) // 2 * int(s["transition_rounds"]),
            "min_l1": s["min_l1_to_training"], "prefix": int(params["train"]["prefix"])}
    licences = {m["name"]: m.get("licence", "see the source") for m in
                (yaml.safe_load(f.read_text()) for f in sorted(SOURCES.glob("*.yaml")))}
    real, real_arrays = read_gaits(IN_REAL)
    named = str(s["named_family"])
    names = [named, *(f for f in s["families"] if f != named)]
    families = [pq.read_table(in_synthetic / name / "gaits.parquet") for name in names]
    lineages = {name: json.loads((in_synthetic / name / "lineage.json").read_text())["model_lineage"]
                for name in names}
    report = publish_directory(real, real_arrays, families, lineages, out, PublishConfig.from_dict(params["publish"]),
                               licences, plan, stage_graph(REPO, LOCK, running="publish"), REPO, LOCK.name)
    report["directory"] = str(out.relative_to(REPO))
    write_json(report, out_report)
    counts, problems = report["counts"], report["verify_problems"]
    print(f"publish: {counts['real']} real + {counts['synthetic']} synthetic gaits "
          f"({', '.join(f'{k} {v}' for k, v in counts['synthetic_by_generator'].items())}) -> {report['directory']}; "
          f"verify {'passed' if not problems else 'FAILED: ' + '; '.join(problems[:5])}")
    return report


if __name__ == "__main__":
    main()
