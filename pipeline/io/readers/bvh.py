"""BVH reader: text in, a skeleton and a (frames x channels) array out.

Handles any rotation order, any subset of the six channels on any joint, End Sites, CRLF, tabs and
scientific notation. The MOTION block is parsed in bulk (a small C parser, ``_motion.c``, or Arrow's CSV
reader when that is not built); only when that fails does a line-by-line pass run, to name the exact line
and value.

A reader knows files, not features: it does not map joints, change units or retarget.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

try:  # the C bulk parser, built by `pip install` from _motion.c
    from pipeline.io.readers import _motion
except ImportError:  # pragma: no cover - source checkouts without a build use the Arrow path
    _motion = None

_MOTION_RE = re.compile(r"^[ \t]*MOTION[ \t]*\r?$", re.MULTILINE)
# Frame rates outside 1-10,000 fps are no capture: a Frame Time of 1e-320 s makes fps infinite, one of 1e308 s
# makes every duration infinite.
MIN_FRAME_TIME, MAX_FRAME_TIME = 1e-4, 1.0
VALID_CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")


class BvhError(ValueError):
    """A malformed BVH file. ``str(err)`` names the file, the line, what was expected and what was found."""

    def __init__(self, path: str, line: int | None, expected: str, found: str):
        self.path, self.line, self.expected, self.found = path, line, expected, found
        where = f"{path}:{line}" if line is not None else path
        super().__init__(f"{where}: expected {_clip(expected)}, found {_clip(found)}")


def _clip(text: str, limit: int = 200) -> str:
    """Text for a message: a 100,000-character joint name or token is named by its start."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


@dataclass(frozen=True)
class BvhSkeleton:
    """Joints in file order; End Sites are joints named ``<parent>/End`` with no channels."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray  # (J, 3) in file units
    channels: tuple[tuple[str, ...], ...]
    is_end_site: tuple[bool, ...]

    @property
    def channel_count(self) -> int:
        return sum(len(c) for c in self.channels)

    def index(self, name: str) -> int:
        return self.names.index(name)


@dataclass(frozen=True)
class BvhClip:
    skeleton: BvhSkeleton
    frame_time: float  # seconds
    motion: np.ndarray = field(repr=False)  # (F, C) float64, channels in file order

    @property
    def frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time


def read_bvh(path: str | Path, data: bytes | None = None) -> BvhClip:
    """Read a BVH file (or its already-loaded bytes). Raises BvhError on malformed input."""
    path = str(path)
    if data is None:
        data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise BvhError(path, line, "UTF-8/ASCII text", f"undecodable byte 0x{data[err.start]:02x}") from None
    return parse_bvh(text, path)


def parse_bvh(text: str, path: str = "<string>") -> BvhClip:
    if "\r" in text and "\n" not in text:  # classic-Mac line ends
        text = text.replace("\r", "\n")
    motion_kw = _MOTION_RE.search(text)
    if motion_kw is None:
        # No MOTION keyword: the hierarchy pass raises the precise error (truncated, or MOTION missing).
        _parse_hierarchy(text.split("\n"), path)
        raise BvhError(path, None, "'MOTION'", "end of file")
    # Lines are counted by "\n" everywhere (not str.splitlines, which also breaks at \v, \f, ...).
    header_lines = text[: motion_kw.start()].split("\n")[:-1] + ["MOTION"]
    skeleton, _ = _parse_hierarchy(header_lines, path)
    return _parse_motion(text[motion_kw.end():], len(header_lines), skeleton, path)


def _parse_hierarchy(lines: list[str], path: str) -> tuple[BvhSkeleton, int]:
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_site: list[bool] = []
    stack: list[int] = []  # indices of open joints
    pending: int | None = None  # joint declared, its "{" not yet seen
    seen_root = False
    i = 0
    n = len(lines)
    while i < n and not lines[i].strip():
        i += 1
    if i >= n or lines[i].split()[0] != "HIERARCHY":
        raise BvhError(path, i + 1 if i < n else None, "'HIERARCHY'", repr(lines[i].strip()[:40]) if i < n else "an empty file")
    i += 1
    while i < n:
        lineno = i + 1
        tokens = lines[i].split()
        i += 1
        if not tokens:
            continue
        key = tokens[0]
        if pending is not None and key != "{":
            # A joint without its block would keep no OFFSET, and what follows would land on its parent.
            raise BvhError(path, lineno, f"'{{' opening the block of {names[pending]!r}", repr(" ".join(tokens)[:40]))
        if key in ("ROOT", "JOINT"):
            if key == "ROOT" and (seen_root or stack):
                raise BvhError(path, lineno, "one ROOT at the top level", "a second ROOT")
            if key == "JOINT" and not stack:
                raise BvhError(path, lineno, "JOINT inside a ROOT block", "JOINT at the top level")
            if len(tokens) < 2:
                raise BvhError(path, lineno, f"a joint name after {key}", "nothing")
            name = " ".join(tokens[1:])
            if name in names:
                raise BvhError(path, lineno, "unique joint names", f"duplicate joint name {name!r}")
            seen_root = True
            names.append(name)
            parents.append(stack[-1] if stack else -1)
            offsets.append([])
            channels.append(())
            end_site.append(False)
            pending = len(names) - 1
        elif key == "End" and len(tokens) >= 2 and tokens[1] == "Site":
            if not stack:
                raise BvhError(path, lineno, "End Site inside a joint", "End Site at the top level")
            names.append(f"{names[stack[-1]]}/End")
            parents.append(stack[-1])
            offsets.append([])
            channels.append(())
            end_site.append(True)
            pending = len(names) - 1
        elif key == "{":
            if pending is None:
                raise BvhError(path, lineno, "ROOT, JOINT or End Site before '{'", "'{'")
            stack.append(pending)
            pending = None
        elif key == "}":
            if not stack:
                raise BvhError(path, lineno, "a matching '{'", "'}'")
            j = stack.pop()
            if len(offsets[j]) != 3:
                raise BvhError(path, lineno, f"an OFFSET line in {names[j]!r}", "none")
            if not stack:
                # Hierarchy closed: the MOTION keyword must follow.
                while i < n and not lines[i].strip():
                    i += 1
                if i >= n:
                    raise BvhError(path, None, "'MOTION' after the hierarchy", "end of file")
                if lines[i].split()[0] != "MOTION":
                    raise BvhError(path, i + 1, "'MOTION' after the hierarchy", repr(lines[i].strip()[:40]))
                skeleton = BvhSkeleton(
                    names=tuple(names),
                    parents=tuple(parents),
                    offsets=np.asarray(offsets, dtype=np.float64),
                    channels=tuple(channels),
                    is_end_site=tuple(end_site),
                )
                return skeleton, i + 1
        elif key == "OFFSET":
            if not stack:
                raise BvhError(path, lineno, "OFFSET inside a joint block", "OFFSET outside any joint")
            j = stack[-1]
            values = tokens[1:]
            if len(values) != 3:
                raise BvhError(path, lineno, f"3 OFFSET values for {names[j]!r}", f"{len(values)}")
            offsets[j] = [_number(v, path, lineno, f"OFFSET of {names[j]!r}") for v in values]
        elif key == "CHANNELS":
            if not stack or end_site[stack[-1]]:
                raise BvhError(path, lineno, "CHANNELS inside a ROOT/JOINT block", "CHANNELS elsewhere")
            j = stack[-1]
            count = _count(tokens[1], path, lineno, "a channel count after CHANNELS") if len(tokens) > 1 else None
            if count is None:
                raise BvhError(path, lineno, "a channel count after CHANNELS", repr(" ".join(tokens[1:2])))
            chans = tuple(tokens[2:])
            if len(chans) != count:
                raise BvhError(path, lineno, f"{count} channel names for {names[j]!r}", f"{len(chans)}")
            for c in chans:
                if c not in VALID_CHANNELS:
                    raise BvhError(path, lineno, f"a channel name in {VALID_CHANNELS}", repr(c))
            if len(set(chans)) != len(chans):
                raise BvhError(path, lineno, "each channel at most once per joint", f"{' '.join(chans)}")
            channels[j] = chans
        else:
            raise BvhError(path, lineno, "ROOT, JOINT, End Site, OFFSET, CHANNELS, '{' or '}'", repr(key))
    open_name = names[stack[-1]] if stack else "the hierarchy"
    raise BvhError(path, None, f"'}}' closing {open_name!r} and then MOTION", "end of file (truncated hierarchy)")


# The number grammar the bulk parser accepts (Python's float() also takes "1_0" and non-ASCII digits).
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.IGNORECASE | re.ASCII)
_COUNT = re.compile(r"[0-9]+")
# Counts past this many digits cannot describe a file (10^18 frame lines): rejected before int() (whose limit is
# 4300 digits) and before the C parser (whose sizes are 64-bit).
_MAX_COUNT_DIGITS = 18
# The bulk parser's separators; Python's str.split() also splits at \x1c-\x1f and Unicode spaces, which the bulk
# parser (rightly) reads as part of a token, so the diagnosis splits as it does.
_FRAME_SPACE = re.compile(r"[ \t\r\f\v]+")


def _count(token: str, path: str, lineno: int, what: str) -> int | None:
    """A non-negative ASCII integer, or None when ``token`` is not one; BvhError when it is absurdly long."""
    if not _COUNT.fullmatch(token):
        return None
    digits = token.lstrip("0") or "0"
    if len(digits) > _MAX_COUNT_DIGITS:
        raise BvhError(path, lineno, f"{what} below 10^{_MAX_COUNT_DIGITS}", f"a number of {len(digits)} digits")
    return int(digits)


def _number(token: str, path: str, lineno: int, what: str) -> float:
    if not _NUMBER.fullmatch(token):
        raise BvhError(path, lineno, f"a number in {what}", repr(token))
    value = float(token)
    if not math.isfinite(value):
        raise BvhError(path, lineno, f"a finite number in {what}", repr(token))
    return value


def _next_line(text: str, pos: int, lineno: int) -> tuple[str, int, int]:
    """The next non-blank line at or after ``pos``: (stripped line, position after it, its line number)."""
    while pos < len(text):
        end = text.find("\n", pos)
        end = len(text) if end < 0 else end + 1
        line = text[pos:end].strip()
        lineno += 1
        pos = end
        if line:
            return line, pos, lineno
    return "", pos, lineno


def _header_value(text: str, pos: int, lineno: int, label: str, path: str) -> tuple[str, int, int]:
    line, pos, lineno = _next_line(text, pos, lineno)
    if not line:
        raise BvhError(path, None, f"a '{label}' line", "end of file")
    if not line.startswith(label):
        raise BvhError(path, lineno, f"'{label} <value>'", repr(line[:40]))
    return line[len(label):].strip(), pos, lineno


def _parse_motion(text: str, motion_lineno: int, skeleton: BvhSkeleton, path: str) -> BvhClip:
    """text: everything after the MOTION keyword; motion_lineno: the MOTION line's number."""
    # The MOTION line's own line break is still at the start of ``text``.
    pos = text.find("\n") + 1 if text.lstrip(" \t\r").startswith("\n") else 0
    frames_text, pos, frames_line = _header_value(text, pos, motion_lineno, "Frames:", path)
    n_frames = _count(frames_text, path, frames_line, "a frame count")
    if n_frames is None:
        raise BvhError(path, frames_line, "a non-negative integer frame count", repr(frames_text[:40]))
    ft_text, pos, ft_line = _header_value(text, pos, frames_line, "Frame Time:", path)
    frame_time = _number(ft_text, path, ft_line, "Frame Time")
    if frame_time <= 0:
        raise BvhError(path, ft_line, "a positive Frame Time in seconds", ft_text)
    if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        rates = f"{1 / MAX_FRAME_TIME:g} to {1 / MIN_FRAME_TIME:g} frames per second"
        raise BvhError(path, ft_line, f"a Frame Time of {MIN_FRAME_TIME:g} to {MAX_FRAME_TIME:g} s ({rates})",
                       ft_text[:40])
    n_channels = skeleton.channel_count
    if n_frames == 0:
        raise BvhError(path, frames_line, "at least one frame", "Frames: 0")
    if n_channels == 0:
        raise BvhError(path, None, "at least one CHANNELS declaration", "none")
    data = text[pos:]
    motion = _bulk_frames(data, n_frames, n_channels)
    if motion is None:
        _diagnose_frames(data, frames_line, ft_line, n_frames, n_channels, skeleton, path)
        raise BvhError(path, None, "parsable frame data", "data the bulk parser rejected")  # pragma: no cover
    return BvhClip(skeleton=skeleton, frame_time=frame_time, motion=motion)


# Every whitespace byte becomes a line break, so the C CSV reader sees one column of numbers.
_ONE_VALUE_PER_LINE = bytes.maketrans(b" \t\r\f\v", b"\n\n\n\n\n")
_CSV_READ = pacsv.ReadOptions(column_names=["v"], use_threads=False, block_size=1 << 20)
_CSV_PARSE = pacsv.ParseOptions(quote_char=False, double_quote=False)
_CSV_CONVERT = pacsv.ConvertOptions(column_types={"v": pa.float64()}, strings_can_be_null=False)


def _bulk_frames(data: str, n_frames: int, n_channels: int) -> np.ndarray | None:
    """(n_frames, n_channels) float64 array, or None if anything is off (the slow path then says what)."""
    raw = data.encode("ascii", errors="replace")
    if n_frames * n_channels > (len(raw) + 1) // 2:
        # Too few bytes for the values claimed (each takes a digit and a separator): never allocate for a claim
        # such as "Frames: 1000000000"; the diagnosis counts the lines there are.
        return None
    if _motion is not None:
        values = _motion.parse(raw, n_frames, n_channels)
        return None if values is None else np.frombuffer(values, dtype=np.float64).reshape(n_frames, n_channels)
    return _bulk_frames_arrow(raw, n_frames, n_channels)


def _bulk_frames_arrow(raw: bytes, n_frames: int, n_channels: int) -> np.ndarray | None:
    """The same as the C parser, with Arrow's CSV reader (about 3x slower); used when _motion is not built."""
    byte = np.frombuffer(raw, dtype=np.uint8)
    if byte.size == 0:
        return None
    # Values per line, vectorised: a value starts after a whitespace byte (<= 32) followed by a non-space.
    space = byte <= 32
    before_value = np.flatnonzero(space[:-1] > space[1:])
    line_of_value = np.searchsorted(np.flatnonzero(byte == 10), before_value, side="right")
    if not space[0]:
        line_of_value = np.concatenate(([0], line_of_value))
    per_line = np.bincount(line_of_value)
    per_line = per_line[per_line > 0]
    if per_line.size != n_frames or (per_line != n_channels).any():
        return None
    try:
        values = pacsv.read_csv(pa.py_buffer(raw.translate(_ONE_VALUE_PER_LINE)), read_options=_CSV_READ,
                                parse_options=_CSV_PARSE, convert_options=_CSV_CONVERT).column(0)
    except pa.ArrowInvalid:
        return None
    if values.null_count or len(values) != n_frames * n_channels:
        return None
    motion = values.to_numpy().reshape(n_frames, n_channels)
    return motion if np.isfinite(motion).all() else None


def _diagnose_frames(data: str, frames_line: int, ft_line: int, n_frames: int, n_channels: int,
                     skeleton: BvhSkeleton, path: str) -> None:
    """Slow path: find the first bad frame line and raise a precise BvhError."""
    labels = [f"{name} {c}" for name, chans in zip(skeleton.names, skeleton.channels) for c in chans]
    frame = 0
    for k, line in enumerate(data.split("\n")):
        lineno = ft_line + k + 1
        tokens = _FRAME_SPACE.split(line.strip(" \t\r\f\v"))
        if tokens == [""]:
            continue
        if frame >= n_frames:
            raise BvhError(path, lineno, f"Frames: {n_frames} frame lines, then end of file", "more frame lines")
        if len(tokens) != n_channels:
            raise BvhError(path, lineno, f"{n_channels} channel values in frame {frame}", f"{len(tokens)}")
        for c, tok in enumerate(tokens):
            if not _NUMBER.fullmatch(tok):
                raise BvhError(path, lineno, f"a number for {labels[c]!r} in frame {frame}", repr(tok))
            if not math.isfinite(float(tok)):
                raise BvhError(path, lineno, f"a finite number for {labels[c]!r} in frame {frame}", repr(tok))
        frame += 1
    if frame != n_frames:
        raise BvhError(path, frames_line, f"Frames: {n_frames} to match the frame lines", f"{frame} frame lines")
