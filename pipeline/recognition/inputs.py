"""What an emotion recogniser reads of a gait, and the pose normalisation the temporal recogniser and the audit's
memorisation check share.

A recogniser reads any number of frames T >= ``MIN_FRAMES`` (a 60-frame window, a 20-frame block of one). This
module knows arrays and the gait table's columns, not files.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch

from pipeline.ops.quaternion import qrot, yaw

MIN_FRAMES = 10
COLUMNS = ("positions", "heading", "affective", "movement")


def heading_frame_poses(positions: torch.Tensor, heading: torch.Tensor) -> torch.Tensor:
    """Root-relative poses in each frame's heading frame: positions (..., T, J, 3) minus the root (joint 0), turned
    about +Y by minus the frame's heading (..., T) (``ops.geometry.heading_angle``: 0 faces +Z, yaw(h) turns +Z
    to the heading), so the body faces +Z in every frame. -> (..., T, J, 3)."""
    relative = positions - positions[..., :1, :]
    turn = yaw(-heading)[..., None, :].expand(*relative.shape[:-1], 4)
    return qrot(turn, relative)


def heading_frame_root_motion(positions: torch.Tensor, heading: torch.Tensor) -> torch.Tensor:
    """The root's displacement from each frame to the next in that frame's heading frame (..., T, 3): z ahead,
    y up (m per frame); the last frame repeats the one before it, so the length stays T."""
    root = positions[..., 0, :]
    step = root[..., 1:, :] - root[..., :-1, :]
    step = torch.cat([step, step[..., -1:, :]], dim=-2)
    return qrot(yaw(-heading), step)


@dataclass(frozen=True)
class RecognitionInputs:
    """Per gait, any number of frames T >= 10 (N gaits):

    positions (N, T, 21, 3) world joint positions in m (canonical skeleton, root = joint 0); heading (N, T) rad
    (the gait table's ``heading``); affective (N, T, 18); movement (N, T, 5) in the gait table's movement order.
    """

    positions: np.ndarray
    heading: np.ndarray
    affective: np.ndarray
    movement: np.ndarray

    def __post_init__(self) -> None:
        n, t = self.heading.shape[:2] if self.heading.ndim == 2 else (None, None)
        expected = {"positions": (n, t, 21, 3), "heading": (n, t), "affective": (n, t, 18), "movement": (n, t, 5)}
        for name, shape in expected.items():
            found = getattr(self, name).shape
            if n is None or found != shape:
                raise ValueError(f"RecognitionInputs.{name}: expected shape (N, T{', ' if len(shape) > 2 else ''}"
                                 f"{', '.join(map(str, shape[2:]))}) with N, T of heading (N, T), found "
                                 f"{tuple(found)} (heading {tuple(self.heading.shape)})")

    def __len__(self) -> int:
        return int(self.heading.shape[0])

    @property
    def frames(self) -> int:
        return int(self.heading.shape[1])

    def finite(self) -> np.ndarray:
        """(N,) whether every value of a gait is finite (a recogniser given a NaN reads NaN: leave such gaits out)."""
        return np.stack([np.isfinite(getattr(self, c)).reshape(len(self), -1).all(1) for c in COLUMNS]).all(0)

    def select(self, rows) -> "RecognitionInputs":
        """The gaits at ``rows`` (a boolean mask or indices)."""
        return RecognitionInputs(self.positions[rows], self.heading[rows], self.affective[rows], self.movement[rows])

    def block(self, start: int, stop: int) -> "RecognitionInputs":
        """Frames [start, stop) of every gait."""
        if not 0 <= start < stop <= self.frames:
            raise ValueError(f"RecognitionInputs.block: expected 0 <= start < stop <= {self.frames}, "
                             f"found [{start}, {stop})")
        s = slice(start, stop)
        return RecognitionInputs(self.positions[:, s], self.heading[:, s], self.affective[:, s], self.movement[:, s])

    @classmethod
    def concatenate(cls, parts: Sequence["RecognitionInputs"]) -> "RecognitionInputs":
        return cls(*(np.concatenate([getattr(p, c) for p in parts]) for c in COLUMNS))

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], rows=slice(None)) -> "RecognitionInputs":
        """From per-gait arrays by column name (the gait table's ``read_gaits``, a synthesis' output), the gaits
        at ``rows``."""
        return cls(*(np.ascontiguousarray(arrays[c][rows], dtype=np.float32) for c in COLUMNS))

    @classmethod
    def from_frame(cls, frame: pd.DataFrame) -> "RecognitionInputs":
        """From ``pipeline.dataset.load_dataframe`` columns positions, heading, affective and movement."""
        missing = [c for c in COLUMNS if c not in frame]
        if missing:
            raise KeyError(f"RecognitionInputs.from_frame: expected columns {', '.join(COLUMNS)}, "
                           f"missing {', '.join(missing)}")
        arrays = {}
        for c in COLUMNS:
            cells = frame[c].to_numpy()
            empty = [str(frame.index[i]) for i, v in enumerate(cells) if v is None]
            if empty:
                raise ValueError(f"RecognitionInputs.from_frame: column {c} has no value in rows {', '.join(empty[:5])}")
            arrays[c] = np.stack(cells).astype(np.float32) if len(cells) else np.zeros((0, 0), np.float32)
        return cls(**arrays)


def pose_channels(inputs: RecognitionInputs) -> torch.Tensor:
    """The temporal recogniser's per-frame input (N, T, 66): the root-relative heading-frame pose (63) and the
    root's motion in the heading frame (3)."""
    positions = torch.from_numpy(np.ascontiguousarray(inputs.positions, dtype=np.float32))
    heading = torch.from_numpy(np.ascontiguousarray(inputs.heading, dtype=np.float32))
    pose = heading_frame_poses(positions, heading).flatten(-2)
    return torch.cat([pose, heading_frame_root_motion(positions, heading)], dim=-1)
