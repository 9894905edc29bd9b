"""The dataset card's "Known limitations": the formulas it measures with, and the figures measured on real gaits and
on families made from them whose difference is known (walking backwards, a nodding head, seeds of another split)."""

from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np
import pyarrow as pa
import pytest
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.io.files import schema_meta, with_schema_meta
from pipeline.io.gait_table import array_column, column_array
from pipeline.ops.geometry import facing_off_travel, path_turns
from pipeline.ops.quaternion import axis_angle, qmul, qspread
from pipeline.publish.card import dataset_card
from pipeline.publish.directory import responsible_ai
from pipeline.publish.limitations import TRUNK_JOINTS, card_section, measure, root_path_figures, trunk_turn_deg
from pipeline.publish.table import generator_entry, real_table


def test_qspread_is_the_largest_turn_between_any_two_frames_in_any_order_and_sign():
    axis = torch.nn.functional.normalize(torch.tensor([0.3, -1.0, 0.5], dtype=torch.float64), dim=0)
    angles = torch.deg2rad(torch.tensor([0.0, 3.0, 10.0, 7.0, -2.0], dtype=torch.float64))
    base = axis_angle(torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64), torch.tensor(0.7, dtype=torch.float64))
    q = qmul(base.expand(5, 4), axis_angle(axis.expand(5, 3), angles))  # turns about one axis, after a fixed pose
    assert math.degrees(float(qspread(q))) == pytest.approx(12.0, abs=1e-9)
    flipped = q[[3, 0, 4, 2, 1]] * torch.tensor([1.0, -1.0, 1.0, -1.0, 1.0], dtype=torch.float64)[:, None]
    assert float(qspread(flipped)) == pytest.approx(float(qspread(q)), abs=1e-12)
    assert float(qspread(base.expand(6, 4))) < 1e-6


def test_facing_off_travel_reads_forwards_sideways_and_backwards():
    t = torch.arange(60, dtype=torch.float64)
    root = torch.stack((0.04 * t, torch.full_like(t, 0.9), torch.zeros_like(t)), -1)  # walking along +x
    for heading, expected in ((math.pi / 2, 0.0), (0.0, -math.pi / 2), (-math.pi / 2, -math.pi)):
        off = facing_off_travel(root, torch.full_like(t, heading), 31)
        assert torch.allclose(off, torch.full_like(off, expected), atol=1e-9), heading


def _loop(path: np.ndarray, first: int, frames: int = 12, radius_m: float = 0.2) -> np.ndarray:
    """A ground path (T, 2) with a circle of ``radius_m`` walked in ``frames`` frames from ``first`` on top of it:
    its steps then turn a full turn in those frames (faster than the walk advances, so it curls back)."""
    t = np.clip(np.arange(len(path)) - first, 0, frames) / frames * 2 * np.pi
    return path + radius_m * np.stack((np.sin(t), 1 - np.cos(t)), -1)


def test_path_turns_find_a_small_loop_and_the_steps_back_in_it_and_nothing_on_a_line_or_a_corner():
    t = np.arange(60, dtype=np.float64)
    line = np.stack((np.zeros_like(t), 0.045 * t), -1)  # 1.35 m/s at 30 fps
    corner = np.where(t[:, None] < 30, line, np.stack((0.045 * (t - 29), np.full_like(t, 0.045 * 29)), -1))
    for path, turn, backs in ((line, 0.0, 0), (corner, 90.0, 0)):
        largest, against = path_turns(torch.from_numpy(path), 15)
        assert math.degrees(float(largest)) == pytest.approx(turn, abs=1e-6)
        assert int(against.sum()) == backs
    largest, against = path_turns(torch.from_numpy(_loop(line, 20)), 15)
    assert math.degrees(float(largest)) > 300.0
    assert 0 < int(against.sum()) < 12 and not against[:5].any() and not against[-10:].any()
    figures = root_path_figures(np.stack([line, corner, _loop(line, 20), _loop(corner, 40)]), 15)
    assert figures["loops"] == 0.5 and figures["reversals"] == 0.5 and 0 < figures["frames_against_travel"] < 0.1


def _replace(table: pa.Table, name: str, values) -> pa.Table:
    i = table.column_names.index(name)
    column = values if isinstance(values, pa.Array) else array_column(np.asarray(values, np.float32))
    return table.set_column(i, table.schema.field(i), column.cast(table.schema.field(i).type))


@pytest.fixture(scope="module")
def published_table(annotated_split):
    """Real gaits (all splits) and two families made from the real labelled train walks: ``backwards`` (the same
    walks with the body turned about: it faces away from where it goes) and ``nodding`` (the head turned 10 degrees
    forwards and back once a gait), its seeds the val split's labelled walks."""
    table, arrays, split, _ = annotated_split
    real = real_table(table, arrays)
    meta = schema_meta(real.schema)
    content = np.array(real.column("content").to_pylist())
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    walks = np.flatnonzero((split == "train") & (content == "walk") & labelled)
    seeds = np.flatnonzero((split == "val") & (content == "walk") & labelled)
    ids = np.array(real.column("gait_id").to_pylist())
    rotations = column_array(real, "rotations", meta["shapes"]["rotations"])
    head = meta["joint_names"].index("head")
    frames = rotations.shape[1]
    nod = axis_angle(torch.tensor([1.0, 0.0, 0.0]).expand(frames, 3),
                     torch.deg2rad(10.0 * torch.sin(torch.linspace(0, 2 * math.pi, frames))))
    nodding_rot = rotations[walks].copy()
    nodding_rot[:, :, head] = qmul(torch.from_numpy(nodding_rot[:, :, head]), nod).numpy()
    families, generators = [], {}
    for name, change in (("backwards", {"heading": column_array(real, "heading", meta["shapes"]["heading"])[walks]
                                        + np.pi}),
                         ("nodding", {"rotations": nodding_rot})):
        part = real.take(walks)
        n = part.num_rows
        for column, value in (("kind", "synthetic"), ("generator", name), ("split", "synthetic")):
            part = _replace(part, column, pa.array([value] * n))
        part = _replace(part, "seed_gait_id", pa.array([str(ids[seeds[i % len(seeds)]]) for i in range(n)]
                                                      if name == "nodding" else [None] * n, pa.string()))
        for column, values in change.items():
            part = _replace(part, column, values)
        families.append(part)
        generators[name] = generator_entry(name, f"{name} real walks", "0" * 64, seeded=name == "nodding")
    out = pa.concat_tables([real, *families])
    meta["generators"] = generators
    return with_schema_meta(out, meta), meta, walks, seeds, split


def test_contents_count_the_real_labelled_gaits_and_read_real_backward_walks_as_such(published_table):
    table, meta, walks, _, _ = published_table
    figures = measure(table, meta)
    kind = np.array(table.column("kind").to_pylist())
    emotion = column_array(table, "emotion", meta["shapes"]["emotion"])
    labelled = (kind == "real") & ~np.isnan(emotion).any(-1)
    content = np.array(table.column("content").to_pylist())
    counted = Counter((c, EMOTIONS[int(np.argmax(e))]) for c, e in zip(content[labelled], emotion[labelled]))
    real = figures["contents"]["real_labelled"]
    assert {(c, e): g["per_emotion"][e] for c, g in real.items() for e in EMOTIONS if g["per_emotion"][e]} == counted
    # the real mocap: forward walks face their direction of travel, backward walks face away from it
    assert real["walk"]["facing_off_travel_deg"] < 15.0
    assert real["walk-back"]["facing_off_travel_deg"] > 150.0
    synthetic = figures["contents"]["synthetic"]
    assert synthetic["backwards"]["facing_off_travel_deg"] > 170.0
    assert synthetic["nodding"]["facing_off_travel_deg"] < 15.0
    assert synthetic["nodding"]["gaits"] == len(walks)
    assert figures["walking"]["nodding"] == figures["walking"]["real_labelled_train_walks"]  # the same walks


def test_a_nodding_head_shows_in_the_trunk_table_and_only_there(published_table):
    table, meta, walks, _, _ = published_table
    figures = measure(table, meta)["trunk_turn_deg"]
    rotations = column_array(table, "rotations", meta["shapes"]["rotations"])
    unchanged = np.median(trunk_turn_deg(rotations[walks], [meta["joint_names"].index(j) for j in TRUNK_JOINTS]), 0)
    # the "backwards" family turns only the heading: its trunk is the real walks'; the nodding one only its head
    assert [figures["backwards"][j] for j in TRUNK_JOINTS] == pytest.approx(unchanged, abs=0.05)
    assert figures["nodding"]["spine"] == figures["backwards"]["spine"]
    assert figures["nodding"]["neck"] == figures["backwards"]["neck"]
    assert figures["nodding"]["head"] >= figures["backwards"]["head"] + 12.0  # a 20-degree nod, less the head's own
    assert figures["nodding"]["ratio_to_real"]["head"] > 2.0
    assert figures["real_train_walks"]["head"] < 10.0  # real heads turn a few degrees within a walk


def test_the_card_and_the_croissant_name_the_seeds_split_the_data_shows(published_table):
    table, meta, _, seeds, split = published_table
    figures = measure(table, meta)
    assert figures["seeds"] == {"nodding": {"gaits": len(seeds), "splits": ["val"], "contents": ["walk"],
                                            "labelled": True}}
    rai = responsible_ai(meta, figures)
    assert "2 generator families (backwards, nodding)" in rai["dataCollection"]
    assert "the seeded ones (nodding) continue the first frames of labelled real val-split gaits (walk)" in \
        " ".join(rai["dataCollection"].split())
    assert "$" not in json.dumps(rai)
    section = card_section(figures)
    for row in ("| real labelled, walk-back |", "| `backwards` |", "| `nodding` |", "| real train-split walks ("):
        assert row in section
    counts = {"synthetic_by_generator": {"backwards": len(seeds), "nodding": len(seeds)}, "real": 1,
              "by_kind_split": {}, "real_by_source": {}, "synthetic_by_family": {}}
    plan = {"trajectories": 1, "emotions": 1, "transitions": 0, "min_l1": 0.5, "prefix": 18}
    card = dataset_card(counts, meta, {}, plan, "dvc.lock", {"real": [], "nodding": []}, "nodding", figures)
    assert "## Known limitations\n" + section in card
    assert "frames of a labelled real val-split gait (walk)" in " ".join(card.split())


def test_a_family_whose_roots_circle_shows_in_the_root_path_table(published_table):
    table, meta, walks, _, _ = published_table
    generator = np.array(table.column("generator").to_pylist())
    paths = column_array(table, "root_path", meta["shapes"]["root_path"]).astype(np.float64)
    looping = generator == "backwards"
    paths[looping] = [_loop(p, 10 + (k % 35)) for k, p in enumerate(paths[looping])]
    measured = measure(_replace(table, "root_path", paths), meta)
    figures = measured["root_path"]
    # the real mocap walks hardly ever loop; the nodding family is real walks unchanged, the other circles in each
    assert figures["real_walks"]["loops"] < 0.01 and figures["real_walks"]["gaits"] > len(walks)
    assert figures["nodding"]["loops"] < 0.02 and figures["nodding"]["frames_against_travel"] < 0.01
    assert figures["backwards"]["loops"] == 1.0 and figures["backwards"]["reversals"] == 1.0
    assert figures["backwards"]["frames_against_travel"] > figures["nodding"]["frames_against_travel"] + 0.05
    assert figures["backwards"]["gaits"] == len(walks)
    section = card_section(measured)
    assert "| `backwards` | " + str(len(walks)) + " | 100.00 % | 100.00 % |" in section
    assert "| real walks | " in section
