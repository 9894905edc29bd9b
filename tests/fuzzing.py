"""Fuzz inputs for the mocap readers and the ingest screen: real files, mutated, and what one input does there.

Seeds are real files read in place from the mocap root (never copied into the repository): BVH files of five
sources and C3D files of c3d.org, most cut to their first frames (the frame count fixed to match) so that an
input costs milliseconds. ``fuzz_input(seeds, run_seed, index)`` mutates one seed by one to three mutators
(four to ten, one time in ten), deterministically: the same (run seed, index) always gives the same bytes, so a
finding is replayed by its index. ``Harness.run`` takes an input through the per-file ingest (``ingest_chunk``:
the screen, the reader, then the format's screen and retargeting) and classifies what happened.
``motion_parser_case`` / ``check_motion_parser`` fuzz the C MOTION parser alone against its contract.

Used by ``benchmarks/fuzz.py`` (100,000 inputs) and ``tests/test_fuzz.py`` (a short run). The library under
``pipeline/`` knows nothing of this module.
"""

from __future__ import annotations

import math
import random
import re
import struct
import tempfile
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pipeline.core.skeleton import load_skeleton
from pipeline.ingest.run import ingest_chunk
from pipeline.ingest.screen import screen_file
from pipeline.io.files import sha256_bytes
from pipeline.io.manifests import load_manifests
from pipeline.io.readers.bvh import BvhError, _bulk_frames_arrow, _motion, read_bvh
from pipeline.io.readers.c3d import C3dError, read_c3d
from stages.common import SKELETON, SOURCES, load_params
from stages.configs import ingest_config

BANDAI = "bandai_namco_motiondataset/dataset/Bandai-Namco-Research-Motiondataset-{}/data/{}"
C3D_ROOT = "c3d_org_samples/tests/c3d_org_samples/"
# (file under the mocap root, frames kept; None keeps the whole file). Cuts keep just over two seconds where the
# source's min_clip_seconds (2 s) should still let the clip reach retargeting, fewer where speed matters more.
BVH_SEEDS = (
    (BANDAI.format(1, "dataset-1_walk_happy_001.bvh"), 75),
    (BANDAI.format(2, "dataset-2_walk-turn-left_active_001.bvh"), 40),
    ("cmu_bvh11/resources/131_01.bvh", 250),  # CRLF header, tabs, ".0083333"
    ("pymo_demo/demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh", 250),
    ("bvh_python_tests/tests/test_freebvh.bvh", None),
    ("bvh_python_tests/tests/test_mocapbank.bvh", 40),  # CRLF throughout
    ("cmu_iclone/All_BVH/subjects/002/002_01.bvh", 30),  # 306 channels
)
C3D_SEEDS = (
    (C3D_ROOT + "sample_00/Innovative Sports Training/Gait with EMG.c3d", None),  # Intel float, metres, analog
    (C3D_ROOT + "sample_00/Motion Analysis Corporation/Walk1.c3d", None),
    (C3D_ROOT + "sample_00/Vicon Motion Systems/pyCGM2 lower limb CGM24 Walking01.c3d", 60),  # TRIAL, EVENT
    (C3D_ROOT + "sample_01/Eb015pi.c3d", 60),  # Intel integer format
    (C3D_ROOT + "sample_03/gait-raw.c3d", None),  # DEC float
    (C3D_ROOT + "sample_06/newwalk.c3d", 130),  # DEC, positive scale (integer data)
    (C3D_ROOT + "sample_11/evart.c3d", None),  # rejected as it is (analog rate disagrees)
    (C3D_ROOT + "sample_26/Walking_Hybrid_1_1.c3d", 490),  # 240 Hz, many analog samples per frame
    (C3D_ROOT + "sample_30/marche281.c3d", 490),  # non-standard residual words
)


@dataclass(frozen=True)
class Seed:
    name: str  # the file under the mocap root (and how many frames were kept)
    source: str  # its source manifest
    rel: str  # its path in the source folder (the manifest's label rule reads the file name)
    format: str  # "bvh" | "c3d"
    data: bytes


def load_seeds(mocap: Path) -> list[Seed]:
    """The seed files, read from ``mocap`` and cut to their first frames where the table says."""
    seeds = []
    for fmt, table, cut in (("bvh", BVH_SEEDS, cut_bvh), ("c3d", C3D_SEEDS, cut_c3d)):
        for rel, frames in table:
            data = (mocap / rel).read_bytes()
            if frames is not None:
                data = cut(data, frames)
            source, inner = rel.split("/", 1)
            seeds.append(Seed(f"{rel}[:{frames or 'all'}]", source, inner, fmt, data))
    return seeds


# --------------------------------------------------------------------------------------------------------------
# BVH: lines and tokens.

_FRAMES_LINE = re.compile(rb"^([ \t]*Frames:[ \t]*)(\d+)", re.MULTILINE)


def cut_bvh(data: bytes, frames: int) -> bytes:
    """The file with only its first ``frames`` frame lines, the Frames: line saying so."""
    m = _FRAMES_LINE.search(data)
    lines = data[m.end():].split(b"\n")  # the rest of the Frames: line, Frame Time, then frame lines
    return data[:m.start(2)] + str(frames).encode() + b"\n".join(lines[:2 + frames]) + b"\n"


def _lines(data: bytes) -> list[bytes]:
    """Lines with their ends kept, split at "\\n" only (as the reader counts lines)."""
    return re.findall(rb"[^\n]*\n|[^\n]+$", data)


def _motion_line(lines: list[bytes]) -> int:
    return next((i for i, line in enumerate(lines) if line.strip() == b"MOTION"), len(lines) // 2)


def _blocks(lines: list[bytes]) -> list[tuple[int, int]]:
    """(first, last + 1) line ranges of every JOINT / End Site block of the hierarchy, braces matched."""
    out, opened, declared = [], [], None  # opened: the declaring line of each open "{" (None: the ROOT's)
    for i, line in enumerate(lines[:_motion_line(lines)]):
        head = line.split()[:2]
        if head[:1] == [b"JOINT"] or head == [b"End", b"Site"]:
            declared = i
        elif head[:1] == [b"{"]:
            opened.append(declared)
            declared = None
        elif head[:1] == [b"}"] and opened:
            start = opened.pop()
            if start is not None:
                out.append((start, i + 1))
    return out


def _eol(line: bytes) -> bytes:
    return line[len(line.rstrip(b"\r\n")):]


HUGE_COUNTS = (b"1000000000", b"999999999999", b"1000000000000000000", b"99999999999999999999",
               b"9" * 40, b"1" + b"0" * 5000, b"4294967296", b"2147483648", b"0", b"-1", b"+5", b"1e3", b"12.0",
               "\u0663".encode(), "\u00b2".encode(), b"0x10", b"")
ODD_NUMBERS = (b"nan", b"NaN", b"-nan", b"inf", b"-Infinity", b"1e309", b"-1e309", b"1e-400", b"4.9e-324",
               b"1.7976931348623157e308", b"0" * 200 + b"1", b"0." + b"0" * 300 + b"1", b"1" * 400, b"1" * 25,
               b"123456789012345678901234567890", b"-0", b"+.5", b"5.", b".", b"-", b"+", b"e5", b"1e", b"1e+",
               b"1.2.3", b"--1", b"0x1p3", b"1_000", "\u0661\u0662".encode(), "\uff11".encode(), b"1,5",
               b"1e99999999999", b"1e-99999999999", b"9007199254740993", b"1" + b"0" * 22 + b".5", b"")


def _m_frames(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    value = rng.choice(HUGE_COUNTS)
    out, n = _FRAMES_LINE.subn(lambda m: m.group(1) + value, data, count=1)
    return out, f"frames={value[:20]!r}" if n else "frames(absent)"


def _m_channels(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    lines = _lines(data)
    where = [i for i, line in enumerate(lines) if line.split()[:1] == [b"CHANNELS"]]
    if not where:
        return data, "channels(absent)"
    i = rng.choice(where)
    tokens = lines[i].split()
    how = rng.randrange(4)
    if how == 0:
        tokens[1] = rng.choice(HUGE_COUNTS)
    elif how == 1:  # a count that matches a long list of names: many channels, each repeated
        k = rng.choice((7, 100, 999))
        tokens = [b"CHANNELS", str(k).encode()] + [b"Xrotation"] * k
    elif how == 2:
        tokens = tokens[:2] + tokens[2:][::-1] + [rng.choice((b"Wrotation", b"Xposition", b"xrotation"))]
    else:
        tokens = tokens[:2]
    lines[i] = lines[i][:len(lines[i]) - len(lines[i].lstrip())] + b" ".join(tokens) + _eol(lines[i])
    return b"".join(lines), f"channels(line {i + 1}, {how})"


def _m_number(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Replace a number token (in OFFSET, Frame Time or frame data) by an odd one."""
    header = rng.random() < 0.5  # half in the hierarchy (OFFSET) and the MOTION header, which hold far fewer
    motion = re.search(rb"^[ \t]*MOTION[^\n]*\n[^\n]*\n[^\n]*\n", data, re.MULTILINE)  # and its 2 lines
    split = motion.end() if motion else len(data) // 2
    lo, hi = (0, split) if header else (split, len(data))
    spans = [t.span() for t in re.finditer(rb"[-+]?\d+\.?\d*(?:[eE][-+]?\d+)?", data[lo:hi])]
    if not spans:
        return data, "number(absent)"
    start, end = (lo + x for x in rng.choice(spans))
    value = rng.choice(ODD_NUMBERS)
    return data[:start] + value + data[end:], f"number@{start}={value[:20]!r}"


def _m_frame_time(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    value = rng.choice((b"0", b"-0.03", b"nan", b"inf", b"1e-320", b"1e308", b"", b"0.0333 0.1", b"1/30"))
    out, n = re.subn(rb"(Frame Time:[ \t]*)([^\r\n]*)", lambda m: m.group(1) + value, data, count=1)
    return out, f"frame_time={value!r}" if n else "frame_time(absent)"


def _m_line(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Duplicate, delete or swap lines, mostly in the header."""
    lines = _lines(data)
    if len(lines) < 2:
        return data, "line(none)"
    top = _motion_line(lines) + 4 if rng.random() < 0.8 else len(lines)
    i, j = rng.randrange(min(top, len(lines))), rng.randrange(min(top, len(lines)))
    how = rng.choice(("dup", "del", "swap", "dup_many"))
    if how == "dup":
        lines.insert(j, lines[i])
    elif how == "del":
        del lines[i]
    elif how == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    else:
        lines[i:i + 1] = [lines[i]] * rng.choice((2, 10, 1000))
    return b"".join(lines), f"line_{how}({i + 1},{j + 1})"


def _m_section(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Duplicate or delete a JOINT / End Site block, or the MOTION header, or nest a chain of joints."""
    lines = _lines(data)
    blocks = _blocks(lines)
    how = rng.choice(("dup_block", "del_block", "move_block", "dup_motion", "del_motion", "deep"))
    if how in ("dup_block", "del_block", "move_block") and blocks:
        a, b = rng.choice(blocks)
        block = lines[a:b]
        if how == "dup_block":
            lines[b:b] = block
        elif how == "del_block":
            del lines[a:b]
        else:
            del lines[a:b]
            k = rng.randrange(len(lines))
            lines[k:k] = block
        return b"".join(lines), f"{how}({a + 1}-{b})"
    m = _motion_line(lines)
    if how == "dup_motion":
        lines[m:m] = lines[m:m + 3]
    elif how == "del_motion":
        del lines[m:m + rng.randint(1, 3)]
    else:  # a deep chain of joints right after the root's channels
        depth = rng.choice((50, 2000))
        chain = [b"JOINT d%d\n{\nOFFSET 0 1 0\nCHANNELS 1 Xrotation\n" % k for k in range(depth)]
        chain += [b"End Site\n{\nOFFSET 0 1 0\n}\n"] + [b"}\n"] * depth
        root_channels = next((k for k, line in enumerate(lines) if line.split()[:1] == [b"CHANNELS"]), 3)
        lines[root_channels + 1:root_channels + 1] = chain
    return b"".join(lines), how


def _m_encoding(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    how = rng.choice(("utf16le", "utf16be", "bom", "latin1", "nul", "crlf", "cr", "lf", "mixed_eol", "tabs",
                      "ff_vt", "unicode_space", "fs_sep", "lower_keywords"))
    text = data.decode("utf-8", errors="surrogateescape")
    if how == "utf16le":
        return text.encode("utf-16-le", errors="surrogatepass")[:-1] if rng.random() < 0.2 else \
            b"\xff\xfe" + text.encode("utf-16-le", errors="surrogatepass"), how
    if how == "utf16be":
        return b"\xfe\xff" + text.encode("utf-16-be", errors="surrogatepass"), how
    if how == "bom":
        return b"\xef\xbb\xbf" + data, how
    k = rng.randrange(len(data) + 1)
    if how == "latin1":
        return data[:k] + rng.choice((b"\xe9", b"\xff", b"\xc3", b"\xa0", b"\x80")) + data[k:], f"latin1@{k}"
    if how == "nul":
        return data[:k] + b"\x00" * rng.choice((1, 4)) + data[k:], f"nul@{k}"
    if how == "crlf":
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n"), how
    if how == "cr":
        return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r"), how
    if how == "lf":
        return data.replace(b"\r", b""), how
    if how == "mixed_eol":
        return data[:k] + data[k:].replace(b"\n", b"\r", rng.randint(1, 50)), f"mixed_eol@{k}"
    if how == "tabs":
        return data.replace(b" ", b"\t"), how
    if how == "ff_vt":
        return data[:k] + data[k:].replace(b" ", rng.choice((b"\f", b"\v", b" \x0b ")), rng.randint(1, 50)), \
            f"ff_vt@{k}"
    if how == "unicode_space":  # spaces Python's str.split() splits at and the C parser does not
        sp = rng.choice(("\u00a0", "\u2003", "\u3000", "\x85")).encode()
        return data[:k] + data[k:].replace(b" ", sp, rng.randint(1, 20)), f"unicode_space@{k}"
    if how == "fs_sep":
        return data[:k] + data[k:].replace(b" ", rng.choice((b"\x1c", b"\x1f", b"\x1e")), rng.randint(1, 20)), \
            f"fs_sep@{k}"
    word = rng.choice((b"MOTION", b"HIERARCHY", b"ROOT", b"JOINT", b"OFFSET", b"CHANNELS", b"Frames:", b"End Site"))
    return data.replace(word, word.lower(), 1), f"lower({word.decode()})"


def _m_frames_extra(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """More or fewer frame lines than the header says; blank lines and trailing garbage in the data."""
    lines = _lines(data)
    m = _motion_line(lines)
    first = min(m + 3, len(lines))
    how = rng.choice(("append", "drop_last", "blank", "garbage", "short_line", "long_line", "no_final_eol"))
    if how == "append":
        lines += lines[-1:] * rng.choice((1, 5, 200))
    elif how == "drop_last" and len(lines) > first:
        del lines[-rng.randint(1, max(1, len(lines) - first)):]
    elif how == "blank":
        lines.insert(rng.randint(first, len(lines)), rng.choice((b"\n", b"  \t\r\n", b"\r\n")))
    elif how == "garbage":
        lines.append(rng.choice((b"END\n", b"\x1a", b"Frames: 3\n", b"MOTION\n", b"}\n")))
    elif how == "short_line" and len(lines) > first:
        k = rng.randrange(first, len(lines))
        lines[k] = b" ".join(lines[k].split()[:-1]) + _eol(lines[k])
    elif how == "long_line" and len(lines) > first:
        k = rng.randrange(first, len(lines))
        lines[k] = lines[k].rstrip(b"\r\n") + b" 0.0" * rng.choice((1, 1000)) + _eol(lines[k])
    elif how == "no_final_eol":
        return data.rstrip(b"\r\n"), how
    return b"".join(lines), f"frames_{how}"


def _m_values(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Well-formed but extreme numbers: every OFFSET zero or huge, one channel column huge, tiny or constant,
    the frames in another order. Such a file parses, so it takes the retargeting path."""
    lines = _lines(data)
    m = _motion_line(lines)
    how = rng.choice(("offsets_zero", "offsets_huge", "column", "frames_constant", "frames_shuffled"))
    if how.startswith("offsets"):
        value = b"0" if how == "offsets_zero" else rng.choice((b"1e30", b"1e300", b"-1e38", b"1e-300"))
        for i, line in enumerate(lines[:m]):
            if line.split()[:1] == [b"OFFSET"] and rng.random() < 0.7:
                lines[i] = line[:len(line) - len(line.lstrip())] + b"OFFSET " + b" ".join([value] * 3) + _eol(line)
        return b"".join(lines), f"{how}={value.decode()}"
    frames = lines[m + 3:]
    if not frames:
        return data, "values(none)"
    if how == "column":
        width = len(frames[0].split())
        c = rng.randrange(max(1, width))
        value = rng.choice((b"1e30", b"-1e300", b"1e15", b"1e-300", b"0", b"3.4028235e38"))
        for k, line in enumerate(frames):
            tokens = line.split()
            if c < len(tokens):
                tokens[c] = value
                frames[k] = b" ".join(tokens) + _eol(line)
        what = f"column({c})={value.decode()}"
    elif how == "frames_constant":
        frames = frames[:1] * len(frames)
        what = how
    else:
        rng.shuffle(frames)
        what = how
    return b"".join(lines[:m + 3] + frames), what


def _m_names(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Joint names: duplicated, empty, very long, with odd characters; an extra ROOT."""
    lines = _lines(data)
    joints = [i for i, line in enumerate(lines) if line.split()[:1] in ([b"JOINT"], [b"ROOT"])]
    if len(joints) < 2:
        return data, "names(none)"
    i, j = rng.sample(joints, 2)
    how = rng.choice(("duplicate", "empty", "long", "odd", "second_root"))
    key = lines[i].split()[0]
    name = {"duplicate": b" ".join(lines[j].split()[1:]), "empty": b"", "long": b"J" * 100000,
            "odd": rng.choice((b"a{b", b"}", b"End", "\u00e9\u4e2d".encode(), b"x\x00y"))}.get(how, b"X")
    if how == "second_root":
        key = b"ROOT"
    lines[i] = key + (b" " + name if name else b"") + _eol(lines[i])
    return b"".join(lines), f"name_{how}(line {i + 1})"


# --------------------------------------------------------------------------------------------------------------
# C3D: header words, the parameter section, the data blocks.

HEADER_WORDS = {"points": 2, "analog_words": 4, "first_frame": 6, "last_frame": 8, "max_gap": 10,
                "data_block": 16, "analog_per_frame": 18}
HEADER_FLOATS = {"scale": 12, "rate": 20}
ODD_WORDS = (0, 1, 2, 0x7FFF, 0x8000, 0xFFFF, 0xFFFE, 255, 256)
ODD_FLOATS = (math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0, 1e38, -1e38, 3.4e38, 1e-45, -1.0, 1e9, 0.001)


@dataclass(frozen=True)
class C3dParam:
    """One group or parameter record of a C3D parameter section (offsets into the file)."""

    start: int  # the record's first byte (name length)
    end: int  # where the next record starts (by its offset word), or the section end
    group_id: int  # < 0: a group record
    name: str
    body: int  # first byte after the offset word: a parameter's type byte, a group's description size
    type: int  # bytes per element (-1: char); 0 for groups
    dims: tuple[int, ...]
    data: int  # first data byte

    @property
    def size(self) -> int:
        return abs(self.type) * math.prod(self.dims)


@dataclass(frozen=True)
class C3dLayout:
    order: str  # "<" or ">" (MIPS)
    proc: int
    section: tuple[int, int]  # the parameter section's byte range
    params: tuple[C3dParam, ...]

    def find(self, group: str, name: str) -> C3dParam | None:
        groups = {-p.group_id: p.name for p in self.params if p.group_id < 0}
        return next((p for p in self.params if p.group_id > 0 and p.name == name and groups.get(p.group_id) == group),
                    None)


def c3d_layout(data: bytes) -> C3dLayout:
    """Walk a (well-formed) parameter section as py-c3d does; stops quietly where the records stop making sense."""
    start = (data[0] - 1) * 512
    blocks, proc = data[start + 2], data[start + 3]
    order = ">" if proc == 86 else "<"
    end = min(len(data), start + 512 * blocks)
    params, pos = [], start + 4
    while pos + 4 <= end:
        n, gid = struct.unpack_from("bb", data, pos)
        if n == 0 or gid == 0:
            break
        off_at = pos + 2 + abs(n)
        if off_at + 2 > end:
            break
        (offset,) = struct.unpack_from(order + "h", data, off_at)
        nxt = off_at + offset if offset > 0 else end
        body = off_at + 2
        name = data[pos + 2:off_at].decode("latin-1")
        if gid > 0 and body + 2 <= end:
            ptype, ndims = struct.unpack_from("bB", data, body)
            dims = tuple(data[body + 2:body + 2 + ndims])
            params.append(C3dParam(pos, nxt, gid, name, body, ptype, dims, body + 2 + ndims))
        else:
            params.append(C3dParam(pos, nxt, gid, name, body, 0, (), body + 1))
        if offset <= 0 or nxt <= pos:
            break
        pos = nxt
    return C3dLayout(order, proc, (start, end), tuple(params))


def _pack_float(value: float, layout: C3dLayout) -> bytes:
    if layout.proc == 85:  # DEC: the IEEE bits of value * 4 with the 16-bit halves swapped
        raw = struct.pack("<f", value * 4 if math.isfinite(value) and abs(value) < 8e37 else value)
        return raw[2:] + raw[:2]
    return struct.pack(layout.order + "f", value)


def _frame_layout(data: bytes) -> tuple[int, int, int, int]:
    """(first frame, data start byte, bytes per frame, frames) from the header, as the reader computes them."""
    points, analog_words, first, last = struct.unpack_from("<HHHH", data, 2)
    (scale,) = struct.unpack_from("<f", data, 12)
    (data_block,) = struct.unpack_from("<H", data, 16)
    if data[(data[0] - 1) * 512 + 3] == 85:  # DEC float: the sign bit is where IEEE has it
        scale = -1.0 if data[13] & 0x80 else 1.0
    word = 4 if scale < 0 else 2
    return first, (data_block - 1) * 512, (4 * points + analog_words) * word, last - first + 1


def cut_c3d(data: bytes, frames: int) -> bytes:
    """The file with only its first ``frames`` frames: header last frame, POINT:FRAMES (and the TRIAL end field
    where present) say so, the data section ends after them."""
    layout = c3d_layout(data)
    first, start, frame_bytes, _ = _frame_layout(data)
    out = bytearray(data[:start + frames * frame_bytes])
    out += bytes(-len(out) % 512)
    struct.pack_into("<H", out, 8, first + frames - 1)
    p = layout.find("POINT", "FRAMES")
    if p is not None and p.type == 2:
        struct.pack_into(layout.order + "H", out, p.data, frames)
    p = layout.find("TRIAL", "ACTUAL_END_FIELD")
    if p is not None and p.type == 2 and p.size == 4:
        end = first + frames - 1
        struct.pack_into(layout.order + "HH", out, p.data, end & 0xFFFF, end >> 16)
    return bytes(out)


def _m_c3d_header(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    out = bytearray(data)
    if rng.random() < 0.6:
        field = rng.choice(list(HEADER_WORDS))
        value = rng.choice(ODD_WORDS) if rng.random() < 0.7 else rng.randrange(65536)
        struct.pack_into("<H", out, HEADER_WORDS[field], value)
        return bytes(out), f"header_{field}={value}"
    if rng.random() < 0.6:
        field = rng.choice(list(HEADER_FLOATS))
        value = rng.choice(ODD_FLOATS)
        struct.pack_into("<f", out, HEADER_FLOATS[field], value)
        return bytes(out), f"header_{field}={value}"
    where = rng.choice(("param_block", "key", "blocks", "processor"))
    at = {"param_block": 0, "key": 1, "blocks": (data[0] - 1) * 512 + 2, "processor": (data[0] - 1) * 512 + 3}[where]
    if at < len(out):
        out[at] = rng.choice((0, 1, 2, 83, 84, 85, 86, 87, 0x50, 255, rng.randrange(256)))
    return bytes(out), f"{where}={out[at] if at < len(out) else None}"


# Parameters whose values the reader leans on, with values that claim too much or make no sense.
C3D_TARGETS = {
    ("POINT", "USED"): (0, 1, 0x7FFF, 0xFFFF, 255),
    ("POINT", "FRAMES"): (0, 1, 0x7FFF, 0xFFFF),
    ("ANALOG", "USED"): (0, 0x7FFF, 0xFFFF, 1000),
    ("EVENT", "USED"): (0, 0x7FFF, 0xFFFF, 50),
    ("POINT", "RATE"): ODD_FLOATS,
    ("POINT", "SCALE"): ODD_FLOATS,
    ("ANALOG", "RATE"): ODD_FLOATS,
    ("ANALOG", "GEN_SCALE"): ODD_FLOATS,
    ("EVENT", "TIMES"): ODD_FLOATS,
    ("TRIAL", "ACTUAL_START_FIELD"): ((0, 0), (0xFFFF, 0xFFFF), (0, 1)),
    ("TRIAL", "ACTUAL_END_FIELD"): ((0xCA00, 0x3B9A), (0xFFFF, 0xFFFF), (0, 0)),  # 0x3B9ACA00 = 10^9
}


def _m_c3d_value(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """A parameter the reader uses set to a huge count, NaN/Inf, zero or negative."""
    layout = c3d_layout(data)
    present = [(k, p) for k in C3D_TARGETS if (p := layout.find(*k)) is not None]
    if not present:
        return data, "param(none)"
    (group, name), p = rng.choice(present)
    value = rng.choice(C3D_TARGETS[(group, name)])
    out = bytearray(data)
    at = p.data if rng.random() < 0.7 or p.size <= 4 else p.data + rng.randrange(0, p.size, max(1, abs(p.type)))
    if at + 4 > len(out):
        return data, "param(outside)"
    if isinstance(value, tuple):
        struct.pack_into(layout.order + "HH", out, at, *value)
    elif p.type == 4:
        out[at:at + 4] = _pack_float(value, layout)
    elif p.type == 2:
        struct.pack_into(layout.order + "H", out, at, int(value) & 0xFFFF if not isinstance(value, float)
                         or math.isfinite(value) else 0xFFFF)
    else:
        out[at] = int(value) & 0xFF if not isinstance(value, float) or math.isfinite(value) else 0xFF
    return bytes(out), f"param_{group}:{name}@{at}={value}"


def _m_c3d_record(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """A record's framing: its type, dimensions, name length, group id or offset to the next record."""
    layout = c3d_layout(data)
    if not layout.params:
        return data, "record(none)"
    p = rng.choice(layout.params)
    out = bytearray(data)
    how = rng.choice(("type", "ndims", "dim", "name_len", "group", "offset", "desc_len"))
    if how == "type" and p.group_id > 0:
        out[p.body] = rng.choice((-1, 0, 1, 2, 3, 4, 5, 127, -128)) & 0xFF
    elif how == "ndims" and p.group_id > 0:
        out[p.body + 1] = rng.choice((0, 1, 2, 3, 7, 255))
    elif how == "dim" and p.dims:
        out[p.body + 2 + rng.randrange(len(p.dims))] = rng.choice((0, 1, 255))
    elif how == "name_len":
        out[p.start] = rng.choice((0, 1, 127, -1, -127, -128, rng.randrange(256))) & 0xFF
    elif how == "group":
        out[p.start + 1] = rng.choice((0, 1, -1, 127, -128, 99, -p.group_id)) & 0xFF
    elif how == "offset":
        value = rng.choice((0, 1, 2, 3, -2, -32768, 32767, rng.randrange(-32768, 32768)))
        struct.pack_into(layout.order + "h", out, p.body - 2, value)
    else:
        at = p.data + p.size if p.group_id > 0 else p.body
        if at < len(out):
            out[at] = rng.choice((0, 255, 127))
    return bytes(out), f"record_{how}({p.name})"


def _m_c3d_records(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Whole records of the parameter section: one duplicated, deleted, or a new parameter added; the section
    keeps its size (what no longer fits is cut off, as a writer with a bug would)."""
    layout = c3d_layout(data)
    recs = [p for p in layout.params if p.end > p.start]
    if not recs:
        return data, "records(none)"
    (lo, hi), first = layout.section, recs[0].start
    chunks = [data[p.start:p.end] for p in recs]
    tail = data[recs[-1].end:hi]
    how = rng.choice(("dup", "del", "add_long_frames", "add_random"))
    k = rng.randrange(len(chunks) - 1) if len(chunks) > 1 else 0  # the last record may run to the section end
    if how == "dup":
        chunks.insert(k, chunks[k])
    elif how == "del":
        del chunks[k]
    else:
        point = next((-p.group_id for p in layout.params if p.group_id < 0 and p.name == "POINT"), 1)
        if how == "add_long_frames":  # claims 10^9 frames (py-c3d reads it when the header's last frame is lower)
            name, ptype, dims, value = b"LONG_FRAMES", 4, b"", _pack_float(1e9, layout)
        else:
            name, ptype = b"X%d" % rng.randrange(100), rng.choice((-1, 1, 2, 4))
            dims, value = bytes([2, 3]), bytes(rng.randrange(256) for _ in range(6 * abs(ptype)))
            point = rng.choice([-p.group_id for p in layout.params if p.group_id < 0] or [1])
        body = struct.pack("bB", ptype, len(dims)) + dims + value + b"\x00"
        rec = struct.pack("bb", len(name), point) + name + struct.pack(layout.order + "h", len(body) + 2) + body
        chunks.insert(k, rec)
    section = b"".join(chunks) + tail
    section = section[:hi - first] + bytes(max(0, hi - first - len(section)))
    return data[:first] + section + data[hi:], f"records_{how}({recs[k].name})"


def _m_c3d_strings(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Labels, units and event texts: duplicated, emptied, non-ASCII, NUL."""
    layout = c3d_layout(data)
    chars = [p for p in layout.params
             if p.group_id > 0 and p.type == -1 and p.size > 0 and p.data + p.size <= len(data)]
    if not chars:
        return data, "strings(none)"
    p = rng.choice(chars)
    out = bytearray(data)
    width = p.dims[0] if p.dims else 1
    how = rng.choice(("copy", "blank", "high", "nul", "units"))
    if how == "copy" and p.size >= 2 * width:  # a label repeated: duplicated names
        out[p.data + width:p.data + 2 * width] = out[p.data:p.data + width]
    elif how == "blank":
        out[p.data:p.data + p.size] = b" " * p.size
    elif how == "high":
        k = rng.randrange(p.size)
        out[p.data + k] = rng.choice((0xE9, 0xFF, 0x80, 0xC3))
    elif how == "nul":
        out[p.data + rng.randrange(p.size)] = 0
    else:
        unit = rng.choice((b"m", b"cm", b"in", b"MM", b"\xb5m", b""))
        target = layout.find("POINT", "UNITS")
        if target is not None and target.type == -1:
            out[target.data:target.data + target.size] = (unit + b" " * target.size)[:target.size]
    return bytes(out), f"strings_{how}({p.name})"


def _m_c3d_frames(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """Frame data: NaN/Inf/huge coordinates, residual words flagged invalid, zeroed samples."""
    first, start, frame_bytes, frames = _frame_layout(data)
    if start < 512 or frame_bytes <= 0 or start >= len(data):
        return data, "frames(none)"
    out = bytearray(data)
    how = rng.choice(("float", "invalid_frame", "zero_block", "noise"))
    if how == "float":
        for _ in range(rng.choice((1, 10, 1000))):
            at = start + 4 * rng.randrange(max(1, (len(data) - start) // 4 - 1))
            out[at:at + 4] = struct.pack("<f", rng.choice(ODD_FLOATS))
    elif how == "invalid_frame":  # the residual word of every point of some frames (or all) -1 (float format)
        first_bad = rng.choice((0, rng.randrange(max(1, frames))))
        for f in range(first_bad, min(frames, first_bad + rng.choice((1, 50, frames)))):
            for k in range(frame_bytes // 16):
                at = start + f * frame_bytes + 16 * k + 12
                out[at:at + 4] = struct.pack("<f", -1.0)
    elif how == "zero_block":
        at, n = rng.randrange(start, len(data)), rng.choice((16, 512, 4096))
        out[at:at + n] = bytes(len(out[at:at + n]))
    else:
        at = rng.randrange(start, len(data))
        n = min(64, len(out) - at)
        out[at:at + n] = bytes(rng.randrange(256) for _ in range(n))
    return bytes(out[:len(data)]), f"data_{how}"


def _m_c3d_blocks(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """512-byte blocks duplicated, deleted, swapped; the file cut at a block boundary."""
    n = len(data) // 512
    if n < 2:
        return data, "blocks(none)"
    blocks = [data[i * 512:(i + 1) * 512] for i in range(n)]
    i, j = rng.randrange(n), rng.randrange(n)
    how = rng.choice(("dup", "del", "swap", "cut"))
    if how == "dup":
        blocks.insert(j, blocks[i])
    elif how == "del":
        del blocks[i]
    elif how == "swap":
        blocks[i], blocks[j] = blocks[j], blocks[i]
    else:
        blocks = blocks[:i]
    return b"".join(blocks) + data[n * 512:], f"blocks_{how}({i},{j})"


# --------------------------------------------------------------------------------------------------------------
# Byte-level mutators, for both formats.


def _m_bit_flip(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    out = bytearray(data)
    k = rng.choice((1, 1, 2, 8, 64))
    for _ in range(k if out else 0):
        out[rng.randrange(len(out))] ^= 1 << rng.randrange(8)
    return bytes(out), f"bit_flip({k})"


def _m_bytes(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    k = rng.randrange(len(data) + 1)
    how = rng.choice(("set", "insert", "delete", "dup_span"))
    if how == "set" and data:
        value = rng.choice((b"\x00", b"\xff", b"\x7f", b"\x80", b"\n", b" ", b"-", b".", b"e", b"{", b"}"))
        return data[:k] + value + data[k + 1:], f"set@{k}={value!r}"
    if how == "insert":
        value = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        return data[:k] + value + data[k:], f"insert@{k}"
    if how == "delete":
        n = rng.choice((1, 2, 16, 64, 512))
        return data[:k] + data[k + n:], f"delete@{k}+{n}"
    n = rng.choice((8, 64, 512, 4096))
    j = rng.randrange(len(data) + 1)
    return data[:j] + data[k:k + n] + data[j:], f"dup_span@{k}+{n}->{j}"


def _m_truncate(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    k = rng.randrange(len(data) + 1) if rng.random() < 0.8 else rng.choice((0, 1, 4, 511, 512, 513))
    return data[:k], f"truncate@{k}"


Mutator = Callable[[bytes, random.Random], tuple[bytes, str]]
# (mutator, weight) per format; byte-level mutators reach what the structured ones do not think of.
MUTATORS: dict[str, tuple[tuple[Mutator, int], ...]] = {
    "bvh": ((_m_frames, 4), (_m_channels, 3), (_m_number, 6), (_m_frame_time, 2), (_m_line, 6), (_m_section, 4),
            (_m_encoding, 5), (_m_frames_extra, 4), (_m_values, 4), (_m_names, 2), (_m_bit_flip, 4), (_m_bytes, 4),
            (_m_truncate, 3)),
    "c3d": ((_m_c3d_header, 6), (_m_c3d_value, 6), (_m_c3d_record, 6), (_m_c3d_records, 3), (_m_c3d_strings, 3),
            (_m_c3d_frames, 4), (_m_c3d_blocks, 3), (_m_bit_flip, 6), (_m_bytes, 3), (_m_truncate, 3)),
}


def fuzz_input(seeds: list[Seed], run_seed: int, index: int) -> tuple[Seed, bytes, list[str]]:
    """Input ``index`` of run ``run_seed``: (its seed, its bytes, the mutations applied, in order)."""
    rng = random.Random(f"{run_seed}:{index}")  # str seeds hash with SHA-512: stable across processes
    seed = rng.choice(seeds)
    data, done = seed.data, []
    mutators, weights = zip(*MUTATORS[seed.format])
    count = rng.choice((1, 1, 1, 2, 2, 3)) if rng.random() < 0.9 else rng.randint(4, 10)  # now and then: havoc
    for mutate in rng.choices(mutators, weights, k=count):
        try:
            data, what = mutate(data, rng)
        except (IndexError, ValueError, ArithmeticError, struct.error):  # on bytes an earlier mutator broke
            what = f"{mutate.__name__[3:]}(skipped)"
        done.append(what)
    return seed, data, done


# --------------------------------------------------------------------------------------------------------------
# The C MOTION parser alone: token soups against its contract, written out in Python.

_TOKENS = (b"0", b"1", b"-2.5", b"+.5", b"5.", b"1e5", b"1E-5", b"-0", b"007", b"9007199254740993",
           b"123456789012345678901", b"1e22", b"1e23", b"4.9e-324", b"2.4703282292062327e-324", b"1e-400",
           b"1.7976931348623157e308", b"1.8e308", b"0." + b"0" * 150 + b"1", b"9" * 140, b"1e99999999999",
           b".", b"-", b"e5", b"1e", b"1.2.3", b"nan", b"inf", b"0x10", b"1_0", b"\x00", b"\xe9", b"?")
_SEPARATORS = (b" ", b"  ", b"\t", b"\r", b"\f", b"\v", b" \r", b"\x1c", b"\xa0")
_PLAIN = re.compile(rb"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def motion_parser_case(rng: random.Random) -> tuple[bytes, int, int]:
    """A frame block for ``_motion.parse`` and the (frames, channels) to ask for: mostly the true counts."""
    frames, channels = rng.randint(1, 6), rng.randint(1, 6)
    lines = []
    for _ in range(frames):
        tokens = [rng.choice(_TOKENS) if rng.random() < 0.3 else b"%.17g" % rng.uniform(-1e3, 1e3)
                  for _ in range(channels)]
        line = b"".join(t + rng.choice(_SEPARATORS[:3] if rng.random() < 0.9 else _SEPARATORS) for t in tokens)
        lines.append(line if rng.random() < 0.9 else line + b"\n")
    data = b"\n".join(lines) + rng.choice((b"", b"\n", b"\r\n", b" "))
    asked_frames = frames if rng.random() < 0.8 else rng.choice((0, frames + 1, 10**9, 2**62, 2**63 - 1))
    asked_channels = channels if rng.random() < 0.8 else rng.choice((-1, channels - 1, 2**40, 2**61))
    return data, asked_frames, asked_channels


def motion_parser_expected(data: bytes, frames: int, channels: int) -> np.ndarray | None:
    """What ``_motion.parse`` must return (as float64 values), by its documented contract."""
    rows = [t for t in (re.split(rb"[ \t\r\f\v]+", line.strip(b" \t\r\f\v")) for line in data.split(b"\n"))
            if t != [b""]]
    if frames <= 0 or channels <= 0 or len(rows) != frames or any(len(r) != channels for r in rows):
        return None
    if not all(_PLAIN.fullmatch(tok) for row in rows for tok in row):
        return None
    values = np.array([[float(tok) for tok in row] for row in rows], dtype=np.float64)
    return values if np.isfinite(values).all() else None


def check_motion_parser(data: bytes, frames: int, channels: int) -> None:
    """AssertionError unless ``_motion.parse`` does exactly what its contract says (bit for bit)."""
    got = _motion.parse(data, frames, channels)
    expected = motion_parser_expected(data, frames, channels)
    if expected is None or got is None:
        if expected is not None or got is not None:
            raise AssertionError(f"_motion.parse({data[:60]!r}..., {frames}, {channels}): "
                                 f"{'None' if got is None else 'values'}, expected "
                                 f"{'None' if expected is None else 'values'}")
        return
    if got != expected.tobytes():
        raise AssertionError(f"_motion.parse({data[:60]!r}..., {frames}, {channels}): values differ from float()")


# --------------------------------------------------------------------------------------------------------------
# What one input does.

READER_ERRORS = (BvhError, C3dError)
# Reasons of the ingest's quarantine that come from the reader (screen.READERS' names).
READER_REJECTION = ("malformed BVH:", "malformed C3D:")


@dataclass(frozen=True)
class Outcome:
    kind: str  # ingested | filtered | rejected_by_reader | quarantined | unexpected
    detail: str  # the reason's first words, or "<exception type>: <message>" when unexpected
    stage: str = ""  # where an unexpected one arose: "screen" (the screen and the readers) or "ingest" (after)

    @property
    def unexpected(self) -> bool:
        return self.kind == "unexpected"


# Where the screen ends: an exception raised in these files (or below them) arose while screening the file.
SCREEN_FILES = (str(Path(screen_file.__code__.co_filename)), str(Path(read_bvh.__code__.co_filename).parent))


class Harness:
    """The per-file ingest of the real manifests, on inputs written to a private folder laid out as the mocap
    root (the manifests' label rules and joint maps apply: each input keeps its seed's path)."""

    def __init__(self, parent: Path | None = None) -> None:
        """parent: a folder its owner removes (worker processes skip exit handlers); else one removed at exit."""
        if parent is None:
            self._folder = tempfile.TemporaryDirectory(prefix="emogait-fuzz-", dir=tmp_dir())
        self.root = Path(tempfile.mkdtemp(dir=parent) if parent is not None else self._folder.name)
        self.manifests = {m.name: m for m in load_manifests(SOURCES, formats=("bvh", "c3d"))}
        self.skeleton = load_skeleton(SKELETON)
        self.cfg = replace(ingest_config(load_params()), mocap_root=self.root)

    def run(self, seed: Seed, data: bytes) -> Outcome:
        """Screen, read and ingest one input. Anything but the ingest's own outcomes is unexpected."""
        path = self.root / seed.source / seed.rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        try:
            result = ingest_chunk(self.manifests[seed.source], self.skeleton, [(seed.rel, sha256_bytes(data))],
                                  self.cfg)
        except Exception as err:  # noqa: BLE001 - the point: ingest promises to record bad input, never raise
            return _unexpected(err, _stage(err))
        (record,) = result.records
        reason = record.reason or ""
        rejected = record.status == "quarantined" and reason.startswith(READER_REJECTION)
        if "data the bulk parser rejected" in reason:  # the reader could not say what is wrong: a bug
            return Outcome("unexpected", f"UnexplainedRejection: {reason[:300]}", "screen")
        if rejected and "MemoryError" in reason:  # the C3D reader's catch-all hid an allocation for a claim
            return Outcome("unexpected", f"MemoryError: {reason[:300]}", "screen")
        try:
            if seed.format == "bvh" and not rejected:
                _check_bulk_parse(data)  # parsed: the C bulk parser must agree with Python's float()
        except Exception as err:  # noqa: BLE001
            return _unexpected(err, "screen")
        try:
            if record.status == "ingested":
                _check_windows(result.windows)
        except Exception as err:  # noqa: BLE001
            return _unexpected(err, "ingest")
        return Outcome("rejected_by_reader" if rejected else record.status, _gist(reason))


def _unexpected(err: Exception, stage: str) -> Outcome:
    return Outcome("unexpected", f"{type(err).__name__}: {str(err)[:300]}", stage)


def _stage(err: Exception) -> str:
    files = [frame.filename for frame in traceback.extract_tb(err.__traceback__)]
    return "screen" if any(f.startswith(SCREEN_FILES) for f in files) else "ingest"


def tmp_dir() -> str | None:
    return "/dev/shm" if Path("/dev/shm").is_dir() else None  # inputs are written and read once: keep them in RAM


def _gist(reason: str) -> str:
    """A reason without the file path and numbers, to count reasons by kind."""
    text = re.sub(r"/\S*/\S*", "<path>", reason[:300])  # cut first: the pattern is quadratic in a long word
    return re.sub(r"(?<![A-Za-z])-?\d[\d.e+-]*", "N", text)[:120]


def _check_windows(windows: list[dict]) -> None:
    for w in windows:
        for key in ("positions", "rotations", "root_path", "heading"):
            if not np.isfinite(w[key]).all():
                raise FloatingPointError(f"window {w['gait_id']}: non-finite {key}")


def _check_bulk_parse(data: bytes) -> None:
    """The reader's motion equals a line-by-line float() parse of the frame lines, and the Arrow fallback's
    parse of them, bit for bit (the C parser promises float()'s correctly rounded values)."""
    clip = read_bvh("<fuzz>", data)
    text = data.decode("utf-8")
    if "\n" not in text:
        text = text.replace("\r", "\n")
    motion = re.split(r"^[ \t]*MOTION[ \t]*\r?$", text, maxsplit=1, flags=re.M)[1]
    after_header = motion[motion.index("Frame Time:"):]
    frame_text = after_header[after_header.find("\n") + 1:] if "\n" in after_header else ""
    rows = [line.split() for line in frame_text.split("\n") if line.split()]
    expected = np.array([[float(v) for v in row] for row in rows], dtype=np.float64)
    arrow = _bulk_frames_arrow(frame_text.encode("ascii", errors="replace"), *clip.motion.shape)
    for name, other in (("float()", expected), ("the Arrow fallback", arrow)):
        if other is None or other.shape != clip.motion.shape or not np.array_equal(
                other.view(np.uint64), clip.motion.view(np.uint64)):
            raise AssertionError(f"bulk parse {clip.motion.shape} differs from {name}: "
                                 f"{None if other is None else other.shape}")


def huge_claims(seeds: list[Seed]) -> list[tuple[str, Seed, bytes]]:
    """Inputs that claim far more than they hold: (what, seed, bytes). BVH: Frames: 10^9 and more, a CHANNELS
    count of 999999; C3D: 10^9 frames (TRIAL:ACTUAL_END_FIELD, or an added POINT:LONG_FRAMES), 65535 frames in
    the header, 65535 points or analog channels. A reader must turn each away without allocating for it."""
    out = []
    for seed in seeds:
        if seed.format == "bvh":
            for count in (b"1000000000", b"9223372036854775807", b"1" + b"0" * 30):
                data = _FRAMES_LINE.sub(lambda m: m.group(1) + count, seed.data, count=1)
                out.append((f"Frames: {count[:12].decode()}{'...' if len(count) > 12 else ''}", seed, data))
            data = re.sub(rb"CHANNELS[ \t]+6", b"CHANNELS 999999", seed.data, count=1)
            out.append(("CHANNELS 999999", seed, data))
            continue
        out.append(("10^9 frames", seed, claim_c3d_frames(seed.data, 10**9)))
        layout = c3d_layout(seed.data)
        for what, edit in (("header last frame 65535", lambda b: struct.pack_into("<H", b, 8, 0xFFFF)),
                           ("POINT:USED 65535", lambda b: _set_word(b, layout, "POINT", "USED", 0xFFFF)),
                           ("ANALOG:USED 65535", lambda b: _set_word(b, layout, "ANALOG", "USED", 0xFFFF))):
            data = bytearray(seed.data)
            edit(data)
            out.append((what, seed, bytes(data)))
    return out


def _set_word(data: bytearray, layout: C3dLayout, group: str, name: str, value: int) -> None:
    p = layout.find(group, name)
    if p is not None and p.type == 2:
        struct.pack_into(layout.order + "H", data, p.data, value)


def claim_c3d_frames(data: bytes, frames: int) -> bytes:
    """The file claiming ``frames`` frames where py-c3d looks past the header's 16-bit last frame: the TRIAL
    end field when the file has one, else a POINT:LONG_FRAMES parameter added to the section."""
    layout = c3d_layout(data)
    trial = layout.find("TRIAL", "ACTUAL_END_FIELD")
    if trial is not None and trial.type == 2 and trial.size == 4:
        out = bytearray(data)
        struct.pack_into(layout.order + "HH", out, trial.data, frames & 0xFFFF, frames >> 16)
        return bytes(out)
    rng = random.Random(0)
    while True:  # the records mutator, drawn until it adds LONG_FRAMES (its value: 10^9)
        out, what = _m_c3d_records(data, rng)
        if what.startswith("records_add_long_frames"):
            return out if frames == 10**9 else out.replace(_pack_float(1e9, layout), _pack_float(frames, layout))


def read_claim(fmt: str, data: bytes) -> str:
    """Read bytes with a format's reader: "parsed" or the reader's error type (others propagate)."""
    try:
        (read_bvh if fmt == "bvh" else read_c3d)("<claim>", data)
    except READER_ERRORS as err:
        return type(err).__name__
    return "parsed"
