"""The emotions gaits are labelled with: their one order, and a label's dominant emotion.

``EMOTIONS`` is the order of the components of every emotion vector in the pipeline: the gait table's ``emotion``
column (and its ``emotion_order`` metadata), the generator's condition, the synthesis plan's recipes and the
published dataset.

This module must never know which source or rule labels a gait, or how labels are used.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

EMOTIONS = ("happy", "sad", "angry", "neutral")

# How a label was obtained (the ``label_method`` column; null: unlabelled, no emotion is ever guessed).
SOURCE_LABEL_METHODS = ("actor_intended", "style_mapping")  # real gaits: the actor's stated intent, a style word
GENERATOR_LABEL_METHOD = "generator_condition"  # synthetic gaits: the condition they were generated with


def dominant_index(emotion: np.ndarray) -> np.ndarray:
    """(...) index of each label's largest component (EMOTIONS order; the first of a tie), -1 where unlabelled
    (NaN components): labels (..., 4) as the gait table stores them."""
    labelled = ~np.isnan(emotion).any(-1)
    return np.where(labelled, np.nan_to_num(emotion).argmax(-1), -1)


def dominant_emotion(emotion: np.ndarray | None, names: Sequence[str]) -> str:
    """The largest component's name, 'tie' when several share it, 'unlabelled' for no label."""
    if emotion is None or not np.isfinite(emotion).all():
        return "unlabelled"
    top = np.flatnonzero(np.isclose(emotion, emotion.max()))
    return names[int(top[0])] if len(top) == 1 else "tie"
