"""DVC stage `fit_motion_graph`: the motion graph family (seed 002; pipeline/generators/motion_graph/) built on
the train split's walks.

data/split/gaits.parquet -> data/motion_graph/graph.pt (frames, kept nodes and edges; its sha256 identifies the
family's gaits), reports/motion_graph.json (DVC metrics: the Table-2 statistics at each k with both thresholds,
the key-state share, the nodes per emotion before and after the SCC, the cost weights; no timings, which are
printed), reports/motion_graph.png (the costs c(i, i + k) with the fitted Johnson SB, paper Fig. 4).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.core.skeleton import load_skeleton
from pipeline.generators.motion_graph.graph import (GraphConfig, build_graph, clip_frames, graph_bytes,
                                                    natural_pairs, transition_cost)
from pipeline.io.files import save_figure, write_bytes, write_json
from pipeline.io.gait_table import read_gaits
from stages.common import REPO, SKELETON, load_params
from stages.configs import annotate_config

IN_GAITS = REPO / "data" / "split" / "gaits.parquet"
OUT_GRAPH = REPO / "data" / "motion_graph" / "graph.pt"
OUT_REPORT = REPO / "reports" / "motion_graph.json"
OUT_PLOT = REPO / "reports" / "motion_graph.png"


def plot_costs(costs: dict[int, np.ndarray], table: list[dict[str, Any]], out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy import stats

    fig, axes = plt.subplots(1, len(costs), figsize=(4 * len(costs), 3.4), squeeze=False)
    for ax, (k, c), row in zip(axes[0], sorted(costs.items()), table):
        top = float(np.quantile(c, 0.995))
        ax.hist(c[c <= top], bins=60, density=True, color="tab:purple", alpha=0.6)
        x = np.linspace(0, top, 200)
        a, b, loc, scale = row["threshold"]["johnson_sb_params"]
        ax.plot(x, stats.johnsonsb.pdf(x, a, b, loc=loc, scale=scale), color="k", lw=1)
        ax.axvline(row["threshold"]["johnson_sb"], color="tab:red", lw=0.8, label="0.95 (Johnson SB)")
        ax.axvline(row["threshold"]["empirical"], color="tab:blue", lw=0.8, ls="--", label="0.95 (empirical)")
        ax.set_title(f"c(i, i+{k}); kept {row['after_scc']['states']}/{row['before_scc']['states']} states",
                     fontsize=9)
        ax.set_xlabel("transition cost")
        ax.legend(fontsize=7)
    save_figure(fig, out)
    return out


def main(params_path: Path | None = None, in_gaits: Path = IN_GAITS, out_graph: Path = OUT_GRAPH,
         out_report: Path = OUT_REPORT, out_plot: Path = OUT_PLOT) -> dict[str, Any]:
    params = load_params(params_path) if params_path else load_params()
    cfg = GraphConfig.from_dict(params["motion_graph"].get("graph"))
    started = time.perf_counter()
    frames = clip_frames(*read_gaits(in_gaits), load_skeleton(SKELETON), cfg, annotate_config(params))
    graph = build_graph(frames, cfg)
    sha = write_bytes(graph_bytes(graph), out_graph)
    seconds = time.perf_counter() - started
    report = {"graph": str(out_graph.relative_to(REPO) if out_graph.is_relative_to(REPO) else out_graph),
              "sha256": sha, **graph.statistics}
    write_json(report, out_report)
    costs = {row["k"]: transition_cost(frames, graph.weights, *natural_pairs(frames, row["k"]))
             for row in graph.statistics["table"]}
    plot_costs(costs, graph.statistics["table"], out_plot)
    row = next(r for r in graph.statistics["table"] if r["k"] == cfg.k)
    print(f"fit_motion_graph: {len(frames)} states of {len(frames.clip_ids)} clips, key states "
          f"{graph.statistics['key_state_share']:.1%}; k = {cfg.k}: threshold {graph.threshold:.3f} (empirical "
          f"{row['threshold']['empirical']:.3f}), {row['after_scc']['states']} states and "
          f"{row['after_scc']['edges']} edges in the SCC; {seconds:.1f} s; sha256 {sha[:12]}")
    return report


if __name__ == "__main__":
    main()
