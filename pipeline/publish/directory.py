"""Publishing a gait directory: Parquet shards, HDF5, stick-figure previews, the dataset card, Croissant 1.1,
PROV-JSON lineage and SHA256SUMS, then the loader's verify over the result.

Takes tables, plain configuration and a stage graph; it never reads params or pipeline files.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import yaml

from pipeline.dataset import HDF5_NAME, verify, write_hdf5_atomic, write_sha256sums
from pipeline.io.files import schema_meta, write_parquet, write_text
from pipeline.io.gait_table import column_array
from pipeline.publish.card import dataset_card
from pipeline.publish.croissant import croissant_metadata, croissant_problems, write_croissant
from pipeline.publish.provenance import PROVENANCE_NAME, prov_document, write_provenance
from pipeline.publish.table import COLUMN_DESCRIPTIONS, composition, published_table, real_table
from pipeline.viz.stick_figures import Motion, render_filmstrip

RESPONSIBLE_AI = Path(__file__).with_name("templates") / "responsible_ai.yaml"


@dataclass(frozen=True)
class PublishConfig:
    """The published dataset's metadata (Croissant) and its Parquet shard size."""

    name: str
    description: str
    version: str
    license: list[str] | str
    citation: str
    url: str
    date_published: str  # given, not read from the clock: the same inputs give the same bytes
    creators: list[dict[str, Any]]
    shard_gaits: int

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PublishConfig:
        return cls(name=d["name"], description=d["description"], version=str(d["version"]), license=d["license"],
                   citation=d["citation"], url=d["url"], date_published=str(d["date_published"]),
                   creators=d["creators"], shard_gaits=int(d["shard_gaits"]))


def previews(table: pa.Table, meta: dict[str, Any], out: Path) -> list[str]:
    """Stick figures: a sample per trajectory family, per dominant emotion, and a transition."""
    positions = column_array(table, "positions", meta["shapes"]["positions"])
    emotion = column_array(table, "emotion", meta["shapes"]["emotion"])
    kind = np.array(table.column("kind").to_pylist())
    family = table.column("trajectory_family").to_pylist()
    recipes = [json.loads(r) if r else None for r in table.column("emotion_recipe").to_pylist()]
    ids = table.column("gait_id").to_pylist()
    names, parents = meta["joint_names"], meta["parents"]

    def motion(i: int, title: str) -> Motion:
        return Motion(f"{ids[i]}: {title}", positions[i], parents, names)

    synthetic = np.flatnonzero(kind == "synthetic")
    single = [i for i in synthetic if recipes[i]["kind"] == "single"]
    first_of_family: dict[str, int] = {}
    for i in single:
        first_of_family.setdefault(family[i], i)
    written = []
    out.mkdir(parents=True, exist_ok=True)
    for chunk in range(0, len(first_of_family), 5):
        items = list(first_of_family.items())[chunk:chunk + 5]
        path = out / f"families_{chunk // 5 + 1}.png"
        render_filmstrip([motion(i, f) for f, i in items], path)
        written.append(path.name)
    per_emotion = []
    for k, name in enumerate(meta["emotion_order"]):
        i = max(single, key=lambda j: emotion[j, k])
        per_emotion.append(motion(i, f"most {name} ({emotion[i, k]:.2f})"))
    render_filmstrip(per_emotion, out / "emotions.png")
    transition = next(i for i in synthetic if recipes[i]["kind"] == "transition")
    ends = " -> ".join(str([round(v, 2) for v in recipes[transition][f"{k}_vector"]]) for k in ("from", "to"))
    render_filmstrip([motion(transition, f"transition {ends}")], out / "transition.png")
    return written + ["emotions.png", "transition.png"]


def publish_directory(real: pa.Table, real_arrays: dict[str, np.ndarray], synthetic: pa.Table, out: Path,
                      cfg: PublishConfig, licences: dict[str, str], plan: dict[str, Any], graph: dict[str, Any],
                      repo_root: Path, lineage_source: str) -> dict[str, Any]:
    """Write the published directory ``out`` (replacing it) and return the report (counts, files, verify).

    licences: source name -> licence; plan: see ``dataset_card``; graph, repo_root: the stage graph and the root
    its paths are relative to (``prov_document``); lineage_source: what the graph was read from, for the card.
    """
    table = published_table(real_table(real, real_arrays), synthetic)
    meta = schema_meta(table.schema)
    if out.exists():
        shutil.rmtree(out)  # a stale shard must not survive a smaller run
    out.mkdir(parents=True)
    for n, first in enumerate(range(0, table.num_rows, cfg.shard_gaits)):
        write_parquet(table.slice(first, cfg.shard_gaits), out / f"gaits-{n:03d}.parquet")
    write_hdf5_atomic(table, {}, out / HDF5_NAME, meta)
    preview_files = previews(table, meta, out / "previews")
    counts = composition(table)
    write_text(dataset_card(counts, meta, licences, plan, lineage_source), out / "README.md")
    doc = croissant_metadata(out, name=cfg.name, description=cfg.description, version=cfg.version,
                             license=cfg.license, citation=cfg.citation, url=cfg.url,
                             date_published=cfg.date_published, creators=cfg.creators,
                             rai=yaml.safe_load(RESPONSIBLE_AI.read_text(encoding="utf-8")),
                             column_descriptions=COLUMN_DESCRIPTIONS)
    write_croissant(out, doc)
    write_provenance(out / PROVENANCE_NAME, prov_document(graph, repo_root, out))
    write_sha256sums(out)
    problems = verify(out) + croissant_problems(out, doc)
    return {"counts": counts, "previews": preview_files, "files": sorted(f.name for f in out.iterdir() if f.is_file()),
            "verify_problems": problems, "verified": not problems}
