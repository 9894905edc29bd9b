"""The audit on a published directory with planted defects: every defect is named, nothing crashes, and the
page shows every figure (slow: the full ingest). The page a person reads (fast, on hand-made gaits): a verdict
per generator family with both recognisers and their intervals, whose numbers are the metrics', every cell
formatted, every feature named in words; the metrics' recognition and memorisation keys. The scores on hand-made
confusion matrices (the recognisers on real gaits: tests/test_recognition.py). (The audit of the real published dataset runs in tests/test_dvc_stage.py.)"""

from __future__ import annotations

import dataclasses
import html
import json
import re

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
import torch

from pipeline.audit.metrics import (
    AuditConfig,
    augmentation_controls,
    augmentation_draw,
    clip_identity,
    describe_affective_feature,
    feature_descriptions,
    gait_problems,
    held_out_by_content,
    js_distance,
    normalised_entropy,
    parse_affective_name,
    recognisability,
    steady_label,
)
from pipeline.audit.report import content_rows, control_line, verdict_lines
from pipeline.audit.run import audit_frame
from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.core.skeleton import canonical_skeleton
from pipeline.ops.features import AFFECTIVE_FEATURES, AFFECTIVE_NAMES, MOVEMENT_NAMES, affective_features
from pipeline.dataset import write_sha256sums
from pipeline.io.gait_table import array_column, column_array
from pipeline.recognition import RECOGNISERS, RecogniserConfig, RecognitionInputs, majority_baseline, scores
from pipeline.publish.table import generator_entry
from stages.audit import main as audit
from tests.test_croissant_provenance import _publish, _published_table


def _set(table: pa.Table, name: str, column: pa.Array) -> pa.Table:
    return table.set_column(table.column_names.index(name), name, column)


@pytest.fixture(scope="module")
def defective(annotated, tmp_path_factory):
    table, meta = _published_table(annotated[0])
    ids = table.column("gait_id").to_pylist()
    emotion = column_array(table, "emotion", meta["shapes"]["emotion"])
    valid = np.isfinite(emotion).all(-1)
    labelled = int(np.flatnonzero(valid)[0])
    emotion[labelled] = [0.5, 0.3, 0.1, 0.0]  # sums to 0.9
    table = _set(table, "emotion", array_column(np.nan_to_num(emotion), ~valid))
    positions = column_array(table, "positions", meta["shapes"]["positions"])
    positions[2, 10, 5, 1] = np.nan
    table = _set(table, "positions", array_column(positions))
    ids[3] = ids[4]  # a duplicate id
    table = _set(table, "gait_id", pa.array(ids, pa.string()))
    synthetic = len(ids) - 1  # the last gait is synthetic
    sha = table.column("checkpoint_sha256").to_pylist()
    assert table.column("kind")[synthetic].as_py() == "synthetic"
    sha[synthetic] = None  # a synthetic gait without its lineage
    table = _set(table, "checkpoint_sha256", pa.array(sha, pa.string()))
    directory = tmp_path_factory.mktemp("defective") / "copy_of_a_download"
    _publish(directory, table, meta)
    write_sha256sums(directory)
    planted = {"sum": ids[labelled], "nan": ids[2], "duplicate": ids[4], "lineage": ids[synthetic]}
    return directory, planted


def test_every_planted_defect_is_named_and_the_page_shows_every_figure(defective, tmp_path):
    directory, planted = defective
    metrics = audit(directory=directory, out=tmp_path / "audit")
    text = [" ".join(str(v) for v in p.values()) for p in metrics["problems"]]
    assert any("do not sum to 1" in t and planted["sum"] in t for t in text)
    assert any("NaN" in t and "positions" in t and planted["nan"] in t for t in text)
    assert any("more than once" in t and planted["duplicate"] in t for t in text)
    assert any(t.startswith(planted["lineage"]) and "checkpoint_sha256" in t for t in text)
    assert metrics["problem_count"] == len(metrics["problems"]) >= 4
    page = (tmp_path / "audit" / "index.html").read_text()
    pngs = sorted(p.name for p in (tmp_path / "audit").glob("*.png"))
    assert pngs and len(re.findall(r'src="data:image/png;base64,', page)) == len(pngs)
    assert planted["duplicate"] in page
    assert json.loads((tmp_path / "audit" / "metrics.json").read_text())["gaits"] == metrics["gaits"]
    assert metrics["memorisation"]["left_out_not_finite"] == 1  # the gait with a NaN position: listed, not measured


def test_each_generator_family_needs_its_own_lineage(annotated):
    """With the metadata's ``generators``: a family without seeds needs no ``seed_gait_id``, a seeded family's
    gait without one is a problem, a gait of an undeclared family or with another model's sha256 is one too."""
    table, _ = _published_table(annotated[0])
    frame = pd.DataFrame({c: table.column(c).to_pylist() for c in ("gait_id", "kind", "checkpoint_sha256",
                                                                   "seed_gait_id", "trajectory_id", "emotion_recipe",
                                                                   "plan_seed", "source_file", "source_sha256",
                                                                   "t_start", "t_end")})
    frame["contacts"] = [np.zeros((60, 4))] * len(frame)
    frame["phase"] = [np.zeros(60)] * len(frame)
    synthetic = np.flatnonzero(frame["kind"] == "synthetic")
    frame["generator"] = None
    frame.loc[synthetic, "generator"] = ["seeded", "seedless"]
    frame.loc[synthetic, "seed_gait_id"] = None
    sha = frame.loc[synthetic[0], "checkpoint_sha256"]
    generators = {name: generator_entry(name, "test", sha, seeded) for name, seeded in (("seeded", True),
                                                                                        ("seedless", False))}
    found = {(p["gait_id"], p["check"]) for p in gait_problems(frame, generators)}
    assert found == {(frame.loc[synthetic[0], "gait_id"], "lineage seed_gait_id")}
    frame.loc[synthetic[1], "checkpoint_sha256"] = "0" * 64
    frame.loc[synthetic[0], "generator"] = "unknown"
    found = {(p["gait_id"], p["check"]) for p in gait_problems(frame, generators)}
    assert found == {(frame.loc[synthetic[1], "gait_id"], "lineage checkpoint_sha256"),
                     (frame.loc[synthetic[0], "gait_id"], "generator")}
    # without the metadata (an older directory), every synthetic gait needs the seeded lineage
    assert {p["check"] for p in gait_problems(frame)} == {"lineage seed_gait_id"}


def test_label_measures():
    assert normalised_entropy(np.eye(4)).tolist() == [0.0] * 4
    assert normalised_entropy(np.full((1, 4), 0.25))[0] == pytest.approx(1.0)
    assert js_distance([1, 0], [1, 0]) == 0.0 and js_distance([1, 0], [0, 1]) == pytest.approx(1.0)
    assert js_distance([3, 1], [1, 3]) == pytest.approx(js_distance([1, 3], [3, 1]))
    matrix = np.array([[8, 2, 0, 0], [0, 5, 5, 0], [0, 0, 10, 0], [0, 0, 0, 0]])  # no true 'neutral'
    result = scores(matrix)
    f1 = [2 * 8 / (10 + 8), 2 * 5 / (10 + 7), 2 * 10 / (10 + 15)]
    assert result["accuracy"] == pytest.approx(23 / 30, abs=1e-4)
    assert result["macro_f1"] == pytest.approx(np.mean(f1), abs=1e-4)


def test_balanced_accuracy_and_majority_baseline_on_a_hand_made_matrix():
    matrix = np.array([[8, 2, 0, 0], [0, 5, 5, 0], [1, 0, 14, 0], [0, 0, 0, 0]])  # no true 'neutral'
    result = scores(matrix)
    assert result["accuracy"] == pytest.approx(27 / 35, abs=1e-4)
    assert result["balanced_accuracy"] == pytest.approx((8 / 10 + 5 / 10 + 14 / 15) / 3, abs=1e-4)
    baseline = majority_baseline(matrix, EMOTIONS)  # always 'angry': 15 of the 35 tested gaits
    assert baseline == {"class": "angry", "accuracy": pytest.approx(15 / 35, abs=1e-4),
                        "balanced_accuracy": pytest.approx(1 / 3, abs=1e-4),
                        "macro_f1": pytest.approx((2 * 15 / (15 + 35)) / 3, abs=1e-4)}
    assert scores(np.diag([3, 0, 4, 1]))["balanced_accuracy"] == 1.0


# ------------------------------------------------------------------------------------ the page, hand-made gaits

FRAMES = 20  # a recogniser reads 10 frames or more


def _gaits(kind: str, split: str, classes: list[int | None], rng, shift: float, **extra) -> list[dict]:
    rows = []
    for i, c in enumerate(classes):
        emotion = None if c is None else np.eye(4, dtype=np.float32)[c]
        affective = rng.normal(1.0, 0.3, (FRAMES, 18)).astype(np.float32)
        positions = rng.normal(0.0, 0.3, (FRAMES, 21, 3)).astype(np.float32)
        if c is not None:
            affective[:, c] += shift  # an emotion shows in one feature, and in one joint
            positions[:, 1 + c, 1] += shift
        rows.append({"gait_id": f"{kind}-{split}-{i}", "kind": kind, "split": split,
                     "source": "mocap" if kind == "real" else "generator",
                     "label_method": None if c is None else ("actor_intended" if kind == "real" else
                                                             "generator_condition"),
                     "emotion": emotion, "contacts": np.zeros((FRAMES, 4), np.float32),
                     "phase": np.linspace(0, 6, FRAMES, dtype=np.float32), "affective": affective,
                     "positions": positions, "heading": rng.uniform(-3, 3, FRAMES).astype(np.float32),
                     "movement": rng.normal(0.0, 0.1, (FRAMES, 5)).astype(np.float32), **extra})
    return rows


def _frame(generators: tuple[str, ...] | None = None) -> tuple[pd.DataFrame, dict]:
    rng = np.random.default_rng(0)
    rows = (_gaits("real", "train", [k % 4 for k in range(48)], rng, 1.5)
            + _gaits("real", "test", [k % 4 for k in range(16)], rng, 1.5)
            + _gaits("real", "val", [k % 4 for k in range(8)], rng, 1.5)
            + _gaits("real", "train", [None] * 5, rng, 0.0))
    for g, name in enumerate(generators or ("",)):
        extra = {"generator": name} if generators else {}
        rows += _gaits("synthetic", "synthetic", [(k + g) % 4 for k in range(20)], rng, 0.5 * g, **extra)
    frame = pd.DataFrame(rows)
    real = frame["kind"] == "real"  # two windows a clip: a clip's windows share a source file
    frame["source_file"] = [f"clip{i // 2}.bvh" if r else None for i, r in enumerate(real)]
    frame["dominant"] = [dominant_emotion(e, EMOTIONS) for e in frame["emotion"]]
    frame.loc[1, "contacts"][3, 2] = 0.5  # two planted problems, so the problems table has rows
    frame.loc[2, "phase"][4] = 7.0
    meta = {"emotion_order": list(EMOTIONS), "affective_names": list(AFFECTIVE_NAMES),
            "movement_names": list(MOVEMENT_NAMES), "joint_names": list(canonical_skeleton().names)}
    return frame, meta


AUDIT = AuditConfig(recognisers=RecogniserConfig.from_dict({"summary": {"epochs": 40}, "temporal": {"epochs": 5}}),
                    seeds={"summary_mlp": (0, 1), "temporal_cnn": (0,)}, bootstrap_resamples=200)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    frame, meta = _frame()
    out = tmp_path_factory.mktemp("audit_page")
    metrics = audit_frame(frame, meta, gait_problems(frame), "hand_made", out, AUDIT)
    return metrics, (out / "index.html").read_text()


def _text(page: str) -> str:
    """The page without its embedded images, tags removed, entities decoded."""
    return html.unescape(re.sub(r"<[^>]+>", " ", re.sub(r'src="data:image/png;base64,[^"]*"', "", page)))


def _cells(page: str) -> list[str]:
    return [html.unescape(re.sub(r"<[^>]+>", "", c)).strip() for c in re.findall(r"<td>(.*?)</td>", page, re.S)]


def test_the_page_leads_with_a_verdict_whose_numbers_are_the_metrics(page):
    metrics, text = page
    r = metrics["recognisability"]
    verdicts = re.findall(r'<li class="verdict">(.*?)</li>', text, re.S)
    assert len(verdicts) == 1 and text.index("verdict") < text.index("<h2>Overview")
    line = html.unescape(re.sub(r"<[^>]+>", "", verdicts[0]))
    pct = lambda x: f"{100 * x:.1f} %"  # noqa: E731
    ci = lambda c: f"(CI {100 * c[0]:.1f}–{100 * c[1]:.1f} %)"  # noqa: E731
    pts = lambda x: f"{'−' if round(100 * x, 1) < 0 else '+'}{abs(100 * x):.1f}"  # noqa: E731
    figures = [20, 100 * r["chance_accuracy"]]
    for kind in RECOGNISERS:
        entry = r["by_recogniser"][kind]
        (family,) = entry["families"]
        assert family == "generator (generator_condition)"
        assert entry["families"][family]["synthetic"] == entry["synthetic"]  # one family: all synthetic gaits'
        syn, real, delta, delta_ci = (entry["synthetic"], entry["real_held_out"], entry["augmentation_delta"],
                                      entry["augmentation_delta_ci95"])
        every, every_ci = entry["augmentation_all_delta"], entry["augmentation_all_delta_ci95"]
        expected = [f"{entry['name']}: balanced accuracy {pct(syn['balanced_accuracy_mean'])} "
                    f"{ci(syn['balanced_accuracy_ci95'])} vs real val + test {pct(real['balanced_accuracy_mean'])} "
                    f"{ci(real['balanced_accuracy_ci95'])}, accuracy {pct(syn['accuracy_mean'])} (majority class "
                    f"{pct(syn['majority_baseline']['accuracy'])})",
                    f"{entry['name']} {pts(delta['macro_f1'])} pts (CI {pts(delta_ci['macro_f1'][0])} to "
                    f"{pts(delta_ci['macro_f1'][1])} pts)",
                    f"{entry['name']} {pts(every['macro_f1'])} pts (CI {pts(every_ci['macro_f1'][0])} to "
                    f"{pts(every_ci['macro_f1'][1])} pts)"]
        for part in expected:
            assert part in line, (part, line)
        figures += [100 * v for v in (syn["balanced_accuracy_mean"], *syn["balanced_accuracy_ci95"],
                                      real["balanced_accuracy_mean"], *real["balanced_accuracy_ci95"],
                                      syn["accuracy_mean"], syn["majority_baseline"]["accuracy"], delta["macro_f1"],
                                      *delta_ci["macro_f1"], every["macro_f1"], *every_ci["macro_f1"])]
    assert line.startswith("generator (generator_condition): 20 synthetic gaits recognised as intended — ")
    assert "chance 25.0 %" in line and "Augmentation, macro-F1 on real val + test: " in line
    assert line.index("Augmentation") < line.index("with every synthetic gait added at weight one: ")
    # every number in the line is one of the metrics' (as a percentage or points), none invented
    for found in re.findall(r"(?<![A-Za-z\d.–])[−+]?\d+(?:\.\d+)?", line.split(":", 1)[1].replace("–", " ")):
        assert min(abs(abs(float(found.replace("−", "-"))) - abs(f)) for f in figures) < 0.051, found


def test_the_audit_metrics_carry_both_recognisers_intervals_and_memorisation(page):
    metrics, text = page
    r = metrics["recognisability"]
    assert r["recognisers"] == list(RECOGNISERS) and r["test_splits"] == ["val", "test"]
    assert r["gaits"] == {"real_train": 48, "real_held_out": 24, "real_held_out_clips": 12, "synthetic": 20,
                          "labelled_left_out_not_finite": 0}
    assert r["seeds"] == {"summary_mlp": [0, 1], "temporal_cnn": [0]}
    for kind in RECOGNISERS:
        entry = r["by_recogniser"][kind]
        for key in ("real_held_out", "synthetic", "augmented_real_held_out", "augmented_all_real_held_out"):
            for s in ("accuracy", "balanced_accuracy", "macro_f1"):
                lo, hi = entry[key][f"{s}_ci95"]
                assert 0.0 <= lo <= hi <= 1.0 and {f"{s}_mean", f"{s}_std"} <= set(entry[key])
            assert set(entry[key]["majority_baseline"]) == {"class", "accuracy", "balanced_accuracy", "macro_f1"}
        assert entry["real_held_out"]["clips"] == 12 and entry["synthetic"]["clips"] == 20
        for key in ("augmentation", "augmentation_all"):
            for s, (lo, hi) in entry[f"{key}_delta_ci95"].items():
                assert -1.0 <= lo <= hi <= 1.0 and s in entry[f"{key}_delta"]
    # 48 labelled real train gaits, one synthetic per real: all 20 synthetic gaits (none has per-frame labels)
    assert r["augmentation"]["drawn"] == {"all": 20} and r["augmentation"]["eligible"] == {"all": 20}
    # the controls: the same protocol with the 48 real train gaits added again, and with their mirror images
    assert list(r["augmentation"]["controls"]) == ["repeated", "mirrored"]
    assert all(c["gaits"] == 48 for c in r["augmentation"]["controls"].values())
    for kind in RECOGNISERS:
        entry = r["by_recogniser"][kind]
        assert list(entry["augmentation_controls"]) == ["repeated", "mirrored"]
        for control in entry["augmentation_controls"].values():
            held = control["augmented_real_held_out"]
            assert held["gaits"] == 24 and held["clips"] == 12
            for s in ("accuracy", "balanced_accuracy", "macro_f1"):
                assert control["augmentation_delta"][s] == pytest.approx(
                    held[f"{s}_mean"] - entry["real_held_out"][f"{s}_mean"], abs=1e-4)
                lo, hi = control["augmentation_delta_ci95"][s]
                assert -1.0 <= lo <= hi <= 1.0
    line = control_line(r)
    assert html.escape(line) in text and line.count("pts (CI ") == 2 * len(RECOGNISERS)
    mlp = r["by_recogniser"]["summary_mlp"]["augmentation_controls"]["mirrored"]["augmentation_delta"]["macro_f1"]
    assert "the real train gaits' mirror images (48 gaits): summary MLP " + ("−" if mlp < 0 else "+") in line
    memo = metrics["memorisation"]
    assert memo["train_windows"] == 53 and memo["real_held_out"]["gaits"] == 24 and memo["synthetic"]["gaits"] == 20
    for key in ("real_held_out", "synthetic"):
        assert 0 < memo[key]["p5"] <= memo[key]["median"] <= memo[key]["p95"]
    assert isinstance(memo["check"]["synthetic_median_ge_real_heldout_median"], bool)
    assert "memorisation.png" in text and "No memorisation" in text


def test_a_transition_whose_dominant_emotion_switches_is_no_whole_gait_example():
    steady_run = np.repeat(np.array([[0.6, 0.3, 0.1, 0.0]]), 10, axis=0)
    blend = np.linspace(0, 1, 10)[:, None]
    switching = (1 - blend) * np.array([0.7, 0.1, 0.1, 0.1]) + blend * np.array([0.1, 0.1, 0.7, 0.1])
    shading = (1 - blend) * np.array([0.7, 0.1, 0.1, 0.1]) + blend * np.array([0.5, 0.1, 0.3, 0.1])
    frame = pd.DataFrame({"emotion_per_frame": [steady_run, switching, shading, None]})
    assert steady_label(frame).tolist() == [True, False, True, True]
    assert steady_label(frame.drop(columns="emotion_per_frame")).tolist() == [True] * 4


def test_the_augmentation_draw_is_seeded_without_replacement_and_capped_by_the_pool():
    pool = np.arange(100, 140)
    drawn = augmentation_draw(pool, 12, seed=3)
    assert len(set(drawn)) == 12 and set(drawn) <= set(pool) and list(drawn) == sorted(drawn)
    assert np.array_equal(drawn, augmentation_draw(pool, 12, seed=3))
    assert not np.array_equal(drawn, augmentation_draw(pool, 12, seed=4))
    assert np.array_equal(augmentation_draw(pool, 99, seed=3), pool)


def test_augmentation_draws_per_real_gait_only_from_gaits_whose_label_holds():
    frame, _ = _frame()
    synthetic = np.flatnonzero(frame["kind"] == "synthetic")
    per_frame = [np.repeat(e[None], FRAMES, 0) if e is not None else None for e in frame["emotion"]]
    for i in synthetic[:8]:  # eight transitions that switch dominant emotion halfway
        per_frame[i] = np.concatenate([per_frame[i][: FRAMES // 2], np.roll(per_frame[i][FRAMES // 2:], 1, -1)])
    frame["emotion_per_frame"] = per_frame
    cfg = dataclasses.replace(AUDIT, synthetic_per_real=0.25, augment_with_all=False,
                              seeds={"summary_mlp": (0,), "temporal_cnn": (0,)})
    r = recognisability(frame, EMOTIONS, cfg)
    assert r["augmentation"]["eligible"] == {"all": 12} and r["augmentation"]["drawn"] == {"all": 12}
    assert "augmentation_delta" in r["by_recogniser"]["summary_mlp"]
    assert "augmentation_all_delta" not in r["by_recogniser"]["summary_mlp"]


def test_augmentation_is_also_scored_on_held_out_contents_the_generators_make_and_on_the_others():
    frame, _ = _frame()
    held = frame["split"].isin(["val", "test"]).to_numpy()
    frame["content"] = "walk"
    assert held_out_by_content(frame, held) == {}  # every held-out gait walks, as the synthetic ones do
    frame.loc[np.flatnonzero(held)[::3], "content"] = "run"  # a third of the held-out clips run
    views = held_out_by_content(frame, held)
    assert set(views) == {"generator_contents", "other_contents"}
    assert (views["generator_contents"] ^ views["other_contents"]).all()
    assert views["other_contents"].sum() == len(np.flatnonzero(held)[::3])
    cfg = dataclasses.replace(AUDIT, augment_with_all=False, seeds={"summary_mlp": (0, 1), "temporal_cnn": (0,)})
    r = recognisability(frame, EMOTIONS, cfg)
    assert r["held_out_by_content"]["other_contents"]["contents"] == ["run"]
    assert r["held_out_by_content"]["generator_contents"]["contents"] == ["walk"]
    assert sum(v["gaits"] for v in r["held_out_by_content"].values()) == r["gaits"]["real_held_out"]
    for entry in r["by_recogniser"].values():
        parts = entry["by_content"]
        # the same predictions, split: the two parts' confusions add up to the whole held-out set's
        for whole, part in ((entry["real_held_out"], lambda v: v["real_held_out"]),
                            (entry["augmented_real_held_out"], lambda v: v["augmented"]["all"]["augmented_real_held_out"])):
            summed = sum(np.array(part(v)["confusion_summed_over_seeds"]) for v in parts.values())
            assert np.array_equal(summed, np.array(whole["confusion_summed_over_seeds"]))
        for v in parts.values():
            change = v["augmented"]["all"]
            for s in ("accuracy", "balanced_accuracy", "macro_f1"):
                assert change["augmentation_delta"][s] == pytest.approx(
                    change["augmented_real_held_out"][f"{s}_mean"] - v["real_held_out"][f"{s}_mean"], abs=1e-4)
                lo, hi = change["augmentation_delta_ci95"][s]
                assert -1.0 <= lo <= hi <= 1.0
    rows = content_rows(r)  # the page's table: one row per recogniser, part and synthetic set, all formatted text
    assert len(rows) == 2 * 2 and all(isinstance(v, str) for row in rows for v in row.values())
    assert [row["held-out gaits"] for row in rows[:2]] == ["generator contents: walk", "other contents: run"]


def test_a_real_clip_is_its_source_file_and_a_synthetic_gait_its_own_unit():
    frame, _ = _frame()
    clips = clip_identity(frame)
    real = (frame["kind"] == "real").to_numpy()
    assert clips[0] == clips[1] == "mocap/clip0.bvh" and clips[2] != clips[1]
    assert list(clips[~real]) == list(frame.loc[~real, "gait_id"])


def test_no_cell_of_the_page_is_a_raw_list_or_dict(page):
    metrics, text = page
    cells = _cells(text)
    assert len(cells) > 100 and metrics["problem_count"] >= 2  # the planted problems are in the table
    # a list, dict, tuple or array repr ('affective[0]' is an index, '[0, 2π)' an interval: both allowed)
    raw = re.compile(r"(?<!\w)\[[^\]]*\]|[{}]|array\(|np\.|^None$|^nan$|^\(.*,.*\)$")
    assert [c for c in cells if raw.search(c)] == []
    assert "happy 0.25 · sad 0.25 · angry 0.25 · neutral 0.25" in cells  # a mean emotion, formatted
    assert any(c.startswith("values 0, 0.5") for c in cells)  # a problem's finding, formatted


def test_the_recognition_table_breaks_each_figure_from_its_interval(page):
    # seen in Chromium at 1280 px: one line per figure and interval made the table wider than the page
    _, text = page
    table = re.search(r'<table class="recognition">(.*?)</table>', text, re.S).group(1)
    head = [html.unescape(h) for h in re.findall(r"<th>(.*?)</th>", table)]
    assert head[4:7] == ["accuracy", "balanced accuracy", "macro-F1"] and max(map(len, head[:6])) <= 20
    rows = [[html.unescape(c) for c in re.findall(r"<td>(.*?)</td>", r, re.S)]
            for r in re.findall(r"<tr>(.*?)</tr>", table, re.S)]
    figures = [c for r in rows if r for c in r[4:7]]
    assert len(figures) >= 3 * 4 and all(len(c.split("\n")) == 2 for c in figures)
    assert all(c.split("\n")[1].startswith("(CI ") and max(map(len, c.split("\n"))) <= 28 for c in figures)
    assert "table.recognition td:nth-child(n+5){white-space:pre}" in text  # a figure line never breaks


def test_every_affective_feature_on_the_page_is_named_in_words_beside_its_index(page):
    _, text = page
    plain = _text(text)
    assert not re.search(r"(angle|distance_ratio|area_ratio)(_\d+)+", plain)
    names = canonical_skeleton().names
    rows = [html.unescape(re.sub(r"<[^>]+>", "|", r)) for r in re.findall(r"<tr>(.*?)</tr>", text, re.S)]
    for i, (kind, joints) in enumerate(AFFECTIVE_FEATURES):
        words = describe_affective_feature(kind, joints, names)
        assert not re.search(r"[\d_]", words) and all(n.split("_")[-1] in words or n == "root" for n in
                                                       (names[j].replace("hand_index", "index finger") for j in joints))
        assert any(f"|affective[{i}]|" in r and f"|{words}|" in r for r in rows), words
    assert "angle at the neck between the head and the left shoulder" in plain


def test_feature_words_come_from_the_definitions():
    assert [parse_affective_name(n) for n in AFFECTIVE_NAMES] == [(k, tuple(j)) for k, j in AFFECTIVE_FEATURES]
    names = canonical_skeleton().names
    described = feature_descriptions(AFFECTIVE_NAMES, MOVEMENT_NAMES, names)
    assert [d["words"] for d in described[:18]] == [describe_affective_feature(k, j, names)
                                                     for k, j in AFFECTIVE_FEATURES]
    assert described[7]["words"] == "angle at the left elbow between the left shoulder and the left hand"
    assert described[0]["words"] == "angle at the lower back between the right and left shoulders"
    assert described[13]["words"] == "ratio of the left toe–right toe distance to the neck–pelvis distance"
    assert parse_affective_name("angle_1_2") is None
    assert feature_descriptions(["tilt_x"], [], names)[0]["words"] == "tilt x"


def test_one_verdict_per_generator_family():
    frame, _ = _frame(generators=("autoregressive", "diffusion"))
    r = recognisability(frame, EMOTIONS, AUDIT)
    assert r["gaits"]["synthetic"] == 40
    for kind in RECOGNISERS:
        families = r["by_recogniser"][kind]["families"]
        assert set(families) == {"autoregressive", "diffusion"} and all(f["gaits"] == 20 for f in families.values())
    lines = verdict_lines(r)
    assert [name for name, _ in lines] == ["autoregressive", "diffusion"]
    for name, line in lines:
        for kind in RECOGNISERS:
            entry = r["by_recogniser"][kind]
            bal = entry["families"][name]["synthetic"]["balanced_accuracy_mean"]
            assert f"{entry['name']}: balanced accuracy {100 * bal:.1f} %" in line
    assert verdict_lines({"skipped": "no labelled real train or held-out gaits"})[0][1].startswith("no emotion")


@pytest.mark.slow  # two whole audits with their plots (~12 s)
def test_the_page_says_so_without_a_classifier_or_without_synthetic_gaits(tmp_path):
    frame, meta = _frame()
    only_train = frame.assign(split=["train" if k == "real" else s for k, s in zip(frame["kind"], frame["split"])])
    real_only = frame[frame["kind"] == "real"].reset_index(drop=True)
    for name, part in (("no_test", only_train), ("real_only", real_only)):
        audit_frame(part, meta, [], name, tmp_path / name, AUDIT)
        page = (tmp_path / name / "index.html").read_text()
        (verdict,) = re.findall(r'<li class="verdict">(.*?)</li>', page, re.S)
        assert ("no emotion recogniser" if name == "no_test" else "no labelled synthetic gaits") in verdict


def test_the_controls_are_the_real_train_gaits_again_and_their_true_mirror_images():
    frame, _ = _frame()
    train = frame[(frame["kind"] == "real") & (frame["split"] == "train")]
    inputs = RecognitionInputs.from_frame(train)
    # affective features that belong to the poses, so the mirror image's can be checked against its poses
    inputs = dataclasses.replace(inputs, affective=affective_features(torch.from_numpy(inputs.positions)).numpy())
    controls = augmentation_controls(inputs)
    assert list(controls) == ["repeated", "mirrored"] and controls["repeated"] is inputs
    image = controls["mirrored"]
    assert len(image) == len(inputs) and image.frames == inputs.frames
    assert not np.allclose(image.positions, inputs.positions)
    # the mirror image's affective features are those its poses have; its movement is the original's
    assert np.allclose(image.affective, affective_features(torch.from_numpy(image.positions)).numpy(), atol=1e-4)
    assert np.array_equal(image.movement, inputs.movement)
    # mirroring twice gives the gaits back
    again = augmentation_controls(image, ["mirrored"])["mirrored"]
    assert np.allclose(again.positions, inputs.positions, atol=1e-6)
    assert np.allclose(again.affective, inputs.affective, atol=1e-6)
    assert np.allclose(np.cos(again.heading - inputs.heading), 1.0, atol=1e-5)
    with pytest.raises(KeyError, match="audit.augmentation.controls: expected names among repeated, mirrored, "
                                       "found shuffled"):
        AuditConfig.from_dict({"seeds": {"summary_mlp": [0]}, "augmentation": {"controls": ["shuffled"]}})
    assert AuditConfig.from_dict({"seeds": {"summary_mlp": [0]},
                                  "augmentation": {"controls": []}}).augmentation_controls == ()
