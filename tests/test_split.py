"""Split by clip: no leaks, stratified, seeded."""

import numpy as np

from pipeline.core.emotions import EMOTIONS, dominant_emotion, dominant_index
from pipeline.split import assign_splits, split_report

FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}


def _strata(annotated):
    table, arrays = annotated
    clip_ids = table.column("clip_id").to_pylist()
    strata = [dominant_emotion(None if np.isnan(e).any() else e, EMOTIONS) for e in arrays["emotion"]]
    return table, clip_ids, strata


def test_no_clip_in_two_splits_and_fractions_per_stratum(annotated):
    table, clip_ids, strata = _strata(annotated)
    clip_strata = dict(zip(clip_ids, strata))
    assignment = assign_splits(clip_strata, FRACTIONS, seed=17)
    report = split_report(clip_ids, table.column("source").to_pylist(), strata, assignment, FRACTIONS, 17)
    assert report["clips_in_two_splits"] == []
    for stratum in set(clip_strata.values()):
        clips = [c for c, s in clip_strata.items() if s == stratum]
        if len(clips) >= 20:
            share = {sp: sum(assignment[c] == sp for c in clips) / len(clips) for sp in FRACTIONS}
            for sp, f in FRACTIONS.items():
                assert abs(share[sp] - f) < 0.05, (stratum, share)
    # every labelled emotion is represented in the test split
    test_emotions = {r["dominant_emotion"] for r in report["counts"] if r["split"] == "test"}
    assert {"happy", "sad", "angry", "neutral"} <= test_emotions


def test_split_is_seeded(annotated):
    _, clip_ids, strata = _strata(annotated)
    clip_strata = dict(zip(clip_ids, strata))
    a = assign_splits(clip_strata, FRACTIONS, seed=17)
    assert a == assign_splits(dict(reversed(list(clip_strata.items()))), FRACTIONS, seed=17)
    assert a != assign_splits(clip_strata, FRACTIONS, seed=18)


def test_dominant_emotion_reports_ties_and_missing_labels():
    assert dominant_emotion(np.array([0.1, 0.6, 0.2, 0.1]), EMOTIONS) == "sad"
    assert dominant_emotion(np.array([0.4, 0.4, 0.1, 0.1]), EMOTIONS) == "tie"
    assert dominant_emotion(None, EMOTIONS) == "unlabelled"


def test_dominant_index_agrees_with_dominant_emotion_on_the_real_labels(annotated):
    """The index form (-1: unlabelled) names the same emotion as the string form for every real gait, keeps the
    leading dimensions, and takes the first of a tie (the string form says 'tie')."""
    _, arrays = annotated
    index = dominant_index(arrays["emotion"])
    named = [dominant_emotion(None if np.isnan(e).any() else e, EMOTIONS) for e in arrays["emotion"]]
    assert (index >= 0).any() and (index == -1).any()
    for k, name in zip(index, named):
        assert (k == -1) == (name == "unlabelled")
        assert k == -1 or name in (EMOTIONS[k], "tie")
    per_frame = np.stack([arrays["emotion"]] * 3, axis=1)  # (N, 3, 4): per-frame labels
    assert (dominant_index(per_frame) == index[:, None]).all()
    assert dominant_index(np.array([0.4, 0.4, 0.1, 0.1])) == 0
    assert dominant_index(np.array([0.1, np.nan, 0.1, 0.1])) == -1


def test_min_held_out_keeps_two_labelled_clips_of_every_emotion_in_val_and_test(annotated):
    table, clip_ids, strata = _strata(annotated)
    clip_strata = dict(zip(clip_ids, strata))
    assignment = assign_splits(clip_strata, FRACTIONS, seed=17, min_held_out=2)
    plain = assign_splits(clip_strata, FRACTIONS, seed=17)
    for emotion in EMOTIONS:
        clips = [c for c, s in clip_strata.items() if s == emotion]
        assert len(clips) >= 6, (emotion, len(clips))  # the default data has enough of every emotion
        held = {sp: sum(assignment[c] == sp for c in clips) for sp in ("train", "val", "test")}
        assert held["val"] >= 2 and held["test"] >= 2 and held["train"] >= 2, (emotion, held)
    # with the plain fractions the rarer emotions have a single test clip: the rule is what changes that
    assert min(sum(plain[c] == "test" for c, s in clip_strata.items() if s == e) for e in EMOTIONS) == 1
    # the unlabelled stratum keeps its plain fractions
    unlabelled = [c for c, s in clip_strata.items() if s == "unlabelled"]
    assert [assignment[c] for c in unlabelled] == [plain[c] for c in unlabelled]
