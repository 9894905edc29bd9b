"""The two independent emotion recognisers, trained on real labelled gaits only and never inside a generator's
training loss:

* ``summary_mlp``: a small MLP on the per-gait mean and standard deviation over frames of the affective and
  movement features;
* ``temporal_cnn``: a 1-D convolution over the frames of the root-relative, heading-frame pose and the root's
  heading-frame motion (``inputs.pose_channels``), global average pooling over time.

Both read any number of frames >= 10: each is trained on the whole windows and, every epoch, on a fresh random
crop of ``block_frames`` frames of every gait (seeded), so a 20-frame block is read as well as a 60-frame window.
The loss is class-balanced (inverse class frequency). The temporal CNN trains ``epochs`` passes of mini-batches,
at most ``max_steps`` steps (a real + synthetic training set is ~20x the real one). Training is deterministic for a seed
(``torch.use_deterministic_algorithms`` while fitting; the global torch RNG is left as it was).
"""

from __future__ import annotations

from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import torch

from pipeline.core.emotions import EMOTIONS
from pipeline.recognition.inputs import MIN_FRAMES, RecognitionInputs, pose_channels

RECOGNISERS = ("summary_mlp", "temporal_cnn")
RECOGNISER_NAMES = {"summary_mlp": "summary MLP", "temporal_cnn": "temporal CNN"}
_CHUNK = 2048  # gaits per forward pass when reading


@dataclass(frozen=True)
class SummaryConfig:
    hidden: int = 32
    epochs: int = 300
    learning_rate: float = 0.01
    weight_decay: float = 1e-3


@dataclass(frozen=True)
class TemporalConfig:
    channels: int = 32
    kernel: int = 5
    epochs: int = 40
    learning_rate: float = 3e-3
    weight_decay: float = 1e-4
    batch: int = 64
    max_steps: int = 500  # at most this many optimiser steps: real + synthetic training sets are ~20x the real one


@dataclass(frozen=True)
class RecogniserConfig:
    """The recognisers' settings (params.yaml ``audit.recognisers``)."""

    block_frames: int = 20
    summary: SummaryConfig = field(default_factory=SummaryConfig)
    temporal: TemporalConfig = field(default_factory=TemporalConfig)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "RecogniserConfig":
        """From {"block_frames", "summary": {...}, "temporal": {...}}; a missing key keeps its default, an unknown
        one is refused (naming it)."""
        d = dict(d or {})
        unknown = set(d) - {"block_frames", "summary", "temporal"}

        def part(kind, values):
            names = {f.name: f.type for f in fields(kind)}
            extra = set(values or {}) - set(names)
            if extra:
                raise KeyError(f"recognisers.{'summary' if kind is SummaryConfig else 'temporal'}: unknown "
                               f"{', '.join(sorted(extra))} (expected {', '.join(names)})")
            defaults = kind()
            return kind(**{k: type(getattr(defaults, k))(v) for k, v in (values or {}).items()})

        if unknown:
            raise KeyError(f"recognisers: unknown {', '.join(sorted(unknown))} (expected block_frames, summary, "
                           "temporal)")
        return cls(block_frames=int(d.get("block_frames", cls.block_frames)),
                   summary=part(SummaryConfig, d.get("summary")), temporal=part(TemporalConfig, d.get("temporal")))


@contextmanager
def _deterministic(seed: int):
    """Seeded, deterministic torch for the duration; the global RNG and the deterministic flag restored after."""
    before = torch.are_deterministic_algorithms_enabled()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        torch.use_deterministic_algorithms(True)
        try:
            yield torch.Generator().manual_seed(seed)
        finally:
            torch.use_deterministic_algorithms(before)


def _class_weights(labels: torch.Tensor, classes: int) -> torch.Tensor:
    counts = torch.bincount(labels, minlength=classes).float()
    return counts.sum() / (classes * counts.clamp_min(1.0))


def _random_blocks(x: torch.Tensor, frames: int, generator: torch.Generator) -> torch.Tensor:
    """A random crop of ``frames`` frames of each row of x (N, T, C) -> (N, frames, C)."""
    n, t = x.shape[:2]
    if frames >= t:
        return x
    start = torch.randint(0, t - frames + 1, (n,), generator=generator)
    index = start[:, None] + torch.arange(frames)
    return torch.gather(x, 1, index[..., None].expand(n, frames, x.shape[2]))


def _check(inputs: RecognitionInputs, what: str) -> None:
    if inputs.frames < MIN_FRAMES:
        raise ValueError(f"{what}: expected at least {MIN_FRAMES} frames per gait, found {inputs.frames}")


class Recogniser:
    """A fitted emotion recogniser. ``probabilities(inputs)`` -> (N, 4) float64 in ``EMOTIONS`` order;
    ``predict(inputs)`` -> (N,) class indices."""

    kind: str = ""

    def _logits(self, inputs: RecognitionInputs) -> torch.Tensor:
        raise NotImplementedError

    def probabilities(self, inputs: RecognitionInputs) -> np.ndarray:
        _check(inputs, f"{self.kind}: reading")
        out = []
        with torch.no_grad():
            for start in range(0, len(inputs), _CHUNK):
                part = inputs.select(slice(start, start + _CHUNK))
                out.append(torch.softmax(self._logits(part).double(), -1).numpy())
        return np.concatenate(out) if out else np.zeros((0, len(EMOTIONS)))

    def predict(self, inputs: RecognitionInputs) -> np.ndarray:
        return self.probabilities(inputs).argmax(-1)


# --------------------------------------------------------------------------------------------- summary MLP

def _summaries(features: torch.Tensor) -> torch.Tensor:
    """(N, T, F) per-frame features -> (N, 2F): mean and standard deviation over the frames."""
    return torch.cat([features.mean(1), features.std(1, unbiased=False)], dim=-1)


def _frame_features(inputs: RecognitionInputs) -> torch.Tensor:
    return torch.from_numpy(np.concatenate([inputs.affective, inputs.movement], axis=-1).astype(np.float32))


def summary_features(affective: np.ndarray, movement: np.ndarray) -> np.ndarray:
    """(N, 2 x 23) the summary MLP's input from affective (N, T, 18) and movement (N, T, 5): the mean and standard
    deviation over the frames of each feature (the affective features' means first)."""
    frames = torch.from_numpy(np.concatenate([affective, movement], axis=-1).astype(np.float32))
    return _summaries(frames).double().numpy()


def gait_summaries(inputs: RecognitionInputs) -> np.ndarray:
    """``summary_features`` of the inputs' gaits."""
    return summary_features(inputs.affective, inputs.movement)


class SummaryMLP(Recogniser):
    kind = "summary_mlp"

    def __init__(self, model: torch.nn.Module, mean: torch.Tensor, std: torch.Tensor):
        self.model, self.mean, self.std = model, mean, std

    def _logits(self, inputs: RecognitionInputs) -> torch.Tensor:
        return self.model((_summaries(_frame_features(inputs)) - self.mean) / self.std)


def _block_summaries(frames: torch.Tensor, frames_per_block: int, generator: torch.Generator):
    """A function drawing ``_summaries`` of a fresh random crop of ``frames_per_block`` frames of each gait
    (N, T, F) -> (N, 2F), from running sums over time (float64), so a crop every epoch costs O(N F)."""
    n, t = frames.shape[:2]
    length = min(frames_per_block, t)
    x = frames.double()
    zero = x.new_zeros(n, 1, x.shape[2])
    # running sums of x and x², (n (T + 1), 2F): a block's sums are the difference of two rows
    sums = torch.cat([torch.cat([zero, x.cumsum(1)], 1), torch.cat([zero, (x * x).cumsum(1)], 1)], -1).flatten(0, 1)
    offset = torch.arange(n) * (t + 1)
    f = x.shape[2]

    def draw() -> torch.Tensor:
        start = offset + torch.randint(0, t - length + 1, (n,), generator=generator)
        block = (sums.index_select(0, start + length) - sums.index_select(0, start)) / length
        mean, square = block[:, :f], block[:, f:]
        return torch.cat([mean, (square - mean * mean).clamp_min(0.0).sqrt()], -1).float()
    return draw


def _fit_summary(inputs: RecognitionInputs, labels: torch.Tensor, cfg: RecogniserConfig, seed: int) -> SummaryMLP:
    c = cfg.summary
    frames = _frame_features(inputs)
    whole = _summaries(frames)
    mean, std = whole.mean(0), whole.std(0, unbiased=False).clamp_min(1e-6)
    k = len(EMOTIONS)
    with _deterministic(seed) as generator:
        model = torch.nn.Sequential(torch.nn.Linear(whole.shape[1], c.hidden), torch.nn.ELU(),
                                    torch.nn.Linear(c.hidden, k))
        weight = _class_weights(labels, k)
        optimiser = torch.optim.Adam(model.parameters(), lr=c.learning_rate, weight_decay=c.weight_decay)
        x_whole = (whole - mean) / std
        y = torch.cat([labels, labels])
        blocks = _block_summaries(frames, cfg.block_frames, generator)
        for _ in range(c.epochs):
            optimiser.zero_grad()
            x = torch.cat([x_whole, (blocks() - mean) / std])
            torch.nn.functional.cross_entropy(model(x), y, weight=weight).backward()
            optimiser.step()
    model.eval()
    return SummaryMLP(model, mean, std)


# -------------------------------------------------------------------------------------------- temporal CNN

class _TemporalNet(torch.nn.Module):
    """Two 1-D convolutions over time (the first with stride 2), zero-padded so any length reads, then the mean
    over time and a linear read-out."""

    def __init__(self, inputs: int, channels: int, kernel: int, classes: int):
        super().__init__()
        pad = kernel // 2
        self.body = torch.nn.Sequential(
            torch.nn.Conv1d(inputs, channels, kernel, stride=2, padding=pad), torch.nn.ELU(),
            torch.nn.Conv1d(channels, channels, kernel, padding=pad), torch.nn.ELU())
        self.head = torch.nn.Linear(channels, classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # x (N, T, C)
        return self.head(self.body(x.transpose(1, 2)).mean(-1))


class TemporalCNN(Recogniser):
    kind = "temporal_cnn"

    def __init__(self, model: torch.nn.Module, mean: torch.Tensor, std: torch.Tensor):
        self.model, self.mean, self.std = model, mean, std

    def _logits(self, inputs: RecognitionInputs) -> torch.Tensor:
        return self.model((pose_channels(inputs) - self.mean) / self.std)


def _fit_temporal(inputs: RecognitionInputs, labels: torch.Tensor, cfg: RecogniserConfig, seed: int) -> TemporalCNN:
    c = cfg.temporal
    x = pose_channels(inputs)
    mean, std = x.mean((0, 1)), x.std((0, 1), unbiased=False).clamp_min(1e-6)
    x = (x - mean) / std
    k = len(EMOTIONS)
    n = len(labels)
    with _deterministic(seed) as generator:
        model = _TemporalNet(x.shape[-1], c.channels, c.kernel, k)
        weight = _class_weights(labels, k)
        optimiser = torch.optim.Adam(model.parameters(), lr=c.learning_rate, weight_decay=c.weight_decay)
        steps = 0
        for _ in range(c.epochs):
            order = torch.randperm(n, generator=generator)
            for start in range(0, n, c.batch):
                if steps == c.max_steps:
                    break
                steps += 1
                rows = order[start:start + c.batch]
                xb, yb = x[rows], labels[rows]
                blocks = _random_blocks(xb, cfg.block_frames, generator)
                optimiser.zero_grad()
                loss = 0.5 * (torch.nn.functional.cross_entropy(model(xb), yb, weight=weight)
                              + torch.nn.functional.cross_entropy(model(blocks), yb, weight=weight))
                loss.backward()
                optimiser.step()
    model.eval()
    return TemporalCNN(model, mean, std)


_FIT = {"summary_mlp": _fit_summary, "temporal_cnn": _fit_temporal}


def fit_recogniser(kind: str, inputs: RecognitionInputs, labels: np.ndarray, cfg: RecogniserConfig, seed: int
                   ) -> Recogniser:
    """A recogniser of ``kind`` (``RECOGNISERS``) fitted to labelled gaits: labels (N,) in ``EMOTIONS`` order."""
    if kind not in _FIT:
        raise ValueError(f"fit_recogniser: expected a kind in {', '.join(RECOGNISERS)}, found {kind!r}")
    labels = np.asarray(labels)
    if labels.shape != (len(inputs),) or len(labels) == 0 or labels.min() < 0 or labels.max() >= len(EMOTIONS):
        raise ValueError(f"fit_recogniser: expected {len(inputs)} labels in 0..{len(EMOTIONS) - 1}, found shape "
                         f"{labels.shape}" + (f", values {labels.min()}..{labels.max()}" if labels.size else ""))
    _check(inputs, f"fit_recogniser({kind})")
    if cfg.block_frames < MIN_FRAMES:
        raise ValueError(f"recognisers.block_frames: expected at least {MIN_FRAMES}, found {cfg.block_frames}")
    return _FIT[kind](inputs, torch.from_numpy(labels.astype(np.int64)), cfg, seed)


__all__ = ["RECOGNISERS", "RECOGNISER_NAMES", "Recogniser", "RecogniserConfig", "SummaryConfig", "TemporalConfig",
           "fit_recogniser", "gait_summaries", "summary_features"]
