"""C3D reader: a motion-capture file in, labelled marker trajectories and annotated gait events out.

The header and parameter section are parsed by py-c3d (the ``c3d`` package on PyPI): pure Python, so a
malformed file raises an exception instead of taking the process down. (ezc3d, the other maintained reader,
crashed with a segmentation fault or hung on about one in ten randomly corrupted parameter sections in our
trials, and silently misaligned every frame of ``sample_11/evart.c3d``, whose header and ANALOG:RATE disagree.)
Around the library this module checks what neither library checks: that the file really holds the frames
the header promises (both readers silently return fewer frames from a truncated file).

What comes out is the file's content, made unambiguous:
  * labels with the subject prefix removed (``A22:LTOE`` -> ``LTOE``, by SUBJECTS:LABEL_PREFIXES or a
    ``Name:`` prefix) and duplicated labels resolved (an empty duplicate is dropped; several non-empty
    occurrences with different data make the label ambiguous, and it is dropped with a note);
  * a validity mask: a sample is invalid when its residual word is negative (the C3D convention), when a
    coordinate is not finite, or when it is exactly (0, 0, 0) - several writers (Vicon Nexus, Qualisys)
    store gaps that way without flagging them;
  * gait events from the EVENT group, normalised to ``foot_strike`` / ``foot_off`` with side ``left`` /
    ``right``, whether the file writes them as "Foot Strike" + context "Left" or as context "LHS", "RTO".

Files whose residual word is written outside the C3D specification (``sample_30/marche281.c3d``: the
float-format 4th word must hold an integer in [-32768, 32767]; this writer stored the bit pattern
0x7F007F00, which as a float is 1.7e38 and casts to a negative integer, so py-c3d flags every sample
invalid) are decoded as the writer evidently meant them: two 16-bit words, camera mask 0x7F and residual 0,
i.e. valid. The coordinates of that file are continuous and inside the capture volume, so they are
trusted; the clip records the decision in ``notes``. A file whose residual words are well-formed and all
negative is genuinely empty and raises C3dError.

A reader knows files, not features: units and axes stay as in the file (see ``positions_m_y_up``), and no
marker is mapped to a joint here.
"""

from __future__ import annotations

import io
import re
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from pipeline.io.manifests import AXES_TO_Y_UP
from pipeline.ops.geometry import to_y_up

UNIT_SCALE_M = {"mm": 0.001, "cm": 0.01, "m": 1.0}
MIN_RATE, MAX_RATE = 1.0, 10000.0  # frames per second; outside, no capture (and 0, NaN or Inf break every time)
_PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}
_EVENT_CODES = {"HS": "foot_strike", "FS": "foot_strike", "IC": "foot_strike",
                "TO": "foot_off", "FO": "foot_off"}
_EVENT_LABELS = {"foot strike": "foot_strike", "heel strike": "foot_strike", "initial contact": "foot_strike",
                 "foot off": "foot_off", "toe off": "foot_off"}


class C3dError(ValueError):
    """A malformed or unusable C3D file. ``str(err)`` names the file, what was expected and what was found."""

    def __init__(self, path: str, expected: str, found: str):
        self.path, self.expected, self.found = path, expected, found
        super().__init__(f"{path}: expected {_clip(expected)}, found {_clip(found)}")


def _clip(text: str, limit: int = 300) -> str:
    """Text for a message: a parser complaint quoting a whole damaged parameter is named by its start."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


@dataclass(frozen=True)
class C3dEvent:
    kind: str  # "foot_strike" | "foot_off"
    side: str  # "left" | "right"
    time: float  # seconds on the file's clock (sample i is at start_time + i / rate)
    label: str  # as written in the file (EVENT:LABELS / EVENT:CONTEXTS)


@dataclass(frozen=True)
class C3dClip:
    path: str
    labels: tuple[str, ...]  # resolved marker labels (prefix removed, unique)
    raw_labels: tuple[str, ...]  # the file's label of each kept column
    positions: np.ndarray = field(repr=False)  # (F, M, 3) float64, file units and axes; NaN where invalid
    residuals: np.ndarray = field(repr=False)  # (F, M) float64, file units; -1 where the file flags invalid
    valid: np.ndarray = field(repr=False)  # (F, M) bool
    rate: float  # point frames per second
    units: str  # POINT:UNITS as written
    unit_scale_m: float  # metres per file unit
    first_frame: int  # 1-based frame number of row 0 (header)
    events: tuple[C3dEvent, ...]
    subjects: tuple[str, ...]
    zero_samples: dict[str, int]  # per marker: (0, 0, 0) samples not flagged invalid by the file
    notes: tuple[str, ...]  # decisions taken while reading (duplicates, residual encoding, ignored events)

    @property
    def frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def start_time(self) -> float:
        return (self.first_frame - 1) / self.rate

    def index(self, label: str) -> int:
        return self.labels.index(label)

    def times(self) -> np.ndarray:
        """Time (s) of every frame on the file's clock (the clock EVENT:TIMES uses)."""
        return self.start_time + np.arange(self.frames) / self.rate


def positions_m_y_up(positions: np.ndarray, unit_scale_m: float, up_axis: str) -> np.ndarray:
    """File-unit positions (..., 3) in the file's axes -> metres, Y up (pipeline.io.manifests.AXES_TO_Y_UP)."""
    if up_axis not in AXES_TO_Y_UP:
        raise ValueError(f"unknown up axis {up_axis!r}; known: {sorted(AXES_TO_Y_UP)}")
    metres = torch.from_numpy(np.asarray(positions, dtype=np.float64) * unit_scale_m)
    return to_y_up(metres, AXES_TO_Y_UP[up_axis]).numpy()


def read_c3d(path: str | Path, data: bytes | None = None) -> C3dClip:
    """Read a C3D file (or its already-loaded bytes). Raises C3dError on malformed or empty input."""
    import c3d as pyc3d  # imported here: only C3D sources need it

    path = str(path)
    if data is None:
        data = Path(path).read_bytes()
    _check_header(path, data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # py-c3d warns about missing optional parameters; we check what matters
        try:
            reader = pyc3d.Reader(io.BytesIO(data))
        except Exception as err:  # noqa: BLE001 - any failure of the parser is a malformed file
            raise C3dError(path, *_diagnose(err)) from None
        layout = _check_data_block(path, data, reader)
        try:
            frames = [points for _, points, _ in reader.read_frames(copy=True)]
        except Exception as err:  # noqa: BLE001
            raise C3dError(path, "readable POINT frames", f"{type(err).__name__}: {err}") from None
    if len(frames) != layout["frames"]:
        raise C3dError(path, f"{layout['frames']} POINT frames (header frames {reader.first_frame}-"
                             f"{reader.last_frame})", f"{len(frames)} frames in the data section")
    raw = np.stack(frames).astype(np.float64)  # (F, P, 5): x, y, z, residual, camera mask
    notes: list[str] = []
    residual = raw[..., 3]
    coords = raw[..., :3]
    present = np.isfinite(coords).all(-1) & (np.abs(coords).sum(-1) > 0)
    if bool((residual < 0).all()) and bool(present.any()):
        decoded = _residual_words(path, data, reader, layout)
        if decoded is None:
            raise C3dError(path, "at least one valid POINT sample (residual >= 0)",
                           f"every residual negative in all {raw.shape[1]} points x {raw.shape[0]} frames")
        residual, note = decoded
        notes.append(note)
    units = _string(reader, "POINT:UNITS", "mm").strip()
    if units.lower() not in UNIT_SCALE_M:
        raise C3dError(path, f"POINT:UNITS one of {sorted(UNIT_SCALE_M)}", repr(units))
    raw_labels = _point_labels(reader, raw.shape[1])
    prefixes = _subject_prefixes(reader)
    resolved = [_strip_prefix(lab, prefixes) for lab in raw_labels]
    finite = np.isfinite(coords).all(-1)
    zero = finite & (coords == 0.0).all(-1) & (residual >= 0)
    valid = finite & (residual >= 0) & ~zero
    keep, dup_notes = _resolve_duplicates(resolved, coords, valid)
    notes.extend(dup_notes)
    if not bool(valid[:, keep].any()):
        raise C3dError(path, "at least one valid POINT sample", f"no valid sample in {len(keep)} points x "
                                                                 f"{raw.shape[0]} frames")
    positions = np.where(valid[..., None], coords, np.nan)[:, keep]
    labels = tuple(resolved[k] for k in keep)
    zero_counts = {labels[i]: int(zero[:, k].sum()) for i, k in enumerate(keep) if zero[:, k].any()}
    rate = float(reader.point_rate)
    first_frame = int(reader.header.first_frame)
    events, event_notes = _events(reader)
    notes.extend(event_notes)
    return C3dClip(
        path=path, labels=labels, raw_labels=tuple(raw_labels[k] for k in keep), positions=positions,
        residuals=np.where(valid, residual, -1.0)[:, keep], valid=valid[:, keep], rate=rate, units=units,
        unit_scale_m=UNIT_SCALE_M[units.lower()], first_frame=first_frame, events=tuple(events),
        subjects=tuple(_strings(reader, "SUBJECTS:NAMES")), zero_samples=zero_counts, notes=tuple(notes))


# --- checks around the library -------------------------------------------------------------------------------

def _check_header(path: str, data: bytes) -> None:
    if len(data) < 512:
        raise C3dError(path, "a 512-byte header block", f"a file of {len(data)} bytes")
    if data[1] != 0x50:
        raise C3dError(path, "the C3D key 0x50 in byte 2 of the header", f"0x{data[1]:02x}")
    param_block = data[0]
    start = (param_block - 1) * 512
    if param_block < 2 or start + 4 > len(data):
        raise C3dError(path, "a parameter section starting at a 512-byte block inside the file",
                       f"block {param_block} in a file of {len(data)} bytes")
    processor = data[start + 3]
    if processor - 83 not in (1, 2, 3):
        raise C3dError(path, "processor type 84 (Intel), 85 (DEC) or 86 (MIPS) in the parameter header",
                       str(processor))


def _check_data_block(path: str, data: bytes, reader) -> dict[str, int]:
    try:  # py-c3d decodes these on access: a parameter of the wrong type or size raises there, not when parsed
        points = int(reader.point_used)
        first, last = int(reader.first_frame), int(reader.last_frame)
        scale, rate = reader.point_scale, float(reader.point_rate)
        analog_words = int(reader.analog_used) * int(reader.analog_per_frame)
        data_block = int(reader.header.data_block)
    except Exception as err:  # noqa: BLE001 - any failure to decode them is a malformed file
        raise C3dError(path, "decodable POINT:USED, frame range, POINT:SCALE, ANALOG:USED and ANALOG:RATE / "
                             "POINT:RATE", f"{type(err).__name__}: {err or 'no message'}") from None
    if points <= 0:
        raise C3dError(path, "POINT:USED > 0 (marker data)", str(points))
    if not MIN_RATE <= rate <= MAX_RATE:
        raise C3dError(path, f"POINT:RATE of {MIN_RATE:g} to {MAX_RATE:g} frames per second", f"{rate:g}")
    if analog_words < 0:
        raise C3dError(path, "ANALOG:USED x analog samples per frame (ANALOG:RATE / POINT:RATE) >= 0",
                       f"{int(reader.analog_used)} x {int(reader.analog_per_frame)}")
    frames = last - first + 1
    if frames <= 0:
        raise C3dError(path, "last frame >= first frame", f"frames {first}-{last}")
    word = 4 if scale < 0 else 2
    frame_bytes = (4 * points + analog_words) * word
    start = (data_block - 1) * 512
    needed = start + frames * frame_bytes
    if start < 512 or needed > len(data):
        whole = max(0, (len(data) - start) // frame_bytes)
        raise C3dError(path, f"{frames} frames x {frame_bytes} bytes from block {reader.header.data_block} "
                             f"(a file of at least {needed} bytes)",
                       f"{len(data)} bytes: truncated after {whole} whole frames")
    return {"frames": frames, "frame_bytes": frame_bytes, "start": start, "points": points, "word": word}


def _diagnose(err: Exception) -> tuple[str, str]:
    """(expected, found) for the parser's complaint, in the file's own terms where the message allows."""
    text = str(err)
    m = re.match(r"inconsistent analog rate! (\S+) header != (\S+) analog-fps / (\S+) point-fps", text)
    if m and all(_is_float(x) for x in m.groups()):
        per, analog, point = (float(x) for x in m.groups())
        ratio = f"{analog / point:.4g}" if point else "no ratio"
        return (f"the header's analog samples per point frame ({per:g}) = ANALOG:RATE / POINT:RATE",
                f"{analog:g} / {point:g} = {ratio} (the analog and point data cannot both be located)")
    m = re.match(r"inconsistent analog count! (\S+) header", text)
    if m:  # py-c3d's message repeats the header count as "analog used": report it without the echo
        return (f"the header's analog words per frame ({m.group(1)}) = ANALOG:USED x analog samples per frame "
                "(parameter section)", "a parameter section that disagrees (damaged or inconsistent ANALOG group)")
    m = re.match(r"inconsistent (point count|scale factor|frame rate)! (\S+) header != (.+)", text)
    if m:
        return f"the header's {m.group(1)} ({m.group(2)}) in the parameter section", m.group(3)
    return ("a well-formed C3D header and parameter section",
            f"{type(err).__name__}: {text or 'no message'} (while parsing the parameter section)")


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _residual_words(path: str, data: bytes, reader, layout: dict[str, int]) -> tuple[np.ndarray, str] | None:
    """Decode non-standard float-format residual words; None when they are standard (really all invalid)."""
    if layout["word"] != 4 or reader._dtypes.is_dec:  # integer format: the word is an int16, never ambiguous
        return None
    order = ">" if reader._dtypes.is_mips else "<"
    block = np.frombuffer(data, dtype=np.uint8, count=layout["frames"] * layout["frame_bytes"],
                          offset=layout["start"]).reshape(layout["frames"], layout["frame_bytes"])
    words = block[:, :16 * layout["points"]].reshape(layout["frames"], layout["points"], 4, 4)[:, :, 3]
    as_float = np.ascontiguousarray(words).view(f"{order}f4")[..., 0].astype(np.float64)
    standard = np.isfinite(as_float) & (as_float == np.round(as_float)) & (np.abs(as_float) <= 32768)
    if bool(standard.any()):
        return None
    halves = np.ascontiguousarray(words).view(f"{order}i2")  # (F, P, 2)
    first = halves[..., 0].astype(np.int64)
    if bool((first < 0).any()):
        return None
    residual = (first & 0xFF) * abs(float(reader.point_scale))
    bits = int(np.ascontiguousarray(words[0, 0]).view(f"{order}u4")[0])
    note = (f"residual word non-standard in every sample (float {as_float.flat[0]:.4g}, bits 0x{bits:08x}; the C3D "
            "float format needs an integer in [-32768, 32767], and a cast makes it negative so py-c3d flags "
            f"every sample invalid); read as 16-bit words it is camera mask 0x{(int(first.flat[0]) >> 8) & 0x7F:02x}, "
            f"residual {int(first.flat[0]) & 0xFF}: coordinates trusted")
    return residual.astype(np.float64), note


# --- parameters ---------------------------------------------------------------------------------------------

def _string(reader, key: str, default: str) -> str:
    param = reader.get(key)
    if param is None:
        return default
    try:
        return param.string_value.replace("\x00", " ")
    except Exception:  # noqa: BLE001 - a parameter of the wrong type counts as absent
        return default


def _strings(reader, key: str) -> list[str]:
    param = reader.get(key)
    if param is None:
        return []
    try:
        values = param.string_array
    except Exception:  # noqa: BLE001
        return []
    return [str(v).replace("\x00", " ").strip() for v in np.asarray(values).reshape(-1)]


def _point_labels(reader, count: int) -> list[str]:
    labels = _strings(reader, "POINT:LABELS")
    k = 2
    while len(labels) < count and reader.get(f"POINT:LABELS{k}") is not None:  # > 255 points
        labels += _strings(reader, f"POINT:LABELS{k}")
        k += 1
    labels = labels[:count] + [f"POINT{i + 1}" for i in range(len(labels), count)]
    return [lab if lab else f"POINT{i + 1}" for i, lab in enumerate(labels)]


def _subject_prefixes(reader) -> list[str]:
    return sorted({p for p in _strings(reader, "SUBJECTS:LABEL_PREFIXES") if p}, key=len, reverse=True)


def _strip_prefix(label: str, prefixes: list[str]) -> str:
    for prefix in prefixes:
        if label.startswith(prefix):
            return label[len(prefix):]
    return label.rsplit(":", 1)[-1] if ":" in label else label


def _resolve_duplicates(labels: list[str], coords: np.ndarray, valid: np.ndarray) -> tuple[list[int], list[str]]:
    counts = Counter(labels)
    keep: list[int] = []
    notes: list[str] = []
    for i, lab in enumerate(labels):
        if counts[lab] == 1:
            keep.append(i)
            continue
        columns = [j for j, other in enumerate(labels) if other == lab]
        if i != columns[0]:
            continue  # decided at the first occurrence
        filled = [j for j in columns if valid[:, j].any()]
        if not filled:
            keep.append(columns[0])
            notes.append(f"label {lab!r} appears {len(columns)} times, all empty: kept one")
        elif len(filled) == 1 or all(_same(coords, valid, filled[0], j) for j in filled[1:]):
            keep.append(filled[0])
            notes.append(f"label {lab!r} appears {len(columns)} times (columns {columns}): kept column {filled[0]}, "
                         f"the {'only one with data' if len(filled) == 1 else 'first of identical copies'}")
        else:
            notes.append(f"label {lab!r} appears {len(columns)} times with different data (columns {filled}): "
                         "ambiguous, dropped")
    return sorted(keep), notes


def _same(coords: np.ndarray, valid: np.ndarray, a: int, b: int) -> bool:
    both = valid[:, a] & valid[:, b]
    return bool((valid[:, a] == valid[:, b]).all()) and bool(np.allclose(coords[both, a], coords[both, b]))


def _events(reader) -> tuple[list[C3dEvent], list[str]]:
    if reader.get("EVENT:TIMES") is None:
        return [], []
    try:
        used = int(reader.get("EVENT:USED").int16_value) if reader.get("EVENT:USED") is not None else None
        times = np.asarray(reader.get("EVENT:TIMES").float_array, dtype=np.float64).reshape(-1, 2)
    except Exception as err:  # noqa: BLE001
        return [], [f"EVENT group unreadable ({type(err).__name__}: {err}): no events"]
    n = len(times) if used is None else min(used, len(times))
    labels = (_strings(reader, "EVENT:LABELS") + [""] * n)[:n]
    contexts = (_strings(reader, "EVENT:CONTEXTS") + [""] * n)[:n]
    events, ignored = [], []
    for k in range(n):
        seconds = 60.0 * times[k, 0] + times[k, 1]  # EVENT:TIMES holds (minutes, seconds)
        kind, side = _event_kind(labels[k], contexts[k])
        written = "/".join(x for x in (labels[k], contexts[k]) if x)
        if kind is None:
            ignored.append(written)
            continue
        events.append(C3dEvent(kind=kind, side=side, time=float(seconds), label=written))
    events.sort(key=lambda e: (e.time, e.side, e.kind))
    notes = [f"events that are not foot strikes/offs ignored: {sorted(set(ignored))}"] if ignored else []
    return events, notes


def _event_kind(label: str, context: str) -> tuple[str | None, str | None]:
    kind = _EVENT_LABELS.get(label.strip().lower())
    side = {"left": "left", "right": "right"}.get(context.strip().lower())
    if kind and side:
        return kind, side
    for code in (context.strip().upper(), label.strip().upper()):  # "LHS", "RTO", ...
        m = re.fullmatch(r"([LR])(HS|FS|IC|TO|FO)", code)
        if m:
            return _EVENT_CODES[m.group(2)], "left" if m.group(1) == "L" else "right"
    return None, None
