"""Source manifests: the shipped ones follow the schema; a malformed one is refused on load with an error that
names the file, the line, the dotted key, what was expected and what was found; ``formats`` is always explicit;
``emogait pin`` rewrites only the ``files:`` list (on the real mocap, every shipped manifest pins to itself)."""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from pipeline.io.manifests import (
    FileEntry,
    ManifestError,
    check_manifest,
    list_inputs,
    load_manifest,
    load_manifests,
    with_files,
)
from stages.cli import main as emogait
from stages.common import SOURCES
from tests.conftest import MOCAP

SHIPPED = sorted(SOURCES.glob("*.yaml"))
PYMO = SOURCES / "pymo_demo.yaml"
C3D = SOURCES / "c3d_org_samples.yaml"
BVH_TESTS = SOURCES / "bvh_python_tests.yaml"
PYMO_SHA = "f81412d16adb128b3ab0bf9c12dc5d847f89490bd2974b87d2c0ca604ee484a4"


def test_every_shipped_manifest_follows_the_schema():
    manifests = {m.name: m for m in load_manifests(SOURCES, formats=("bvh", "c3d"))}
    assert sorted(manifests) == [p.stem for p in SHIPPED]
    assert {m.format for m in manifests.values()} == {"bvh", "c3d"}
    assert manifests["c3d_org_samples"].max_gap_seconds == 0.1
    assert [s["name"] for s in manifests["c3d_org_samples"].marker_sets][:2] == ["innovative_sports", "plug_in_gait"]
    assert manifests["pymo_demo"].max_gap_seconds is None and manifests["pymo_demo"].marker_sets == []


def test_formats_are_explicit():
    with pytest.raises(TypeError):
        load_manifests(SOURCES)  # no default that silently drops the C3D source
    assert [m.name for m in load_manifests(SOURCES, formats=("c3d",))] == ["c3d_org_samples"]
    assert len(load_manifests(SOURCES, formats=("bvh",))) == len(SHIPPED) - 1
    for bad in ("bvh", (), ("bvh", "fbx")):
        with pytest.raises(ValueError, match=r"formats: expected a non-empty list of \['bvh', 'c3d'\]"):
            load_manifests(SOURCES, formats=bad)


# --------------------------------------------------------------------------------------------------------------
# Malformed manifests: each edit of a shipped manifest, and the one error it must give.


@dataclass(frozen=True)
class Malformed:
    name: str
    manifest: Path
    old: str  # replaced (once) by new in the shipped text; the error's line is the line where it starts
    new: str
    key: str
    expected: str
    found: str
    line_offset: int = 0  # the error's line, relative to the line where `old` starts (None-able below)
    no_line: bool = False


CASES = [
    Malformed("missing_key", PYMO, "up_axis: +Y\n", "", "up_axis",
              "a value (a required key)", "no such key", no_line=True),
    Malformed("wrong_type", PYMO, "unit_scale_m: 0.0254", "unit_scale_m: '0.0254'", "unit_scale_m",
              "a number", "'0.0254'"),
    Malformed("unknown_format", PYMO, "format: bvh", "format: fbx", "format", "'bvh' or 'c3d'", "'fbx'"),
    Malformed("unknown_up_axis", PYMO, "up_axis: +Y", "up_axis: -Y", "up_axis", "'+Y' or '+Z'", "'-Y'"),
    Malformed("bad_label_regex", PYMO, "pattern: ^AV_(?P<content>", "pattern: ^AV_(?P<content", "label_rule.pattern",
              "a valid regular expression", "'^AV_(?P<content[0-9A-Za-z]+)_(?P<actor>[A-Za-z]+)_(?P<style>[A-Z]+)_Rep"
              "(?P<take>\\\\d+)\\\\.bvh$' (bad character in group name 'content[0-9A-Za-z]+)_(?P<actor' at position 8)"),
    Malformed("bad_sha256", PYMO, f"sha256: {PYMO_SHA}", f"sha256: {PYMO_SHA[:-1]}G", "files[0].sha256",
              "a sha256 digest (64 lowercase hexadecimal digits)", f"'{PYMO_SHA[:-1]}G' (64 characters)"),
    Malformed("short_sha256", PYMO, f"sha256: {PYMO_SHA}", f"sha256: {PYMO_SHA[:12]}", "files[0].sha256",
              "a sha256 digest (64 lowercase hexadecimal digits)", f"'{PYMO_SHA[:12]}' (12 characters)"),
    Malformed("unknown_key_typo", PYMO, "min_clip_seconds: 2.0", "min_clip_second: 2.0", "min_clip_second",
              "one of the keys ['attribution', 'content_note', 'files', 'format', 'fps', 'gait_contents', 'globs', "
              "'joint_map', 'joint_map_note', 'joint_map_overrides', 'label_rule', 'labels_table', 'licence', "
              "'marker_sets', "
              "'max_gap_seconds', 'min_clip_seconds', 'name', 'root_offset', 'root_offset_note', 'title', "
              "'unit_scale_m', 'units', 'up_axis', 'upstream']",
              "unknown key 'min_clip_second' (did you mean 'min_clip_seconds'?)"),
    Malformed("nested_typo", PYMO, "  content_map:", "  contentmap:", "label_rule.contentmap",
              "one of the keys ['content_map', 'emotions', 'fixed', 'pattern', 'rationale']",
              "unknown key 'contentmap' (did you mean 'content_map'?)"),
    Malformed("joint_map_weights", PYMO, "    LeftShoulder: 0.5\n    Head: 0.5", "    LeftShoulder: 0.5\n    Head: 0.6",
              "joint_map.neck", "a source joint name or a mapping {source point: weight} whose weights sum to 1",
              "weights [0.5, 0.6] summing to 1.1", line_offset=-1),
    Malformed("joint_map_list", PYMO, "  head: Head\n", "  head: [Head]\n", "joint_map.head",
              "a source joint name or a mapping {source point: weight}", "['Head']"),
    Malformed("joint_map_override_number", BVH_TESTS, "    head: mixamorig:Head", "    head: 3",
              "joint_map_overrides.'test_freebvh.bvh'.head",
              "a source joint name or a mapping {source point: weight}", "3"),
    Malformed("emotion_not_one_hot", PYMO, "    - 1\n    - 0\n    - 0\n    - 0\n", "    - 1\n    - 1\n    - 0\n    - 0\n",
              "label_rule.emotions[0].emotion", "4 non-negative weights (happy, sad, angry, neutral) summing to 1",
              "[1.0, 1.0, 0.0, 0.0]", line_offset=-1),
    Malformed("emotion_condition_on_no_field", PYMO, "      style: HVHA", "      styl: HVHA",
              "label_rule.emotions[0].when.styl",
              "a field the label rule gives (pattern groups and fixed: ['actor', 'content', 'style', 'take'])", "'styl'"),
    Malformed("emotion_condition_not_text", PYMO, "      style: HVHA", "      style: 1",
              "label_rule.emotions[0].when.style", "a string", "1"),
    Malformed("unknown_label_method", PYMO, "label_method: style_mapping", "label_method: guessed",
              "label_rule.emotions[0].label_method", "'actor_intended' or 'style_mapping'", "'guessed'"),
    Malformed("file_url_without_path", PYMO, "ba24f5f8d8911173f41e2ea1a367fa7955a6da9f/{path}",
              "ba24f5f8d8911173f41e2ea1a367fa7955a6da9f/", "upstream.file_url", "a URL template containing {path}",
              "'https://github.com/omimo/PyMO/raw/ba24f5f8d8911173f41e2ea1a367fa7955a6da9f/'"),
    Malformed("duplicate_key", PYMO, "units: inch\n", "units: inch\nunits: cm\n", "units",
              "each key once (first at line 13)", "units again", line_offset=1),
    Malformed("name_not_file_name", PYMO, "name: pymo_demo", "name: pymo", "name",
              "'pymo_demo' (the manifest's file name)", "'pymo'"),
    Malformed("not_yaml", PYMO, "units: inch\n", "units: [inch\n", "(document)", "valid YAML",
              "a syntax error: expected ',' or ']', but got ':'", line_offset=1),
    Malformed("marker_set_without_a_contact", C3D,
              "  contacts: {left_heel: LCAL, left_toe: LTOE, right_heel: RCAL, right_toe: RTOE}",
              "  contacts: {left_heel: LCAL, left_toe: LTOE, right_heel: RCAL}", "marker_sets[0].contacts",
              "a rule for each of ['left_heel', 'left_toe', 'right_heel', 'right_toe']", "none for ['right_toe']"),
    Malformed("marker_weights", C3D, "    left_toe: {MT1G: 0.5, MT5G: 0.5}", "    left_toe: {MT1G: 0.5, MT5G: 0.4}",
              "marker_sets[5].contacts.left_toe", "a mapping {marker: weight} whose weights sum to 1",
              "weights [0.5, 0.4] summing to 0.9"),
    Malformed("hip_centre_side", C3D, "    left_hip: {hip_centre: left}", "    left_hip: {hip_centre: middle}",
              "marker_sets[1].canonical.left_hip", "{hip_centre: left} or {hip_centre: right}",
              "{'hip_centre': 'middle'}"),
    Malformed("c3d_without_marker_sets", C3D, "marker_sets:\n", "marker_set:\n", "marker_set",
              "one of the keys ['attribution', 'content_note', 'files', 'format', 'fps', 'gait_contents', 'globs', "
              "'joint_map', 'joint_map_note', 'joint_map_overrides', 'label_rule', 'labels_table', 'licence', "
              "'marker_sets', "
              "'max_gap_seconds', 'min_clip_seconds', 'name', 'root_offset', 'root_offset_note', 'title', "
              "'unit_scale_m', 'units', 'up_axis', 'upstream']", "unknown key 'marker_set' (did you mean 'marker_sets'?)"),
    Malformed("no_globs", PYMO, "globs:\n- demos/data/*.bvh", "globs: []", "globs", "at least 1 item", "[]"),
    Malformed("pinned_twice", PYMO, f"  sha256: {PYMO_SHA}\n",
              f"  sha256: {PYMO_SHA}\n- path: demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh\n  sha256: {PYMO_SHA}\n",
              "files[1].path", "each file pinned once",
              "'demos/data/AV_8Walk_Meredith_HVHA_Rep1.bvh' again (first at files[0])", line_offset=1),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_malformed_manifest_gives_its_named_error(tmp_path, case: Malformed):
    text = case.manifest.read_text()
    assert text.count(case.old) >= 1, case.old
    start = text.index(case.old)
    path = tmp_path / case.manifest.name
    path.write_text(text.replace(case.old, case.new, 1))
    line = None if case.no_line else text.count("\n", 0, start) + 1 + case.line_offset
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    err = info.value
    assert (err.path, err.key, err.line, err.expected, err.found) == (str(path), case.key, line, case.expected,
                                                                      case.found)
    where = f"{path}:{line}" if line else f"{path}"
    assert str(err).splitlines()[0] == f"{where}: {case.key}: expected {case.expected}, found {case.found}"
    assert len(err.problems) == 1, str(err)


def test_several_problems_are_reported_together(tmp_path):
    text = PYMO.read_text().replace("format: bvh", "format: fbx").replace("up_axis: +Y", "up_axis: Y")
    path = tmp_path / PYMO.name
    path.write_text(text)
    with pytest.raises(ManifestError) as info:
        load_manifests(tmp_path, formats=("bvh", "c3d"))
    assert [p.key for p in info.value.problems] == ["format", "up_axis"]
    assert len(str(info.value).splitlines()) == 2


def test_a_manifest_is_never_a_key_error(tmp_path):
    """Whatever is missing, loading says so as a ManifestError (the old loader raised KeyError: 'name')."""
    for key in ("name", "format", "globs", "label_rule", "joint_map", "upstream"):
        text = PYMO.read_text()
        lines = text.splitlines(keepends=True)
        start = next(k for k, line in enumerate(lines) if line.startswith(f"{key}:"))
        stop = next(k for k in range(start + 1, len(lines)) if not lines[k].startswith((" ", "-")))
        path = tmp_path / PYMO.name
        path.write_text("".join(lines[:start] + lines[stop:]))
        with pytest.raises(ManifestError) as info:
            load_manifest(path)
        assert info.value.key == key and info.value.found == "no such key", str(info.value)


# --------------------------------------------------------------------------------------------------------------
# emogait pin: only the files: block changes.


@pytest.mark.usefixtures("mocap")
@pytest.mark.parametrize("shipped", SHIPPED, ids=lambda p: p.stem)
def test_pin_leaves_every_shipped_manifest_byte_identical(tmp_path, shipped):
    copy = tmp_path / shipped.name
    shutil.copy(shipped, copy)
    assert emogait(["pin", str(copy), "--mocap-root", str(MOCAP)]) == 0
    assert copy.read_bytes() == shipped.read_bytes()


def _damage_files_block(text: str) -> str:
    """Drop the first and last pinned entries, change one sha256 to another digest and garble one path."""
    lines = text.splitlines(keepends=True)
    start = lines.index("files:\n")
    entries = [lines[k:k + 2] for k in range(start + 1, len(lines), 2)]
    assert all(e[0].startswith("- path: ") and e[1].startswith("  sha256: ") for e in entries)
    kept = entries[1:-1] if len(entries) > 2 else entries[:1]
    if kept:
        kept[0] = [kept[0][0], "  sha256: " + "0" * 64 + "\n"]
    if len(kept) > 1:
        kept[-1] = ["- path: no/such/file.bvh\n", "  sha256: not-a-digest\n"]
    return "".join(lines[:start + 1] + [line for e in kept for line in e])


@pytest.mark.usefixtures("mocap")
@pytest.mark.parametrize("shipped", SHIPPED, ids=lambda p: p.stem)
def test_pin_restores_the_shipped_bytes_after_the_files_list_is_damaged(tmp_path, shipped):
    text = shipped.read_text()
    copy = tmp_path / shipped.name
    damaged = _damage_files_block(text)
    assert damaged != text
    copy.write_text(damaged)
    assert emogait(["pin", str(copy), "--mocap-root", str(MOCAP)]) == 0
    assert copy.read_bytes() == shipped.read_bytes()
    # ... and from no files: block at all, or an empty one
    for without in (text[:text.index("\nfiles:\n") + 1], text[:text.index("\nfiles:\n") + 1] + "files: []\n"):
        copy.write_text(without)
        assert emogait(["pin", str(copy), "--mocap-root", str(MOCAP)]) == 0
        assert copy.read_bytes() == shipped.read_bytes()


def test_pin_keeps_comments_and_keys_after_the_files_block(tmp_path):
    text = ("# header\nname: x\nfiles:\n- path: a.bvh\n  sha256: old\n# this comment introduces the next key\n"
            "\nafter: 1  # stays\n")
    out = with_files(text, [FileEntry("a.bvh", "a1" * 32), FileEntry("b c/d.bvh", "b2" * 32)])
    assert out == ("# header\nname: x\nfiles:\n- path: a.bvh\n  sha256: " + "a1" * 32 + "\n- path: b c/d.bvh\n"
                   "  sha256: " + "b2" * 32 + "\n# this comment introduces the next key\n\nafter: 1  # stays\n")
    # the c3d manifest's marker-set comments are where they were after a pin (the old pin moved them to the top)
    c3d = C3D.read_text()
    assert with_files(c3d, []).split("\nfiles:")[0] == c3d.split("\nfiles:")[0]


def test_pin_refuses_a_malformed_manifest_and_says_why(tmp_path, capsys):
    path = tmp_path / PYMO.name
    path.write_text(PYMO.read_text().replace("up_axis: +Y", "up_axis: -Y"))
    before = path.read_bytes()
    assert emogait(["pin", str(path), "--mocap-root", str(MOCAP)]) == 2
    assert path.read_bytes() == before
    assert re.search(r"pymo_demo.yaml:15: up_axis: expected '\+Y' or '\+Z', found '-Y'", capsys.readouterr().err)


def test_check_manifest_without_pins_ignores_only_the_files_list():
    text = PYMO.read_text().replace(f"sha256: {PYMO_SHA}", "sha256: broken")
    with pytest.raises(ManifestError, match="files\\[0\\].sha256"):
        check_manifest(text, PYMO)
    assert check_manifest(text, PYMO, pins=False)["name"] == "pymo_demo"


@pytest.mark.usefixtures("mocap")
def test_list_inputs_unchanged_on_the_real_data():
    """The inputs every stage accounts for are the pinned files, as pathlib's glob finds them."""
    for manifest in load_manifests(SOURCES, formats=("bvh", "c3d")):
        folder = MOCAP / manifest.name
        by_pathlib = sorted({p.relative_to(folder).as_posix() for g in manifest.globs for p in folder.glob(g)
                             if p.is_file()})
        assert [rel for rel, _ in list_inputs(manifest, folder)] == by_pathlib == [f.path for f in manifest.files]
