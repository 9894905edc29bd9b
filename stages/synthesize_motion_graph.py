"""DVC stage `synthesize_motion_graph`: the same 5,000-row plan searched in the motion graph (seed 002).

data/split/gaits.parquet + data/motion_graph/graph.pt -> data/synthesized/motion_graph/ and
reports/synthesize_motion_graph.{json,png} (stages/synthesis_run.py; the report adds the search's outcome).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pipeline.core.skeleton import load_skeleton
from pipeline.generators.motion_graph.family import MotionGraphFamily
from pipeline.synth.synthesis import SynthesisPlan
from stages.common import REPO, SKELETON, load_params
from stages.configs import motion_graph_settings, placement_config
from stages.synthesis_run import IN_GAITS, run_synthesis

IN_GRAPH = REPO / "data" / "motion_graph" / "graph.pt"


def family(params: dict[str, Any], work: SynthesisPlan | None = None, in_graph: Path = IN_GRAPH,
           **search: Any) -> MotionGraphFamily:
    """The built graph (no seeds needed); ``search`` overrides search settings (the ablation's constraints)."""
    settings, walk = motion_graph_settings(params, **search)
    return MotionGraphFamily.from_file(in_graph, load_skeleton(SKELETON), placement_config(params), settings, walk)


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, in_graph: Path = IN_GRAPH,
         out: Path | None = None, out_report: Path | None = None, out_plot: Path | None = None) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    return run_synthesis("synthesize_motion_graph", params, lambda work: family(params, work, in_graph), in_gaits,
                         out, out_report, out_plot)


if __name__ == "__main__":
    main()
