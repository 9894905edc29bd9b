"""The one table of gait columns: name, type, per-gait shape, unit and meaning.

The ingested/annotated gait table (``pipeline.io.gait_table``), the published table (``pipeline.publish.table``),
the dataset card, Croissant and HDF5 all take their columns from here, so a column is described once. Shapes are
per gait, with ``T`` for frames and ``J`` for joints; an array column is stored as a fixed-size list of float32,
row-major. A unit given here is written into the table's metadata (and from there into Croissant and HDF5).
"""

from __future__ import annotations

from dataclasses import dataclass

import pyarrow as pa

from pipeline.core.emotions import EMOTIONS

ARROW_TYPES = {"string": pa.string(), "float64": pa.float64(), "int64": pa.int64()}


@dataclass(frozen=True)
class Column:
    name: str
    dtype: str  # "string", "float64", "int64" (scalars) or "float32" (arrays, with a shape)
    description: str
    shape: tuple[str | int, ...] = ()  # per gait; () for a scalar
    unit: str | None = None

    @property
    def is_array(self) -> bool:
        return bool(self.shape)

    @property
    def arrow_type(self) -> pa.DataType:
        return ARROW_TYPES[self.dtype]

    def gait_shape(self, frames: int, joints: int) -> tuple[int, ...]:
        return tuple(frames if d == "T" else joints if d == "J" else int(d) for d in self.shape)


COLUMNS = {c.name: c for c in (
    Column("gait_id", "string", "unique id; real: <source clip>#w<window>, synthetic: syn-<trajectory>-<index>"),
    Column("clip_id", "string", "the source clip the window was cut from: <source>/<file>"),
    Column("kind", "string", "real (annotated motion capture) or synthetic (generated)"),
    Column("split", "string", "train/val/test for real gaits (by clip; the generator saw train only); synthetic"),
    Column("source", "string", "mocap source (manifests/sources) or 'generator'"),
    Column("file", "string", "mocap file path under the source root"),
    Column("sha256", "string", "sha256 of the mocap file"),
    Column("t_start", "float64", "real gaits: window start in the source clip, seconds", unit="s"),
    Column("t_end", "float64", "real gaits: window end in the source clip, seconds", unit="s"),
    Column("source_fps", "float64", "frame rate of the source clip, frames per second"),
    Column("fps", "float64", "frame rate of the gait after resampling, frames per second"),
    Column("scale", "float64", "canonical leg length / the source's leg length (retargeting scale)"),
    Column("source_leg_m", "float64", "the source skeleton's leg length, metres"),
    Column("content", "string", "what the clip shows (walk, walk-turn-left, run, ...); synthetic gaits walk"),
    Column("style", "string", "the source's style or emotion word for the clip"),
    Column("label_method", "string", "how the emotion label was obtained (actor_intended, style_mapping, "
                                     "generator_condition; null: unlabelled)"),
    Column("emotion", "float32", "label, weights over emotion_order summing to 1; synthetic: the mean per-frame "
                                 "condition", (len(EMOTIONS),)),
    Column("emotion_per_frame", "float32", "per-frame emotion weights (transitions interpolate; real: the label "
                                           "repeated)", ("T", len(EMOTIONS)), "simplex weights, emotion_order"),
    Column("positions", "float32", "world joint positions, metres (frames x 21 joints x xyz)", ("T", "J", 3), "m"),
    Column("rotations", "float32", "local joint rotations, unit quaternions w,x,y,z (frames x 21 x 4)", ("T", "J", 4)),
    Column("root_path", "float32", "pelvis ground position x,z per frame, metres", ("T", 2), "m"),
    Column("heading", "float32", "body heading about +Y per frame, radians (0 = facing +Z)", ("T",), "rad"),
    Column("contacts", "float32", "foot contact flags per frame: left heel, left toe, right heel, right toe",
           ("T", 4), "0/1"),
    Column("phase", "float32", "stepping phase per frame, radians [0, 2pi): 0 at left strike, pi at right strike",
           ("T",), "rad [0, 2π), 0 at left strike, π at right strike"),
    Column("phase_rate", "float32", "phase change per frame, radians", ("T",), "rad per frame"),
    Column("affective", "float32", "the 18 pose affective features per frame (angles, distance ratios, area "
                                   "ratios)", ("T", 18), "rad or ratio (scale-free)"),
    Column("movement", "float32", "movement features per frame: root height, root speed, low-passed speed, "
                                  "heading-to-path angle, path curvature", ("T", 5), "m, m/frame, m/frame, rad, m/frame"),
    Column("source_file", "string", "real gaits: mocap file path under the source root"),
    Column("source_sha256", "string", "real gaits: sha256 of the mocap file"),
    Column("generator", "string", "synthetic gaits: the generator family that made the gait "
                                  "(autoregressive_affect, pca_gaussian, ...; the metadata's 'generators' describes "
                                  "each); real gaits: null"),
    Column("checkpoint_sha256", "string", "synthetic gaits: sha256 of the generator family's model file"),
    Column("seed_gait_id", "string", "synthetic gaits of a seeded family: the real train-split gait whose first "
                                     "frames seeded the generator (not published as synthetic frames); null for a "
                                     "family that needs no seed"),
    Column("trajectory_id", "string", "synthetic gaits: planned trajectory"),
    Column("trajectory_family", "string", "synthetic gaits: trajectory family"),
    Column("emotion_recipe", "string", "synthetic gaits: JSON recipe (single emotion or transition from/to, with "
                                       "vectors)"),
    Column("plan_seed", "int64", "synthetic gaits: the plan row's random seed (draws its seed gait)"),
    Column("source_segments", "string", "synthetic gaits of a family that re-sequences real motion (motion_graph): "
                                        "JSON list of [clip_id, first frame, last frame] (frames of the rebuilt "
                                        "real clip at the gaits' rate), in the order the gait plays them; null "
                                        "for other families"),
)}

# The tables, column order as stored.
INGESTED = ("gait_id", "clip_id", "source", "file", "sha256", "t_start", "t_end", "source_fps", "fps", "scale",
            "source_leg_m", "content", "style", "label_method", "emotion", "positions", "rotations", "root_path",
            "heading")
ANNOTATIONS = ("contacts", "phase", "phase_rate", "affective", "movement")  # added by annotate
PUBLISHED = ("gait_id", "kind", "generator", "split", "source", "content", "label_method", "emotion", "emotion_per_frame",
             "positions", "rotations", "root_path", "heading", *ANNOTATIONS, "source_file", "source_sha256",
             "t_start", "t_end", "checkpoint_sha256", "seed_gait_id", "trajectory_id", "trajectory_family",
             "emotion_recipe", "plan_seed", "source_segments")


def columns(names: tuple[str, ...]) -> list[Column]:
    return [COLUMNS[n] for n in names]


def units(names: tuple[str, ...]) -> dict[str, str]:
    """{column: unit} of the named columns that have one (as written into a table's metadata)."""
    return {c.name: c.unit for c in columns(names) if c.unit is not None}


def descriptions(names: tuple[str, ...]) -> dict[str, str]:
    return {c.name: c.description for c in columns(names)}
