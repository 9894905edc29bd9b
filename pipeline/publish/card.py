"""The dataset card (README.md of a published directory): datasheet sections (Gebru et al. 2021) in the template
``templates/card.md``, filled from the composition counts, the schema metadata, the sources' licences and the plan."""

from __future__ import annotations

from pathlib import Path
from string import Template
from typing import Any

from pipeline.publish.table import COLUMN_DESCRIPTIONS

TEMPLATE = Path(__file__).with_name("templates") / "card.md"


def dataset_card(counts: dict[str, Any], meta: dict[str, Any], licences: dict[str, str], plan: dict[str, Any],
                 lineage_source: str) -> str:
    """plan: trajectories, emotions, transitions, min_l1, prefix; lineage_source: where the provenance's stage
    graph was read from (named in the card)."""
    shapes = meta["shapes"]
    return Template(TEMPLATE.read_text(encoding="utf-8")).substitute(
        synthetic=counts["synthetic"], real=counts["real"],
        rows="\n".join(f"| {k} | {v} |" for k, v in counts["by_kind_split"].items()),
        sources="\n".join(f"| {k} | {v} | {licences.get(k, 'see the source')} |"
                          for k, v in counts["real_by_source"].items()),
        families=", ".join(f"{k} ({v})" for k, v in counts["synthetic_by_family"].items()),
        columns="\n".join(f"| `{c}` | {shapes.get(c, 'scalar')} | {d} |" for c, d in COLUMN_DESCRIPTIONS.items()),
        emotion_order=", ".join(meta["emotion_order"]), lineage_source=lineage_source,
        **{k: plan[k] for k in ("trajectories", "emotions", "transitions", "min_l1", "prefix")})
