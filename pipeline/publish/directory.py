"""Publishing a gait directory: Parquet shards, HDF5, stick-figure previews, the dataset card (with the known
limitations measured on the gaits), Croissant 1.1, PROV-JSON lineage, the generator families' model lineage and
SHA256SUMS, then the loader's verify over the result.

Every shard holds one part, the real gaits or one generator family's, and names it
(``gaits-<n>-<part>.parquet``, n counting over all shards in part order), so the card's Hugging Face configs can
name each family's files while the loaders read every ``gaits-*.parquet`` in name order.

Takes tables, plain configuration and a stage graph; it never reads params or pipeline files.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from string import Template
from typing import Any

import numpy as np
import pyarrow as pa
import yaml

from pipeline.dataset import HDF5_NAME, verify, write_hdf5_atomic, write_sha256sums
from pipeline.io.files import schema_meta, write_json, write_parquet, write_text
from pipeline.io.gait_table import column_array
from pipeline.publish.card import dataset_card
from pipeline.publish.croissant import croissant_metadata, croissant_problems, write_croissant
from pipeline.publish.limitations import measure, seed_text
from pipeline.publish.provenance import PROVENANCE_NAME, prov_document, write_provenance
from pipeline.publish.table import COLUMN_DESCRIPTIONS, composition, published_parts, real_table
from pipeline.viz.stick_figures import Motion, render_filmstrip

RESPONSIBLE_AI = Path(__file__).with_name("templates") / "responsible_ai.yaml"
GENERATORS_NAME = "generators.json"  # each family's entry and model lineage (e.g. the real cycles it was fitted on)


def shard_name(number: int, part: str) -> str:
    return f"gaits-{number:03d}-{part}.parquet"


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


def previews(table: pa.Table, meta: dict[str, Any], out: Path, named_family: str) -> list[str]:
    """Stick figures: the named family's gaits, a sample per trajectory family; per generator family the gait
    most of each emotion (``emotions.png``, another family's ``emotions_<family>.png``) and a transition
    (``transition.png``, ``transition_<family>.png``)."""
    positions = column_array(table, "positions", meta["shapes"]["positions"])
    emotion = column_array(table, "emotion", meta["shapes"]["emotion"])
    generator = np.array([g or "" for g in table.column("generator").to_pylist()])
    family = table.column("trajectory_family").to_pylist()
    recipes = [json.loads(r) if r else None for r in table.column("emotion_recipe").to_pylist()]
    ids = table.column("gait_id").to_pylist()
    names, parents = meta["joint_names"], meta["parents"]

    def motion(i: int, title: str) -> Motion:
        return Motion(f"{ids[i]}: {title}", positions[i], parents, names)

    written = []
    out.mkdir(parents=True, exist_ok=True)
    for name in meta["generators"]:
        rows = np.flatnonzero(generator == name)
        single = [i for i in rows if recipes[i]["kind"] == "single"]
        suffix = "" if name == named_family else f"_{name}"
        if name == named_family:
            first_of_family: dict[str, int] = {}
            for i in single:
                first_of_family.setdefault(family[i], i)
            for chunk in range(0, len(first_of_family), 5):
                items = list(first_of_family.items())[chunk:chunk + 5]
                path = out / f"families_{chunk // 5 + 1}.png"
                render_filmstrip([motion(i, f) for f, i in items], path)
                written.append(path.name)
        per_emotion = []
        for k, emotion_name in enumerate(meta["emotion_order"]):
            i = max(single, key=lambda j: emotion[j, k])
            per_emotion.append(motion(i, f"{name}, most {emotion_name} ({emotion[i, k]:.2f})"))
        render_filmstrip(per_emotion, out / f"emotions{suffix}.png")
        transition = next(i for i in rows if recipes[i]["kind"] == "transition")
        ends = " -> ".join(str([round(v, 2) for v in recipes[transition][f"{k}_vector"]]) for k in ("from", "to"))
        render_filmstrip([motion(transition, f"{name}, transition {ends}")], out / f"transition{suffix}.png")
        written += [f"emotions{suffix}.png", f"transition{suffix}.png"]
    return written


def responsible_ai(meta: dict[str, Any], figures: dict[str, Any]) -> dict[str, str]:
    """The Croissant RAI fields (``templates/responsible_ai.yaml``) with what they say of the generator families
    and their seeds filled from the published table (``limitations.seed_text``)."""
    words = {"families": ", ".join(meta["generators"]), "family_count": str(len(meta["generators"])),
             **seed_text(figures)}
    fields = yaml.safe_load(RESPONSIBLE_AI.read_text(encoding="utf-8"))
    return {k: Template(v).substitute(words) for k, v in fields.items()}


def publish_directory(real: pa.Table, real_arrays: dict[str, np.ndarray], families: list[pa.Table],
                      lineages: dict[str, dict[str, Any]], out: Path, cfg: PublishConfig, licences: dict[str, str],
                      plan: dict[str, Any], graph: dict[str, Any], repo_root: Path,
                      lineage_source: str) -> dict[str, Any]:
    """Write the published directory ``out`` (replacing it) and return the report (counts, files, verify).

    families: each generator family's synthetic table (``synthetic_table``), the named dataset's first;
    lineages: family name -> its model lineage (``GeneratorFamily.lineage``), written to generators.json;
    licences: source name -> licence; plan: see ``dataset_card``; graph, repo_root: the stage graph and the root
    its paths are relative to (``prov_document``); lineage_source: what the graph was read from, for the card.
    """
    parts = published_parts(real_table(real, real_arrays), families)
    table = pa.concat_tables([t for _, t in parts]).combine_chunks()
    meta = schema_meta(table.schema)
    named_family = parts[1][0]
    if out.exists():
        shutil.rmtree(out)  # a stale shard must not survive a smaller run
    out.mkdir(parents=True)
    shards: dict[str, list[str]] = {}
    number = 0
    for part, part_table in parts:
        for first in range(0, part_table.num_rows, cfg.shard_gaits):
            name = shard_name(number, part)
            write_parquet(part_table.slice(first, cfg.shard_gaits), out / name)
            shards.setdefault(part, []).append(name)
            number += 1
    write_hdf5_atomic(table, {}, out / HDF5_NAME, meta)
    write_json({name: {**meta["generators"][name], "gaits": sum(len(t) for p, t in parts if p == name),
                       "model_lineage": lineages.get(name, {})} for name in meta["generators"]},
               out / GENERATORS_NAME)
    preview_files = previews(table, meta, out / "previews", named_family)
    counts = composition(table)
    figures = measure(table, meta)
    write_text(dataset_card(counts, meta, licences, plan, lineage_source, shards, named_family, figures),
               out / "README.md")
    doc = croissant_metadata(out, name=cfg.name, description=cfg.description, version=cfg.version,
                             license=cfg.license, citation=cfg.citation, url=cfg.url,
                             date_published=cfg.date_published, creators=cfg.creators,
                             rai=responsible_ai(meta, figures), column_descriptions=COLUMN_DESCRIPTIONS, parts=shards)
    write_croissant(out, doc)
    write_provenance(out / PROVENANCE_NAME, prov_document(graph, repo_root, out))
    write_sha256sums(out)
    problems = verify(out) + croissant_problems(out, doc)
    return {"counts": counts, "limitations": figures, "shards": shards, "previews": preview_files,
            "files": sorted(f.name for f in out.iterdir() if f.is_file()), "verify_problems": problems,
            "verified": not problems}
