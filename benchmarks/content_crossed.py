"""Would synthetic gaits help the recogniser more if they crossed every emotion with every walking content?

The held-out labelled gaits pair emotions and contents the train split never pairs: its angry backward walks (7)
and sad walks to one side (18) are all in val or test, and the train split's angry gaits are forward and left
walks only. Today's synthesis seeds every gait from a labelled train forward walk of its own emotion, so the
synthetic gaits only add forward walks, and the summary MLP loses most on the held-out gaits of other contents
(the audit's ``by_content``). A generator can do what the real data cannot: continue a sad backward walk under the
angry condition. This measures, with the audit's own protocol, whether that helps:

- seeds: every labelled train gait of each walking content (``walk*``), its 18-frame prefix, continued 60 frames
  on a straight line with the synthesis placement under each of the four one-hot emotions (label: the condition);
- sets: ``walk_own`` (forward-walk seeds under their own emotion: today's rule, on a straight line),
  ``walk_crossed`` (forward-walk seeds under all four), ``all_crossed`` (every walking content under all four),
  ``other_crossed`` (the contents other than forward walks under all four);
- per recogniser and audit seed, the audit's augmentation (one synthetic gait drawn per real train gait, the same
  draw rule) against real-only, macro-F1 on the real held-out val + test gaits, all and split by content (the
  audit's views) and by held-out split (val, test), with the paired 95 % clip-bootstrap interval of the change; the published family's steady-label
  gaits beside, also split into thirds by mean |path curvature| and by the share of their dominant emotion;
- each set also drawn per emotion (``+matched``: as many synthetic gaits of each emotion as real train gaits have
  it), since the audit's draw follows the synthetic label mix (a fifth angry) while the real train split is three
  quarters neutral: with the class-balanced loss, the synthetic gaits then make up most of every rare emotion.

Checkpoints: the pipeline's generator and any given with ``--checkpoints`` (e.g. content_repeats.py's). The figures
choose nothing inside a generator: they say whether a seed rule is worth landing; the held-out gaits are few (117
from 20 clips), so read the intervals. Printed as JSON and written to benchmarks/out/content_crossed.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/content_crossed.py [--checkpoints P ...]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.audit.metrics import AuditConfig, augmentation_draw, clip_identity, held_out_by_content  # noqa: E402
from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.evaluation.autoregressive import straight_path  # noqa: E402
from pipeline.evaluation.controllability import generated_inputs, under_each_emotion  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, place_paths  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.ops.features import MOVEMENT_NAMES  # noqa: E402
from pipeline.recognition import (  # noqa: E402
    RECOGNISERS,
    RecognitionInputs,
    bootstrap_delta_interval,
    confusion,
    fit_recogniser,
    scores,
)
from pipeline.synth.synthesis import window_features  # noqa: E402
from stages.common import load_params  # noqa: E402
from stages.configs import annotate_config, placement_config  # noqa: E402

from generator_data import MODEL, generator, split_gaits  # noqa: E402
from published import published_gaits  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "content_crossed.json"
FRAMES = 60
MATCHED = "+matched"  # the set drawn per emotion (``matched_draw``)


def crossed_gaits(model_path: Path) -> tuple[str, RecognitionInputs, np.ndarray, np.ndarray, np.ndarray]:
    """Every labelled train walking seed under the four one-hot emotions: (checkpoint sha256, inputs, label (the
    condition), seed content, seed's own emotion), gaits ordered condition-major."""
    params = load_params()
    prefix = int(params["train"]["prefix"])
    arrays, split, content, dominant = split_gaits()
    model, sha, skeleton, offsets = generator(model_path)
    annotate = annotate_config(params)
    rows = np.flatnonzero((split == "train") & (dominant >= 0) & np.char.startswith(content.astype(str), "walk"))
    seeds = Seeds.from_arrays(arrays, rows, prefix)
    paths = place_paths(straight_path(), seeds)
    with torch.no_grad():
        generated = under_each_emotion(model, seeds, paths, FRAMES, offsets, skeleton.parents,
                                       placement_config(params))
    inputs = RecognitionInputs.concatenate([
        generated_inputs(g, lambda p, r: window_features(p, r, skeleton, annotate)) for g in generated])
    label = np.repeat(np.arange(len(EMOTIONS)), len(rows))
    return sha, inputs, label, np.tile(content[rows], len(EMOTIONS)), np.tile(dominant[rows], len(EMOTIONS))


def matched_draw(pool: np.ndarray, pool_label: np.ndarray, real_label: np.ndarray, seed: int) -> np.ndarray:
    """As ``augmentation_draw``, but per emotion: as many synthetic gaits of each label as the real train split has
    (all of them where fewer), so every emotion gets as many synthetic gaits as it has real ones."""
    return np.sort(np.concatenate([augmentation_draw(pool[pool_label[pool] == k], int((real_label == k).sum()),
                                                     seed + 1000 * k) for k in range(len(EMOTIONS))]))


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoints", type=Path, nargs="*", default=[])
    args = parser.parse_args()
    torch.set_num_threads(2)
    cfg = AuditConfig.from_dict(load_params()["audit"])
    published = published_gaits()
    names, inputs, label, train, test = (published.names, published.inputs, published.label, published.train,
                                         published.held)
    assert list(names) == list(EMOTIONS), (names, EMOTIONS)
    held_split = published.frame["split"].to_numpy()[test]
    views = {"all": np.ones(int(test.sum()), bool), **held_out_by_content(published.frame, test),
             **{split: held_split == split for split in sorted(set(held_split))}}
    groups = clip_identity(published.frame)[test]
    real_train, held, y = inputs.select(train), inputs.select(test), label[test]
    count = int(train.sum())

    # name -> (gaits, the rows of them the set draws from, every gait's label)
    sets: dict[str, tuple[RecognitionInputs, np.ndarray, np.ndarray]] = {}
    published_rows = np.flatnonzero(published.families["autoregressive_affect"])
    sets["published"] = (inputs, published_rows, label)
    # thirds of the published gaits by path curvature and by the share of their dominant emotion
    curvature = np.abs(inputs.movement[published_rows, :, MOVEMENT_NAMES.index("path_curvature")]).mean(1)
    share = np.array([max(published.frame["emotion"].iloc[i]) for i in published_rows])
    for name, value in {"curvature": curvature, "dominant_share": share}.items():
        low, high = np.quantile(value, [1 / 3, 2 / 3])
        sets[f"published:lowest_third_{name}"] = (inputs, published_rows[value <= low], label)
        sets[f"published:highest_third_{name}"] = (inputs, published_rows[value >= high], label)
    checkpoints: dict[str, str] = {}
    for path in [MODEL, *args.checkpoints]:
        started = time.perf_counter()
        sha, gen, gen_label, gen_content, own = crossed_gaits(path)
        tag = path.stem
        checkpoints[tag] = sha
        walk = gen_content == "walk"
        rules = {"walk_own": walk & (own == gen_label), "walk_crossed": walk, "all_crossed": np.ones_like(walk),
                 "other_crossed": ~walk}
        for rule, mask in rules.items():
            sets[f"{tag}:{rule}"] = (gen, np.flatnonzero(mask), gen_label)
        print(f"content_crossed: {tag}: {len(gen_label)} gaits generated in {time.perf_counter() - started:.0f} s",
              flush=True)

    sets.update({f"{name}{MATCHED}": entry for name, entry in list(sets.items())})

    def mean_macro_f1(predictions: list[np.ndarray]) -> dict[str, float]:
        """Per view, macro-F1 on the held-out gaits averaged over the seeds' predictions."""
        return {v: float(np.mean([scores(confusion(y[m], p[m], len(names)))["macro_f1"] for p in predictions]))
                for v, m in views.items()}

    out: dict = {"protocol": "audit.augmentation: per seed, one synthetic gait drawn per labelled real train gait; "
                             "macro-F1 on the real held-out val + test gaits (mean over the audit's seeds), change "
                             "from real-only with its paired 95 % clip-bootstrap interval",
                 "checkpoints": checkpoints, "real_train": count,
                 "held_out": {v: int(m.sum()) for v, m in views.items()},
                 "pool_sizes": {name: int(len(rows)) for name, (_, rows, _) in sets.items()}, "recognisers": {}}
    for kind in RECOGNISERS:
        started = time.perf_counter()
        before: list[np.ndarray] = []
        after: dict[str, list[np.ndarray]] = {name: [] for name in sets}
        for seed in cfg.seeds[kind]:
            before.append(fit_recogniser(kind, real_train, label[train], cfg.recognisers, seed).predict(held))
            for name, (source, pool, labels) in sets.items():
                drawn = (matched_draw(pool, labels, label[train], seed) if name.endswith(MATCHED)
                         else augmentation_draw(pool, count, seed))
                both = RecognitionInputs.concatenate([real_train, source.select(drawn)])
                fitted = fit_recogniser(kind, both, np.concatenate([label[train], labels[drawn]]), cfg.recognisers,
                                        seed)
                after[name].append(fitted.predict(held))
        entry: dict = {"real_only_macro_f1": {v: round(f, 4) for v, f in mean_macro_f1(before).items()}, "sets": {}}
        for name, answers in after.items():
            per_view = {}
            mean_after = mean_macro_f1(answers)
            for v, m in views.items():
                ci = bootstrap_delta_interval(groups[m], y[m], np.stack([p[m] for p in before]),
                                              np.stack([p[m] for p in answers]), len(names), cfg.bootstrap_resamples)
                per_view[v] = {"macro_f1": round(mean_after[v], 4),
                               "delta_pts": round(100 * (mean_after[v] - entry["real_only_macro_f1"][v]), 1),
                               "delta_ci95_pts": [round(100 * c, 1) for c in ci["macro_f1"]]}
            entry["sets"][name] = per_view
            print(f"content_crossed: {kind} {name}: " + ", ".join(
                f"{v} {d['delta_pts']:+.1f} [{d['delta_ci95_pts'][0]:+.1f}, {d['delta_ci95_pts'][1]:+.1f}]"
                for v, d in per_view.items()), flush=True)
        entry["seconds"] = round(time.perf_counter() - started, 1)
        out["recognisers"][kind] = entry
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
