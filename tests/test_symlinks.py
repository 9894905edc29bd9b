"""Mocap reached through symbolic links: a linked mocap root, linked source folders, a linked folder inside a
source (even under a ``**`` glob, and a link back to its own folder) give the same inputs, windows, trials and
previews as the real paths. Links are built at run time under tmp_path; the real data stays where it is."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml

from pipeline.ingest.run import run_ingest
from pipeline.ingest.screen import screen_file
from pipeline.io.manifests import list_inputs, load_manifest, locate_source_file
from stages import validate_contacts
from stages.cli import main as emogait
from stages.common import PARAMS, SOURCES
from tests.conftest import MOCAP

SMALL = ("pymo_demo", "bvh_python_tests")
PYMO_FILE = "demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh"


@pytest.fixture(scope="module")
def links(tmp_path_factory, mocap):
    """tmp/mocap -> the real root; tmp/sources/<name> -> the real source folders; tmp/linked -> tmp/sources."""
    tmp = tmp_path_factory.mktemp("links")
    (tmp / "mocap").symlink_to(MOCAP, target_is_directory=True)
    (tmp / "sources").mkdir()
    for name in (*SMALL, "c3d_org_samples"):
        (tmp / "sources" / name).symlink_to(MOCAP / name, target_is_directory=True)
    (tmp / "linked").symlink_to(tmp / "sources", target_is_directory=True)
    return tmp


def _ingest(manifests, skeleton, cfg, root):
    return run_ingest([manifests[n] for n in SMALL], skeleton, replace(cfg, mocap_root=root), workers=1,
                      progress=False)


@pytest.mark.slow  # three dask ingests of two small sources
def test_ingest_through_links_gives_the_same_windows(links, manifests, skeleton, ingest_config):
    real_windows, real_report = _ingest(manifests, skeleton, ingest_config, MOCAP)
    assert real_report["files_ingested"] >= 2 and len(real_windows) > 0
    for root in (links / "mocap", links / "linked"):
        windows, report = _ingest(manifests, skeleton, ingest_config, root)
        assert report == real_report, root
        assert [w["gait_id"] for w in windows] == [w["gait_id"] for w in real_windows]
        for a, b in zip(windows, real_windows):
            assert {k: v for k, v in a.items() if not isinstance(v, np.ndarray)} == \
                   {k: v for k, v in b.items() if not isinstance(v, np.ndarray)}
            for k in ("positions", "rotations", "root_path", "heading"):
                np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.slow  # three previews, each retargeting the clip
def test_preview_of_a_bvh_through_links_writes_a_png(links, tmp_path):
    params = yaml.safe_load(PARAMS.read_text())
    params["data"]["mocap_root"] = str(links / "linked")  # a linked root whose source folders are links
    linked_params = tmp_path / "params.yaml"
    linked_params.write_text(yaml.safe_dump(params))
    calls = [
        ["--params", str(linked_params), "--bvh", str(links / "linked" / "pymo_demo" / PYMO_FILE)],  # was ValueError
        ["--params", str(linked_params), "--bvh", str(MOCAP / "pymo_demo" / PYMO_FILE)],  # the real path of it
        ["--bvh", str(links / "mocap" / "pymo_demo" / PYMO_FILE)],  # the repository's root, the file via a link
    ]
    for k, args in enumerate(calls):
        out = tmp_path / f"clip{k}.png"
        assert emogait(["preview", *args, "--out", str(out)]) == 0, args
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_preview_of_a_file_outside_the_sources_names_it(links, tmp_path, capsys):
    outside = tmp_path / "elsewhere.bvh"
    outside.write_bytes((MOCAP / "pymo_demo" / PYMO_FILE).read_bytes())
    assert emogait(["preview", "--bvh", str(outside), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert f"{outside}: expected a file under a source folder of the mocap root" in err
    assert not (tmp_path / "x.png").exists()


def test_locate_source_file_through_links(links):
    names = list(SMALL)
    for root in (MOCAP, links / "mocap", links / "linked"):
        for given in (MOCAP / "pymo_demo" / PYMO_FILE, links / "mocap" / "pymo_demo" / PYMO_FILE,
                      links / "linked" / "pymo_demo" / PYMO_FILE, links / "sources" / "pymo_demo" / PYMO_FILE):
            assert locate_source_file(given, root, names) == ("pymo_demo", PYMO_FILE), (root, given)
    with pytest.raises(ValueError, match="expected a file under a source folder"):
        locate_source_file(MOCAP / "cmu_bvh11" / "resources" / "131_01.bvh", links / "linked", names)


def test_validate_contacts_through_links(links):
    vcfg = validate_contacts.validation_config(yaml.safe_load(PARAMS.read_text()))
    real, real_skipped = validate_contacts.load_trials(MOCAP, SOURCES, vcfg)
    linked, skipped = validate_contacts.load_trials(links / "linked", SOURCES, vcfg)
    assert [t.name for t in linked] == [t.name for t in real] and len(real) == 7
    for a, b in zip(linked, real):
        np.testing.assert_array_equal(a.points, b.points)
        assert a.annotated == b.annotated and a.filled == b.filled
    # reasons name the file where it was read (through the link)
    assert [{**s, "reason": s["reason"].replace(str(links / "linked"), str(MOCAP))} for s in skipped] == real_skipped


@pytest.mark.usefixtures("mocap")
def test_linked_folders_inside_a_source_are_followed_once(tmp_path):
    """A ``**`` glob walks into a linked folder (pathlib's glob of Python 3.11 does not) and a link back to an
    enclosing folder is walked once; the file found through the link passes the screen."""
    source = tmp_path / "root" / "linky"
    source.mkdir(parents=True)
    (source / "nested").symlink_to(MOCAP / "pymo_demo" / "demos", target_is_directory=True)
    (source / "loop").symlink_to(source, target_is_directory=True)
    doc = yaml.safe_load((SOURCES / "pymo_demo.yaml").read_text())
    doc.update(name="linky", globs=["**/*.bvh"], files=[{"path": "nested/data/AV_8Walk_Meredith_HVHA_Rep1.bvh",
                                                         "sha256": doc["files"][0]["sha256"]}])
    path = tmp_path / "linky.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    manifest = load_manifest(path)
    inputs = list_inputs(manifest, source)
    assert inputs == [("nested/data/AV_8Walk_Meredith_HVHA_Rep1.bvh", doc["files"][0]["sha256"])]
    screened = screen_file(manifest, source, *inputs[0])
    assert screened.rejection is None and screened.clip.frames > 0
