"""The affect-based autoregressive gait generator (paper §4): network, inputs, losses.

One step of the network reads frame t of a gait and predicts frame t + 1:

    i1 = [a, m]                                  -> FC_enc1 (3 layers)  -> H1
    i2 = [sin θ, cos θ, ω, s, κ, m]              -> FC_enc2 (3 layers)  -> H2      γ = [FC_enc1; FC_enc2]
    [q; γ]                                       -> GRU                 -> q̃
    [q̃; sin θ, cos θ, sin 2θ, cos 2θ]            -> FC_versors (2 layers) -> q̂
    [h, s, δ; γ]                                 -> FC_root             -> FC_h, FC_s, FC_δ      -> ĥ, ŝ, δ̂

q are the 20 non-root versors of the paper plus one for the pelvis, relative to the direction of travel
(``pipeline.ops.geometry.path_direction``): the pelvis tilts, rolls and yaws about that direction through every
stride, and a generated gait without that motion skates (measured on real test walks: freezing the pelvis'
rotation relative to the heading triples the heel/toe speed during contact, 0.14 -> 0.41 m/s). The trajectory
still owns the direction of travel; the network owns the pelvis relative to it. a are the 18 affective
features, m the condition: the emotion vector [happy, sad, angry, neutral] plus a flag that says whether the
gait has an emotion label at all (unlabelled gaits train the motion model with m = 0 and the flag 0, so no
emotion is invented for them). θ, ω: stepping phase and its rate; s, κ, h, δ: root speed (m/frame),
path curvature, height deviation and heading-to-path angle (pipeline.ops.features.movement_features). The
versor and root heads are residual (frame t + 1 = frame t + a learned change), ELU everywhere.

Continuous inputs are standardised with the training set's mean and standard deviation, kept as buffers in
the model (so a checkpoint carries them). The losses (paper §4.3) use the one forward kinematics and the one
affective-feature implementation, on the predictions, with gradients.

The stepping phase also reaches the versor head directly (its first two harmonics, as the phase-functioned
networks use it): without it the free-running limb motion damps over a 200-frame rollout (joint rotation
1.9 -> 0.6 deg/frame, real walks 2.4) and the walk slows to a halt; with it the motion keeps 2.2 -> 1.6
deg/frame and the speed holds (measured in reports/eval.json).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import torch
from torch import nn

from pipeline.core.emotions import EMOTIONS
from pipeline.core.skeleton import canonical_skeleton
from pipeline.generators.autoregressive.critic import style_loss, style_match_loss
from pipeline.ops.features import affective_features
from pipeline.ops.geometry import unit_direction, wrap_angle_atan2
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import qangle, qnormalize, qrot, quat_to_euler, yaw

JOINTS = 21
VERSORS = JOINTS  # the pelvis relative to the direction of travel + the 20 non-root joints
CONDITION = len(EMOTIONS) + 1  # emotion vector + "labelled" flag
SCALARS = ("omega", "s", "kappa", "h", "delta")  # standardised per-frame scalars
FIXED_BONE_TOLERANCE_DEG = 0.1  # a versor that stays this close to its first value through the prefix is a fixed bone
ROOT_FEATURES = ("h", "s", "delta")
FOOT_JOINTS = canonical_skeleton().foot_joints  # heel and toe of each foot, by name in the canonical skeleton


@dataclass(frozen=True)
class GeneratorConfig:
    """Layer sizes (the pipeline params' ``train.model``). Defaults are a CPU size; the paper's code used a
    2×1024 GRU."""

    affect_layers: tuple[int, ...] = (32, 32, 16)  # FC_enc1, last = H1
    movement_layers: tuple[int, ...] = (16, 16, 8)  # FC_enc2, last = H2
    gru_hidden: int = 256  # H3
    gru_layers: int = 1
    versor_hidden: int = 256  # first layer of FC_versors
    root_hidden: int = 32  # H4
    use_affective: bool = True  # False: the "no affect" ablation (no a in i1)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> GeneratorConfig:
        d = dict(d)
        for k in ("affect_layers", "movement_layers"):
            if k in d:
                d[k] = tuple(int(x) for x in d[k])
        return cls(**d)


@dataclass(frozen=True)
class LossWeights:
    """λ of paper Eq. 13 (the pipeline params' ``train.loss``); λ_versor weighs the unit-norm term of Eq. 8."""

    motion: float = 1.0
    pose: float = 1.0
    affective: float = 1.0
    root: float = 1.0
    foot: float = 1.0
    versor: float = 1.0
    style: float = 0.0  # the style critic's reading of the generated frames vs the condition (critic.py)
    style_match: float = 0.0  # the generated frames' statistics vs the real ones of the condition (critic.py)
    # joint name -> its weight inside the motion term (unnamed joints 1). The head is a leaf: only this term sees
    # its rotation, and free-running gaits turned it 2.4x as far as real walks at equal weights (README).
    motion_joints: dict[str, float] = field(default_factory=dict)

    def __post_init__(self):
        unknown = sorted(set(self.motion_joints) - set(canonical_skeleton().names))
        if unknown:
            raise ValueError(f"train.loss.motion_joints: {unknown} are not joints of the canonical skeleton "
                             f"(expected some of {list(canonical_skeleton().names)})")

    def motion_joint_weights(self) -> torch.Tensor:
        """(21,) weight of each canonical joint's Euler angles in the motion term."""
        names = canonical_skeleton().names
        return torch.tensor([float(self.motion_joints.get(n, 1.0)) for n in names])


def _mlp(sizes: Sequence[int], final_activation: bool = True) -> nn.Sequential:
    layers: list[nn.Module] = []
    for k, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if final_activation or k < len(sizes) - 2:
            layers.append(nn.ELU())
    return nn.Sequential(*layers)


class EmotiveGaitNet(nn.Module):
    """The paper's encoder-predictor; ``forward`` runs it over L consecutive frames (L = 1: one step)."""

    def __init__(self, cfg: GeneratorConfig = GeneratorConfig()):
        super().__init__()
        self.cfg = cfg
        affect_in = (18 if cfg.use_affective else 0) + CONDITION
        self.enc_affect = _mlp((affect_in, *cfg.affect_layers))
        self.enc_movement = _mlp((5 + CONDITION, *cfg.movement_layers))
        gamma = cfg.affect_layers[-1] + cfg.movement_layers[-1]
        self.gru = nn.GRU(4 * VERSORS + gamma, cfg.gru_hidden, num_layers=cfg.gru_layers, batch_first=True)
        self.fc_versors = _mlp((cfg.gru_hidden + 4, cfg.versor_hidden, 4 * VERSORS), final_activation=False)
        self.fc_root = _mlp((3 + gamma, cfg.root_hidden))
        self.fc_h, self.fc_s, self.fc_delta = (nn.Linear(cfg.root_hidden, 1) for _ in range(3))
        # Standardisation of the inputs (set from the training data by ``set_statistics``).
        self.register_buffer("affective_low", torch.full((18,), -1e6))
        self.register_buffer("affective_high", torch.full((18,), 1e6))
        self.register_buffer("affective_mean", torch.zeros(18))
        self.register_buffer("affective_std", torch.ones(18))
        self.register_buffer("scalar_mean", torch.zeros(len(SCALARS)))
        self.register_buffer("scalar_std", torch.ones(len(SCALARS)))

    def set_statistics(self, affective: torch.Tensor, scalars: torch.Tensor) -> None:
        """affective (..., 18), scalars (..., 5) in SCALARS order, from the training split."""
        a, s = affective.reshape(-1, 18).double(), scalars.reshape(-1, len(SCALARS)).double()
        # Inputs are clipped to the 1st-99th percentile first: the heavy-tailed area ratio would otherwise
        # reach ~100 standard deviations.
        self.affective_low.copy_(torch.quantile(a, 0.01, dim=0))
        self.affective_high.copy_(torch.quantile(a, 0.99, dim=0))
        a = torch.minimum(torch.maximum(a, self.affective_low.double()), self.affective_high.double())
        self.affective_mean.copy_(a.mean(0))
        self.affective_std.copy_(a.std(0).clamp_min(1e-6))
        self.scalar_mean.copy_(s.mean(0))
        self.scalar_std.copy_(s.std(0).clamp_min(1e-6))

    def standardise(self, name: str, x: torch.Tensor) -> torch.Tensor:
        k = SCALARS.index(name)
        return (x - self.scalar_mean[k]) / self.scalar_std[k]

    def destandardise(self, name: str, x: torch.Tensor) -> torch.Tensor:
        k = SCALARS.index(name)
        return x * self.scalar_std[k] + self.scalar_mean[k]

    def forward(self, frames: dict[str, torch.Tensor], hidden: torch.Tensor | None = None
                ) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
        """frames: q (B, L, 21, 4), affective (B, L, 18), condition (B, L, 5), theta, omega, s, kappa, h, delta
        (B, L), optionally fixed (B, 21) (``fixed_bones`` of the gait's prefix). Returns the predicted next frames
        {q (normalised), q_raw, h, s, delta (B, L, ...)} and the GRU state."""
        cond = frames["condition"]
        std = {k: self.standardise(k, frames[k]) for k in SCALARS}
        affect_in = [cond]
        if self.cfg.use_affective:
            clipped = torch.minimum(torch.maximum(frames["affective"], self.affective_low), self.affective_high)
            affect_in.insert(0, (clipped - self.affective_mean) / self.affective_std)
        gamma = torch.cat([
            self.enc_affect(torch.cat(affect_in, -1)),
            self.enc_movement(torch.cat([torch.sin(frames["theta"])[..., None], torch.cos(frames["theta"])[..., None],
                                         std["omega"][..., None], std["s"][..., None], std["kappa"][..., None],
                                         cond], -1)),
        ], -1)
        q = frames["q"]
        batch, length = q.shape[:2]
        latent, hidden = self.gru(torch.cat([q.reshape(batch, length, 4 * VERSORS), gamma], -1), hidden)
        theta = frames["theta"][..., None]
        harmonics = torch.cat([torch.sin(theta), torch.cos(theta), torch.sin(2 * theta), torch.cos(2 * theta)], -1)
        q_raw = q + self.fc_versors(torch.cat([latent, harmonics], -1)).reshape(batch, length, VERSORS, 4)
        if "fixed" in frames:  # the gait's fixed bones (``fixed_bones``) keep the versor they are fed
            q_raw = torch.where(frames["fixed"][:, None, :, None], q, q_raw)
        root_latent = self.fc_root(torch.cat([std["h"][..., None], std["s"][..., None], std["delta"][..., None],
                                              gamma], -1))
        out = {"q": qnormalize(q_raw), "q_raw": q_raw}
        for name, head in (("h", self.fc_h), ("s", self.fc_s), ("delta", self.fc_delta)):
            out[name] = self.destandardise(name, std[name] + head(root_latent).squeeze(-1))
        return out, hidden


def fixed_bones(q: torch.Tensor) -> torch.Tensor:
    """(B, P, 21, 4) versors of the frames a gait starts from -> (B, 21) bool: the joints whose versor stays within
    ``FIXED_BONE_TOLERANCE_DEG`` of its first value through them (never the pelvis, which turns with every step).

    Retargeting leaves some bones of a source skeleton fixed: the hips and the lower back, from which it builds the
    pelvis frame, and the hand tips where a source has none. Each keeps one versor through a real clip, a different
    one per source. Predicted through the residual versor head, they drifted ~7 degrees over a 60-frame rollout
    and carried the upper body and legs against the pelvis, in no real frame; given their prefix versor, they stay.
    """
    angle = qangle(q, q[:, :1]).amax(1)
    fixed = angle <= math.radians(FIXED_BONE_TOLERANCE_DEG)
    fixed[:, 0] = False
    return fixed


def condition_vectors(emotion: torch.Tensor) -> torch.Tensor:
    """(..., 4) emotion rows (NaN where unlabelled) -> (..., 5) condition m: [emotion, 1] or [0, 0, 0, 0, 0]."""
    labelled = ~torch.isnan(emotion).any(-1, keepdim=True)
    return torch.cat([torch.where(labelled, emotion, torch.zeros_like(emotion)), labelled.to(emotion.dtype)], -1)


def sharpened(emotion: torch.Tensor, power: float) -> torch.Tensor:
    """(..., 4) emotion rows -> m^p / sum(m^p): the dominant component grows, a one-hot stays itself, p = 1 changes
    nothing (NaN rows stay NaN)."""
    if power == 1.0:
        return emotion
    raised = emotion.clamp_min(0.0) ** power
    return raised / raised.sum(-1, keepdim=True).clamp_min(1e-12)


def travel_frame_positions(q: torch.Tensor, offsets: torch.Tensor, parents: Sequence[int]) -> torch.Tensor:
    """Joint positions (..., 21, 3) relative to the root, in the frame of the direction of travel, from the 21
    versors (..., 21, 4) (q[..., 0]: the pelvis relative to that direction).

    The pose without its trajectory: what the pose and affective losses compare, and what the evaluation's
    pose error measures.
    """
    return canonical_positions(torch.zeros(q.shape[:-2] + (3,), dtype=q.dtype, device=q.device), q,
                               offsets.to(q.dtype), parents)


def world_feet(pose: torch.Tensor, speed: torch.Tensor, height: torch.Tensor, target: dict[str, torch.Tensor]
               ) -> torch.Tensor:
    """World heel/toe positions (B, T, 4, 3) of predicted frames: the root advanced by the predicted speeds along
    the true direction of travel from the true start, at the base height plus the predicted ĥ, and the predicted
    travel-frame pose turned to that direction. So the foot term ties the root's speed to the legs' motion (a foot
    on the floor stays put only if the two agree) - what the paper's foot-contact loss is for."""
    direction = target["direction"]
    step = speed[..., None] * unit_direction(direction)
    ground = target["start"][:, None, [0, 2]] + step.cumsum(dim=1)
    root = torch.stack((ground[..., 0], target["base_height"][:, None] + height, ground[..., 1]), dim=-1)
    turn = yaw(direction)[..., None, :].expand(*direction.shape, len(FOOT_JOINTS), 4)
    return root[..., None, :] + qrot(turn, pose[..., list(FOOT_JOINTS), :])


@dataclass
class Losses:
    motion: torch.Tensor
    pose: torch.Tensor
    affective: torch.Tensor
    root: torch.Tensor
    foot: torch.Tensor
    total: torch.Tensor
    style: torch.Tensor | None = None
    style_match: torch.Tensor | None = None
    terms: dict[str, torch.Tensor] = field(default_factory=dict)

    def as_floats(self) -> dict[str, float]:
        names = ("motion", "pose", "affective", "root", "foot", "total") + tuple(
            k for k in ("style", "style_match") if getattr(self, k) is not None)
        return {k: float(getattr(self, k).detach()) for k in names}


def generator_losses(pred: dict[str, torch.Tensor], target: dict[str, torch.Tensor], model: EmotiveGaitNet,
                     offsets: torch.Tensor, parents: Sequence[int], weights: LossWeights = LossWeights(),
                     content_weight: torch.Tensor | None = None, critic: nn.Module | None = None,
                     style_target: torch.Tensor | None = None, own_style: torch.Tensor | None = None) -> Losses:
    """Paper Eqs. 8-13 over predicted frames, plus the style term. pred: q, q_raw (B, T, 21, 4), h, s, delta
    (B, T); target: q (B, T, 21, 4), affective (B, T, 18), h, s, delta (B, T) and, for the foot term, feet
    (B, T, 4, 3) world heel/toe positions, direction (B, T), start (B, 3) root position before the first predicted
    frame, base_height (B,) (see ``world_feet``). Sums over joints / features, means over frames, then a mean over
    gaits weighted by ``content_weight`` (B,) (a mismatched pair's ground truth shows another emotion than its
    condition: it only keeps the walk plausible). Root features are compared in standardised units (s is
    ~0.04 m/frame, δ ~0.3 rad). The style term (with ``critic`` and ``style_target`` (B, 4), NaN rows for no
    condition) is the critic's cross-entropy against the condition, over the conditioned gaits; style matching
    (``weights.style_match``) pulls their statistics towards the condition's centroid or, with ``own_style`` (B, 4),
    the emotion each gait's ground truth shows, towards its own ground truth moved by the centroids' difference
    (``critic.style_match_loss``)."""
    weight = torch.ones(pred["q"].shape[0], device=pred["q"].device) if content_weight is None else content_weight

    def over_gaits(per_frame: torch.Tensor) -> torch.Tensor:
        return (per_frame.mean(-1) * weight).sum() / weight.sum().clamp_min(1e-12)

    angle = quat_to_euler(pred["q"], "ZYX") - quat_to_euler(target["q"], "ZYX")
    wrapped = wrap_angle_atan2(angle)
    versor_norm = (torch.linalg.vector_norm(pred["q_raw"], dim=-1) - 1.0) ** 2
    squared = wrapped ** 2
    if weights.motion_joints:
        squared = squared * weights.motion_joint_weights().to(squared)[:, None]
    motion = over_gaits(squared.sum((-1, -2))) + weights.versor * over_gaits(versor_norm.sum(-1))
    predicted_pose = travel_frame_positions(pred["q"], offsets, parents)
    target_pose = travel_frame_positions(target["q"], offsets, parents)
    pose = over_gaits(((predicted_pose - target_pose) ** 2).sum(-1)[..., 1:].sum(-1))
    # Huber, not squared: an area ratio with a nearly flat triangle (#6: hands and root almost in line) has a
    # heavy tail (99th percentile 13, maximum ~500) that would otherwise dominate the term.
    affective = over_gaits(torch.nn.functional.huber_loss(affective_features(predicted_pose), target["affective"],
                                                          reduction="none", delta=1.0).sum(-1))
    root = over_gaits(sum((model.standardise(k, pred[k]) - model.standardise(k, target[k])).abs()
                          for k in ROOT_FEATURES))
    foot = over_gaits((world_feet(predicted_pose, pred["s"], pred["h"], target) - target["feet"]).abs().sum((-1, -2)))
    total = (weights.motion * motion + weights.pose * pose + weights.affective * affective + weights.root * root
             + weights.foot * foot)
    style, match = None, None
    if critic is not None and style_target is not None:
        conditioned = ~torch.isnan(style_target).any(-1)
        if conditioned.any():
            style = style_loss(critic(predicted_pose[conditioned]), style_target[conditioned])
        else:
            style = predicted_pose.new_zeros(())
        total = total + weights.style * style
        if weights.style_match > 0.0:
            own = (None, None) if own_style is None else (target_pose[conditioned], own_style[conditioned])
            match = (style_match_loss(critic, predicted_pose[conditioned], style_target[conditioned], *own)
                     if conditioned.any() else predicted_pose.new_zeros(()))
            total = total + weights.style_match * match
    return Losses(motion=motion, pose=pose, affective=affective, root=root, foot=foot, total=total, style=style,
                  style_match=match)
