"""Small loops in the published root paths: where a generated step hesitates, the placed root can curl round on
itself (a few cm) instead of moving on. No recogniser is involved; real walks are the reference.

Per gait, the root's ground step of each frame (root_path, 60 x 2) and its direction; a **loop** is the step
direction turning by more than 270 deg within ``--window`` seconds (real walks turn so in about 1 gait in 700, a
plan's sharpest corners are 135 deg), a **reversal** by more than 180 deg. Also the share of frames whose step
points against the local direction of travel (the displacement over the same window centred on the frame).
Groups: the real walks (content ``walk``, every split), each generator family, and each family per trajectory
family (the plan's shapes), so a shape that loops more shows.

``--rev REV`` reads the published directory of that commit's ``dvc.lock`` from the DVC cache too (e.g. the lock
before a retrain), so two checkpoints' gaits are compared in one run.

Printed as JSON and written to benchmarks/out/root_loops.json. Run from the repository root after ``dvc repro``:
``python benchmarks/root_loops.py [--rev a58f7b3]`` (seconds).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from pipeline.dataset import load_dataframe  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.publish.limitations import LOOP_DEG, REVERSAL_DEG, root_path_row  # noqa: E402
from stages.common import load_params  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "root_loops.json"
PUBLISHED = Path("data") / "published" / "synthesized_emotive_gaits"
COLUMNS = ["kind", "generator", "content", "trajectory_family", "root_path"]


def groups(directory: Path, frames: int) -> dict:
    frame = load_dataframe(directory, COLUMNS)
    paths = np.stack(frame["root_path"].to_list())
    real = (frame["kind"] == "real").to_numpy()
    out = {"real walks": root_path_row(paths[real & (frame["content"] == "walk").to_numpy()], frames)}
    for family in sorted(frame.loc[~real, "generator"].unique()):
        rows = (frame["generator"] == family).to_numpy()
        out[family] = root_path_row(paths[rows], frames)
        out[family]["by_trajectory_family"] = {
            shape: root_path_row(paths[rows & (frame["trajectory_family"] == shape).to_numpy()], frames)
            for shape in sorted(frame.loc[rows, "trajectory_family"].dropna().unique())}
    return out


def published_at(rev: str, into: Path) -> Path:
    """The published directory of ``rev``'s dvc.lock, linked file by file from the DVC cache into ``into``."""
    lock = yaml.safe_load(subprocess.run(["git", "show", f"{rev}:dvc.lock"], cwd=REPO, check=True,
                                         capture_output=True, text=True).stdout)
    md5 = next(out["md5"] for out in lock["stages"]["publish"]["outs"] if out["path"] == str(PUBLISHED))
    cache = REPO / ".dvc" / "cache" / "files" / "md5"
    listing = cache / md5[:2] / md5[2:]
    if not listing.is_file():
        raise FileNotFoundError(f"{rev}: the published directory {md5} is not in the DVC cache ({listing})")
    for entry in json.loads(listing.read_text()):
        link = into / entry["relpath"]
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(cache / entry["md5"][:2] / entry["md5"][2:])
    return into


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=0.5, help="seconds within which a turn counts")
    parser.add_argument("--rev", help="also the published gaits of this commit's dvc.lock (from the DVC cache)")
    args = parser.parse_args()
    frames = max(2, round(args.window * float(load_params()["ingest"]["target_fps"])))
    out = {"window_frames": frames, "loop_deg": LOOP_DEG, "reversal_deg": REVERSAL_DEG,
           "published": groups(REPO / PUBLISHED, frames)}
    if args.rev:
        with tempfile.TemporaryDirectory() as tmp:
            out[f"published at {args.rev}"] = groups(published_at(args.rev, Path(tmp)), frames)
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
