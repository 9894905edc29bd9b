"""A short fuzz run of the readers and the ingest screen (``tests.fuzzing``; ``benchmarks/fuzz.py`` runs 100,000
inputs), files that claim far more than they hold, and the fuzzer's findings, each pinned as a small case.

Seeds are the real files, read in place; mutated inputs live in a temporary folder only.
"""

from __future__ import annotations

import random
import struct
import time
import tracemalloc
from collections import Counter

import numpy as np
import pytest

from pipeline.io.readers.bvh import BvhError, _motion, parse_bvh, read_bvh
from pipeline.io.readers.c3d import C3dError, read_c3d
from tests.fuzzing import (
    C3D_ROOT,
    Harness,
    c3d_layout,
    check_motion_parser,
    fuzz_input,
    huge_claims,
    load_seeds,
    motion_parser_case,
)
from tests.test_bad_inputs import SMALL

RUN_SEED = 14  # the number; any seed will do, a fixed one makes a failure replayable
INPUTS = 2000  # ~15 s; benchmarks/fuzz.py --seed 14 --replay INDEX reruns a failure with its traceback
PARSER_CASES = 5000  # the C MOTION parser alone: microseconds each
CLAIM_PEAK_MB = 32
FRAME_TIME_RANGE = "a Frame Time of 0.0001 to 1 s (1 to 10000 frames per second)"


@pytest.fixture(scope="module")
def seeds(mocap):
    return load_seeds(mocap)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # mutated numbers overflow float32 casts downstream
def test_short_fuzz_run_raises_nothing_unexpected(seeds):
    harness = Harness()
    outcomes: Counter = Counter()
    unexpected = []
    for index in range(INPUTS):
        seed, data, mutations = fuzz_input(seeds, RUN_SEED, index)
        outcome = harness.run(seed, data)
        outcomes[(seed.format, outcome.kind)] += 1
        if outcome.unexpected:
            unexpected.append((index, seed.name, mutations, outcome.detail))
    assert not unexpected, f"unexpected outcomes (index, seed, mutations, error): {unexpected[:5]}"
    for fmt in ("bvh", "c3d"):  # the run reached both the readers' errors and the ingest beyond them
        assert outcomes[(fmt, "rejected_by_reader")] > 0.2 * INPUTS / 2, outcomes
        assert outcomes[(fmt, "ingested")] + outcomes[(fmt, "filtered")] > 0.05 * INPUTS / 2, outcomes


@pytest.mark.skipif(_motion is None, reason="the C MOTION parser is not built (the reader uses Arrow)")
def test_motion_parser_keeps_its_contract():
    for case in range(PARSER_CASES):
        check_motion_parser(*motion_parser_case(random.Random(f"{RUN_SEED}:parser:{case}")))


def test_huge_claims_are_rejected_without_allocating_for_them(seeds):
    claims = huge_claims(seeds)
    assert {what for what, *_ in claims} >= {"Frames: 1000000000", "10^9 frames"}
    for what, seed, data in claims:
        tracemalloc.start()
        start = time.perf_counter()
        try:
            (read_bvh if seed.format == "bvh" else read_c3d)("claim", data)
            outcome = "parsed"
        except (BvhError, C3dError) as err:
            outcome = type(err).__name__
        finally:
            seconds = time.perf_counter() - start
            peak_mb = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
        if what.startswith("Frames") or what == "10^9 frames":  # (65535 analog channels may be right)
            assert outcome == {"bvh": "BvhError", "c3d": "C3dError"}[seed.format], (seed.name, what)
        assert peak_mb < CLAIM_PEAK_MB and seconds < 2.0, (seed.name, what, peak_mb, seconds)


def test_bvh_claiming_a_billion_frames_names_the_frames_line():
    with pytest.raises(BvhError) as info:
        parse_bvh(SMALL.replace("Frames: 3", "Frames: 1000000000"), "small.bvh")
    assert (info.value.line, info.value.found) == (17, "3 frame lines")


# --------------------------------------------------------------------------------------------------------------
# Findings: what each input raised before its fix, now the reader's own error (file, line, expected, found).


@pytest.mark.parametrize(
    ("text", "line", "expected", "found"),
    [  # ValueError from int(): str.isdigit() accepts "²" and int() refuses more than 4300 digits
        pytest.param(SMALL.replace("Frames: 3", "Frames: \u00b2"), 17, "a non-negative integer frame count", "'²'",
                     id="frames-superscript-digit"),
        pytest.param(SMALL.replace("Frames: 3", "Frames: 1" + "0" * 5000), 17, "a frame count below 10^18",
                     "a number of 5001 digits", id="frames-5001-digits"),
        # OverflowError: the count did not fit the C parser's 64-bit size
        pytest.param(SMALL.replace("Frames: 3", "Frames: 99999999999999999999"), 17, "a frame count below 10^18",
                     "a number of 20 digits", id="frames-past-2^64"),
        # MemoryError / SystemError / a heap overflow: frames x channels x 8 bytes were allocated before reading;
        # for these 9 channels that is 2^64 + 56 bytes, which wrapped to 56
        pytest.param(SMALL.replace("Frames: 3", "Frames: 256204778801521551"), 17,
                     "Frames: 256204778801521551 to match the frame lines", "3 frame lines", id="frames-size-wraps"),
        pytest.param(SMALL.replace("CHANNELS 3", "CHANNELS \u00b3"), 9, "a channel count after CHANNELS", "'³'",
                     id="channels-superscript-digit"),
        # numpy ValueError (ragged OFFSET array): a declared End Site never opened kept no OFFSET
        pytest.param(SMALL.replace("    End Site\n", "    End Site\n    End Site\n"), 11,
                     "'{' opening the block of 'Leg/End'", "'End Site'", id="end-site-twice"),
        pytest.param(SMALL.replace("  JOINT Leg\n", "  JOINT Leg\n  }\n"), 7, "'{' opening the block of 'Leg'",
                     "'}'", id="joint-without-block"),
        # OverflowError in resampling (an infinite duration) / an infinite fps
        pytest.param(SMALL.replace("Frame Time: 0.1", "Frame Time: 1e308"), 18, FRAME_TIME_RANGE, "1e308",
                     id="frame-time-1e308"),
        pytest.param(SMALL.replace("Frame Time: 0.1", "Frame Time: 1e-320"), 18, FRAME_TIME_RANGE, "1e-320",
                     id="frame-time-denormal"),
        # "data the bulk parser rejected" with no line: separators and digits that str.split() and \d accept
        pytest.param(SMALL.replace("1 1 1 1 1", "1 1 1\u00a01 1"), 20, "9 channel values in frame 1", "8",
                     id="nbsp-separator"),
        pytest.param(SMALL.replace("1 1 1 1 1", "1 1 1\x1c1 1"), 20, "9 channel values in frame 1", "8",
                     id="file-separator-byte"),
        pytest.param(SMALL.replace("2 2 2 2 2", "2 2 \uff12 2 2"), 21, "a number for 'Hips Zposition' in frame 2",
                     "'２'", id="fullwidth-digit"),
    ],
)
def test_fuzz_finding_raises_bvh_error(text, line, expected, found):
    with pytest.raises(BvhError) as info:
        parse_bvh(text, "small.bvh")
    assert (info.value.line, info.value.expected, info.value.found) == (line, expected, found)


def test_long_numbers_parse_as_float_does():
    """A 150-digit value was refused by the C parser (a 128-byte buffer) and then found fine by the diagnosis."""
    long_value = "0." + "0" * 150 + "1"
    clip = parse_bvh(SMALL.replace("1 1 1 1 1", f"1 1 1 1 {long_value}"), "small.bvh")
    assert clip.motion[1, 4] == float(long_value)
    if _motion is not None:
        assert _motion.parse(b"9" * 300 + b" 1\n", 1, 2) == struct.pack("dd", float("9" * 300), 1.0)


def test_a_huge_joint_name_is_quoted_by_its_start():
    name = "J" * 100_000
    with pytest.raises(BvhError) as info:
        parse_bvh(SMALL.replace("ROOT Hips", f"ROOT {name}").replace("JOINT Leg", f"JOINT {name}"), "small.bvh")
    assert info.value.line == 6 and len(str(info.value)) < 500
    found = "duplicate joint name '" + "J" * 178  # the first 200 of its 100,023 characters
    assert str(info.value).endswith(f"found {found}... (100023 characters)")


@pytest.mark.usefixtures("mocap")
@pytest.mark.parametrize(
    ("edit", "expected"),
    [  # ValueError from py-c3d's lazy decoding of POINT:FRAMES (read outside the reader's try)
        pytest.param(lambda data, layout: data.__setitem__(layout.find("POINT", "FRAMES").body, 0),
                     "decodable POINT:USED, frame range", id="point-frames-of-0-byte-elements"),
        # ZeroDivisionError in the message for an analog/point rate mismatch with POINT:RATE 0
        pytest.param(lambda data, layout: (struct.pack_into("<f", data, 20, 0.0),
                                           data.__setitem__(slice(layout.find("POINT", "RATE").data,
                                                                  layout.find("POINT", "RATE").data + 4),
                                                            struct.pack("<f", 0.0))),
                     "analog samples per point frame", id="point-rate-zero"),
    ],
)
def test_fuzz_finding_raises_c3d_error(mocap, edit, expected):
    data = bytearray((mocap / C3D_ROOT / "sample_01" / "Eb015pi.c3d").read_bytes())  # Intel integer format
    edit(data, c3d_layout(bytes(data)))
    with pytest.raises(C3dError) as info:
        read_c3d("eb015pi.c3d", bytes(data))
    assert expected in info.value.expected


def test_seeds_read_as_their_sources(seeds):
    """The cut seeds are still their files: each reads (evart.c3d is rejected as a whole file too)."""
    for seed in seeds:
        if seed.name.startswith(C3D_ROOT + "sample_11/"):
            continue
        clip = (read_bvh if seed.format == "bvh" else read_c3d)(seed.name, seed.data)
        assert clip.frames > 0 and np.isfinite(clip.positions if seed.format == "c3d" else clip.motion).any()
