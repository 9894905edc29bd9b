"""Ingest throughput benchmark: our full ingest, per core, against the `bvh` PyPI package's channel extraction.

What it measures, in one run:

1. ``ours``: ``pipeline.ingest.run.ingest_chunk`` run serially in this one process over every chunk of every
   source manifest (``plan_chunks``; the default data is 361 BVH files, ~78k source frames). That is the
   whole per-file ingest: read bytes, sha256, BVH parse, forward kinematics, retarget, bone rotations,
   resampling and gait windows. ``ingest_chunk`` pins torch to one thread, so this is the rate of one core.
   One untimed warm-up over two chunks, then ``--repeats`` timed full passes; the median is reported as
   source frames (sum of the records' ``frames_in``) per second, in total and per source.
2. ``bvh_package``: the `bvh` package (PyPI ``bvh``) on a fixed sample of the same files (``SAMPLE`` below:
   the first 3 Bandai ``dataset-1_walk_*`` files by sorted path plus CMU ``cmu_bvh11/resources/131_01.bvh``,
   1,428 frames). Timed: ``Bvh(text)`` plus, for every joint, ``joint_channels(name)`` and
   ``frames_joint_channels(name, channels)``, i.e. every channel of every frame as floats, which is what our
   reader produces. Reading the file into a string is not timed (a favour to the package; ours is timed
   reading bytes). The values it returns are checked against our ``read_bvh(path).motion`` (to 1e-9) for
   every sample file, so the two sides extract the same numbers (``values_match``).
3. ``ours_on_bvh_sample``: our full ``ingest_chunk`` on exactly that sample (entries with the manifests'
   pinned sha256), so ``ratio_same_files`` compares identical inputs; ``ratio_full_vs_bvh`` uses the full
   pass. The acceptance target is a ratio of at least ``TARGET_RATIO``; ``meets_target`` is true only when
   both ratios reach it and ``values_match`` holds.

Parameters (target_fps, window, stride, min_gait_speed, chunk_frames, the mocap root) come from
``params.yaml``, as for the pipeline. The JSON result is printed and written to ``benchmarks/out/ingest.json``.

Run from the repository root:  ``make bench``  or  ``python benchmarks/ingest.py [--repeats N] [--quick]``
(``--quick``: a few chunks, one repeat and a one-file bvh sample, for smoke testing; written to
``benchmarks/out/ingest-quick.json`` instead).
"""

from __future__ import annotations

import argparse
import fnmatch
import gc
import json
import os
import platform
import statistics
import sys
import time
from collections import Counter, defaultdict
from importlib import metadata
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.ingest.run import IngestConfig, ingest_chunk, missing_data_message, plan_chunks  # noqa: E402
from pipeline.io.files import sha256_bytes, write_json  # noqa: E402
from pipeline.io.readers.bvh import read_bvh  # noqa: E402
from pipeline.core.skeleton import load_skeleton  # noqa: E402
from pipeline.io.manifests import SourceManifest, load_manifests  # noqa: E402
from stages.common import PARAMS, SKELETON, SOURCES, load_params  # noqa: E402
from stages.configs import ingest_config  # noqa: E402

TARGET_RATIO = 300
OUT_DIR = REPO / "benchmarks" / "out"
# The bvh-package sample: (source, file-name pattern, how many of the manifest's pinned files, by sorted path).
# Bandai is 94 % of the default frames; CMU adds a 120 fps, 31-joint rig. ~2,300 frames, ~17 s for the package.
SAMPLE = (
    ("bandai_namco_motiondataset", "dataset-1_walk_*.bvh", 9),
    ("cmu_bvh11", "131_01.bvh", 1),
)
QUICK_SAMPLE = (("bandai_namco_motiondataset", "dataset-1_walk_*.bvh", 1),)
QUICK_CHUNKS = 3
SAMPLE_MIN_REPEATS = 5  # the sample pass is short (tens of ms); take more repeats for a stable median
VALUE_TOL = 1e-9


def timed_pass(chunks: list, skeleton, cfg: IngestConfig) -> tuple[float, dict[str, float], list]:
    """One serial pass of ingest_chunk over ``chunks``: (wall seconds, seconds per source, records)."""
    gc.collect()
    per_source: dict[str, float] = defaultdict(float)
    records = []
    start = time.perf_counter()
    for manifest, entries in chunks:
        t0 = time.perf_counter()
        result = ingest_chunk(manifest, skeleton, entries, cfg)
        per_source[manifest.name] += time.perf_counter() - t0
        records.extend(result.records)  # windows are dropped: only the work counts, not keeping it
    return time.perf_counter() - start, dict(per_source), records


def bench_ours(chunks: list, skeleton, cfg: IngestConfig, repeats: int) -> dict:
    for manifest, entries in (chunks[:1] + chunks[-1:]) if len(chunks) > 1 else chunks:  # warm-up
        ingest_chunk(manifest, skeleton, entries, cfg)
    walls, source_secs, records = [], defaultdict(list), []
    for _ in range(repeats):
        wall, per_source, records = timed_pass(chunks, skeleton, cfg)
        walls.append(wall)
        for name, secs in per_source.items():
            source_secs[name].append(secs)
    frames = sum(r.frames_in for r in records)
    source_frames = Counter()
    source_files = Counter()
    for r in records:
        source_frames[r.source] += r.frames_in
        source_files[r.source] += 1
    median = statistics.median(walls)
    per_source = {}
    for name in sorted(source_secs):
        secs = statistics.median(source_secs[name])
        per_source[name] = {"files": source_files[name], "source_frames": source_frames[name],
                            "seconds_median": round(secs, 4),
                            "frames_per_s_per_core": round(source_frames[name] / secs, 1)}
    return {
        "files": len(records),
        "chunks": len(chunks),
        "statuses": dict(sorted(Counter(r.status for r in records).items())),
        "source_frames": frames,
        "repeats": repeats,
        "seconds_all": [round(w, 4) for w in walls],
        "seconds_median": round(median, 4),
        "frames_per_s_per_core": round(frames / median, 1),
        "per_source": per_source,
    }


def read_parse_breakdown(chunks: list, cfg: IngestConfig) -> dict:
    """One untimed-by-the-above pass of read + sha256 + read_bvh only, to show its share of the full ingest."""
    gc.collect()
    frames = 0
    start = time.perf_counter()
    for manifest, entries in chunks:
        for rel, _ in entries:
            path = cfg.mocap_root / manifest.name / rel
            if path.is_file():
                data = path.read_bytes()
                sha256_bytes(data)  # the screen's pin check
                frames += read_bvh(path, data).frames
    secs = time.perf_counter() - start
    return {"what": "read bytes + sha256 + read_bvh only (one pass, same files)", "source_frames": frames,
            "seconds": round(secs, 4), "frames_per_s": round(frames / secs, 1)}


def sample_entries(manifests: list[SourceManifest], spec: tuple) -> list[tuple[SourceManifest, str, str]]:
    """(manifest, relative path, pinned sha256) for the sample, taken from the manifests' pinned files."""
    by_name = {m.name: m for m in manifests}
    out = []
    for source, pattern, count in spec:
        if source not in by_name:
            sys.exit(f"benchmark sample: no manifest named {source!r} under {SOURCES}")
        manifest = by_name[source]
        picked = sorted((f for f in manifest.files if fnmatch.fnmatch(Path(f.path).name, pattern)),
                        key=lambda f: f.path)[:count]
        if len(picked) < count:
            sys.exit(f"benchmark sample: manifest {source!r} pins {len(picked)} files matching {pattern!r}, "
                     f"need {count}")
        out.extend((manifest, f.path, f.sha256) for f in picked)
    return out


def bvh_package_extract(text: str):
    """What is timed for the `bvh` package: parse, then every channel of every frame of every joint."""
    from bvh import Bvh

    mocap = Bvh(text)
    joints = {}
    for name in mocap.get_joints_names():
        channels = mocap.joint_channels(name)
        joints[name] = (tuple(channels), mocap.frames_joint_channels(name, channels))
    return joints


def values_match(path: Path, joints: dict) -> tuple[bool, float]:
    """Whether the `bvh` package's per-joint values equal our reader's motion columns (max abs difference)."""
    clip = read_bvh(path)
    skel = clip.skeleton
    ours = {n: c for n, c, end in zip(skel.names, skel.channels, skel.is_end_site) if not end}
    if set(ours) != set(joints):
        return False, float("inf")
    col = 0
    worst = 0.0
    for name, channels in zip(skel.names, skel.channels):
        if not channels:
            continue
        theirs_channels, theirs = joints[name]
        if theirs_channels != channels:
            return False, float("inf")
        theirs_arr = np.asarray(theirs, dtype=np.float64).reshape(clip.frames, len(channels))
        worst = max(worst, float(np.abs(theirs_arr - clip.motion[:, col:col + len(channels)]).max()))
        col += len(channels)
    return worst <= VALUE_TOL, worst


def bench_bvh_package(sample: list, cfg: IngestConfig) -> dict:
    files, frames, seconds, match, worst = [], 0, 0.0, True, 0.0
    for manifest, rel, _ in sample:
        path = cfg.mocap_root / manifest.name / rel
        text = path.read_text()  # not timed
        gc.collect()
        t0 = time.perf_counter()
        joints = bvh_package_extract(text)
        secs = time.perf_counter() - t0
        n = len(next(iter(joints.values()))[1])
        ok, diff = values_match(path, joints)
        match, worst = match and ok, max(worst, diff)
        files.append({"path": f"{manifest.name}/{rel}", "frames": n, "seconds": round(secs, 4)})
        frames += n
        seconds += secs
    return {
        "package": f"bvh {metadata.version('bvh')}",
        "timed": "Bvh(text) + joint_channels(name) + frames_joint_channels(name, channels) for every joint; "
                 "file read not timed",
        "files": files,
        "source_frames": frames,
        "seconds": round(seconds, 4),
        "frames_per_s": round(frames / seconds, 1),
        "values_match": match,
        "values_max_abs_diff": worst,
    }


def bench_ours_on_sample(sample: list, skeleton, cfg: IngestConfig, repeats: int) -> dict:
    chunks: dict[str, tuple[SourceManifest, list]] = {}
    for manifest, rel, pinned in sample:
        chunks.setdefault(manifest.name, (manifest, []))[1].append((rel, pinned))
    chunk_list = list(chunks.values())
    for manifest, entries in chunk_list:  # warm-up
        ingest_chunk(manifest, skeleton, entries, cfg)
    walls, records = [], []
    for _ in range(repeats):
        wall, _, records = timed_pass(chunk_list, skeleton, cfg)
        walls.append(wall)
    frames = sum(r.frames_in for r in records)
    median = statistics.median(walls)
    return {
        "files": len(records),
        "statuses": dict(sorted(Counter(r.status for r in records).items())),
        "source_frames": frames,
        "repeats": repeats,
        "seconds_median": round(median, 5),
        "frames_per_s_per_core": round(frames / median, 1),
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="timed full passes (median reported; default 3)")
    parser.add_argument("--quick", action="store_true",
                        help=f"smoke test: first {QUICK_CHUNKS} chunks, 1 repeat, a one-file bvh sample")
    parser.add_argument("--out", type=Path, help="JSON output (default benchmarks/out/ingest.json, "
                                                 "ingest-quick.json with --quick)")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else max(1, args.repeats)

    params = load_params(PARAMS)
    cfg = ingest_config(params)
    manifests = load_manifests(SOURCES, formats=("bvh",))  # the bvh package reads BVH only
    if not cfg.mocap_root.is_dir():
        sys.exit(missing_data_message(manifests, cfg.mocap_root, "params.yaml data.mocap_root"))
    skeleton = load_skeleton(SKELETON)
    chunks = plan_chunks(manifests, cfg)
    if args.quick:
        chunks = chunks[:QUICK_CHUNKS]
    sample = sample_entries(manifests, QUICK_SAMPLE if args.quick else SAMPLE)

    ours = bench_ours(chunks, skeleton, cfg, repeats)
    ours["breakdown"] = read_parse_breakdown(chunks, cfg)
    package = bench_bvh_package(sample, cfg)
    ours_sample = bench_ours_on_sample(sample, skeleton, cfg, max(repeats, SAMPLE_MIN_REPEATS))

    ratio_full = ours["frames_per_s_per_core"] / package["frames_per_s"]
    ratio_same = ours_sample["frames_per_s_per_core"] / package["frames_per_s"]
    result = {
        "benchmark": "ingest",
        "quick": args.quick,
        "machine": {
            "cores": os.cpu_count(),
            "cores_usable": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
            "cpu": platform.processor() or platform.machine(),
            "python": platform.python_version(),
            "torch": torch.__version__,
            "torch_threads": torch.get_num_threads(),
            "numpy": np.__version__,
            "pyarrow": metadata.version("pyarrow"),
        },
        "config": {"mocap_root": str(cfg.mocap_root), "target_fps": cfg.target_fps, "window": cfg.window,
                   "stride": cfg.stride, "min_gait_speed": cfg.min_gait_speed, "chunk_frames": cfg.chunk_frames},
        "ours": ours,
        "bvh_package": package,
        "ours_on_bvh_sample": ours_sample,
        "ratio_full_vs_bvh": round(ratio_full, 1),
        "ratio_same_files": round(ratio_same, 1),
        "target_ratio": TARGET_RATIO,
        "meets_target": bool(package["values_match"] and min(ratio_full, ratio_same) >= TARGET_RATIO),
    }
    out = args.out or OUT_DIR / ("ingest-quick.json" if args.quick else "ingest.json")
    write_json(result, out, sort_keys=False)
    print(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
