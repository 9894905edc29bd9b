"""The emotions: their one order (every emotion vector in the pipeline is weights over these, summing to 1)."""

from __future__ import annotations

EMOTIONS = ("happy", "sad", "angry", "neutral")
