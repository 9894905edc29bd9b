"""Shared fixtures: the real mocap (read in place), the manifests, and one full ingest of the default data."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.io.gait_table import read_gaits, to_table, write_parquet_atomic
from pipeline.ingest.run import IngestConfig, run_ingest
from pipeline.core.skeleton import load_skeleton
from pipeline.io.manifests import load_manifests
from stages.common import REPO, SKELETON, SOURCES, load_params, mocap_root

MOCAP = mocap_root(load_params())


def pytest_sessionstart(session):
    if not MOCAP.is_dir():
        raise pytest.UsageError(f"the real mocap data is required at {MOCAP} (params.yaml data.mocap_root)")


@pytest.fixture(scope="session")
def skeleton():
    return load_skeleton(SKELETON)


@pytest.fixture(scope="session")
def manifests():
    return {m.name: m for m in load_manifests(SOURCES, formats=("bvh",))}


@pytest.fixture(scope="session")
def ingest_config():
    p = load_params()["ingest"]
    return IngestConfig(mocap_root=MOCAP, target_fps=float(p["target_fps"]), window=int(p["window"]),
                        stride=int(p["stride"]), min_gait_speed=float(p["min_gait_speed"]),
                        chunk_frames=int(p["chunk_frames"]))


@pytest.fixture(scope="session")
def full_ingest(tmp_path_factory, manifests, skeleton, ingest_config):
    """The whole default data through the local dask scheduler, written as the stage writes it."""
    windows, report = run_ingest(list(manifests.values()), skeleton, ingest_config, workers=2, progress=False)
    path = tmp_path_factory.mktemp("ingest") / "gaits.parquet"
    write_parquet_atomic(to_table(windows, skeleton, ingest_config.window), path)
    table, arrays = read_gaits(path)
    return {"windows": windows, "report": report, "path": path, "table": table, "arrays": arrays}


def repo_path(*parts: str) -> Path:
    return REPO.joinpath(*parts)


@pytest.fixture(scope="session")
def annotated(tmp_path_factory, full_ingest, skeleton):
    """The annotate stage's output for the full ingest, written and read back as the stage does."""
    from pipeline.annotate.annotation import ANNOTATION_META, annotate_windows
    from pipeline.io.gait_table import with_arrays
    from stages.annotate import config

    cfg = config(load_params())
    table, arrays = full_ingest["table"], full_ingest["arrays"]
    ann, clips = annotate_windows(table.column("clip_id").to_pylist(), table.column("t_start").to_numpy(),
                                  arrays["positions"], arrays["rotations"], skeleton, cfg)
    path = tmp_path_factory.mktemp("annotated") / "gaits.parquet"
    write_parquet_atomic(with_arrays(table, ann, ANNOTATION_META), path)
    table2, arrays2 = read_gaits(path)
    arrays2["clips"] = clips
    return table2, arrays2
