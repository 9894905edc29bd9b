"""Whether synthesis could seed from labelled gaits of other contents than forward walks: real data and the
generator only, no recogniser.

The synthesis seeds are labelled train-split forward walks (``synthesize.seed_content: walk``). The labelled train
gaits also hold backward walks (happy and sad only), walks to one side and turns. A gait continued from such a seed
keeps that content only if the generator and the placement keep the body's facing relative to its direction of
travel (about 180 degrees for a backward walk). Every labelled train gait of each walking content is generated on a
straight line under its own one-hot emotion (60 frames after its 18-frame prefix), placed two ways:
- ``published``: the synthesis placement (stance foot, root smoothing, path fit, foot locking);
- ``stance_foot``: the stance-foot placement alone (no smoothing, path fit or locking).
Reported per content: the median over gaits of the median |facing - direction of travel| (degrees; the direction
of travel as the generator reads it, ``geometry.path_direction``) and the median net speed (m/s), of the real
windows (frames 18-59) and of each placement; for the placements also how far the direction of travel points off
the straight path (laid along the seed's own direction of travel) over the first and the last ten frames.

Printed as JSON and written to benchmarks/out/seed_contents.json.
Run from the repository root after ``dvc repro``:  ``python benchmarks/seed_contents.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pipeline.core.emotions import EMOTIONS  # noqa: E402
from pipeline.evaluation.autoregressive import straight_path  # noqa: E402
from pipeline.generators.autoregressive.rollout import Seeds, generate, place_paths  # noqa: E402
from pipeline.generators.autoregressive.training import DIRECTION_FRAMES  # noqa: E402
from pipeline.io.files import write_json  # noqa: E402
from pipeline.ops.geometry import facing_off_travel, path_direction, travel_direction, wrap_angle  # noqa: E402
from stages.common import load_params  # noqa: E402
from stages.configs import placement_config  # noqa: E402

from generator_data import MODEL, generator, legs_placement, split_gaits  # noqa: E402

OUT = REPO / "benchmarks" / "out" / "seed_contents.json"
FRAMES = 60


def _degrees(angle: torch.Tensor) -> float:
    """Median over gaits of the median over frames of |angle| (N, T), in degrees."""
    return round(float(torch.rad2deg(angle.abs().median(dim=1).values).median()), 1)


def _facing_and_speed(positions: torch.Tensor, heading: torch.Tensor, fps: float,
                      path: torch.Tensor | None = None) -> dict:
    """positions (N, T, 21, 3), heading (N, T) -> median |facing - travel| (deg) and median net speed (m/s); with
    the placed straight paths (N, K, 2), also how far the direction of travel points off the path, over the first
    and the last ten frames."""
    root = positions[:, :, 0].double()
    travel = path_direction(root, heading.double(), DIRECTION_FRAMES)
    net = torch.linalg.vector_norm(root[:, -1, [0, 2]] - root[:, 0, [0, 2]], dim=-1) * fps / (root.shape[1] - 1)
    out = {"facing_vs_travel_deg": _degrees(facing_off_travel(root, heading.double(), DIRECTION_FRAMES)),
           "net_speed_m_s": round(float(net.median()), 3)}
    if path is not None:
        along = travel_direction(path.double(), 1)[:, None]
        off = wrap_angle(travel - along)
        out["travel_vs_path_deg_first_last_10_frames"] = [_degrees(off[:, :10]), _degrees(off[:, -10:])]
    return out


def contents_kept(model_path: Path = MODEL, verbose: bool = True) -> dict:
    """The figures of the module docstring for the generator checkpoint ``model_path``."""
    torch.set_num_threads(2)
    params = load_params()
    prefix = int(params["train"]["prefix"])
    arrays, split, content, dominant = split_gaits()
    model, sha, skeleton, offsets = generator(model_path)
    placements = {"published": placement_config(params), "stance_foot": legs_placement(params)}
    fps = placements["published"].fps
    out = {"checkpoint_sha256": sha, "frames": FRAMES, "by_content": {}}
    labelled_train = (split == "train") & (dominant >= 0)
    for name in sorted(c for c in set(content[labelled_train]) if c.startswith("walk")):
        rows = np.flatnonzero(labelled_train & (content == name))
        seeds = Seeds.from_arrays(arrays, rows, prefix)
        paths = place_paths(straight_path(), seeds)
        condition = torch.nn.functional.one_hot(torch.from_numpy(dominant[rows]), len(EMOTIONS)).float()
        condition = condition[:, None].expand(-1, FRAMES, -1)
        entry = {"seeds": int(len(rows)),
                 "seeds_per_emotion": {e: int((dominant[rows] == k).sum()) for k, e in enumerate(EMOTIONS)},
                 "real_window": _facing_and_speed(torch.from_numpy(arrays["positions"][rows, prefix:]),
                                                  torch.from_numpy(arrays["heading"][rows, prefix:]), fps)}
        for placement_name, placement in placements.items():
            with torch.no_grad():
                g = generate(model, seeds, paths, condition, offsets, skeleton.parents, placement)
            entry[placement_name] = _facing_and_speed(g.positions, g.heading, fps, paths)
        out["by_content"][name] = entry
        if verbose:
            print(f"{name}: {json.dumps(entry)}", flush=True)
    return out


def main() -> dict:
    out = contents_kept()
    write_json(out, OUT)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
