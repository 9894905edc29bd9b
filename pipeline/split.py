"""Train/val/test assignment by clip: no window of a clip in two splits, stratified by dominant emotion.

Deterministic: clips are sorted, then shuffled with a seeded generator inside each stratum; each stratum
gives round(fraction * n) clips to val and test (a stratum too small for that stays in train). Labelled strata
(every stratum but ``unlabelled``) give at least ``min_held_out`` clips to each of val and test where that leaves
at least as many in train: the recognisers' held-out figures need more than one clip of every emotion, and an
emotion with one test clip scores one recording, not the emotion.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Sequence

import numpy as np


SPLITS = ("train", "val", "test")


UNLABELLED = "unlabelled"


def held_out_counts(n: int, fractions: dict[str, float], min_held_out: int) -> tuple[int, int]:
    """(val, test) clip counts of a stratum of n clips (``min_held_out`` 0: the plain fractions)."""
    n_test = int(round(fractions["test"] * n))
    n_val = int(round(fractions["val"] * n))
    if min_held_out and n - 2 * min_held_out >= min_held_out:
        n_test, n_val = max(n_test, min_held_out), max(n_val, min_held_out)
    if n_test + n_val >= n:  # too small to hold out: keep it for training
        n_test = n_val = 0
    return n_val, n_test


def assign_splits(clip_strata: dict[str, str], fractions: dict[str, float], seed: int,
                  min_held_out: int = 0) -> dict[str, str]:
    """{clip_id: split} with about ``fractions`` of the clips of every stratum in each split (and at least
    ``min_held_out`` clips of every labelled stratum in val and in test, where it has enough)."""
    if abs(sum(fractions.values()) - 1.0) > 1e-9 or set(fractions) != set(SPLITS):
        raise ValueError(f"split fractions must be {SPLITS} summing to 1, found {fractions}")
    rng = np.random.default_rng(seed)
    by_stratum: dict[str, list[str]] = defaultdict(list)
    for clip, stratum in sorted(clip_strata.items()):
        by_stratum[stratum].append(clip)
    assignment: dict[str, str] = {}
    for stratum in sorted(by_stratum):
        clips = by_stratum[stratum]
        order = [clips[i] for i in rng.permutation(len(clips))]
        n_val, n_test = held_out_counts(len(clips), fractions, 0 if stratum == UNLABELLED else min_held_out)
        for k, clip in enumerate(order):
            assignment[clip] = "test" if k < n_test else "val" if k < n_test + n_val else "train"
    return assignment


def split_report(clip_ids: Sequence[str], sources: Sequence[str], strata: Sequence[str],
                 assignment: dict[str, str], fractions: dict[str, float], seed: int) -> dict:
    """Counts of gaits and clips per split x source x dominant emotion, and the no-leak check."""
    gaits: Counter = Counter()
    clips_seen: dict[tuple, set] = defaultdict(set)
    splits_of_clip: dict[str, set] = defaultdict(set)
    for cid, src, stratum in zip(clip_ids, sources, strata):
        split = assignment[cid]
        gaits[(split, src, stratum)] += 1
        clips_seen[(split, src, stratum)].add(cid)
        splits_of_clip[cid].add(split)
    table = [{"split": sp, "source": src, "dominant_emotion": st, "gaits": n, "clips": len(clips_seen[(sp, src, st)])}
             for (sp, src, st), n in sorted(gaits.items())]
    totals = {sp: {"gaits": sum(r["gaits"] for r in table if r["split"] == sp),
                   "clips": sum(r["clips"] for r in table if r["split"] == sp)} for sp in SPLITS}
    leaks = sorted(c for c, s in splits_of_clip.items() if len(s) > 1)
    return {"seed": seed, "fractions": fractions, "totals": totals, "counts": table,
            "clips_in_two_splits": leaks, "clips": len(splits_of_clip)}
