"""The emotions gaits are labelled with: their one order, and a label's dominant emotion.

``EMOTIONS`` is the order of the components of every emotion vector in the pipeline: the gait table's ``emotion``
column (and its ``emotion_order`` metadata), the generator's condition, the synthesis plan's recipes and the
published dataset.

This module must never know where labels come from (sources, label rules, files) or how they are used.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

EMOTIONS = ("happy", "sad", "angry", "neutral")


def dominant_emotion(emotion: np.ndarray | None, names: Sequence[str]) -> str:
    """The largest component's name, 'tie' when several share it, 'unlabelled' for no label."""
    if emotion is None or not np.isfinite(emotion).all():
        return "unlabelled"
    top = np.flatnonzero(np.isclose(emotion, emotion.max()))
    return names[int(top[0])] if len(top) == 1 else "tie"
