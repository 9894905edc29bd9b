"""Ingest: mocap files named by source manifests -> canonical, resampled, 60-frame gait windows.

Every input ends in exactly one of three states, with a reason for the last two:
  ingested     at least one window came out of it;
  quarantined  the file is bad (unreadable, malformed, wrong checksum, unmappable) - a data problem;
  filtered     the file is fine but not wanted here (too short, not a gait) - a policy decision.

Files are processed as dask tasks, one task per chunk of files of one source, so that forward kinematics
and retargeting run once over all frames of a chunk. With no client the local process scheduler runs
them; with a ``distributed`` client the same tasks run on its cluster. Results are ordered by source and
path, so the output does not depend on where or in which order tasks ran.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.ops.geometry import ground_speed, heading_angle
from pipeline.ops.kinematics import canonical_positions
from pipeline.ingest.marker_trials import MarkerMotion, NotUsable, canonical_motion
from pipeline.ops.quaternion import qfix
from pipeline.io.readers.bvh import BvhClip
from pipeline.io.readers.c3d import C3dClip
from pipeline.ops.resample import resample, window_starts
from pipeline.ingest.retarget import (
    RetargetError,
    bone_rotations,
    bvh_point_positions,
    check_source_body,
    map_joints,
    referenced_points,
)
from pipeline.core.skeleton import Skeleton
from pipeline.io.manifests import Label, SourceManifest, list_inputs
from pipeline.ingest.screen import screen_file


@dataclass(frozen=True)
class IngestConfig:
    mocap_root: Path
    target_fps: float = 30.0
    window: int = 60
    stride: int = 30
    min_gait_speed: float = 0.2  # m/s, mean horizontal root speed below which a clip is not a gait
    chunk_frames: int = 20000  # source frames per dask task (bounds task memory and balances work)


@dataclass
class FileRecord:
    source: str
    path: str
    sha256: str | None  # as found on disk (None when missing)
    status: str = "pending"
    reason: str | None = None
    frames_in: int = 0
    gaits: int = 0

    def report_entry(self) -> dict[str, Any]:
        return {"source": self.source, "path": self.path, "sha256": self.sha256, "reason": self.reason}


@dataclass
class ChunkResult:
    records: list[FileRecord] = field(default_factory=list)
    windows: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class _Prepared:
    record: FileRecord
    clip: BvhClip | MarkerMotion  # MarkerMotion: canonical joint positions from C3D markers (metres, Y up)
    label: Label
    joint_map: dict[str, Any]
    time_offset: float = 0.0  # s from the source clip's start to the first frame used


def plan_chunks(manifests: Sequence[SourceManifest], cfg: IngestConfig) -> list[tuple[SourceManifest, list]]:
    """Split every source's inputs into chunks of about ``cfg.chunk_frames`` source frames (by file size)."""
    chunks = []
    for manifest in manifests:
        source_dir = cfg.mocap_root / manifest.name
        inputs = list_inputs(manifest, source_dir)
        budget = cfg.chunk_frames * 600  # ~600 bytes per BVH frame line on the default data
        current: list = []
        size = 0
        for rel, pinned in inputs:
            path = source_dir / rel
            current.append((rel, pinned))
            size += path.stat().st_size if path.is_file() else 0
            if size >= budget:
                chunks.append((manifest, current))
                current, size = [], 0
        if current:
            chunks.append((manifest, current))
    return chunks


def ingest_chunk(manifest: SourceManifest, skeleton: Skeleton, entries: list, cfg: IngestConfig) -> ChunkResult:
    """Process one chunk of files of one source. Never raises for bad input: it records it."""
    torch.set_num_threads(1)  # tasks are the unit of parallelism; avoid oversubscribing cores
    result = ChunkResult()
    prepared: list[_Prepared] = []
    source_dir = cfg.mocap_root / manifest.name
    for rel, pinned in entries:
        rec = FileRecord(source=manifest.name, path=rel, sha256=None)
        result.records.append(rec)
        item = _read_and_screen(manifest, source_dir, rel, pinned, rec, cfg, skeleton)
        if item is not None:
            prepared.append(item)
    # Files with the same hierarchy layout and joint map are solved together.
    groups: dict[tuple, list[_Prepared]] = defaultdict(list)
    markers = [item for item in prepared if isinstance(item.clip, MarkerMotion)]
    for item in prepared:
        if isinstance(item.clip, MarkerMotion):
            continue
        s = item.clip.skeleton
        groups[(s.names, s.parents, s.channels, repr(item.joint_map))].append(item)
    for items in groups.values():
        result.windows.extend(_retarget_group(manifest, skeleton, items, cfg))
    if markers:  # marker trials arrive as canonical joint positions already
        points = torch.from_numpy(np.concatenate([i.clip.points for i in markers])).to(torch.float32)
        result.windows.extend(_windows_from_points(manifest, skeleton, markers, points, cfg))
    return result


def _read_and_screen(manifest: SourceManifest, source_dir: Path, rel: str, pinned: str | None,
                     rec: FileRecord, cfg: IngestConfig, skeleton: Skeleton) -> _Prepared | None:
    screened = screen_file(manifest, source_dir, rel, pinned)
    rec.sha256 = screened.sha256
    if screened.rejection is not None:
        _quarantine(rec, screened.rejection)
        return None
    if manifest.format == "c3d":
        return _screen_c3d(manifest, screened.clip, rel, rec, cfg, skeleton)
    clip = screened.clip
    rec.frames_in = clip.frames
    label = _gait_label(manifest, rel, rec)
    if label is None:
        return None
    duration = (clip.frames - 1) * clip.frame_time
    needed = max(manifest.min_clip_seconds, (cfg.window - 1) / cfg.target_fps)
    if duration + 1e-9 < needed:
        _filter(rec, f"too short: {duration:.2f} s ({clip.frames} frames at {clip.fps:.2f} fps); a clip needs "
                     f">= {needed:.2f} s for one {cfg.window}-frame window at {cfg.target_fps:g} fps")
        return None
    return _Prepared(rec, clip, label, manifest.joint_map(rel))


def _gait_label(manifest: SourceManifest, rel: str, rec: FileRecord) -> Label | None:
    """The file's label, or None after quarantining (no label rule fits) or filtering (content not a gait)."""
    try:
        label = manifest.label(rel)
    except ValueError as err:
        _quarantine(rec, f"label rule: {err}")
        return None
    if label.content not in manifest.gait_contents:
        _filter(rec, f"content {label.content!r} is not a gait for this source (gait contents: "
                     f"{sorted(manifest.gait_contents)})")
        return None
    return label


def _screen_c3d(manifest: SourceManifest, clip: C3dClip, rel: str, rec: FileRecord,
                cfg: IngestConfig, skeleton: Skeleton) -> _Prepared | None:
    """A C3D trial that passed the screen: filtered (not a gait, lower-body only, too short) or prepared."""
    rec.frames_in = clip.frames
    label = _gait_label(manifest, rel, rec)
    if label is None:
        return None
    needed = max(manifest.min_clip_seconds, (cfg.window - 1) / cfg.target_fps)
    try:
        motion = canonical_motion(manifest, clip, skeleton.names, needed)
    except NotUsable as err:
        _filter(rec, str(err))
        return None
    return _Prepared(rec, motion, label, manifest.marker_sets, time_offset=motion.time_offset)


def _retarget_group(manifest: SourceManifest, skeleton: Skeleton, items: list[_Prepared],
                    cfg: IngestConfig) -> list[dict[str, Any]]:
    joint_map = items[0].joint_map
    names = referenced_points(joint_map)
    try:
        points = map_joints(names, bvh_point_positions([i.clip for i in items], names, manifest.root_offset,
                                                       manifest.up_axis), joint_map, skeleton)
    except RetargetError as err:
        for item in items:
            _quarantine(item.record, f"joint map: {err}")
        return []
    return _windows_from_points(manifest, skeleton, items, points, cfg)


def _windows_from_points(manifest: SourceManifest, skeleton: Skeleton, items: list[_Prepared],
                         points: torch.Tensor, cfg: IngestConfig) -> list[dict[str, Any]]:
    """Canonical joint positions (sum of frames, 21, 3) of the items' clips -> rotations, resampling, windows."""
    rotations = bone_rotations(points, skeleton)
    bounds = np.cumsum([0] + [i.clip.frames for i in items])
    clips = []
    for k, item in enumerate(items):
        clip_points = points[bounds[k]:bounds[k + 1]]
        try:
            scale, leg_m = check_source_body(clip_points, skeleton, manifest.unit_scale_m)
        except RetargetError as err:
            _quarantine(item.record, f"retarget: {err}")
            continue
        root, rot = resample(clip_points[:, 0] * scale, qfix(rotations[bounds[k]:bounds[k + 1]], dim=0),
                             item.clip.frame_time, cfg.target_fps)
        clips.append((item, root, rot, scale, leg_m))
    if not clips:
        return []
    # Canonical forward kinematics once for all resampled frames of the group.
    offsets = torch.from_numpy(skeleton.offsets).to(rotations.dtype)
    all_pos = canonical_positions(torch.cat([c[1] for c in clips]), torch.cat([c[2] for c in clips]), offsets,
                                  skeleton.parents)
    all_heading = heading_angle(torch.cat([c[2][:, 0] for c in clips]))  # body heading about +Y, 0 = facing +Z
    sizes = np.cumsum([0] + [c[1].shape[0] for c in clips])
    windows = []
    for k, (item, root, rot, scale, leg_m) in enumerate(clips):
        part = slice(sizes[k], sizes[k + 1])
        windows.extend(_windows_of_clip(manifest, skeleton, item, root, rot, all_pos[part], all_heading[part],
                                        scale, leg_m, cfg))
    return windows


def _windows_of_clip(manifest: SourceManifest, skeleton: Skeleton, item: _Prepared, root: torch.Tensor,
                     rot: torch.Tensor, pos: torch.Tensor, heading: torch.Tensor, scale: float, leg_m: float,
                     cfg: IngestConfig) -> list[dict[str, Any]]:
    rec = item.record
    # Floor: the lowest foot point of the clip is the ground (y = 0).
    floor = float(pos[:, list(skeleton.foot_joints), 1].min())
    pos = pos.clone()
    pos[..., 1] -= floor
    root = root.clone()
    root[:, 1] -= floor
    step = ground_speed(root)
    speed = float(step.mean()) * cfg.target_fps if step.numel() else 0.0
    if speed < cfg.min_gait_speed:
        _filter(rec, f"not a gait: mean horizontal root speed {speed:.2f} m/s < {cfg.min_gait_speed} m/s")
        return []
    starts = window_starts(root.shape[0], cfg.window, cfg.stride)
    stem = Path(rec.path).with_suffix("").as_posix()
    clip_id = f"{manifest.name}/{stem}"
    label = item.label
    out = []
    for w, s in enumerate(starts):
        e = s + cfg.window
        out.append({
            "gait_id": f"{clip_id}#w{w:03d}",
            "clip_id": clip_id,
            "source": manifest.name,
            "file": rec.path,
            "sha256": rec.sha256,
            "t_start": item.time_offset + s / cfg.target_fps,
            "t_end": item.time_offset + (e - 1) / cfg.target_fps,
            "source_fps": item.clip.fps,
            "fps": cfg.target_fps,
            "scale": scale,
            "source_leg_m": leg_m,
            "content": label.content,
            "style": label.style,
            "emotion": None if label.emotion is None else np.asarray(label.emotion, dtype=np.float32),
            "label_method": label.label_method,
            "positions": pos[s:e].to(torch.float32).numpy(),
            "rotations": rot[s:e].to(torch.float32).numpy(),
            "root_path": root[s:e][:, [0, 2]].to(torch.float32).numpy(),
            "heading": heading[s:e].to(torch.float32).numpy(),
        })
    rec.gaits = len(out)
    rec.status = "ingested"
    return out


def _quarantine(rec: FileRecord, reason: str) -> None:
    rec.status, rec.reason = "quarantined", reason


def _filter(rec: FileRecord, reason: str) -> None:
    rec.status, rec.reason = "filtered", reason


def run_ingest(manifests: Sequence[SourceManifest], skeleton: Skeleton, cfg: IngestConfig,
               scheduler_address: str | None = None, workers: int | None = None,
               progress: bool = True) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Ingest every input of every manifest. Returns (windows sorted by id, report)."""
    import dask

    chunks = plan_chunks(manifests, cfg)
    tasks = [dask.delayed(ingest_chunk, pure=True)(m, skeleton, entries, cfg) for m, entries in chunks]
    if scheduler_address:
        from distributed import Client, progress as dist_progress

        with Client(scheduler_address) as client:
            futures = client.compute(tasks)
            if progress:
                dist_progress(futures)
            results = client.gather(futures)
    else:
        from dask.diagnostics import ProgressBar

        if progress:
            with ProgressBar(dt=1.0):
                results = dask.compute(*tasks, scheduler="processes", num_workers=workers)
        else:
            results = dask.compute(*tasks, scheduler="processes", num_workers=workers)
    records = sorted((r for res in results for r in res.records), key=lambda r: (r.source, r.path))
    windows = sorted((w for res in results for w in res.windows), key=lambda w: w["gait_id"])
    return windows, build_report(records, windows, cfg)


def build_report(records: Sequence[FileRecord], windows: Sequence[dict[str, Any]], cfg: IngestConfig) -> dict:
    by_status: dict[str, list[FileRecord]] = defaultdict(list)
    for r in records:
        by_status[r.status].append(r)
    unknown = set(by_status) - {"ingested", "quarantined", "filtered"}
    if unknown:  # a file fell through every branch: a bug, never silently dropped
        raise AssertionError(f"files with no outcome: {[r.path for s in unknown for r in by_status[s]]}")
    per_source: dict[str, dict[str, int]] = {}
    for r in records:
        s = per_source.setdefault(r.source, {"files_seen": 0, "files_ingested": 0, "files_quarantined": 0,
                                             "files_filtered": 0, "clips": 0, "gaits": 0, "frames_in": 0})
        s["files_seen"] += 1
        s[f"files_{r.status}"] += 1
        s["frames_in"] += r.frames_in
        s["gaits"] += r.gaits
        s["clips"] += r.status == "ingested"
    labelled = sum(w["emotion"] is not None for w in windows)
    return {
        "files_seen": len(records),
        "files_ingested": len(by_status["ingested"]),
        "files_quarantined": len(by_status["quarantined"]),
        "files_filtered": len(by_status["filtered"]),
        "clips": len(by_status["ingested"]),
        "gaits": len(windows),
        "gaits_labelled": labelled,
        "frames_in": sum(r.frames_in for r in records),
        "target_fps": cfg.target_fps,
        "window": cfg.window,
        "stride": cfg.stride,
        "per_source": per_source,
        "quarantine": [r.report_entry() for r in by_status["quarantined"]],
        "filtered": [r.report_entry() for r in by_status["filtered"]],
    }



def missing_data_message(manifests: Sequence[SourceManifest], mocap_root: Path, setting: str) -> str:
    """What to fetch, and from where, when the raw-data folder is absent (nothing is downloaded); setting: where
    the user points the pipeline at the folder."""
    lines = [f"The mocap root {mocap_root} does not exist. Point {setting} at a folder holding:"]
    for m in manifests:
        up = m.doc["upstream"]
        lines.append(f"  {m.name}/  {len(m.files)} files from {up['repository']} at commit {up['commit']} "
                     f"(paths as in the repository; each pinned by sha256 in manifests/sources/{m.name}.yaml)")
    return "\n".join(lines)
