"""Generation API: seed gaits + target trajectories + per-frame emotions -> new gaits, N agents in one batch.

For every agent the network continues its seed's prefix one frame at a time (its own predictions fed back,
paper §4 and §5.4) and the root is placed from the predicted root features (paper §5.4-5.5):

* advance (``root_advance``): ``stance_foot`` (default) moves the root so that the lowest heel/toe point stays
  where it stood: the body walks by its own legs and the feet do not skate. A foot in its swing phase (by the
  stepping phase the network is given, ``stance_fraction``) is never that point: a generated swing foot can skim
  lower than the stance foot. The network's ŝ alone advances the root faster than its strides carry it (feet
  then slide ~3.4x as fast as real stance feet: reports/eval.md), so ŝ is kept as the network's input (it
  conditions the motion) but no longer places the root.
  With ``forward_steps_only`` the part of that step against the travel direction is dropped: where a generated
  step hesitates, the stance point can slip forward and carry the root back, a small loop in the root's path
  (benchmarks/root_loops.py); the stance foot then slides by that much instead.
  ``predicted_speed`` is the paper's placement: the root advances by ŝ (m/frame, clamped to [0, max_speed])
  along the travel direction.
* direction: the travel direction turns towards a point ``lookahead_m`` ahead on the target path (pure
  pursuit), at most ``max_turn_deg_per_s``; so a path sharper than a person turns is cut (the path fit
  after the last frame lays the walk back onto it; the deviation left is measured). With ``stance_foot`` the body's steps may run at an angle to the travel direction
  (a pelvis turned relative to it); that angle, averaged over ``drift_seconds`` and at most ``max_drift_deg``,
  is steered out so that the body, not the travel frame, follows the path;
* pelvis: the predicted pelvis versor, which is relative to the direction of travel, turned to the travel
  direction (so the body faces where the network's pelvis says, relative to where it walks: a side-stepping
  seed keeps side-stepping);
* height: the seed prefix's mean root height plus the predicted deviation ĥ.

After the last frame (so the network reads its frames as it placed them): root smoothing (``root_smoothing_s``),
the path fit (``path_fit_s``: the walk's travel line bent onto the path, its sway kept; ``ops.path_fit``; the
pursuit alone cut curves and corners) and foot locking (``foot_lock``).

The next step's inputs are those of the placed frame: its versors, their affective features, ŝ, ĥ, δ̂, the
curvature κ of the travel direction (steps of length ŝ), the stepping phase continued at the seed's rate, and
the condition built from that frame's emotion (a NaN row: unlabelled, as for unlabelled training gaits).

Deterministic: no random draws; the same inputs give the same outputs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from pipeline.generators.base import fit_placed
from pipeline.generators.autoregressive.network import (FOOT_JOINTS, EmotiveGaitNet, condition_vectors, fixed_bones,
                                                       sharpened)
from pipeline.ops.geometry import (
    arc_lengths,
    direction_of,
    from_local_frame,
    heading_angle,
    moving_average,
    odd_frames,
    pursue,
    to_local_frame,
    unit_direction,
    wrap_phase,
)
from pipeline.ops.contacts import ContactConfig
from pipeline.ops.footlock import lock_feet
from pipeline.ops.kinematics import canonical_positions
from pipeline.ops.quaternion import qmul, qnormalize, yaw
from pipeline.generators.autoregressive.training import GaitTensors, extrapolated_phase, predicted_affective


@dataclass(frozen=True)
class PlacementConfig:
    """Where generated gaits go: the root placement rules (the pipeline params' ``generate``)."""

    fps: float = 30.0
    lookahead_m: float = 0.6
    max_turn_deg_per_s: float = 240.0
    max_speed_m_s: float = 3.0
    root_advance: str = "stance_foot"  # or "predicted_speed"
    stance_softness_m: float = 0.002
    stance_fraction: float = 1.0  # a foot swings for the rest of its stepping cycle (``swinging_points``)
                                  # and is then never the stance foot (1: the lowest point, whatever the phase)
    drift_seconds: float = 1.0
    max_drift_deg: float = 15.0
    forward_steps_only: bool = False  # drop the part of a stance step against the travel direction (a hesitating
                                      # generated step would carry the root back: a small loop in its path)
    guidance: float = 1.0  # classifier-free guidance w of the condition (1: none; see ``generate``)
    expression_sharpness: float = 1.0  # the condition of an emotion m is m^p / sum(m^p) (1: m itself; ``generate``)
    root_smoothing_s: float = 0.0  # centred moving average of the placed root's ground path (``smoothed_root``)
    path_fit_s: float = 0.0  # lay the walk's travel line (averaged over this long) onto its path (ops.path_fit; 0: no)
    path_corner_m: float = 0.2  # ... the root following the path with its corners rounded over this much arc,
    path_turn_m: float = 0.6  # ... the body facing along it with its corners rounded over this much
    foot_lock: bool = False  # hold stance feet still by leg IK after generation (ops.footlock)
    contacts: ContactConfig = ContactConfig()  # what a stance foot is (the annotation's rule)

    @classmethod
    def from_dict(cls, generate: dict[str, Any], fps: float, contacts: ContactConfig = ContactConfig()
                  ) -> PlacementConfig:
        """From a ``generate`` mapping (numbers, the ``root_advance`` name, ``foot_lock``) at the gaits' frame rate."""
        return cls(fps=float(fps), contacts=contacts,
                   **{k: (v if isinstance(v, (str, bool)) else float(v)) for k, v in generate.items()})

    def __post_init__(self) -> None:
        if self.root_advance not in ("stance_foot", "predicted_speed"):
            raise ValueError(f"generate.root_advance: expected 'stance_foot' or 'predicted_speed', "
                             f"found {self.root_advance!r}")


@dataclass
class Seeds:
    """Prefix frames of N seed gaits (P frames each) and their body headings."""

    gaits: GaitTensors  # (N, P, ...)
    heading: torch.Tensor  # (N, P) rad, body heading about +Y (0 = facing +Z)

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], rows: np.ndarray, prefix: int) -> Seeds:
        heading = np.ascontiguousarray(arrays["heading"][rows][:, :prefix], dtype=np.float32)
        return cls(gaits=prefix_of(GaitTensors.from_arrays(arrays, rows), prefix), heading=torch.from_numpy(heading))

    def __len__(self) -> int:
        return len(self.gaits)

    def travel_direction(self) -> torch.Tensor:
        """(N,) direction of travel at the last prefix frame (geometry.path_direction, over the seed window)."""
        return self.gaits.direction[:, -1]


def prefix_of(gaits: GaitTensors, frames: int) -> GaitTensors:
    """The first ``frames`` frames of every gait (the per-gait condition is kept whole)."""
    return GaitTensors(**{k: (v if k == "condition" else v[:, :frames]) for k, v in gaits.__dict__.items()})


@dataclass
class Generated:
    rotations: torch.Tensor  # (N, S, 21, 4)
    positions: torch.Tensor  # (N, S, 21, 3)
    h: torch.Tensor  # (N, S) predicted root features
    s: torch.Tensor
    advance: torch.Tensor  # (N, S) horizontal distance the root moved into each frame (m/frame)
    delta: torch.Tensor
    theta: torch.Tensor  # (N, S) stepping phase fed to the network
    condition: torch.Tensor  # (N, S, 5)
    heading: torch.Tensor  # (N, S) body heading
    travel: torch.Tensor  # (N, S) direction of travel the frame was placed with
    versors: torch.Tensor  # (N, S, 21, 4) the network's versors (pelvis relative to the direction of travel)


def place_paths(shapes: torch.Tensor, seeds: Seeds) -> torch.Tensor:
    """Paths given in a local frame (K, 2) or (N, K, 2) as (x, z), starting at (0, 0) towards +z, moved to start at
    each seed's last root position and turned to its travel direction -> (N, K, 2) world (x, z)."""
    shapes = shapes.expand(len(seeds), *shapes.shape[-2:]) if shapes.dim() == 2 else shapes
    along = unit_direction(seeds.travel_direction()[:, None])  # +z turns to (sin α, cos α)
    return from_local_frame(shapes, along, seeds.gaits.root_position[:, -1, [0, 2]][:, None])


def _root_relative(root_rotation: torch.Tensor, joint_versors: torch.Tensor, height: torch.Tensor,
                   offsets: torch.Tensor, parents: Sequence[int]) -> torch.Tensor:
    """World-oriented joint positions (N, 21, 3) of a pose whose root stands at (0, height, 0)."""
    root = torch.stack((torch.zeros_like(height), height, torch.zeros_like(height)), dim=-1)
    return canonical_positions(root, torch.cat([root_rotation[:, None], joint_versors], dim=1), offsets, parents)


SWING_LIFT_M = 1.0  # a swinging point counts as this much higher: out of the stance weights (softness ~ mm)


def stance_step(previous_feet: torch.Tensor, feet: torch.Tensor, softness_m: float, max_step: float,
                swinging: torch.Tensor | None = None) -> torch.Tensor:
    """Ground step (N, 2) of the root that keeps the stance foot where it stood.

    previous_feet, feet: root-relative heel/toe points (N, 4, 3) of two consecutive frames. The stance point is the
    lowest one (weights exp(-height above the lowest / softness), so two points level with each other share);
    the root moves by the opposite of that point's root-relative horizontal motion, at most ``max_step``.
    swinging: (N, 4) bool, points of a foot in its swing phase (``swinging_points``): never the
    stance point, unless every point swings. A generated swing foot can skim lower than the stance foot; taken as
    the stance it would carry the root backwards (measured: a third of the frames of emotional walks).
    """
    height = 0.5 * (previous_feet[..., 1] + feet[..., 1])
    if swinging is not None:
        height = torch.where(swinging & ~swinging.all(-1, keepdim=True), height + SWING_LIFT_M, height)
    weight = torch.exp(-(height - height.min(-1, keepdim=True).values) / softness_m)
    step = (weight[..., None] * (previous_feet - feet)[..., [0, 2]]).sum(1) / weight.sum(1, keepdim=True)
    length = torch.linalg.vector_norm(step, dim=-1, keepdim=True)
    return step * (length.clamp(max=max_step) / length.clamp_min(1e-9))


def forward_only(step: torch.Tensor, along: torch.Tensor) -> torch.Tensor:
    """A ground step (N, 2) without its part against the unit travel direction ``along`` (N, 2): a hesitating
    generated step whose stance point slips forward would carry the root back, a small loop in its path."""
    return step - (step * along).sum(-1, keepdim=True).clamp(max=0.0) * along


def placed_step(previous_feet: torch.Tensor, feet: torch.Tensor, along: torch.Tensor, cfg: PlacementConfig,
                swinging: torch.Tensor | None = None) -> torch.Tensor:
    """The root's ground step (N, 2) under the placement rules: the stance foot's (``stance_step``, at most
    ``max_speed_m_s``), without its part against the travel direction ``along`` with ``forward_steps_only``.
    Every family that places its root by the stance foot steps through here."""
    step = stance_step(previous_feet, feet, cfg.stance_softness_m, cfg.max_speed_m_s / cfg.fps, swinging)
    return forward_only(step, along) if cfg.forward_steps_only else step


def swinging_points(theta: torch.Tensor, stance_fraction: float) -> torch.Tensor:
    """(..., 4) bool in ``ops.contacts.CONTACT_POINTS`` order: the heel/toe points of a foot in its swing phase by
    the stepping phase θ (...) (0 at a left strike, π at the next right strike): a foot is down for the first
    ``stance_fraction`` of its cycle (about 0.6 when walking) and swings for the rest. Both feet are down in double
    support; with ``stance_fraction`` < 0.5 (running) both may swing."""
    cycle = 2.0 * math.pi * stance_fraction
    left = wrap_phase(theta) >= cycle
    right = wrap_phase(theta - math.pi) >= cycle
    return torch.stack((left, left, right, right), dim=-1)


def _guide(conditioned: dict[str, torch.Tensor], free: dict[str, torch.Tensor], w: float) -> dict[str, torch.Tensor]:
    """Classifier-free guidance: free + w (conditioned - free) on the versors (renormalised) and root features.
    w > 1 moves a frame further along what the condition changes; both branches are fed the guided frame."""
    out = {k: free[k] + w * (conditioned[k] - free[k]) for k in ("q_raw", "h", "s", "delta")}
    out["q"] = qnormalize(out["q_raw"])
    return out


def smoothed_root(positions: torch.Tensor, prefix_ground: torch.Tensor, frames: int) -> torch.Tensor:
    """Generated frames (N, S, J, 3) with the root's ground path (x, z) replaced by its centred moving average over
    ``frames`` (odd); every joint moves with the root, heights are kept. Left of the first frame the average reads
    the seed's prefix path (N, P, 2) (the join stays continuous), right of the last the path mirrored through its
    end point (its trend continues). The stance-foot placement carries the root by the lowest foot point, which
    jumps when the stance passes from foot to foot; the average keeps the stride and removes those jumps (the
    feet are then held by ``foot_lock``)."""
    half = frames // 2
    ground = positions[..., 0, [0, 2]]
    if half == 0 or ground.shape[1] < 2:
        return positions
    tail = min(half, ground.shape[1] - 1)
    mirrored = 2 * ground[:, -1:] - ground[:, -2 - torch.arange(tail)]
    left = prefix_ground[:, -half:]
    padded = torch.cat([left, ground, mirrored], 1).transpose(1, 2)  # (N, 2, P' + S + tail)
    averaged = moving_average(padded, frames).transpose(1, 2)[:, left.shape[1]:left.shape[1] + ground.shape[1]]
    shift = averaged - ground
    return positions + torch.stack((shift[..., 0], torch.zeros_like(shift[..., 0]), shift[..., 1]), -1)[:, :, None]


@torch.no_grad()
def generate(model: EmotiveGaitNet, seeds: Seeds, paths: torch.Tensor, emotions: torch.Tensor,
             offsets: torch.Tensor, parents: Sequence[int], cfg: PlacementConfig = PlacementConfig()) -> Generated:
    """Generate S = emotions.shape[1] frames for each of the N seeds in one batch.

    paths: (N, K, 2) world (x, z) polylines to follow (see ``place_paths``); emotions: (N, S, 4) per generated
    frame (rows summing to 1; NaN rows for "unlabelled"). Returns the generated frames only (not the prefix).
    """
    model.eval()
    seed = seeds.gaits
    offsets = offsets.to(torch.float32)
    steps = emotions.shape[1]
    condition = condition_vectors(sharpened(emotions.to(torch.float32), cfg.expression_sharpness))
    prefix = seed.q.shape[1]
    theta, omega = extrapolated_phase(seed.theta, seed.omega, steps)
    frames = {**seed.frames(0, prefix), "fixed": fixed_bones(seed.q)}
    pred, hidden = model(frames)
    guided = cfg.guidance != 1.0
    if guided:  # the same network without a condition (m = 0, as it learnt unlabelled gaits), its own state
        free_pred, free_hidden = model({**frames, "condition": torch.zeros_like(frames["condition"])})
        pred = _guide(pred, free_pred, cfg.guidance)
    current = {k: v[:, -1] for k, v in pred.items()}
    cumulative = arc_lengths(paths)
    ground = seed.root_position[:, -1, [0, 2]].clone()
    previous_step = ground - seed.root_position[:, -2, [0, 2]]
    travel = seeds.travel_direction()
    base_height = seed.root_position[:, :, 1].mean(-1)
    max_turn = math.radians(cfg.max_turn_deg_per_s) / cfg.fps
    out = {k: [] for k in ("rotations", "positions", "h", "s", "advance", "delta", "heading", "travel", "versors")}
    feet = list(FOOT_JOINTS)
    stance_foot = cfg.root_advance == "stance_foot"
    previous_feet = _root_relative(qmul(yaw(travel), seed.q[:, -1, 0]), seed.q[:, -1, 1:],
                                   seed.root_position[:, -1, 1], offsets, parents)[:, feet]
    drift = torch.zeros_like(travel)  # mean angle between the body's realised steps and the travel direction
    mean_step = torch.zeros(len(travel), 2)  # (sideways, ahead) in the travel frame, exponentially averaged
    max_drift = math.radians(cfg.max_drift_deg)
    for t in range(steps):
        speed = current["s"].clamp(0.0, cfg.max_speed_m_s / cfg.fps)
        travel = pursue(travel, ground, paths, cumulative, cfg.lookahead_m, max_turn, drift)
        along = unit_direction(travel)
        delta = current["delta"].clamp(0.0, math.pi)
        root_rotation = qmul(yaw(travel), current["q"][:, 0])
        heading = heading_angle(root_rotation)
        rotations = torch.cat([root_rotation[:, None], current["q"][:, 1:]], dim=1)
        local = _root_relative(root_rotation, current["q"][:, 1:], base_height + current["h"], offsets, parents)
        nominal = speed[:, None] * along  # the step the predicted root speed asks for
        if stance_foot:
            swinging = swinging_points(theta[:, t], cfg.stance_fraction) if cfg.stance_fraction < 1.0 else None
            step = placed_step(previous_feet, local[:, feet], along, cfg, swinging)
            previous_feet = local[:, feet]
            relative = to_local_frame(step, along)  # (sideways, ahead) of the travel direction
            mean_step = mean_step + (relative - mean_step) / (cfg.drift_seconds * cfg.fps)
            drift = direction_of(mean_step[:, 0], mean_step[:, 1].abs().clamp_min(1e-6)).clamp(-max_drift, max_drift)
        else:
            step = nominal
        ground = ground + step
        positions = local + torch.stack((ground[:, 0], torch.zeros_like(ground[:, 0]), ground[:, 1]), -1)[:, None]
        kappa = torch.linalg.vector_norm(nominal - previous_step, dim=-1)
        previous_step = nominal
        for k, v in (("rotations", rotations), ("positions", positions), ("h", current["h"]), ("s", speed),
                     ("advance", torch.linalg.vector_norm(step, dim=-1)), ("delta", delta), ("heading", heading),
                     ("travel", travel), ("versors", current["q"])):
            out[k].append(v)
        if t == steps - 1:
            break
        inputs = {"q": current["q"][:, None], "affective": predicted_affective(current["q"], offsets, parents)[:, None],
                  "condition": condition[:, t:t + 1], "theta": theta[:, t:t + 1], "omega": omega[:, t:t + 1],
                  "s": speed[:, None], "kappa": kappa[:, None], "h": current["h"][:, None], "delta": delta[:, None],
                  "fixed": frames["fixed"]}
        pred, hidden = model(inputs, hidden)
        if guided:
            free_pred, free_hidden = model({**inputs, "condition": torch.zeros_like(inputs["condition"])}, free_hidden)
            pred = _guide(pred, free_pred, cfg.guidance)
        current = {k: v[:, 0] for k, v in pred.items()}
    stacked = {k: torch.stack(v, dim=1) for k, v in out.items()}
    window = odd_frames(cfg.root_smoothing_s, cfg.fps)
    if window > 1:
        stacked["positions"] = smoothed_root(stacked["positions"], seed.root_position[..., [0, 2]], window)
        path = torch.cat([seed.root_position[:, -1:, [0, 2]], stacked["positions"][..., 0, [0, 2]]], 1)
        stacked["advance"] = torch.linalg.vector_norm(path.diff(dim=1), dim=-1)
    if cfg.path_fit_s > 0:  # laid onto the path after the network has run: what it read stays as it generated it
        stacked["positions"], stacked["rotations"], turn = fit_placed(stacked["positions"], stacked["rotations"],
                                                                      paths, cfg)
        stacked["heading"] = heading_angle(stacked["rotations"][..., 0, :])
        stacked["travel"] = stacked["travel"] + turn
    if cfg.foot_lock:  # the network's own inputs were its unlocked frames; only what is published changes
        stacked["rotations"], stacked["positions"] = lock_feet(stacked["rotations"], stacked["positions"][..., 0, :],
                                                               offsets, parents, cfg.fps, cfg.contacts)
        stacked["versors"] = torch.cat([stacked["versors"][..., :1, :], stacked["rotations"][..., 1:, :]], dim=-2)
    return Generated(theta=theta, condition=condition, **stacked)
