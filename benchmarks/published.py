"""The published directory read as the audit reads it, for the benchmarks that compare groups of its gaits
(asymmetry.py, diversity.py): labels, the real train and held-out gaits, and each family's steady-label gaits."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline.audit.metrics import (  # noqa: E402
    AuditConfig,
    generator_families,
    labelled_gaits,
    load_for_audit,
    steady_label,
)
from pipeline.recognition import RecognitionInputs  # noqa: E402
from stages.common import load_params  # noqa: E402

PUBLISHED = REPO / "data" / "published" / "synthesized_emotive_gaits"


@dataclass
class PublishedGaits:
    frame: pd.DataFrame
    names: list[str]         # emotion order
    inputs: RecognitionInputs
    label: np.ndarray        # dominant emotion's index in names (-1: none)
    train: np.ndarray        # usable real train gaits
    held: np.ndarray         # usable real gaits of the audit's test splits
    families: dict[str, np.ndarray]  # per family, its usable gaits whose label holds in every frame


def published_gaits(directory: Path = PUBLISHED) -> PublishedGaits:
    cfg = AuditConfig.from_dict(load_params()["audit"])
    frame, meta = load_for_audit(directory)
    names = meta["emotion_order"]
    inputs = RecognitionInputs.from_frame(frame)
    label, usable, train, held = labelled_gaits(frame, names, inputs, cfg.test_splits)
    steady = steady_label(frame)
    families = {family: mask & usable & steady for family, mask in generator_families(frame).items()}
    return PublishedGaits(frame, names, inputs, label, train, held, families)
