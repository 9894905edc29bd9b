"""The audit on a published directory with planted defects: every defect is named, nothing crashes, and the
page shows every figure. (The audit of the real published dataset runs in tests/test_dvc_stage.py.)"""

from __future__ import annotations

import json
import re

import numpy as np
import pyarrow as pa
import pytest

from pipeline.audit.metrics import js_distance, normalised_entropy, scores
from pipeline.dataset import write_sha256sums
from pipeline.io.gait_table import array_column, column_array
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
