"""The generator's own style critic: what its recognition (perceptual) loss asks generated frames to look like.

The paper's affective loss compares the features of predicted frames with those of the ground truth, so the
condition m can never matter in training: the prefix already shows the emotion m names, and the network learns
to follow the prefix and regress to one average walk. The style loss instead asks a frozen critic, trained on
the real labelled train windows before the generator, to read the generated frames as the condition, also for
mismatched pairs (a prefix of emotion A generated under condition B; ``training.mismatched_conditions``).

The critic is deliberately not one of the evaluation recognisers (``pipeline.recognition``): it is a different
kind of model (a linear softmax on frame statistics, not an MLP on feature summaries or a convolution over
poses), with its own seed, and the evaluation recognisers never see the generator's training. Its inputs are
computed with gradients from travel-frame joint positions (``network.travel_frame_positions``): the mean and
standard deviation over frames of the 18 affective features (clipped and standardised with the generator's
statistics) and of the root-relative speed of each of the 20 non-root joints (how much the limbs move, which
the affective features, being per-frame posture, cannot see). It is trained on random crops of ``crop_frames``
(the generated span) of the labelled real train windows (with ``train.mirror``, also of their mirror images,
``ops.mirror``), full-batch, seeded.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from pipeline.core.emotions import EMOTIONS
from pipeline.ops.features import affective_features

STATISTICS = 2 * (18 + 20)  # mean and std over frames of the affective features and of the joint speeds


@dataclass(frozen=True)
class CriticConfig:
    """The critic's fit (the pipeline params' ``train.critic``)."""

    crop_frames: int = 42  # frames of a training crop: the span the generator predicts
    crops: int = 4  # random crops per real window
    epochs: int = 400  # full-batch Adam steps
    learning_rate: float = 0.05
    weight_decay: float = 0.05  # smooths it: held-out real balanced accuracy 0.74 either way, max probability 0.88
    seed: int = 11

    def to_dict(self) -> dict:
        return asdict(self)


class StyleCritic(nn.Module):
    """Linear softmax over frame statistics of travel-frame poses (B, T, 21, 3) -> emotion logits (B, 4)."""

    def __init__(self) -> None:
        super().__init__()
        self.linear = nn.Linear(STATISTICS, len(EMOTIONS))
        self.register_buffer("affective_low", torch.full((18,), -1e6))
        self.register_buffer("affective_high", torch.full((18,), 1e6))
        self.register_buffer("affective_mean", torch.zeros(18))
        self.register_buffer("affective_std", torch.ones(18))
        self.register_buffer("statistics_mean", torch.zeros(STATISTICS))
        self.register_buffer("statistics_std", torch.ones(STATISTICS))
        # per emotion, the mean standardised statistics of the real crops: what the style-matching term pulls a
        # generated gait towards (a linear critic reads a few directions; the rest of the statistics can drift)
        self.register_buffer("centroids", torch.zeros(len(EMOTIONS), STATISTICS))

    def statistics(self, pose: torch.Tensor, bounded: bool = True) -> torch.Tensor:
        """(B, T, 21, 3) travel-frame positions -> (B, STATISTICS), before standardisation. ``bounded``: the
        affective features clamped to the real range (the generator's 1st-99th percentiles), as the critic reads
        them, so it cannot reward a posture for going past what real gaits do."""
        a = affective_features(pose)
        if bounded:
            a = torch.minimum(torch.maximum(a, self.affective_low), self.affective_high)
        a = (a - self.affective_mean) / self.affective_std
        speed = torch.linalg.vector_norm(pose[:, 1:, 1:] - pose[:, :-1, 1:], dim=-1)  # (B, T-1, 20) m/frame
        return torch.cat([a.mean(1), a.std(1), speed.mean(1), speed.std(1)], -1)

    def standardised(self, pose: torch.Tensor, bounded: bool = True) -> torch.Tensor:
        """(B, T, 21, 3) -> (B, STATISTICS) in the real crops' standard units."""
        return (self.statistics(pose, bounded) - self.statistics_mean) / self.statistics_std

    def forward(self, pose: torch.Tensor) -> torch.Tensor:
        return self.linear(self.standardised(pose))


def random_crops(pose: torch.Tensor, frames: int, crops: int, generator: torch.Generator) -> torch.Tensor:
    """(N, T, 21, 3) -> (N * crops, frames, 21, 3): ``crops`` seeded random crops of every window."""
    n, t = pose.shape[:2]
    starts = torch.randint(0, t - frames + 1, (n, crops), generator=generator)
    index = starts[..., None] + torch.arange(frames)
    return pose[torch.arange(n)[:, None, None], index].reshape(n * crops, frames, *pose.shape[2:])


def fit_critic(pose: torch.Tensor, emotion: torch.Tensor, affective_bounds: tuple[torch.Tensor, ...],
               cfg: CriticConfig = CriticConfig()) -> tuple[StyleCritic, dict]:
    """Fit the critic on labelled real windows: pose (N, T, 21, 3) travel-frame positions (mirror images
    included by the caller), emotion (N, 4) soft labels; affective_bounds: the generator's (low, high, mean, std)
    of the affective features. Returns the frozen critic and its training figures (accuracy on its own crops)."""
    generator = torch.Generator().manual_seed(cfg.seed)
    with torch.random.fork_rng(devices=[]):  # its own seed; the caller's random stream is left as it was
        torch.manual_seed(cfg.seed)
        critic = StyleCritic()
    for name, value in zip(("affective_low", "affective_high", "affective_mean", "affective_std"), affective_bounds):
        getattr(critic, name).copy_(value)
    crops = random_crops(pose, cfg.crop_frames, cfg.crops, generator)
    target = emotion.repeat_interleave(cfg.crops, dim=0)
    with torch.no_grad():
        x = critic.statistics(crops)
        critic.statistics_mean.copy_(x.mean(0))
        critic.statistics_std.copy_(x.std(0).clamp_min(1e-6))
        x = (x - critic.statistics_mean) / critic.statistics_std
        critic.centroids.copy_((target.T @ x) / target.sum(0).clamp_min(1e-12)[:, None])
    # class-balanced: the labelled windows are mostly neutral
    weight = target.sum(0).sum() / (len(EMOTIONS) * target.sum(0).clamp_min(1.0))
    optimiser = torch.optim.Adam(critic.linear.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    for _ in range(cfg.epochs):
        optimiser.zero_grad()
        style_loss(critic.linear(x), target, weight).backward()
        optimiser.step()
    critic.eval()
    for p in critic.parameters():
        p.requires_grad_(False)
    with torch.no_grad():
        said = critic.linear(x).argmax(-1)
    truth = target.argmax(-1)
    recall = [float((said[truth == k] == k).double().mean()) for k in range(len(EMOTIONS)) if (truth == k).any()]
    return critic, {"windows": int(len(pose)), "crops": int(len(crops)),
                    "train_accuracy": round(float((said == truth).double().mean()), 4),
                    "train_balanced_accuracy": round(sum(recall) / max(len(recall), 1), 4)}


def style_loss(logits: torch.Tensor, target: torch.Tensor, weight: torch.Tensor | None = None,
               reduction: str = "mean") -> torch.Tensor:
    """Cross-entropy of logits (B, 4) against soft emotion targets (B, 4) (rows summing to 1), optionally
    class-weighted; ``reduction="none"`` gives it per gait."""
    per = -(target * torch.log_softmax(logits, -1))
    if weight is not None:
        per = per * weight
    per = per.sum(-1)
    return per.mean() if reduction == "mean" else per


def style_match_loss(critic: StyleCritic, pose: torch.Tensor, target: torch.Tensor,
                     own_pose: torch.Tensor | None = None, own_emotion: torch.Tensor | None = None) -> torch.Tensor:
    """Huber distance (per statistic, mean over them and over gaits) of generated gaits' standardised statistics
    (pose (B, T, 21, 3)) from the real statistics of their target emotions (B, 4). Unlike the critic's
    cross-entropy, which a gait satisfies by going far along the few directions a linear reader uses, it asks for
    the real emotion's posture and limb speeds in every statistic. It reads the features unclamped: clamped, a
    posture past the real range (a head tilted 17 degrees towards one shoulder under "angry") would cost nothing
    here and gain nothing from the critic, so nothing would pull it back.

    Without ``own_pose`` the wanted statistics are the target's centroid (target @ centroids): every gait of an
    emotion is pulled towards one point. With the real frames of the gait's own window (``own_pose``, the ground
    truth, of ``own_emotion`` (B, 4); ``train.style_match_own``) they are those frames' statistics moved by the
    difference of the two emotions' centroids: a gait keeps its own deviation from its emotion's centroid (its
    performer's walk), and under its own emotion the target is simply its own frames. Tried and not kept: the
    published gaits' spread barely moved (benchmarks/diversity.py; README)."""
    if own_pose is None:
        wanted = target @ critic.centroids
    else:
        wanted = critic.standardised(own_pose, bounded=False) + (target - own_emotion) @ critic.centroids
    return torch.nn.functional.huber_loss(critic.standardised(pose, bounded=False), wanted, reduction="none",
                                          delta=1.0).mean()
