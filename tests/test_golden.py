"""Reference gaits: a few windows' numbers kept as golden files, so a change in the numbers is seen, not guessed.

After a deliberate change (new canonical lengths, a retargeting fix), regenerate with
    EMOGAIT_UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/test_golden.py
and say in the commit why the numbers moved.
"""

import json
import os
from pathlib import Path

import numpy as np
import pytest

GOLDEN = Path(__file__).parent / "golden" / "ingest_reference.json"
GAITS = [
    "bandai_namco_motiondataset/dataset/Bandai-Namco-Research-Motiondataset-1/data/dataset-1_walk_happy_001#w001",
    "cmu_iclone/All_BVH/subjects/002/002_01#w000",
    "pymo_demo/demos/data/AV_8Walk_Meredith_HVHA_Rep1#w005",
]
FRAMES = [0, 29, 59]


def _snapshot(full_ingest):
    ids = full_ingest["table"].column("gait_id").to_pylist()
    table, arrays = full_ingest["table"], full_ingest["arrays"]
    out = {}
    for gid in GAITS:
        k = ids.index(gid)
        out[gid] = {
            "t_start": table.column("t_start")[k].as_py(),
            "scale": round(table.column("scale")[k].as_py(), 6),
            "positions": np.round(arrays["positions"][k][FRAMES].astype(np.float64), 4).tolist(),
            "rotations": np.round(arrays["rotations"][k][FRAMES].astype(np.float64), 4).tolist(),
            "heading": np.round(arrays["heading"][k][FRAMES].astype(np.float64), 4).tolist(),
        }
    return out


def test_reference_gaits_are_unchanged(full_ingest):
    now = _snapshot(full_ingest)
    if os.environ.get("EMOGAIT_UPDATE_GOLDEN"):
        GOLDEN.write_text(json.dumps(now) + "\n")
        pytest.skip("golden file rewritten")
    golden = json.loads(GOLDEN.read_text())
    assert set(golden) == set(now)
    for gid, ref in golden.items():
        assert now[gid]["t_start"] == ref["t_start"], gid
        assert now[gid]["scale"] == pytest.approx(ref["scale"], abs=1e-6), gid
        for key in ("positions", "rotations", "heading"):
            np.testing.assert_allclose(now[gid][key], ref[key], atol=2e-4, err_msg=f"{gid} {key}")
