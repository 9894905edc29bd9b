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

import dataclasses
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pipeline.ops.discontinuities import continuous_spans, pose_jumps
from pipeline.ops.floor import FloorConfig, fit_floor
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
    max_joint_speed: float = 15.0  # m/s; a joint faster than this between two frames is a discontinuity
    floor: FloorConfig = field(default_factory=FloorConfig)


@dataclass
class FileRecord:
    source: str
    path: str
    sha256: str | None  # as found on disk (None when missing)
    status: str = "pending"
    reason: str | None = None
    frames_in: int = 0
    gaits: int = 0
    discontinuities: list[dict[str, Any]] = field(default_factory=list)  # each with its frame and what was done
    clips: list[dict[str, Any]] = field(default_factory=list)  # per clip made of the file: its floor model
    window_floor: list[tuple[str, float, float]] = field(default_factory=list)  # per window: content, lowest foot
    # point (m) with the clip's lowest foot point as the floor (before) and with the modelled floor (after)
    floor_series: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)  # per trend
    # clip: its id, lowest foot point per frame and modelled floor (m, above the clip's lowest foot point), and the
    # corrected joint positions (T, J, 3), for the report's plot

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
    span: tuple[int, int] | None = None  # source frames [first, end) of this part of the clip (between discontinuities)
    part: str = ""  # appended to the clip id where a file was cut into several clips


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
    """The file's label, or None after quarantining (neither a table row nor the label rule gives one) or filtering
    (content not a gait)."""
    try:
        label = manifest.label(rel)
    except ValueError as err:  # its message starts with "label rule:" or "labels table:"
        _quarantine(rec, str(err))
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
        for part in _continuous_parts(manifest, item, clip_points * scale, skeleton, cfg):
            a, b = part.span
            root, rot = resample(clip_points[a:b, 0] * scale, qfix(rotations[bounds[k] + a:bounds[k] + b], dim=0),
                                 item.clip.frame_time, cfg.target_fps)
            clips.append((part, root, rot, scale, leg_m))
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


def _continuous_parts(manifest: SourceManifest, item: _Prepared, metres: torch.Tensor, skeleton: Skeleton,
                      cfg: IngestConfig) -> list[_Prepared]:
    """The clip cut at its pose discontinuities (``pose_jumps`` on the canonical points in metres): the parts long
    enough for a window, each with its span and time offset; every discontinuity is recorded with its frame and
    what became of the frames around it (trimmed at an edge, dropped between two, or a cut between two kept parts).
    A file left with no part is filtered."""
    rec, frames, dt = item.record, item.clip.frames, item.clip.frame_time
    needed = max(manifest.min_clip_seconds, (cfg.window - 1) / cfg.target_fps)
    jumps = pose_jumps(metres, dt, cfg.max_joint_speed)
    kept, dropped = continuous_spans(frames, jumps, int(np.ceil(needed / dt - 1e-6)) + 1)
    for j in jumps:
        before = next(s for s in kept + dropped if s[1] == j.frame + 1)
        after = next(s for s in kept + dropped if s[0] == j.frame + 1)
        action = ("cut between two clips" if before in kept and after in kept else
                  "trimmed at the start" if before == (0, j.frame + 1) and before in dropped else
                  "trimmed at the end" if after == (j.frame + 1, frames) and after in dropped else
                  "frames dropped around it")
        rec.discontinuities.append({"frame": j.frame, "to_frame": j.frame + 1, "joint": skeleton.names[j.joint],
                                    "speed_mps": round(j.speed, 2), "limit_mps": cfg.max_joint_speed,
                                    "action": action})
    if not kept:
        _filter(rec, f"no part between its {len(jumps)} pose discontinuities (a joint faster than "
                     f"{cfg.max_joint_speed:g} m/s between frames) lasts {needed:.2f} s")
        return []
    return [dataclasses.replace(item, span=(a, b), time_offset=item.time_offset + a * dt,
                                part="" if len(kept) == 1 else f"@{n + 1}") for n, (a, b) in enumerate(kept)]


def _windows_of_clip(manifest: SourceManifest, skeleton: Skeleton, item: _Prepared, root: torch.Tensor,
                     rot: torch.Tensor, pos: torch.Tensor, heading: torch.Tensor, scale: float, leg_m: float,
                     cfg: IngestConfig) -> list[dict[str, Any]]:
    rec = item.record
    stem = Path(rec.path).with_suffix("").as_posix()
    clip_id = f"{manifest.name}/{stem}{item.part}"
    bad = ~torch.isfinite(pos).all(dim=(1, 2))
    if bad.any():  # a degenerate rig (e.g. a bone of zero length) solved to NaN: nothing downstream can use it
        f = int(bad.nonzero()[0])
        _quarantine(rec, f"retarget: expected finite joint positions, found non-finite ones in {int(bad.sum())} "
                         f"of {len(bad)} resampled frames of {clip_id} (the first: frame {f})")
        return []
    # Floor: followed along the clip (ops/floor: level where it is, the clip's lowest foot point; a trend where
    # the capture floor tilts or the root height drifts); y = 0 on it.
    feet = pos[:, list(skeleton.foot_joints), 1]
    lowest = feet.min(dim=1).values.double().numpy()
    model = fit_floor(lowest, root[:, [0, 2]].double().numpy(), cfg.target_fps, cfg.floor)
    rec.clips.append({"clip_id": clip_id, **model.report()})
    if model.residual_m > cfg.floor.tolerance_m:
        _unless_ingested(rec, f"floor not modelled: the stance samples lie {100 * model.residual_m:.1f} cm from "
                              f"the {model.kind} floor model (median; tolerance {100 * cfg.floor.tolerance_m:g} cm)")
        return []
    floor = torch.from_numpy(model.heights).to(pos.dtype)
    before = float(lowest.min())
    pos = pos.clone()
    pos[..., 1] -= floor[:, None] if model.kind == "trend" else float(model.heights[0])
    if model.kind == "trend":
        rec.floor_series.append((clip_id, (lowest - before).astype(np.float32),
                                 (model.heights - before).astype(np.float32), pos.to(torch.float32).numpy()))
    root = root.clone()
    root[:, 1] -= floor if model.kind == "trend" else float(model.heights[0])
    step = ground_speed(root)
    speed = float(step.mean()) * cfg.target_fps if step.numel() else 0.0
    if speed < cfg.min_gait_speed:
        _unless_ingested(rec, f"not a gait: mean horizontal root speed {speed:.2f} m/s < {cfg.min_gait_speed} m/s")
        return []
    starts = window_starts(root.shape[0], cfg.window, cfg.stride)
    label = item.label
    # stored as float32, converted once per clip (each window a copy of its slice)
    arrays = {"positions": pos.to(torch.float32).numpy(), "rotations": rot.to(torch.float32).numpy(),
              "root_path": root[:, [0, 2]].to(torch.float32).numpy(), "heading": heading.to(torch.float32).numpy()}
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
            **{name: values[s:e].copy() for name, values in arrays.items()},
        })
    raw_feet, feet = feet.numpy(), pos[..., list(skeleton.foot_joints), 1].numpy()
    rec.window_floor.extend((label.content, float(raw_feet[s:s + cfg.window].min()) - before,
                             float(feet[s:s + cfg.window].min())) for s in starts)
    rec.gaits += len(out)
    rec.status, rec.reason = "ingested", None
    return out


def _quarantine(rec: FileRecord, reason: str) -> None:
    rec.status, rec.reason = "quarantined", reason


def _filter(rec: FileRecord, reason: str) -> None:
    rec.status, rec.reason = "filtered", reason


def _unless_ingested(rec: FileRecord, reason: str) -> None:
    """Filter a file for one of its clips, unless another clip of it was ingested (the reason stays with that
    clip's entry)."""
    rec.clips[-1]["filtered"] = reason
    if rec.status != "ingested":
        _filter(rec, reason)


def run_ingest(manifests: Sequence[SourceManifest], skeleton: Skeleton, cfg: IngestConfig,
               scheduler_address: str | None = None, workers: int | None = None, progress: bool = True,
               floor_series: bool = False) -> tuple:
    """Ingest every input of every manifest. Returns (windows sorted by id, report), and with ``floor_series`` the
    trend clips' (clip id, lowest foot point per frame, floor, corrected positions) as a third element (for the
    report's plot)."""
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
    report = build_report(records, windows, cfg, manifests)
    return (windows, report, [f for r in records for f in r.floor_series]) if floor_series else (windows, report)


def build_report(records: Sequence[FileRecord], windows: Sequence[dict[str, Any]], cfg: IngestConfig,
                 manifests: Sequence[SourceManifest] = ()) -> dict:
    """Counts per status and source, every quarantined and filtered file with its reason, the floor and the
    discontinuities; for a source with a labels table (of ``manifests``), its ``labels_table`` entry."""
    by_status: dict[str, list[FileRecord]] = defaultdict(list)
    for r in records:
        by_status[r.status].append(r)
    unknown = set(by_status) - {"ingested", "quarantined", "filtered"}
    if unknown:  # a file fell through every branch: a bug, never silently dropped
        raise AssertionError(f"files with no outcome: {[r.path for s in unknown for r in by_status[s]]}")
    per_source: dict[str, dict[str, Any]] = {}
    counts = ("files_seen", "files_ingested", "files_quarantined", "files_filtered", "clips", "gaits", "frames_in")
    for r in records:
        s = per_source.setdefault(r.source, dict.fromkeys(counts, 0))
        s["files_seen"] += 1
        s[f"files_{r.status}"] += 1
        s["frames_in"] += r.frames_in
        s["gaits"] += r.gaits
        s["clips"] += r.status == "ingested"
    for m in manifests:
        if m.labels is not None:
            per_source.setdefault(m.name, dict.fromkeys(counts, 0))["labels_table"] = labels_table_report(
                m, [r for r in records if r.source == m.name])
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
        "floor": floor_report(records, cfg),
        "discontinuities": {
            "limit_mps": cfg.max_joint_speed,
            "count": sum(len(r.discontinuities) for r in records),
            "events": [{"source": r.source, "path": r.path, **d} for r in records for d in r.discontinuities]},
    }


def labels_table_report(manifest: SourceManifest, records: Sequence[FileRecord]) -> dict[str, Any]:
    """What a source's labels table covers of its inputs (``records``: one per input, pinned or found): the rows
    for no input or for a pinned file that is missing, and the inputs without a row (labelled by the label rule,
    or quarantined where the manifest has none)."""
    table = manifest.labels
    assert table is not None
    missing = {r.path for r in records if r.sha256 is None}  # pinned, but no file in the source folder
    unused, unrowed = table.coverage(r.path for r in records)
    rows_without_file = sorted(
        [{"line": line, "file": f, "why": "neither pinned nor found by the globs"} for line, f in unused]
        + [{"line": line, "file": f, "why": "pinned, but no file is in the source folder"}
           for f, (line, _) in table.rows.items() if f in missing], key=lambda e: e["line"])
    return {"path": table.path, "sha256": table.sha256, "rows": len(table.rows),
            "files_with_row": len(records) - len(unrowed), "rows_without_file": rows_without_file,
            "files_without_row": unrowed,
            "files_without_row_get": "the label rule's label" if manifest.doc.get("label_rule") is not None else
            "quarantined (no label rule)"}


def _heights_summary(metres: Sequence[float], tolerance_m: float) -> dict[str, Any]:
    v = np.asarray(metres, dtype=np.float64)
    if not len(v):
        return {"windows": 0}
    p1, p50, p99 = np.percentile(v, [1, 50, 99]) * 100
    return {"windows": len(v), "within_tolerance": round(float(np.mean(np.abs(v) <= tolerance_m)), 4),
            "p1_cm": round(float(p1), 2), "median_cm": round(float(p50), 2), "p99_cm": round(float(p99), 2)}


def floor_report(records: Sequence[FileRecord], cfg: IngestConfig) -> dict[str, Any]:
    """Per source: the lowest foot point of every walk window (it should be on the floor) with the clip's lowest
    foot point as the floor (before) and with the modelled floor (after), and the floor models; per clip: its
    model (level or trend, drift, tilt, residual)."""
    tolerance = cfg.floor.tolerance_m
    per_source: dict[str, Any] = {}
    for source in sorted({r.source for r in records}):
        mine = [r for r in records if r.source == source]
        walks = [w for r in mine for w in r.window_floor if w[0].startswith("walk")]
        kinds = [c["floor"] for r in mine for c in r.clips]
        per_source[source] = {
            "walk_windows_before": _heights_summary([w[1] for w in walks], tolerance),
            "walk_windows_after": _heights_summary([w[2] for w in walks], tolerance),
            "clips": {k: kinds.count(k) for k in ("level", "trend")},
            "clips_not_modelled": sum("floor not modelled" in c.get("filtered", "") for r in mine for c in r.clips),
            "largest_drift_cm": max((c["drift_cm"] for r in mine for c in r.clips), default=0.0)}
    walks = [w for r in records for w in r.window_floor if w[0].startswith("walk")]
    return {"tolerance_cm": round(100 * tolerance, 2), "level_cm": round(100 * cfg.floor.level_m, 2),
            "walk_windows_before": _heights_summary([w[1] for w in walks], tolerance),
            "walk_windows_after": _heights_summary([w[2] for w in walks], tolerance),
            "per_source": per_source,
            "clips": [{"source": r.source, "path": r.path, **c} for r in records for c in r.clips]}



def missing_data_message(manifests: Sequence[SourceManifest], mocap_root: Path, setting: str) -> str:
    """What to fetch, and from where, when the raw-data folder is absent (nothing is downloaded); setting: where
    the user points the pipeline at the folder."""
    lines = [f"The mocap root {mocap_root} does not exist. Point {setting} at a folder holding:"]
    for m in manifests:
        up = m.doc["upstream"]
        lines.append(f"  {m.name}/  {len(m.files)} files from {up['repository']} at commit {up['commit']} "
                     f"(paths as in the repository; each pinned by sha256 in manifests/sources/{m.name}.yaml)")
    return "\n".join(lines)
