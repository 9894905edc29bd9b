"""Previews are real pictures: both sides of the body drawn, figures upright above the floor."""

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest

from pipeline.viz.stick_figures import Motion, filmstrip
from stages.cli import main
from tests.conftest import MOCAP


def _colour_fraction(img, rgb):
    return (np.abs(img[..., :3] - np.array(rgb) / 255).sum(-1) < 0.1).mean()


def test_preview_of_gait_ids_draws_both_sides(tmp_path, full_ingest):
    ids = full_ingest["table"].column("gait_id").to_pylist()
    happy = next(i for i in ids if "dataset-1_walk_happy_001" in i)
    cmu = next(i for i in ids if i.startswith("cmu_iclone"))
    out = tmp_path / "walks.png"
    assert main(["preview", "--gaits", str(full_ingest["path"]), "--gait", happy, "--gait", cmu, "--out", str(out)]) == 0
    img = mpimg.imread(out)
    assert img.shape[0] > 300 and img.shape[1] > 1000
    assert _colour_fraction(img, (0x1F, 0x5F, 0xBF)) > 1e-3  # left limbs
    assert _colour_fraction(img, (0xC0, 0x39, 0x2B)) > 1e-3  # right limbs


@pytest.mark.slow
@pytest.mark.usefixtures("mocap")
def test_preview_of_a_bvh_clip_and_a_gif(tmp_path):
    bvh = MOCAP / "cmu_iclone/All_BVH/subjects/002/002_01.bvh"
    png, gif = tmp_path / "clip.png", tmp_path / "clip.gif"
    assert main(["preview", "--bvh", str(bvh), "--out", str(png)]) == 0
    assert main(["preview", "--bvh", str(bvh), "--canonical-only", "--out", str(gif)]) == 0
    assert mpimg.imread(png).shape[0] > 400  # two rows: canonical and source rig
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")


def test_long_row_titles_stay_beside_their_own_row(full_ingest, skeleton):
    # the published previews' titles (gait id, family, emotion) ran into the neighbouring rows' titles
    table, arrays = full_ingest["table"], full_ingest["arrays"]
    ids = table.column("gait_id").to_pylist()
    rows = [ids.index(next(i for i in ids if "dataset-1_walk_happy_001" in i)),
            ids.index(next(i for i in ids if i.startswith("cmu_iclone"))), 0]
    motions = [Motion(f"{ids[i]}: autoregressive_affect, most happy (0.63)", arrays["positions"][i],
                      skeleton.parents, skeleton.names) for i in rows]
    assert min(len(m.title) for m in motions) > 80
    fig = filmstrip(motions)
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        labels = [ax.yaxis.label.get_window_extent(renderer) for ax in fig.axes[::9]]
        row_height = fig.bbox.height / len(motions)
        assert all(0 < box.height < row_height for box in labels)
        assert all(upper.y0 > lower.y1 for upper, lower in zip(labels, labels[1:]))  # rows top to bottom
        assert all("\n" in ax.yaxis.label.get_text() for ax in fig.axes[::9])
    finally:
        plt.close(fig)
