"""Training the generator: gait tensors, the autoregressive rollout, curriculum teacher forcing, checkpoints.

A window of T = 60 frames is split into a prefix of 18 frames (given) and 42 frames the network predicts one at
a time, each prediction fed back as the next input (paper §4, §5.3). With probability β^E (epoch E) a gait's
input at a step is the ground-truth frame instead of the network's own prediction (curriculum teacher
forcing, drawn per gait and step from a seeded generator). The stepping phase of predicted frames is
extrapolated from the prefix at its mean rate, exactly as generation does, so training and generation see the
same controls; the path curvature κ comes from the ground-truth path (the trajectory is given).

Everything is seeded and runs with deterministic algorithms: the same data, config and seed give the same
weights, bit for bit, on the same machine and thread count. Device ``auto`` uses CUDA when present; nothing
requires it.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.generators.autoregressive.critic import CriticConfig, StyleCritic, fit_critic
from pipeline.ops.features import affective_features
from pipeline.ops.geometry import path_direction, wrap_phase
from pipeline.io.files import sha256_bytes
from pipeline.generators.autoregressive.network import (
    FOOT_JOINTS,
    EmotiveGaitNet,
    GeneratorConfig,
    LossWeights,
    condition_vectors,
    fixed_bones,
    generator_losses,
    sharpened,
    travel_frame_positions,
)
from pipeline.ops.quaternion import qmul, yaw

DIRECTION_FRAMES = 31  # ~1 s at 30 fps: about one stride, over which the direction of travel is averaged


@dataclass(frozen=True)
class TrainConfig:
    """The training run: curriculum, optimiser, batches, seed (the pipeline params' ``train``, less the model sizes)."""

    epochs: int = 300
    batch_size: int = 128
    batches_per_epoch: int = 2  # an "epoch" of the curriculum: this many batches (0: one pass over the data)
    learning_rate: float = 1e-3
    lr_decay: float = 0.999  # per epoch
    teacher_forcing_decay: float = 0.995  # β: teacher forcing with probability β^E
    prefix: int = 18
    grad_clip: float = 1.0
    validate_every: int = 10  # epochs between free-running validation rollouts
    seed: int = 7
    threads: int = 2
    device: str = "auto"
    labelled_share: float = 0.0  # share of each batch drawn from the labelled gaits (0: batches ignore labels)
    mismatch: float = 0.0  # probability that a labelled gait is generated under another condition than its own
    mismatch_content: float = 0.25  # weight of a mismatched pair's ground-truth (content) terms
    mirror: bool = False  # train also on the mirror images of the train gaits (ops.mirror; label-preserving)
    style_sharpness: float = 1.0  # the style term asks for m^p / sum(m^p) (p > 1: a mixture reads as its dominant)
    style_match_own: bool = False  # style matching keeps a gait's own deviation from its emotion (critic.py)


@dataclass
class GaitTensors:
    """What the generator trains on, per gait (N, T, ...), float32."""

    q: torch.Tensor  # (N, T, 21, 4): the pelvis relative to the direction of travel, then the 20 local versors
    direction: torch.Tensor  # (N, T) direction of travel, rad about +Y (geometry.path_direction)
    root_rotation: torch.Tensor  # (N, T, 4)
    root_position: torch.Tensor  # (N, T, 3)
    feet: torch.Tensor  # (N, T, 4, 3) world heel/toe positions (generator.FOOT_JOINTS)
    affective: torch.Tensor  # (N, T, 18)
    theta: torch.Tensor  # (N, T)
    omega: torch.Tensor  # (N, T)
    s: torch.Tensor  # (N, T) m/frame
    kappa: torch.Tensor  # (N, T)
    h: torch.Tensor  # (N, T)
    delta: torch.Tensor  # (N, T)
    condition: torch.Tensor  # (N, 5)

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], rows: np.ndarray | slice = slice(None),
                    direction_frames: int = DIRECTION_FRAMES) -> GaitTensors:
        """From ``read_gaits`` arrays of the annotated table (movement order h, s, s̄, δ, κ)."""
        def t(name: str) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(arrays[name][rows], dtype=np.float32))

        rot, mov, root = t("rotations"), t("movement"), t("positions")[:, :, 0]
        direction = path_direction(root, t("heading"), direction_frames)
        pelvis = qmul(yaw(-direction), rot[:, :, 0])
        return cls(q=torch.cat([pelvis[:, :, None], rot[:, :, 1:]], dim=2), direction=direction,
                   root_rotation=rot[:, :, 0], root_position=root, feet=t("positions")[:, :, list(FOOT_JOINTS)],
                   affective=t("affective"), theta=t("phase"), omega=t("phase_rate"), s=mov[..., 1],
                   kappa=mov[..., 4], h=mov[..., 0], delta=mov[..., 3], condition=condition_vectors(t("emotion")))

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def select(self, idx: torch.Tensor | slice) -> GaitTensors:
        return GaitTensors(**{k: v[idx] for k, v in self.__dict__.items()})

    def to(self, device: torch.device) -> GaitTensors:
        return GaitTensors(**{k: v.to(device) for k, v in self.__dict__.items()})

    def scalars(self) -> torch.Tensor:
        """(N, T, 5) in generator.SCALARS order: ω, s, κ, h, δ."""
        return torch.stack((self.omega, self.s, self.kappa, self.h, self.delta), dim=-1)

    def frames(self, start: int, stop: int) -> dict[str, torch.Tensor]:
        """Network inputs of frames [start, stop) as (B, L, ...)."""
        length = stop - start
        return {"q": self.q[:, start:stop], "affective": self.affective[:, start:stop],
                "condition": self.condition[:, None].expand(-1, length, -1),
                "theta": self.theta[:, start:stop], "omega": self.omega[:, start:stop], "s": self.s[:, start:stop],
                "kappa": self.kappa[:, start:stop], "h": self.h[:, start:stop], "delta": self.delta[:, start:stop]}


def extrapolated_phase(theta: torch.Tensor, omega: torch.Tensor, steps: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Phase of ``steps`` frames after a prefix (B, P): continue from the last θ at the prefix's mean ω.

    Returns θ (B, steps) wrapped to [0, 2π) and ω (B, steps). The generator has no cadence head (paper §4.2), so
    the stepping rhythm of a generated gait is its seed's.
    """
    rate = omega[:, 1:].mean(-1, keepdim=True) if omega.shape[1] > 1 else omega[:, :1]
    k = torch.arange(1, steps + 1, dtype=theta.dtype, device=theta.device)
    return wrap_phase(theta[:, -1:] + rate * k), rate.expand(-1, steps)


def predicted_affective(q: torch.Tensor, offsets: torch.Tensor, parents: Sequence[int]) -> torch.Tensor:
    """Affective features (..., 18) of predicted versors (..., 21, 4): the features are rotation free, so the
    travel-frame pose gives the same numbers as the world pose."""
    return affective_features(travel_frame_positions(q, offsets, parents))


def rollout(model: EmotiveGaitNet, gaits: GaitTensors, offsets: torch.Tensor, parents: Sequence[int], prefix: int,
            teacher_forcing: float = 0.0, generator: torch.Generator | None = None,
            condition: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """Predict frames prefix..T-1 autoregressively. Returns q, q_raw (B, T-prefix, 21, 4), h, s, delta (B, T-prefix).

    teacher_forcing: probability that a gait's input at a step is the ground-truth frame (drawn per gait and step).
    condition: (B, 5) the condition of the predicted frames where it is not the gait's own (the prefix is read
    under its own, as generation reads a seed).
    """
    frames = gaits.q.shape[1]
    steps = frames - prefix
    theta, omega = extrapolated_phase(gaits.theta[:, :prefix], gaits.omega[:, :prefix], steps)
    fixed = fixed_bones(gaits.q[:, :prefix])
    pred, hidden = model({**gaits.frames(0, prefix), "fixed": fixed})
    current = {k: v[:, -1:] for k, v in pred.items()}
    outputs = [current]
    for step in range(steps - 1):
        t = prefix + step  # the frame now fed in
        truth = gaits.frames(t, t + 1)
        fed = {
            "q": current["q"], "h": current["h"], "s": current["s"], "delta": current["delta"],
            "affective": predicted_affective(current["q"], offsets, parents),
        }
        if teacher_forcing > 0.0:
            coin = torch.rand(gaits.q.shape[0], generator=generator).to(gaits.q.device) < teacher_forcing
            for k, v in fed.items():
                mask = coin.view(-1, *([1] * (v.dim() - 1)))
                fed[k] = torch.where(mask, truth[k], v)
        inputs = {**truth, **fed, "theta": theta[:, step:step + 1], "omega": omega[:, step:step + 1], "fixed": fixed}
        if condition is not None:
            inputs["condition"] = condition[:, None]
        current, hidden = model(inputs, hidden)
        outputs.append(current)
    return {k: torch.cat([o[k] for o in outputs], dim=1) for k in outputs[0]}


def targets(gaits: GaitTensors, prefix: int) -> dict[str, torch.Tensor]:
    """What the losses compare the predicted frames with (generator.generator_losses)."""
    return {"q": gaits.q[:, prefix:], "affective": gaits.affective[:, prefix:], "h": gaits.h[:, prefix:],
            "s": gaits.s[:, prefix:], "delta": gaits.delta[:, prefix:], "feet": gaits.feet[:, prefix:],
            "direction": gaits.direction[:, prefix:], "start": gaits.root_position[:, prefix - 1],
            "base_height": gaits.root_position[..., 1].mean(-1)}


class BatchSampler:
    """Seeded batches of train gaits: ``labelled_share`` of each batch from the labelled gaits, the rest from the
    unlabelled ones, each pool walked in fresh permutations (share 0: one pool, every gait alike). The labelled
    windows are few (a sixth of the train split) and they are the only ones the condition can be learnt from."""

    def __init__(self, labelled: torch.Tensor, batch_size: int, share: float, generator: torch.Generator):
        self.generator = generator
        if share > 0.0 and labelled.any() and (~labelled).any():
            self.pools = [torch.nonzero(labelled).flatten(), torch.nonzero(~labelled).flatten()]
            n = min(batch_size, max(1, int(round(share * batch_size))))
            self.sizes = [n, batch_size - n]
        else:
            self.pools, self.sizes = [torch.arange(len(labelled))], [batch_size]
        self.orders = [pool[torch.randperm(len(pool), generator=generator)] for pool in self.pools]
        self.cursors = [0] * len(self.pools)

    def next(self) -> torch.Tensor:
        out = []
        for k, size in enumerate(self.sizes):
            if size == 0:
                continue
            if self.cursors[k] + size > len(self.orders[k]):  # a new pass: a fresh permutation
                pool = self.pools[k]
                self.orders[k], self.cursors[k] = pool[torch.randperm(len(pool), generator=self.generator)], 0
            out.append(self.orders[k][self.cursors[k]:self.cursors[k] + size])
            self.cursors[k] += size
        return torch.cat(out)


def mismatched_conditions(condition: torch.Tensor, probability: float, generator: torch.Generator
                          ) -> tuple[torch.Tensor, torch.Tensor]:
    """(conditions of the predicted frames (B, 5), mismatched (B,) bool). A labelled gait is, with
    ``probability``, generated under another emotion: half of them a one-hot of another emotion, half a random
    mixture of the simplex (Dirichlet(1)), so the network learns to follow the condition, not the prefix."""
    labelled = condition[:, -1] > 0.5
    if probability <= 0.0:  # no draws: the run's random stream stays that of plain training
        return condition, torch.zeros_like(labelled)
    b, k = condition.shape[0], condition.shape[1] - 1
    coin = torch.rand(b, generator=generator) < probability
    own = condition[:, :k].argmax(-1)
    other = (own + torch.randint(1, k, (b,), generator=generator)) % k
    one_hot = torch.nn.functional.one_hot(other, k).to(condition.dtype)
    gamma = -torch.log(torch.rand(b, k, generator=generator).clamp_min(1e-12))
    mixture = gamma / gamma.sum(-1, keepdim=True)
    pick_mixture = torch.rand(b, generator=generator) < 0.5
    emotion = torch.where(pick_mixture[:, None], mixture, one_hot)
    mismatched = coin.to(condition.device) & labelled
    out = condition.clone()
    out[:, :k] = torch.where(mismatched[:, None], emotion.to(condition.device), condition[:, :k])
    return out, mismatched


def style_targets(condition: torch.Tensor, sharpness: float = 1.0) -> torch.Tensor:
    """(B, 5) conditions -> (B, 4) emotions the style term asks for (NaN rows: no condition, no style term).

    With ``sharpness`` p > 1 a mixture m asks for m^p / sum(m^p): a blend of walks reads as its most vivid
    component, not as its largest one (measured on a model trained with p = 1: three quarters of sad-, angry- and
    neutral-dominant mixtures were read as happy), so the style term asks for the dominant emotion to show while
    the others still move the gait."""
    labelled = condition[:, -1:] > 0.5
    emotion = sharpened(condition[:, :-1], sharpness)
    return torch.where(labelled, emotion, torch.full_like(emotion, float("nan")))


def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


@dataclass
class TrainResult:
    model: EmotiveGaitNet
    history: list[dict[str, Any]]  # per epoch: train and validation losses, teacher forcing, learning rate
    critic: StyleCritic | None = None
    critic_figures: dict[str, Any] | None = None


def train_generator(train: GaitTensors, val: GaitTensors, offsets: torch.Tensor, parents: Sequence[int],
                    model_cfg: GeneratorConfig, cfg: TrainConfig, weights: LossWeights,
                    progress: Callable[[dict[str, Any]], None] | None = None,
                    critic_cfg: CriticConfig = CriticConfig()) -> TrainResult:
    """Seeded, deterministic training; validation is a free-running rollout (no teacher forcing) every epoch.
    With a style weight, the style critic is fitted first on the labelled train gaits (critic.py)."""
    torch.set_num_threads(cfg.threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(cfg.seed)
    device = resolve_device(cfg.device)
    draws = torch.Generator().manual_seed(cfg.seed)
    model = EmotiveGaitNet(model_cfg)
    model.set_statistics(train.affective, train.scalars())
    critic, critic_figures = None, None
    if weights.style > 0.0 or weights.style_match > 0.0:
        labelled = train.condition[:, -1] > 0.5
        pose = travel_frame_positions(train.q[labelled], offsets.to(torch.float32), parents)
        critic, critic_figures = fit_critic(pose, train.condition[labelled, :-1],
                                            (model.affective_low, model.affective_high, model.affective_mean,
                                             model.affective_std), critic_cfg)
        critic.to(device)
    model.to(device)
    offsets = offsets.to(device=device, dtype=torch.float32)
    train_d, val_d = train.to(device), val.to(device)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
    schedule = torch.optim.lr_scheduler.ExponentialLR(optimiser, gamma=cfg.lr_decay)
    history = []
    per_epoch = cfg.batches_per_epoch or math.ceil(len(train_d) / cfg.batch_size)
    sampler = BatchSampler(train.condition[:, -1] > 0.5, cfg.batch_size, cfg.labelled_share, draws)
    for epoch in range(cfg.epochs):
        model.train()
        tf = cfg.teacher_forcing_decay ** epoch
        sums: dict[str, float] = {}
        batches = 0
        for _ in range(per_epoch):
            batch = train_d.select(sampler.next().to(device))
            condition, mismatched = mismatched_conditions(batch.condition, cfg.mismatch, draws)
            content = torch.where(mismatched, torch.full_like(condition[:, 0], cfg.mismatch_content),
                                  torch.ones_like(condition[:, 0]))
            pred = rollout(model, batch, offsets, parents, cfg.prefix, tf, draws,
                           condition if bool(mismatched.any()) else None)
            losses = generator_losses(pred, targets(batch, cfg.prefix), model, offsets, parents, weights,
                                      content, critic, style_targets(condition, cfg.style_sharpness),
                                      style_targets(batch.condition) if cfg.style_match_own else None)
            optimiser.zero_grad(set_to_none=True)
            losses.total.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            optimiser.step()
            for k, v in losses.as_floats().items():
                sums[k] = sums.get(k, 0.0) + v
            batches += 1
        lr = optimiser.param_groups[0]["lr"]
        schedule.step()
        val_losses = (evaluate_losses(model, val_d, offsets, parents, cfg.prefix, weights, critic=critic,
                                      style_match_own=cfg.style_match_own)
                      if (epoch + 1) % cfg.validate_every == 0 or epoch + 1 == cfg.epochs else {})
        row = {"epoch": epoch + 1, "teacher_forcing": round(tf, 6), "learning_rate": lr,
               **{f"train_{k}": v / max(batches, 1) for k, v in sums.items()},
               **{f"val_{k}": v for k, v in val_losses.items()}}
        history.append(row)
        if progress:
            progress(row)
    model.cpu()
    if critic is not None:
        critic.cpu()
    return TrainResult(model=model, history=history, critic=critic, critic_figures=critic_figures)


@torch.no_grad()
def evaluate_losses(model: EmotiveGaitNet, gaits: GaitTensors, offsets: torch.Tensor, parents: Sequence[int],
                    prefix: int, weights: LossWeights, batch_size: int = 256, critic: StyleCritic | None = None,
                    style_match_own: bool = False) -> dict[str, float]:
    """Loss terms of a free-running rollout under the gaits' own conditions, averaged over gaits (style matching
    as in training: ``style_match_own``)."""
    model.eval()
    totals: dict[str, float] = {}
    for start in range(0, len(gaits), batch_size):
        batch = gaits.select(slice(start, start + batch_size))
        pred = rollout(model, batch, offsets, parents, prefix)
        losses = generator_losses(pred, targets(batch, prefix), model, offsets, parents, weights, critic=critic,
                                  style_target=style_targets(batch.condition),
                                  own_style=style_targets(batch.condition) if style_match_own else None)
        for k, v in losses.as_floats().items():
            totals[k] = totals.get(k, 0.0) + v * len(batch)
    return {k: v / max(len(gaits), 1) for k, v in totals.items()}


# --- checkpoints ---------------------------------------------------------------------------------------------

def checkpoint_bytes(model: EmotiveGaitNet, extra: dict[str, Any]) -> bytes:
    """The checkpoint as bytes: deterministic for the same weights (no times, paths or random names)."""
    buffer = io.BytesIO()
    state = {k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}
    torch.save({"format": "emogait-generator/1", "config": model.cfg.to_dict(), "state_dict": state, **extra}, buffer)
    return buffer.getvalue()


def load_checkpoint(path: str | Path) -> tuple[EmotiveGaitNet, dict[str, Any], str]:
    """(model in eval mode, the checkpoint's extra fields, sha256 of the file)."""
    data = Path(path).read_bytes()
    blob = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    model = EmotiveGaitNet(GeneratorConfig.from_dict(blob["config"]))
    model.load_state_dict(blob["state_dict"])
    model.eval()
    extra = {k: v for k, v in blob.items() if k not in ("config", "state_dict")}
    return model, extra, sha256_bytes(data)


def config_dicts(model_cfg: GeneratorConfig, cfg: TrainConfig, weights: LossWeights) -> dict[str, Any]:
    return {"model": model_cfg.to_dict(), "train": asdict(cfg), "loss": asdict(weights)}
