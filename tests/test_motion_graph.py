"""The motion graph family (seed 002): graph, search and generated gaits, on the real default data."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.generators.motion_graph.family import MotionGraphFamily, segments
from pipeline.generators.motion_graph.graph import (EVENTS, GraphConfig, build_graph, clip_frames, graph_bytes,
                                                    load_graph, transition_cost)
from pipeline.generators.motion_graph.search import LEVELS, SearchConfig, search
from pipeline.synth.synthesis import SynthesisConfig, SynthesisPlan, row_inputs
from stages.common import load_params
from stages.configs import annotate_config, motion_graph_settings, placement_config


@pytest.fixture(scope="module")
def params():
    return load_params()


@pytest.fixture(scope="module")
def frames(annotated_split, skeleton, params):
    table, arrays, _, _ = annotated_split
    return clip_frames(table, arrays, skeleton, GraphConfig.from_dict(params["motion_graph"]["graph"]),
                       annotate_config(params))


@pytest.fixture(scope="module")
def graph(frames, params):
    return build_graph(frames, GraphConfig.from_dict(params["motion_graph"]["graph"]))


@pytest.fixture(scope="module")
def plan(annotated_split, params):
    table, arrays, _, _ = annotated_split
    cfg = SynthesisConfig.from_dict(params["synthesize"], frames=int(params["ingest"]["window"]))
    return SynthesisPlan.prepare(table, arrays, cfg), cfg


def test_transition_cost_is_zero_between_consecutive_frames_only(frames, graph):
    i = np.flatnonzero(frames.successor() >= 0)[::97]
    assert np.array_equal(transition_cost(frames, graph.weights, i, i + 1), np.zeros(len(i)))
    j = i[frames.clip[i] == frames.clip[np.minimum(i + 2, len(frames) - 1)]]
    assert (transition_cost(frames, graph.weights, j, j + 2) > 0).all()


def test_graph_statistics_report_every_k_with_both_thresholds(graph):
    stats = graph.statistics
    assert [row["k"] for row in stats["table"]] == [2, 3, 4]
    thresholds = [row["threshold"]["johnson_sb"] for row in stats["table"]]
    assert thresholds == sorted(thresholds)  # frames further apart differ more
    for row in stats["table"]:
        assert row["after_scc"]["states"] <= row["before_scc"]["states"]
        assert abs(row["threshold"]["johnson_sb"] / row["threshold"]["empirical"] - 1) < 0.2  # the fit is close
    assert 0.05 < stats["key_state_share"] < 0.3
    assert all(v["after_scc"] > 0 for v in stats["nodes_per_emotion"].values())


def test_kept_graph_is_strongly_connected_and_its_edges_obey_the_rules(frames, graph):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    src, dst = graph.edges()
    kept = np.flatnonzero(graph.kept)
    assert graph.kept[src].all() and graph.kept[dst].all()
    index = np.full(len(graph.kept), -1)
    index[kept] = np.arange(len(kept))
    matrix = coo_matrix((np.ones(len(src)), (index[src], index[dst])), shape=(len(kept), len(kept)))
    count, _ = connected_components(matrix, directed=True, connection="strong")
    assert count == 1 + len(graph.statistics["table"][1]["scc"]["added_for_emotions"])
    # synthetic edges: i and j - 1 are key states of the same foot event, cost below the threshold, not near
    s, col = np.nonzero(graph.out >= 0)
    j = graph.out[s, col]
    assert (frames.event[s] >= 0).all() and np.array_equal(frames.event[s], frames.event[j - 1])
    assert np.array_equal(frames.clip[j], frames.clip[j - 1])
    assert (graph.out_cost[s, col] < graph.threshold).all()
    assert np.allclose(graph.out_cost[s, col], transition_cost(frames, graph.weights, s, j))
    k = graph.config.k
    assert not ((frames.clip[s] == frames.clip[j]) & (np.abs(s - j) < k)).any()
    assert set(EVENTS) == {"left_strike", "left_off", "right_strike", "right_off"}


def test_graph_file_round_trips(graph, tmp_path):
    data = graph_bytes(graph)
    path = tmp_path / "graph.pt"
    path.write_bytes(data)
    loaded, sha = load_graph(path)
    assert np.array_equal(loaded.kept, graph.kept) and np.array_equal(loaded.out, graph.out)
    assert np.array_equal(loaded.frames.rotations, graph.frames.rotations) and loaded.threshold == graph.threshold
    assert np.array_equal(loaded.frames.dominant, graph.frames.dominant) and loaded.statistics == graph.statistics
    assert loaded.frames.clip_ids == graph.frames.clip_ids and loaded.weights == graph.weights
    assert graph_bytes(graph) == data and len(sha) == 64  # the same graph, the same bytes


def _rows(plan, kind: str, count: int):
    work, cfg = plan
    rows = [r for r in work.plan if r["recipe"]["kind"] == kind][::37][:count]
    shapes, per_frame = row_inputs(rows, work.emotions, {t.id: t for t in work.trajectories}, cfg)
    return rows, shapes, per_frame


def test_seeded_search_is_deterministic_and_each_row_depends_on_itself_only(graph, plan, params):
    settings, walk = motion_graph_settings(params)
    rows, shapes, per_frame = _rows(plan, "single", 6)
    seeds = [int(r["plan_seed"]) for r in rows]
    paths = shapes.double().numpy()
    first, level = search(graph, per_frame, paths, seeds, walk.context, settings)
    again, _ = search(graph, per_frame, paths, seeds, walk.context, settings)
    alone, _ = search(graph, per_frame[-1:], paths[-1:], seeds[-1:], walk.context, settings)
    assert np.array_equal(first, again) and np.array_equal(first[-1], alone[0])
    assert len({tuple(p) for p in first}) == len(rows)  # different rows, different walks
    # every step follows a kept edge, and a constrained single-emotion walk walks its dominant emotion only
    natural = graph.natural
    for path, lv, emotion in zip(first, level, per_frame.mean(1).argmax(-1)):
        for a, b in zip(path[:-1], path[1:]):
            assert b == natural[a] or b in graph.out[a]
        if lv == LEVELS[0]:
            assert (graph.frames.dominant[path] == emotion).all()


def test_transitions_walk_from_the_start_emotion_to_the_end_emotion(graph, plan, params):
    settings, walk = motion_graph_settings(params)
    rows, shapes, per_frame = _rows(plan, "transition", 8)
    nodes, level = search(graph, per_frame, shapes.double().numpy(), [int(r["plan_seed"]) for r in rows],
                          walk.context, settings)
    walked = graph.frames.dominant[nodes[:, walk.context:]]
    planned = per_frame.argmax(-1)
    checked = 0
    for w, p, lv in zip(walked, planned, level):
        if lv == LEVELS[0] and p[0] != p[-1]:
            assert w[0] == p[0] and w[-1] == p[-1]
            checked += 1
    assert checked >= 4  # most sampled transitions switch their dominant emotion and are found


def test_generated_gaits_play_the_real_frames_their_lineage_names(graph, plan, params, skeleton):
    settings, walk = motion_graph_settings(params)
    family = MotionGraphFamily(graph, "0" * 64, skeleton, placement_config(params), settings, walk)
    rows, shapes, per_frame = _rows(plan, "single", 4)
    g = family.generate(rows, shapes, torch.from_numpy(per_frame.astype(np.float32)))
    assert g.positions.shape == (4, 60, 21, 3) and torch.isfinite(g.positions).all()
    nodes, _ = search(graph, per_frame, shapes.double().numpy(), [int(r["plan_seed"]) for r in rows], walk.context,
                      settings)
    spine = [skeleton.index(n) for n in ("lower_back", "spine", "neck", "head")]
    for n, (lineage, path) in enumerate(zip(g.source_segments, nodes)):
        runs = json.loads(lineage)
        assert sum(last - first + 1 for _, first, last in runs) == 60
        assert [[graph.frames.clip_ids[c], a, b] for c, a, b in segments(path[walk.context:], graph)] == runs
        # outside the cross-fades a published frame's upper body is its source frame's (legs are foot-locked)
        whole = [t for t in range(60) if all(path[walk.context + t - d] + d == path[walk.context + t]
                                             for d in range(1, walk.blend_frames + 1))]
        assert whole
        source = torch.from_numpy(graph.frames.rotations[path[walk.context:]][whole][:, spine])
        assert torch.allclose(g.rotations[n, whole][:, spine], source, atol=1e-6)
    report = family.report()
    assert report["search"]["gaits"] == 4 and sum(report["search"]["levels"].values()) == 4
    assert set(report["search"]["per_emotion"]) <= set(EMOTIONS)


def test_real_sway_reference_is_the_distance_from_a_walks_own_travel_line():
    from pipeline.synth.synthesis import path_deviation, root_sway

    t = np.arange(60, dtype=np.float64)
    straight = np.stack([np.zeros(60), 0.04 * t], -1)[None]
    assert root_sway(straight, 30.0) < 1e-12
    # a root swaying 3 cm either side once per stride (~1 s) around a straight line: the mean |sin| is 2/π
    swaying = straight.copy()
    swaying[0, :, 0] = 0.03 * np.sin(2 * np.pi * t / 31)
    assert abs(root_sway(swaying, 30.0) - 0.03 * 2 / np.pi) < 0.004
    out = path_deviation(np.array([0.04, 0.06, 0.08]), ["arc", "arc", "wave"], 0.02)
    assert out["arc"]["ratio_to_real_sway"] == 2.5 and out["wave"]["ratio_to_real_sway"] == 4.0
    assert out["real_walk_sway_m"]["mean"] == 0.02
