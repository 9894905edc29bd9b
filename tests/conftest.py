"""Shared fixtures: the real mocap (read in place), the manifests, one full ingest of the default data, and a small
ingest of the reference gaits' clips.

Two tiers (``slow`` in pyproject.toml): ``make test-fast`` runs ``-m "not slow"``, ``make test`` runs everything.
A test that takes ``full_ingest`` or ``annotated`` (itself or through another fixture) is ``slow`` by the rule in
``pytest_collection_modifyitems`` below: those fixtures ingest the whole default data (minutes). Other slow tests
carry ``@pytest.mark.slow`` where they stand. A fast test that needs real gaits takes ``reference_ingest`` /
``reference_annotated`` (the three reference clips, every window of each, through the same code: seconds).

The mocap is needed only where a test reads it: such a test takes the ``mocap`` fixture (itself, through
``ingest_config`` and the ingest fixtures, or by ``@pytest.mark.usefixtures("mocap")``) and is skipped, naming the
folder and how to get the data, where the folder is absent. Nothing skips when it is present.
``EMOGAIT_MOCAP_ROOT`` overrides params.yaml ``data.mocap_root`` for the tests only (``EMOGAIT_MOCAP_ROOT=/nowhere``
shows what runs without the data).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import torch

from pipeline.annotate.annotation import ANNOTATION_META, annotate_windows
from pipeline.core.emotions import EMOTIONS, dominant_emotion
from pipeline.core.skeleton import load_skeleton
from pipeline.ingest.run import build_report, ingest_chunk, plan_chunks, run_ingest
from pipeline.io.files import write_parquet
from pipeline.io.gait_table import read_gaits, to_table, with_arrays
from pipeline.io.manifests import SourceManifest, load_manifests
from pipeline.split import assign_splits
from stages.common import REPO, SKELETON, SOURCES, load_params, mocap_root
from stages.configs import annotate_config, ingest_config as params_ingest_config

MOCAP_ENV = "EMOGAIT_MOCAP_ROOT"
MOCAP = Path(os.environ[MOCAP_ENV]).resolve() if os.environ.get(MOCAP_ENV) else mocap_root(load_params())
MOCAP_HOW = MOCAP_ENV if os.environ.get(MOCAP_ENV) else "params.yaml data.mocap_root"

# Fixtures that ingest the whole default data: a test needing one is slow.
FULL_DATA_FIXTURES = frozenset({"full_ingest", "annotated"})

# Three reference windows: three sources, three styles (a Bandai Namco actor-labelled happy walk, a CMU iClone
# plain walk, a PyMO demo high-valence high-arousal walk). Their clips are the fast tier's real data.
REFERENCE_GAITS = (
    "bandai_namco_motiondataset/dataset/Bandai-Namco-Research-Motiondataset-1/data/dataset-1_walk_happy_001#w001",
    "cmu_iclone/All_BVH/subjects/002/002_01#w000",
    "pymo_demo/demos/data/AV_8Walk_Meredith_HVHA_Rep1#w005",
)


@pytest.hookimpl(tryfirst=True)  # before -m deselects, so "not slow" sees the markers added here
def pytest_collection_modifyitems(config, items):
    for item in items:
        if FULL_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def mocap() -> Path:
    """The real mocap folder; the test is skipped, saying where and how to get it, where the folder is absent."""
    if not MOCAP.is_dir():
        pytest.skip(f"no mocap at {MOCAP} ({MOCAP_HOW}); fetch the files pinned in manifests/sources/*.yaml from their "
                    "upstream repositories (the ingest stage lists them)")
    return MOCAP


@pytest.fixture(scope="session")
def skeleton():
    return load_skeleton(SKELETON)


@pytest.fixture(scope="session")
def manifests():
    return {m.name: m for m in load_manifests(SOURCES, formats=("bvh",))}


@pytest.fixture(scope="session")
def ingest_config(mocap):
    return dataclasses.replace(params_ingest_config(load_params()), mocap_root=mocap)


def repo_path(*parts: str) -> Path:
    return REPO.joinpath(*parts)


def _written_and_read(table, path: Path):
    write_parquet(table, path)
    return read_gaits(path)


@pytest.fixture(scope="session")
def full_ingest(tmp_path_factory, manifests, skeleton, ingest_config):
    """The whole default data through the local dask scheduler, written as the stage writes it."""
    windows, report = run_ingest(list(manifests.values()), skeleton, ingest_config, workers=2, progress=False)
    path = tmp_path_factory.mktemp("ingest") / "gaits.parquet"
    table, arrays = _written_and_read(to_table(windows, skeleton, ingest_config.window), path)
    return {"windows": windows, "report": report, "path": path, "table": table, "arrays": arrays}


def clip_manifests(manifests: dict[str, SourceManifest], gait_ids) -> list[SourceManifest]:
    """The source manifests cut down to the files of these gaits' clips (each still pinned by its sha256)."""
    wanted: dict[str, set[str]] = {}
    for gid in gait_ids:
        source, stem = gid.split("#")[0].split("/", 1)
        wanted.setdefault(source, set()).add(stem)
    out = []
    for source, stems in sorted(wanted.items()):
        m = manifests[source]
        files = tuple(f for f in m.files if Path(f.path).with_suffix("").as_posix() in stems)
        assert len(files) == len(stems), f"{source}: no pinned file for some of {sorted(stems)}"
        out.append(dataclasses.replace(m, doc={**m.doc, "globs": [f.path for f in files]}, files=files))
    return out


@pytest.fixture(scope="session")
def reference_ingest(tmp_path_factory, manifests, skeleton, ingest_config):
    """The reference gaits' clips, every window of each, through the ingest's own per-chunk function in this
    process (what every scheduler runs; a process pool would cost more than the work), written and read back as
    the stage does. Each clip's windows are the full ingest's (test_golden checks it against ``full_ingest``)."""
    chosen = clip_manifests(manifests, REFERENCE_GAITS)
    threads = torch.get_num_threads()  # ingest_chunk pins torch to one thread (it expects a worker process)
    try:
        results = [ingest_chunk(m, skeleton, entries, ingest_config)
                   for m, entries in plan_chunks(chosen, ingest_config)]
    finally:
        torch.set_num_threads(threads)
    records = sorted((r for res in results for r in res.records), key=lambda r: (r.source, r.path))
    windows = sorted((w for res in results for w in res.windows), key=lambda w: w["gait_id"])
    path = tmp_path_factory.mktemp("reference_ingest") / "gaits.parquet"
    table, arrays = _written_and_read(to_table(windows, skeleton, ingest_config.window), path)
    return {"windows": windows, "report": build_report(records, windows, ingest_config), "path": path,
            "table": table, "arrays": arrays}


def _annotate(tmp_path_factory, ingested, skeleton, name: str):
    """The annotate stage's output for an ingest, written and read back as the stage does."""
    table, arrays = ingested["table"], ingested["arrays"]
    ann, clips = annotate_windows(table.column("clip_id").to_pylist(), table.column("t_start").to_numpy(),
                                  arrays["positions"], arrays["rotations"], skeleton, annotate_config(load_params()))
    table2, arrays2 = _written_and_read(with_arrays(table, ann, ANNOTATION_META),
                                        tmp_path_factory.mktemp(name) / "gaits.parquet")
    arrays2["clips"] = clips
    return table2, arrays2


@pytest.fixture(scope="session")
def annotated(tmp_path_factory, full_ingest, skeleton):
    """The annotate stage's output for the full ingest."""
    return _annotate(tmp_path_factory, full_ingest, skeleton, "annotated")


@pytest.fixture(scope="session")
def annotated_split(annotated):
    """The annotated windows with the pipeline's split (``pipeline.split``, the params' seed and held-out rule):
    (table with a ``split`` column, arrays, split (N,) array, dominant emotion names (N,) list)."""
    table, arrays = annotated
    p = load_params()["split"]
    clip_ids = table.column("clip_id").to_pylist()
    labelled = ~np.isnan(arrays["emotion"]).any(-1)
    dominant = [dominant_emotion(arrays["emotion"][i] if labelled[i] else None, EMOTIONS) for i in range(len(clip_ids))]
    split_of = assign_splits(dict(zip(clip_ids, dominant)), p["fractions"], p["seed"], p["min_held_out_clips"])
    split = np.array([split_of[c] for c in clip_ids])
    return table.append_column("split", pa.array(split.tolist(), type=pa.string())), arrays, split, dominant


@pytest.fixture(scope="session")
def reference_annotated(tmp_path_factory, reference_ingest, skeleton):
    """The annotate stage's output for the reference clips (annotation is per clip: the full data's numbers)."""
    return _annotate(tmp_path_factory, reference_ingest, skeleton, "reference_annotated")
