"""Stick-figure previews: filmstrips (PNG) and animations (GIF) of gaits, for people to check by eye.

Each row is one motion: a strip of frames seen from the side (the horizontal axis is the direction of
travel, so a walker moves left to right), each frame centred on its root, with the floor drawn at y = 0,
and a top view of the root path. Left limbs are blue, right limbs red, the trunk black.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402

from pipeline.core.skeleton import Skeleton  # noqa: E402
from pipeline.io.files import atomic_path, save_figure  # noqa: E402

LEFT, RIGHT, TRUNK = "#1f5fbf", "#c0392b", "#222222"


@dataclass(frozen=True)
class Motion:
    title: str
    positions: np.ndarray  # (T, J, 3), metres, Y up
    parents: Sequence[int]
    names: Sequence[str]
    root: int = 0  # the pelvis: frames are centred on it and its path is the one shown


_LEFT_NAME = re.compile(r"left|(?<![a-z])l(?![a-z])")
_RIGHT_NAME = re.compile(r"right|(?<![a-z])r(?![a-z])")


def _bone_colour(name: str) -> str:
    """Colour by side, from canonical names (left_knee) or common source names (LeftLeg, Foot_L, CC_Base_L_Calf)."""
    lower = name.lower()
    if _LEFT_NAME.search(lower):
        return LEFT
    if _RIGHT_NAME.search(lower):
        return RIGHT
    return TRUNK


def _travel_axes(pos: np.ndarray, root: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit horizontal vectors (forward, lateral) from the root's net travel (+Z if it stands still)."""
    travel = pos[-1, root, [0, 2]] - pos[0, root, [0, 2]]
    if np.linalg.norm(travel) < 1e-3:
        travel = np.array([0.0, 1.0])
    fwd = travel / np.linalg.norm(travel)
    return fwd, np.array([-fwd[1], fwd[0]])


def _side_view(ax, p: np.ndarray, fwd: np.ndarray, motion: Motion, colour: str | None = None) -> None:
    """One pose (J, 3) seen from the side: along travel horizontally (root at 0), height vertically; bones coloured
    by side unless ``colour`` is given."""
    u = (p[:, [0, 2]] - p[motion.root, [0, 2]]) @ fwd
    for j, parent in enumerate(motion.parents):
        if parent >= 0:
            ax.plot([u[parent], u[j]], [p[parent, 1], p[j, 1]], color=colour or _bone_colour(motion.names[j]), lw=2)
    ax.scatter(u, p[:, 1], s=6, color=colour or "#555555", zorder=3)


def _row_label(title: str, width: int = 34) -> str:
    """A row's title wrapped to the row's height (8 pt, 2.6 in): unwrapped, a long one ran into its neighbours'."""
    return "\n".join(textwrap.fill(line, width, break_on_hyphens=False) for line in title.split("\n"))


def filmstrip(motions: Sequence[Motion], frames: int = 8) -> plt.Figure:
    """One row per motion: ``frames`` evenly spaced side views plus a top view of the path (the row's title at its
    left)."""
    fig, axes = plt.subplots(len(motions), frames + 1, figsize=(1.6 * frames + 3.0, 2.6 * len(motions)),
                             squeeze=False, gridspec_kw={"width_ratios": [1] * frames + [1.8]})
    for row, motion in zip(axes, motions):
        pos = np.asarray(motion.positions, dtype=np.float64)
        fwd, _ = _travel_axes(pos, motion.root)
        picks = np.linspace(0, len(pos) - 1, frames).round().astype(int)
        top = max(2.0, float(pos[..., 1].max()) + 0.1)
        for ax, t in zip(row[:-1], picks):
            _side_view(ax, pos[t], fwd, motion)
            ax.axhline(0.0, color="#8a6d3b", lw=1.5)
            ax.set_xlim(-0.8, 0.8)
            ax.set_ylim(-0.1, top)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"t={t}", fontsize=8)
        row[0].set_ylabel(_row_label(motion.title), fontsize=8)
        ax = row[-1]
        r = motion.root
        ax.plot(pos[:, r, 0], pos[:, r, 2], color=TRUNK, lw=1.5)
        for foot, colour in (("left", LEFT), ("right", RIGHT)):
            idx = [j for j, n in enumerate(motion.names) if n.lower().startswith(foot) and "toe" in n.lower()]
            if idx:
                ax.plot(pos[:, idx[0], 0], pos[:, idx[0], 2], color=colour, lw=0.8)
        ax.scatter(pos[0, r, 0], pos[0, r, 2], color="green", s=15, zorder=3, label="start")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("top view (x, z)", fontsize=8)
        ax.tick_params(labelsize=6)
    fig.tight_layout()
    return fig


def render_filmstrip(motions: Sequence[Motion], out: str | Path, frames: int = 8, dpi: int = 100) -> Path:
    """``filmstrip`` saved to ``out``."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(filmstrip(motions, frames), out, dpi=dpi)
    return out


def render_gif(motion: Motion, out: str | Path, fps: float = 30.0) -> Path:
    """An animation of one motion from the side, following the root."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    out = Path(out)
    pos = np.asarray(motion.positions, dtype=np.float64)
    fwd, _ = _travel_axes(pos, motion.root)
    fig, ax = plt.subplots(figsize=(3, 3.5))
    lines = [ax.plot([], [], color=_bone_colour(motion.names[j]), lw=2)[0] if p >= 0 else None
             for j, p in enumerate(motion.parents)]
    ax.axhline(0.0, color="#8a6d3b", lw=1.5)
    ax.set_xlim(-1, 1)
    ax.set_ylim(-0.1, max(2.0, float(pos[..., 1].max()) + 0.1))
    ax.set_aspect("equal")
    ax.set_title(motion.title, fontsize=8)

    def draw(t: int):
        p = pos[t]
        u = (p[:, [0, 2]] - p[motion.root, [0, 2]]) @ fwd
        for j, parent in enumerate(motion.parents):
            if parent >= 0:
                lines[j].set_data([u[parent], u[j]], [p[parent, 1], p[j, 1]])
        return [ln for ln in lines if ln is not None]

    with atomic_path(out) as tmp:
        FuncAnimation(fig, draw, frames=len(pos), blit=True).save(tmp, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out


@dataclass(frozen=True)
class AnnotatedClip:
    title: str
    fps: float
    foot_heights: np.ndarray  # (T, 4) heel/toe heights, m, in contact_names order
    contacts: np.ndarray  # (T, 4) 0/1
    phase: np.ndarray  # (T,) rad
    contact_names: Sequence[str]


def render_annotation(clips: Sequence[AnnotatedClip], out: str | Path, dpi: int = 100) -> Path:
    """Per clip: heel/toe heights with their contact intervals shaded, and the stepping phase below."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2 * len(clips), 1, figsize=(12, 3.2 * len(clips)), squeeze=False,
                             gridspec_kw={"height_ratios": [2, 1] * len(clips)})
    for k, clip in enumerate(clips):
        ax, axp = axes[2 * k, 0], axes[2 * k + 1, 0]
        t = np.arange(len(clip.phase)) / clip.fps
        for j, name in enumerate(clip.contact_names):
            colour = LEFT if name.startswith("left") else RIGHT
            style = "-" if "heel" in name else "--"
            ax.plot(t, clip.foot_heights[:, j], style, color=colour, lw=1.2, label=name)
            down = clip.contacts[:, j] > 0.5
            ax.fill_between(t, -0.02 - 0.01 * j, -0.01 - 0.01 * j, where=down, color=colour,
                            alpha=0.9 if "heel" in name else 0.5, step="mid", lw=0)
        ax.set_ylabel("height (m)")
        ax.set_title(f"{clip.title}: heel (solid) / toe (dashed) heights; bars = contact", fontsize=9)
        ax.legend(fontsize=7, ncol=4, loc="upper right")
        phase = np.asarray(clip.phase, dtype=float).copy()
        phase[1:][np.diff(phase) < -np.pi] = np.nan  # break the line where the phase wraps to 0
        axp.plot(t, phase, color=TRUNK, lw=1.2)
        axp.set_ylim(0, 2 * np.pi)
        axp.set_yticks([0, np.pi, 2 * np.pi], ["0 (L strike)", "π (R strike)", "2π"])
        axp.set_xlabel("time (s)")
    fig.tight_layout()
    save_figure(fig, out, dpi=dpi)
    return out


def render_trajectories(trajectories: Sequence[tuple[str, np.ndarray, Sequence[np.ndarray]]], out: str | Path,
                        per_trajectory: int = 25, dpi: int = 100) -> Path:
    """Top views: each planned trajectory (grey) with the root paths of some of its generated gaits drawn where
    they start on it. trajectories: (id, planned points (K, 2), generated root paths (T, 2) placed on it)."""
    cols = 5
    rows = -(-len(trajectories) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    for ax, (tid, points, paths) in zip(axes.flat, trajectories):
        ax.plot(points[:, 0], points[:, 1], color="0.6", lw=3)
        for path in paths[:: max(1, len(paths) // per_trajectory)]:
            ax.plot(path[:, 0], path[:, 1], lw=0.8)
        ax.set_title(f"{tid} ({len(paths)} gaits)", fontsize=9)
        ax.set_aspect("equal", "datalim")
        ax.tick_params(labelsize=6)
    for ax in list(axes.flat)[len(trajectories):]:
        ax.axis("off")
    fig.suptitle("Planned trajectories (grey, metres, start at the origin heading up) and generated root paths")
    fig.tight_layout()
    out = Path(out)
    save_figure(fig, out, dpi=dpi)
    return out


def annotation_examples(table: pa.Table, arrays: dict[str, np.ndarray], annotations: dict[str, np.ndarray],
                        skeleton: Skeleton, contact_points: Sequence[str], fps: float, out: Path) -> None:
    """Heights, contacts and phase of the ``contact_points`` (joint names) of the first (labelled, where there is
    one) walk of up to three sources, drawn by ``render_annotation``."""
    chosen: dict[str, str] = {}
    for cid, src, content, method in zip(table.column("clip_id").to_pylist(), table.column("source").to_pylist(),
                                         table.column("content").to_pylist(), table.column("label_method").to_pylist()):
        if content == "walk" and (src not in chosen or (method and not chosen[src][1])):
            chosen[src] = (cid, method)
    clip_ids = table.column("clip_id").to_pylist()
    starts = np.round(table.column("t_start").to_numpy() * fps).astype(int)
    points = [skeleton.index(n) for n in contact_points]
    examples = []
    for src, (cid, _) in sorted(chosen.items())[:3]:
        rows = [r for r, c in enumerate(clip_ids) if c == cid]
        frames = starts[rows[-1]] + arrays["positions"].shape[1]
        heights, contacts, phase = np.zeros((frames, 4)), np.zeros((frames, 4)), np.zeros(frames)
        for r in rows:
            s = slice(starts[r], starts[r] + arrays["positions"].shape[1])
            heights[s] = arrays["positions"][r][:, points, 1]
            contacts[s] = annotations["contacts"][r]
            phase[s] = annotations["phase"][r]
        examples.append(AnnotatedClip(cid, fps, heights, contacts, phase, tuple(contact_points)))
    render_annotation(examples, out)


def preview_gaits(windows: Sequence[dict], skeleton: Skeleton) -> list[Motion]:
    """One gait per source, a labelled walk where the source has one, for a look at the retargeting."""
    picked: dict[str, dict] = {}
    rank = lambda w: (w["emotion"] is not None, w["content"] == "walk")  # noqa: E731
    for w in windows:
        if w["source"] not in picked or rank(w) > rank(picked[w["source"]]):
            picked[w["source"]] = w
    return [Motion(f"{w['gait_id'].split('/')[0]}\n{w['style']} {w['content']}", w["positions"], skeleton.parents,
                   skeleton.names) for w in picked.values()]


def render_floor_models(series: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray]], fps: float, out: Path,
                        skeleton: Skeleton, limit: int = 6) -> None:
    """The clips whose floor drifts most (``series``: clip id, lowest foot point per frame, modelled floor, both in
    metres above the clip's lowest foot point, and the corrected joint positions): raw heights with the floor model
    on top, corrected heights below them, and at the bottom the frame where the two floors differ most, its raw legs
    (the clip's lowest foot point as the floor, grey) behind the corrected ones."""
    chosen = sorted(series, key=lambda s: -float(np.ptp(s[2])))[:limit]
    fig, axes = plt.subplots(3, max(1, len(chosen)), figsize=(3.2 * max(1, len(chosen)), 7.4), squeeze=False,
                             sharey="row", gridspec_kw={"height_ratios": [1, 1, 0.9]})
    for k, (clip_id, lowest, floor, positions) in enumerate(chosen):
        t = np.arange(len(lowest)) / fps
        top, middle, pose = axes[0, k], axes[1, k], axes[2, k]
        top.plot(t, 100 * lowest, lw=0.8, color="0.4", label="lowest foot point")
        top.plot(t, 100 * floor, lw=1.6, color="tab:red", label="floor model")
        top.set_title(clip_id.split("/", 1)[0] + "\n" + clip_id.rsplit("/", 1)[-1], fontsize=8)
        middle.plot(t, 100 * (lowest - floor), lw=0.8, color="tab:blue")
        middle.axhline(0, color="k", lw=0.6)
        middle.set_xlabel("s")
        f = int(np.argmax(floor))  # the raw clip floats highest above its one floor here
        motion = Motion(clip_id, positions, skeleton.parents, skeleton.names)
        fwd, _ = _travel_axes(np.asarray(positions, dtype=np.float64), motion.root)
        corrected = np.asarray(positions[f], dtype=np.float64)
        _side_view(pose, corrected + np.array([0.0, float(floor[f]), 0.0]), fwd, motion, colour="0.7")
        _side_view(pose, corrected, fwd, motion)
        pose.axhline(0.0, color="#8a6d3b", lw=1.5)
        pose.set_xlim(-0.6, 0.6)
        pose.set_ylim(-0.05, 0.55)  # the legs: centimetres show at this scale
        pose.set_aspect("equal")
        pose.set_xticks([])
        pose.set_title(f"{t[f]:.1f} s: raw (grey) {100 * floor[f]:.1f} cm up", fontsize=8)
    if chosen:
        axes[0, 0].set_ylabel("raw: cm above the clip's lowest point", fontsize=8)
        axes[1, 0].set_ylabel("corrected: cm above the floor", fontsize=8)
        axes[2, 0].set_ylabel("legs (m): raw grey", fontsize=8)
        axes[0, 0].legend(fontsize=7)
    else:
        axes[0, 0].text(0.5, 0.5, "every clip's floor is level", ha="center", transform=axes[0, 0].transAxes)
    fig.suptitle("Floors that drift or tilt: followed (ops/floor)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, out, dpi=90)
