"""The BVH reader on the real files, against the `bvh` package, and on hand-made hierarchies with known answers."""

import csv

import numpy as np
import pytest
import torch
from bvh import Bvh

from pipeline.io.readers.bvh import parse_bvh, read_bvh
from pipeline.ingest.retarget import bvh_point_positions
from tests.conftest import MOCAP

SHARED_ROWS = ([r for r in csv.DictReader(open(MOCAP / "manifest.csv")) if r["kind"] == "bvh"]
               if (MOCAP / "manifest.csv").is_file() else [])  # without the mocap its tests skip (conftest)


@pytest.mark.usefixtures("mocap")
def test_every_real_bvh_parses_with_the_documented_frames_and_rate():
    assert len(SHARED_ROWS) == 361
    for row in SHARED_ROWS:
        clip = read_bvh(MOCAP / row["local"])
        assert clip.frames == int(row["frames"]), row["local"]
        assert abs(clip.fps - float(row["fps"])) < 0.01, row["local"]
        assert len([n for n, e in zip(clip.skeleton.names, clip.skeleton.is_end_site) if not e]) == int(row["joints"])
        assert np.isfinite(clip.motion).all()


@pytest.mark.slow  # the `bvh` package parses in pure Python: seconds per file
@pytest.mark.usefixtures("mocap")
@pytest.mark.parametrize("rel", [
    "cmu_bvh11/resources/131_01.bvh",  # CRLF line ends, tabs, 3-channel joints, ZYX
    "bandai_namco_motiondataset/dataset/Bandai-Namco-Research-Motiondataset-1/data/dataset-1_walk_happy_001.bvh",  # 6 channels everywhere, 1e-06 notation
    "pymo_demo/demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh",  # XYZ order
    "cmu_iclone/All_BVH/subjects/005/005_01.bvh",  # 100 joints
])
def test_channel_values_equal_the_bvh_package(rel):
    text = (MOCAP / rel).read_text()
    ref = Bvh(text)
    ours = read_bvh(MOCAP / rel)
    col = 0
    for name, chans, end in zip(ours.skeleton.names, ours.skeleton.channels, ours.skeleton.is_end_site):
        if end:
            continue
        assert tuple(ref.joint_channels(name)) == chans
        if name == ours.skeleton.names[0] or col < 40:  # the bvh package is slow: compare the first joints fully
            expected = np.asarray(ref.frames_joint_channels(name, list(chans)), dtype=np.float64)
            np.testing.assert_array_equal(ours.motion[:, col:col + len(chans)], expected)
        col += len(chans)
    assert col == ours.motion.shape[1]


CHAIN = """HIERARCHY
ROOT Hips
{{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT A
\t{{
\t\tOFFSET 0 10 0
\t\tCHANNELS 2 {order}
\t\tEnd Site
\t\t{{
\t\t\tOFFSET 0 10 0
\t\t}}
\t}}
}}
MOTION
Frames: 1
Frame Time: 1.0E-1
1 2 3 90 0 0 90 90
"""


def _points(text):
    clip = parse_bvh(text)
    return bvh_point_positions([clip], ["Hips", "A", "A/End"], "add", "+Y").double()


def test_hand_made_chain_positions_follow_bvh_semantics():
    # Root at (1,2,3) turned 90 deg about Z: A's offset (0,10,0) -> (-10,0,0).
    # A = Rz(90) Rx(90): its End offset (0,10,0) -> Rx -> (0,0,10) -> Rz -> (0,0,10), then the root's Rz.
    p = _points(CHAIN.format(order="Zrotation Xrotation"))[0]
    assert torch.allclose(p[0], torch.tensor([1.0, 2, 3], dtype=torch.float64))
    assert torch.allclose(p[1], torch.tensor([-9.0, 2, 3], dtype=torch.float64), atol=1e-5)
    assert torch.allclose(p[2], torch.tensor([-9.0, 2, 13], dtype=torch.float64), atol=1e-5)


def test_channel_order_changes_the_result():
    # A = Rx(90) Rz(90): (0,10,0) -> Rz -> (-10,0,0) -> Rx -> (-10,0,0); then the root's Rz -> (0,-10,0).
    p = _points(CHAIN.format(order="Xrotation Zrotation"))[0]
    assert torch.allclose(p[2], torch.tensor([-9.0, -8, 3], dtype=torch.float64), atol=1e-5)


def test_crlf_tabs_and_blank_lines_parse_the_same():
    text = CHAIN.format(order="Zrotation Xrotation")
    messy = text.replace("\n", "\r\n").replace("Frames: 1", "Frames:\t1\r\n").replace(" 90 90", "\t90   90 ")
    a, b = parse_bvh(text), parse_bvh(messy)
    np.testing.assert_array_equal(a.motion, b.motion)
    assert a.frame_time == b.frame_time == pytest.approx(0.1)


TOKENS_OK = ["0", "-0", "1.", ".5", "+7", "0.1", "0.30000000000000004", "5.1072e-06", "-1.2E+3", "1e22", "1e23",
             "9007199254740993", "123456789012345678901234", "0.000000000000000000000000001234",
             "2.2250738585072014e-308", "4.9e-324", "1e-400", "179769313486231570000000000000000000000e270"]
TOKENS_BAD = ["1_0", "0x10", "nan", "-inf", "1e400", "1e", "--1", ".", "1.2.3", "\u0661", "1,5", '"1"']


def test_bulk_parser_is_bit_identical_to_python_float():
    from pipeline.io.readers import bvh

    line = " ".join(TOKENS_OK)
    got = bvh._bulk_frames(f"{line}\n{line}\r\n", 2, len(TOKENS_OK))
    expected = np.array([float(t) for t in TOKENS_OK])
    assert got is not None and (got.view(np.int64) == expected.view(np.int64)).all()  # bit for bit, -0.0 included
    for token in TOKENS_BAD:
        assert bvh._bulk_frames(f"1 {token}\n", 1, 2) is None, token


@pytest.mark.usefixtures("mocap")
def test_c_and_arrow_paths_agree_on_every_real_file():
    from pipeline.io.readers import bvh

    assert bvh._motion is not None, "the C parser is not built: `pip install -e .` compiles it"
    for row in SHARED_ROWS[::7] + SHARED_ROWS[-12:]:
        text = (MOCAP / row["local"]).read_text()
        clip = parse_bvh(text)
        data = text[text.index("Frame Time"):].split("\n", 1)[1]
        arrow = bvh._bulk_frames_arrow(data.encode(), clip.frames, clip.skeleton.channel_count)
        np.testing.assert_array_equal(clip.motion, arrow)
