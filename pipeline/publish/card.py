"""The dataset card (README.md of a published directory): a Hugging Face YAML header (one config per part: each
generator family's synthetic gaits and the real gaits, the named dataset's family the default) and datasheet
sections (Gebru et al. 2021) in the template ``templates/card.md``, filled from the composition counts, the schema
metadata, the sources' licences, the plan and the known limitations measured on the published gaits."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from string import Template
from typing import Any

import yaml

from pipeline.publish.limitations import card_section, seed_text
from pipeline.publish.table import COLUMN_DESCRIPTIONS

TEMPLATE = Path(__file__).with_name("templates") / "card.md"
HF_LICENSE = "cc-by-nc-4.0"  # the most restrictive source licence (Bandai Namco) binds the whole


def hf_header(parts: Mapping[str, list[str]], named_family: str, name: str) -> str:
    """The YAML front matter the Hugging Face Hub and ``datasets`` read: a config per part whose ``data_files``
    name its shards by pattern (``gaits-*-<part>.parquet``), and ``all`` for every shard."""
    configs = [{"config_name": part, **({"default": True} if part == named_family else {}),
                "data_files": [{"split": "train", "path": f"gaits-*-{part}.parquet"}]}
               for part in [named_family, *(p for p in parts if p != named_family)]]
    configs.append({"config_name": "all", "data_files": [{"split": "train", "path": "gaits-*.parquet"}]})
    header = {"pretty_name": name, "license": HF_LICENSE, "task_categories": ["other"],
              "tags": ["motion-capture", "gait", "emotion", "synthetic", "animation"], "configs": configs}
    return "---\n" + yaml.safe_dump(header, sort_keys=False, width=110) + "---\n"


def dataset_card(counts: dict[str, Any], meta: dict[str, Any], licences: dict[str, str], plan: dict[str, Any],
                 lineage_source: str, parts: Mapping[str, list[str]], named_family: str,
                 limitations: dict[str, Any], name: str = "Synthesized Emotive Gaits") -> str:
    """plan: trajectories, emotions, transitions, min_l1, prefix; lineage_source: where the provenance's stage
    graph was read from (named in the card); parts: part name -> its shard files; limitations: the figures
    ``limitations.measure`` took from the published table."""
    shapes = meta["shapes"]
    generators = meta["generators"]
    by_generator = counts["synthetic_by_generator"]
    return hf_header(parts, named_family, name) + Template(TEMPLATE.read_text(encoding="utf-8")).substitute(
        synthetic=by_generator.get(named_family, 0), real=counts["real"], named_family=named_family,
        rows="\n".join(f"| {k} | {v} |" for k, v in counts["by_kind_split"].items()),
        sources="\n".join(f"| {k} | {v} | {licences.get(k, 'see the source')} |"
                          for k, v in counts["real_by_source"].items()),
        generators="\n".join(f"| `{g}` | {by_generator.get(g, 0)} | {e['description']} | "
                             f"{'yes' if e['seeded'] else 'no'} | `{e['model_sha256'][:12]}…` |"
                             for g, e in generators.items()),
        configs="\n".join(f"| `{p}` | `gaits-*-{p}.parquet` | {len(files)} |" for p, files in parts.items()),
        families=", ".join(f"{k} ({v})" for k, v in counts["synthetic_by_family"].items()),
        columns="\n".join(f"| `{c}` | {shapes.get(c, 'scalar')} | {d} |" for c, d in COLUMN_DESCRIPTIONS.items()),
        emotion_order=", ".join(meta["emotion_order"]), lineage_source=lineage_source,
        limitations=card_section(limitations), **seed_text(limitations),
        **{k: plan[k] for k in ("trajectories", "emotions", "transitions", "min_l1", "prefix")})
