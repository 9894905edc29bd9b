"""Bad inputs to the ingest stage: each one ends quarantined (bad data) or filtered (policy) with a reason
that names the problem, and the good files beside them are still ingested.

Every input is built at run time in pytest's tmp_path, mostly by corrupting the real CMU file 131_01.bvh
(CRLF header, tabs, 120 fps, 994 frames, 96 channels), and all of them are the files of ONE temporary source
manifest, ingested by ONE ``run_ingest`` call (module-scoped fixture). Each case is then its own test: the
status, the report entry and the reason; for parser errors the whole reason,
``malformed BVH: <path>:<line>: expected ..., found ...``, with the line computed from the corruption.
Direct ``parse_bvh`` tests at the end pin ``err.line`` on small hand-written texts.
"""

from __future__ import annotations

import copy
import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from pipeline.ingest.run import IngestConfig, run_ingest
from pipeline.io.readers.bvh import VALID_CHANNELS, BvhError, parse_bvh, read_bvh
from pipeline.core.skeleton import load_skeleton
from pipeline.io.manifests import load_manifest

REPO = Path(__file__).resolve().parents[1]
BASE_BVH = REPO.parent / "shared/data/mocap/cmu_bvh11/resources/131_01.bvh"
BASE_SHA256 = "525a261b085d44ea302205f7bbdf824c20ca8256b9e0797aeae43183326fce27"
SOURCE = "bad_inputs"

# Layout of 131_01.bvh (1-based line numbers; checked against the file by the fixture).
LHIPJOINT_JOINT = 6  # "JOINT LHipJoint"
LHIPJOINT_CHANNELS = 9  # "CHANNELS 3 Zrotation Yrotation Xrotation"
LEFTHIP_OFFSET = 12  # "OFFSET 1.24777 -1.64261 0.71711"
LEFTHIP_CHANNELS = 13
LEFTKNEE_JOINT = 14
LEFTKNEE_OFFSET = 16  # "OFFSET 2.49329 -6.85026 0.00000"
LEFTKNEE_CHANNELS = 17
ROOT_CLOSE = 184  # the "}" closing Hips
MOTION_LINE = 185
FRAMES_LINE = 186  # "Frames: 994"
FRAME_TIME_LINE = 187  # "Frame Time: .0083333"
N_FRAMES = 994
N_CHANNELS = 96
LAST_LINE = FRAME_TIME_LINE + N_FRAMES  # 1181


def frame_line(f: int) -> int:
    """The line number of frame ``f`` (0-based) in the base file: header lines + frame index + 1."""
    return FRAME_TIME_LINE + f + 1


# --------------------------------------------------------------------------------------------------------------
# Editing helpers: ``lines`` is the base text split with line endings kept; line numbers are 1-based.


def _eol(line: str) -> str:
    return line[len(line.rstrip("\r\n")):]


def sub(lines: list[str], n: int, old: str, new: str) -> list[str]:
    assert old in lines[n - 1], f"line {n} is {lines[n - 1]!r}, not containing {old!r}"
    lines[n - 1] = lines[n - 1].replace(old, new, 1)
    return lines


def set_line(lines: list[str], n: int, new: str) -> list[str]:
    lines[n - 1] = new + _eol(lines[n - 1])
    return lines


def edit_values(lines: list[str], n: int, fn: Callable[[list[str]], list[str]]) -> list[str]:
    lines[n - 1] = " ".join(fn(lines[n - 1].split())) + _eol(lines[n - 1])
    return lines


def put(tokens: list[str], k: int, value: str) -> list[str]:
    tokens[k] = value
    return tokens


def delete(lines: list[str], n: int) -> list[str]:
    del lines[n - 1]
    return lines


def insert_after(lines: list[str], n: int, *new: str) -> list[str]:
    lines[n:n] = list(new)
    return lines


def encode(lines: list[str]) -> bytes:
    return "".join(lines).encode()


# --------------------------------------------------------------------------------------------------------------
# Builders that need more than one edit.


def truncated_mid_motion(lines: list[str]) -> bytes:
    """The last frame line cut in half at a space, without its line break."""
    tokens = lines[-1].split()
    return encode(lines[:-1]) + " ".join(tokens[: len(tokens) // 2]).encode()


def bad_value_after_blank_line(lines: list[str]) -> bytes:
    """A blank line after frame 2 (allowed), then 'abc' in frame 5: the reported line must count the blank."""
    edit_values(lines, frame_line(5), lambda t: put(t, 10, "abc"))
    return encode(insert_after(lines, frame_line(2), "\n"))


def non_utf8_byte_in_frame(lines: list[str]) -> bytes:
    n = frame_line(2)
    return encode(lines[: n - 1]) + b"\xff" + encode(lines[n - 1:])


def checksum_mismatch(lines: list[str]) -> bytes:
    """A well-formed file whose content changed (one value) since it was pinned."""
    return encode(edit_values(lines, frame_line(0), lambda t: put(t, 0, "5.2301")))


def bone_collapses_at_frame_500(lines: list[str]) -> bytes:
    """LeftKnee gets position channels: its OFFSET in every frame, except frame 500 where it sits on LeftHip."""
    sub(lines, LEFTKNEE_CHANNELS, "CHANNELS 3 ", "CHANNELS 6 Xposition Yposition Zposition ")
    for f in range(N_FRAMES):
        pos = ["0", "0", "0"] if f == 500 else ["2.49329", "-6.85026", "0.00000"]
        edit_values(lines, frame_line(f), lambda t, pos=pos: t[:12] + pos + t[12:])
    return encode(lines)


def giant_offsets(lines: list[str]) -> bytes:
    """Every OFFSET x100: a body about 80 m tall-legged at the manifest's unit scale (wrong units)."""
    for n, line in enumerate(lines[:ROOT_CLOSE], start=1):
        tokens = line.split()
        if tokens and tokens[0] == "OFFSET":
            indent = line[: len(line) - len(line.lstrip())]
            set_line(lines, n, indent + "OFFSET " + " ".join(f"{100 * float(v):.5f}" for v in tokens[1:]))
    return encode(lines)


def all_zero_motion(lines: list[str]) -> bytes:
    for f in range(N_FRAMES):
        set_line(lines, frame_line(f), " ".join(["0.0"] * N_CHANNELS))
    return encode(lines)


def too_short(lines: list[str]) -> bytes:
    """40 frames at 120 fps: 39 frame times = 0.325 s (printed 0.32)."""
    set_line(lines, FRAMES_LINE, "Frames: 40")
    return encode(lines[: frame_line(39)])


def tolerated_variants(lines: list[str]) -> bytes:
    """Not bad: LF line endings, blank lines between frames, trailing blank lines and spaces."""
    out = []
    for n, line in enumerate(lines, start=1):
        out.append(line.rstrip("\r\n") + "\n")
        if n > FRAME_TIME_LINE and (n - FRAME_TIME_LINE) % 100 == 0:
            out.append("\n  \t\n")
    return encode(out + ["   \n", "\n"])


def cr_only_line_endings(lines: list[str]) -> bytes:
    return "".join(line.rstrip("\r\n") + "\r" for line in lines).encode()


# --------------------------------------------------------------------------------------------------------------
# The cases.

WRONG_MAP_OVERRIDE = {"left_knee": "NoSuchJoint"}


@dataclass(frozen=True)
class Case:
    name: str  # file stem; the file is <name>.bvh in the source folder
    build: Callable[[list[str], bytes], bytes | None]  # (base lines, base bytes) -> file bytes; None: not written
    status: str  # "ingested", "quarantined" or "filtered"
    error: tuple[int | None, str, str] | None = None  # a BvhError's (line, expected, found): the whole reason
    contains: tuple[str, ...] = ()  # otherwise: substrings of the reason ("{path}" = the file's absolute path)
    pin: str = "actual"  # "actual": sha256 of the built file; "base": of the unmodified base; "none": unpinned
    joint_map_override: dict | None = None  # canonical joint -> source joint, overriding the manifest's map

    @property
    def file(self) -> str:
        return f"{self.name}.bvh"


def lines_case(name: str, edit: Callable[[list[str]], list[str]], line: int | None, expected: str,
               found: str) -> Case:
    """A malformed file made by editing the base lines, with the BvhError it must be quarantined for."""
    return Case(name, lambda lines, raw: encode(edit(lines)), "quarantined", error=(line, expected, found))


def raw_case(name: str, data: bytes, line: int | None, expected: str, found: str) -> Case:
    return Case(name, lambda lines, raw: data, "quarantined", error=(line, expected, found))


CASES = [
    # --- good and tolerated files: the run must go on past every bad file ---
    Case("good", lambda lines, raw: raw, "ingested"),
    Case("tolerated_lf_and_blank_lines", lambda lines, raw: tolerated_variants(lines), "ingested"),
    # --- truncation ---
    lines_case("truncated_mid_hierarchy", lambda L: L[:LEFTKNEE_OFFSET], None,
               "'}' closing 'LeftKnee' and then MOTION", "end of file (truncated hierarchy)"),
    Case("truncated_mid_motion", lambda lines, raw: truncated_mid_motion(lines), "quarantined",
         error=(LAST_LINE, f"{N_CHANNELS} channel values in frame {N_FRAMES - 1}", f"{N_CHANNELS // 2}")),
    lines_case("truncated_at_frame_500", lambda L: L[: frame_line(499)], FRAMES_LINE,
               "Frames: 994 to match the frame lines", "500 frame lines"),
    # --- frame lines ---
    lines_case("frame_value_missing", lambda L: edit_values(L, frame_line(3), lambda t: t[:-1]), frame_line(3),
               f"{N_CHANNELS} channel values in frame 3", f"{N_CHANNELS - 1}"),
    lines_case("frame_value_extra", lambda L: edit_values(L, frame_line(10), lambda t: t + ["0.0"]),
               frame_line(10), f"{N_CHANNELS} channel values in frame 10", f"{N_CHANNELS + 1}"),
    lines_case("frame_value_abc", lambda L: edit_values(L, frame_line(5), lambda t: put(t, 10, "abc")),
               frame_line(5), "a number for 'LeftHip Yrotation' in frame 5", "'abc'"),
    lines_case("frame_value_nan", lambda L: edit_values(L, frame_line(7), lambda t: put(t, 0, "nan")),
               frame_line(7), "a finite number for 'Hips Xposition' in frame 7", "'nan'"),
    lines_case("frame_value_inf", lambda L: edit_values(L, LAST_LINE, lambda t: put(t, 95, "-inf")), LAST_LINE,
               f"a finite number for 'RThumb Yrotation' in frame {N_FRAMES - 1}", "'-inf'"),  # RThumb: Z X Y order
    Case("bad_value_after_blank_line", lambda lines, raw: bad_value_after_blank_line(lines), "quarantined",
         error=(frame_line(5) + 1, "a number for 'LeftHip Yrotation' in frame 5", "'abc'")),
    Case("underscore_in_number",
         lambda lines, raw: encode(edit_values(lines, frame_line(4), lambda t: put(t, 20, "1_0"))),
         "quarantined", contains=(f"{{path}}:{frame_line(4)}: expected", "'1_0'")),
    Case("quoted_number",
         lambda lines, raw: encode(edit_values(lines, frame_line(2), lambda t: put(t, 3, '"1"'))),
         "quarantined", contains=(f"{{path}}:{frame_line(2)}: expected", "'\"1\"'")),
    # --- MOTION header ---
    lines_case("motion_keyword_missing", lambda L: delete(L, MOTION_LINE), MOTION_LINE,
               "'MOTION' after the hierarchy", "'Frames: 994'"),
    lines_case("frames_more_than_data", lambda L: set_line(L, FRAMES_LINE, "Frames: 1000"), FRAMES_LINE,
               "Frames: 1000 to match the frame lines", "994 frame lines"),
    lines_case("frames_fewer_than_data", lambda L: set_line(L, FRAMES_LINE, "Frames: 990"), frame_line(990),
               "Frames: 990 frame lines, then end of file", "more frame lines"),
    lines_case("frames_not_integer", lambda L: set_line(L, FRAMES_LINE, "Frames: 994.5"), FRAMES_LINE,
               "a non-negative integer frame count", "'994.5'"),
    lines_case("frames_zero", lambda L: set_line(L, FRAMES_LINE, "Frames: 0"), FRAMES_LINE,
               "at least one frame", "Frames: 0"),
    lines_case("frame_time_zero", lambda L: set_line(L, FRAME_TIME_LINE, "Frame Time: 0"), FRAME_TIME_LINE,
               "a positive Frame Time in seconds", "0"),
    lines_case("frame_time_negative", lambda L: set_line(L, FRAME_TIME_LINE, "Frame Time: -.0083333"),
               FRAME_TIME_LINE, "a positive Frame Time in seconds", "-.0083333"),
    lines_case("frame_time_not_number", lambda L: set_line(L, FRAME_TIME_LINE, "Frame Time: fast"),
               FRAME_TIME_LINE, "a number in Frame Time", "'fast'"),
    lines_case("frame_time_missing", lambda L: delete(L, FRAME_TIME_LINE), FRAME_TIME_LINE,
               "'Frame Time: <value>'", "'5.2300 16.9002 -33.8986 -5.4029 9.8098 1'"),
    # --- hierarchy ---
    lines_case("unknown_channel", lambda L: sub(L, LHIPJOINT_CHANNELS, "Xrotation", "Wrotation"),
               LHIPJOINT_CHANNELS, f"a channel name in {VALID_CHANNELS}", "'Wrotation'"),
    lines_case("channel_count_mismatch", lambda L: sub(L, LEFTHIP_CHANNELS, "CHANNELS 3", "CHANNELS 4"),
               LEFTHIP_CHANNELS, "4 channel names for 'LeftHip'", "3"),
    lines_case("duplicate_channel", lambda L: sub(L, LEFTHIP_CHANNELS, "Yrotation", "Zrotation"),
               LEFTHIP_CHANNELS, "each channel at most once per joint", "Zrotation Zrotation Xrotation"),
    lines_case("duplicate_joint_name", lambda L: sub(L, LEFTKNEE_JOINT, "JOINT LeftKnee", "JOINT LeftHip"),
               LEFTKNEE_JOINT, "unique joint names", "duplicate joint name 'LeftHip'"),
    lines_case("second_root_nested", lambda L: sub(L, LHIPJOINT_JOINT, "JOINT LHipJoint", "ROOT LHipJoint"),
               LHIPJOINT_JOINT, "one ROOT at the top level", "a second ROOT"),
    lines_case("second_root_top_level",
               lambda L: insert_after(L, ROOT_CLOSE, "ROOT Extra\r\n", "{\r\n", "\tOFFSET 0 0 0\r\n",
                                      "\tCHANNELS 3 Zrotation Yrotation Xrotation\r\n", "}\r\n"),
               ROOT_CLOSE + 1, "'MOTION' after the hierarchy", "'ROOT Extra'"),
    lines_case("offset_two_values", lambda L: sub(L, LEFTHIP_OFFSET, " 0.71711", ""), LEFTHIP_OFFSET,
               "3 OFFSET values for 'LeftHip'", "2"),
    lines_case("offset_not_number", lambda L: sub(L, LEFTHIP_OFFSET, "-1.64261", "1.2.3"), LEFTHIP_OFFSET,
               "a number in OFFSET of 'LeftHip'", "'1.2.3'"),
    lines_case("extra_close_brace", lambda L: insert_after(L, ROOT_CLOSE, "}\r\n"), ROOT_CLOSE + 1,
               "'MOTION' after the hierarchy", "'}'"),
    lines_case("missing_close_brace", lambda L: delete(L, ROOT_CLOSE), ROOT_CLOSE,
               "ROOT, JOINT, End Site, OFFSET, CHANNELS, '{' or '}'", "'MOTION'"),
    # --- not BVH text at all ---
    raw_case("empty_file", b"", None, "'HIERARCHY'", "an empty file"),
    raw_case("blank_lines_only", b"\r\n  \n\t\n", None, "'HIERARCHY'", "an empty file"),
    raw_case("text_not_bvh", b"\nhello, this is not a BVH file\n", 2, "'HIERARCHY'",
             "'hello, this is not a BVH file'"),
    # bytes 0..255 after an 8-byte header: one b"\n" (0x0a) precedes the first invalid byte 0x80 -> line 2
    raw_case("binary_garbage", b"\x7fELF\x02\x01\x01\x00" + bytes(range(256)), 2, "UTF-8/ASCII text",
             "undecodable byte 0x80"),
    Case("non_utf8_byte_in_frame", lambda lines, raw: non_utf8_byte_in_frame(lines), "quarantined",
         error=(frame_line(2), "UTF-8/ASCII text", "undecodable byte 0xff")),
    # classic-Mac line ends are a valid encoding, not an error
    Case("cr_only_line_endings", lambda lines, raw: cr_only_line_endings(lines), "ingested"),
    # --- manifest: checksum, presence, pinning, joint map, label rule ---
    Case("checksum_mismatch", lambda lines, raw: checksum_mismatch(lines), "quarantined", pin="base",
         contains=(f"sha256 mismatch: expected {BASE_SHA256} (manifest), found {{sha256}}",)),
    Case("missing_file", lambda lines, raw: None, "quarantined", pin="base",
         contains=(f"missing: the manifest pins missing_file.bvh (sha256 {BASE_SHA256}) but no file is at {{path}}",
                   "obtain it from https://github.com/")),
    Case("unpinned_file", lambda lines, raw: raw, "quarantined", pin="none",
         contains=("not pinned: the manifest lists no sha256 for this file (found {sha256}); pin it to ingest it",)),
    Case("joint_map_names_missing_joint", lambda lines, raw: raw, "quarantined",
         joint_map_override=WRONG_MAP_OVERRIDE,
         contains=("joint map: the joint map names ['NoSuchJoint'] which the file lacks (it has 38 joints)",)),
    Case("Name-Not-In-Label-Rule", lambda lines, raw: raw, "quarantined",
         contains=("label rule: file name 'Name-Not-In-Label-Rule.bvh' does not match the label pattern",)),
    # --- readable, but cannot be retargeted ---
    Case("zero_length_bone", lambda lines, raw: encode(set_line(lines, LEFTKNEE_OFFSET, "\t\t\t\tOFFSET 0 0 0")),
         "quarantined", contains=("retarget: frame 0: bone left_hip->left_knee has length 0 source units",)),
    Case("bone_collapses_at_frame_500", lambda lines, raw: bone_collapses_at_frame_500(lines), "quarantined",
         contains=("retarget: frame 500: bone left_hip->left_knee has length 0 source units",
                   "expected a non-zero bone")),
    Case("giant_offsets", lambda lines, raw: giant_offsets(lines), "quarantined",
         contains=("retarget: leg length ", " m (at 0.0564 m per unit) is outside the human range 0.4-1.4 m")),
    # --- fine data, not wanted: filtered ---
    Case("all_zero_motion", lambda lines, raw: all_zero_motion(lines), "filtered",
         contains=("not a gait: mean horizontal root speed 0.00 m/s < 0.2 m/s",)),
    Case("too_short", lambda lines, raw: too_short(lines), "filtered",
         contains=("too short: 0.32 s (40 frames at 120.00 fps); a clip needs >= 2.00 s for one 60-frame window "
                   "at 30 fps",)),
]


def _case_of(param) -> Case:
    return param.values[0] if hasattr(param, "values") else param


ALL_CASES = [_case_of(p) for p in CASES]
assert len({c.name for c in ALL_CASES}) == len(ALL_CASES), "case names must be unique"


# --------------------------------------------------------------------------------------------------------------
# One ingest run over all cases.


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    if not BASE_BVH.is_file():
        pytest.skip(f"the real CMU file {BASE_BVH} is not available")
    raw = BASE_BVH.read_bytes()
    assert hashlib.sha256(raw).hexdigest() == BASE_SHA256
    base_lines = raw.decode().splitlines(keepends=True)
    assert len(base_lines) == raw.count(b"\n") == LAST_LINE
    for n, start in [(LHIPJOINT_JOINT, "JOINT LHipJoint"), (LEFTKNEE_OFFSET, "OFFSET 2.49329 -6.85026 0.00000"),
                     (ROOT_CLOSE, "}"), (MOTION_LINE, "MOTION"), (FRAMES_LINE, "Frames: 994"),
                     (FRAME_TIME_LINE, "Frame Time: .0083333")]:
        assert base_lines[n - 1].strip() == start, (n, base_lines[n - 1])
    assert len(base_lines[frame_line(0) - 1].split()) == N_CHANNELS

    mocap_root = tmp_path_factory.mktemp("mocap")
    source_dir = mocap_root / SOURCE
    source_dir.mkdir()
    pins, overrides, written = [], {}, {}
    base_map = yaml.safe_load((REPO / "manifests/sources/cmu_bvh11.yaml").read_text())["joint_map"]
    for case in ALL_CASES:
        data = case.build(list(base_lines), raw)
        if data is not None:
            (source_dir / case.file).write_bytes(data)
            written[case.file] = hashlib.sha256(data).hexdigest()
        if case.pin != "none":
            pins.append({"path": case.file, "sha256": BASE_SHA256 if case.pin == "base" else written[case.file]})
        if case.joint_map_override:
            overrides[case.file] = {**base_map, **case.joint_map_override}

    doc = copy.deepcopy(yaml.safe_load((REPO / "manifests/sources/cmu_bvh11.yaml").read_text()))
    doc["name"] = SOURCE
    doc["globs"] = ["*.bvh"]
    doc["label_rule"] = {"pattern": r"^(?P<case>[a-z0-9_]+)\.bvh$", "fixed": {"content": "walk", "style": "test"},
                         "emotions": []}
    doc["gait_contents"] = ["walk"]
    doc["joint_map_overrides"] = overrides
    doc["files"] = pins
    manifest_path = mocap_root / f"{SOURCE}.yaml"
    manifest_path.write_text(yaml.safe_dump(doc, sort_keys=False))
    manifest = load_manifest(manifest_path)

    skeleton = load_skeleton(REPO / "manifests/skeleton.yaml")
    cfg = IngestConfig(mocap_root=mocap_root, target_fps=30, window=60, stride=30, min_gait_speed=0.2,
                       chunk_frames=20000)
    windows, report = run_ingest([manifest], skeleton, cfg, workers=1, progress=False)
    return SimpleNamespace(source_dir=source_dir, sha256=written, windows=windows, report=report)


def _entries(report: dict, file: str) -> list[tuple[str, dict]]:
    return [(kind, e) for kind in ("quarantine", "filtered") for e in report[kind] if e["path"] == file]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_case_outcome(run, case: Case):
    entries = _entries(run.report, case.file)
    path = run.source_dir / case.file
    if case.status == "ingested":
        assert entries == []
        gaits = [w for w in run.windows if w["file"] == case.file]
        assert len(gaits) > 0
        return
    assert len(entries) == 1, f"{case.file}: expected exactly one report entry, found {entries}"
    kind, entry = entries[0]
    assert kind == {"quarantined": "quarantine", "filtered": "filtered"}[case.status], entry
    assert entry["source"] == SOURCE
    assert entry["path"] == case.file
    assert entry["sha256"] == run.sha256.get(case.file)  # as found on disk; None when missing
    reason = entry["reason"]
    if case.error is not None:
        line, expected, found = case.error
        where = f"{path}:{line}" if line is not None else f"{path}"
        assert reason == f"malformed BVH: {where}: expected {expected}, found {found}"
    for part in case.contains:
        part = part.replace("{path}", str(path)).replace("{sha256}", str(run.sha256.get(case.file)))
        assert part in reason


def test_report_accounts_for_every_file(run):
    report = run.report
    made = len(ALL_CASES)  # every case is one file (the missing one is listed in the manifest only)
    assert len(run.sha256) == made - 1
    assert report["files_seen"] == made
    assert report["files_ingested"] + report["files_quarantined"] + report["files_filtered"] == made
    expected = {s: sum(c.status == s for c in ALL_CASES) for s in ("ingested", "quarantined", "filtered")}
    assert report["files_ingested"] == expected["ingested"]
    assert report["files_quarantined"] == expected["quarantined"] == len(report["quarantine"])
    assert report["files_filtered"] == expected["filtered"] == len(report["filtered"])
    listed = [e["path"] for e in report["quarantine"] + report["filtered"]]
    assert sorted(listed) == sorted(c.file for c in ALL_CASES if c.status != "ingested")
    assert report["per_source"][SOURCE]["files_seen"] == made
    assert report["gaits"] == len(run.windows) == report["per_source"][SOURCE]["gaits"]


def test_good_files_proceed(run):
    """The bad files do not stop or change the good ones; a tolerated variant gives the very same windows."""
    files = {w["file"] for w in run.windows}
    assert files == {c.file for c in ALL_CASES if c.status == "ingested"}
    good = [w for w in run.windows if w["file"] == "good.bvh"]
    variant = [w for w in run.windows if w["file"] == "tolerated_lf_and_blank_lines.bvh"]
    cr_only = [w for w in run.windows if w["file"] == "cr_only_line_endings.bvh"]
    assert len(good) == len(variant) == len(cr_only) > 0
    for a, b in zip(good, cr_only):
        np.testing.assert_array_equal(a["positions"], b["positions"])
    for a, b in zip(good, variant):
        assert a["content"] == "walk" and a["source"] == SOURCE and a["sha256"] == BASE_SHA256
        np.testing.assert_array_equal(a["positions"], b["positions"])


# --------------------------------------------------------------------------------------------------------------
# parse_bvh / read_bvh directly, on a small hand-written file.

SMALL = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Leg
  {
    OFFSET 0 -1 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.1
0 0 0 0 0 0 0 0 0
1 1 1 1 1 1 1 1 1
2 2 2 2 2 2 2 2 2
"""  # line 6: JOINT Leg, 8: its OFFSET, 9: its CHANNELS, 17: Frames, 18: Frame Time, 19-21: frames 0-2


def test_small_file_parses():
    clip = parse_bvh(SMALL, "small.bvh")
    assert clip.skeleton.names == ("Hips", "Leg", "Leg/End")
    assert clip.frames == 3 and clip.skeleton.channel_count == 9
    np.testing.assert_array_equal(clip.motion[2], np.full(9, 2.0))


@pytest.mark.parametrize(
    ("text", "line", "expected", "found"),
    [
        pytest.param(SMALL.replace("1 1 1 1", "1 1 1 x"), 20, "a number for 'Hips Zrotation' in frame 1", "'x'",
                     id="bad-value-frame-1"),
        pytest.param(SMALL.replace("Frames: 3", "Frames: 4"), 17, "Frames: 4 to match the frame lines",
                     "3 frame lines", id="frames-more-than-data"),
        pytest.param(SMALL.replace("OFFSET 0 -1 0\n    CHANNELS", "OFFSET 0 -1\n    CHANNELS"), 8,
                     "3 OFFSET values for 'Leg'", "2", id="offset-two-values"),
        pytest.param(SMALL.replace("JOINT Leg", "JOINT Hips"), 6, "unique joint names",
                     "duplicate joint name 'Hips'", id="duplicate-joint"),
        pytest.param("\r\n\r\n" + SMALL.replace("\n", "\r\n").replace("2 2 2 2", "2 2 nan 2"), 23,
                     "a finite number for 'Hips Zposition' in frame 2", "'nan'", id="crlf-leading-blank-lines"),
    ],
)
def test_parse_error_line(text, line, expected, found):
    with pytest.raises(BvhError) as info:
        parse_bvh(text, "small.bvh")
    err = info.value
    assert (err.path, err.line, err.expected, err.found) == ("small.bvh", line, expected, found)
    assert str(err) == f"small.bvh:{line}: expected {expected}, found {found}"


def test_read_bvh_undecodable_byte_line():
    data = SMALL.encode().replace(b"1 1 1 1 1", b"1 1 \xe9 1 1")
    with pytest.raises(BvhError) as info:
        read_bvh("small.bvh", data)
    assert info.value.line == 20
    assert str(info.value) == "small.bvh:20: expected UTF-8/ASCII text, found undecodable byte 0xe9"


def test_frames_mismatch_names_frames_line_after_blank_line():
    with pytest.raises(BvhError) as info:
        parse_bvh(SMALL.replace("Frames: 3\n", "Frames: 4\n\n"), "small.bvh")
    assert info.value.line == 17
