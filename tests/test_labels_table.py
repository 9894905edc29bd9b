"""Labels from a side table (``labels_table``): a CSV with one row per file, pinned by sha256 in the manifest.

The test sources are the real cmu_bvh11 (two files) and pymo_demo (one file) sources, read in place from the real
mocap root: their shipped manifests are copied into tmp_path with a table written here, and ingested by
``run_ingest`` (the stage's own call). A row overrides the label rule for its file; a file without a row gets the
rule's label, or is quarantined where the manifest has no rule; rows for files the source does not have and
files without a row are reported (a ManifestWarning on load, the ingest report's ``labels_table``). A malformed
table is refused with the CSV file, line, column, what was expected and what was found.
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from pipeline.ingest.run import run_ingest
from pipeline.io.files import sha256_file
from pipeline.io.manifests import LABEL_COLUMNS, ManifestError, ManifestWarning, load_manifest, read_labels_table
from stages.cli import main as emogait
from stages.common import REPO, SOURCES
from tests.conftest import MOCAP

CMU = SOURCES / "cmu_bvh11.yaml"
PYMO = SOURCES / "pymo_demo.yaml"
EXAMPLE = REPO / "manifests/examples/pymo_demo.yaml"
TABLE = "cmu_bvh11.labels.csv"
HEADER = "file,content,style,happy,sad,angry,neutral,label_method,description\n"
ROW_01 = 'resources/131_01.bvh,walk,start-walk-stop,0,0,0,1,actor_intended,"CMU index: ""Start Walk Stop"""\n'
ROW_GONE = "resources/131_03.bvh,hop,hop,,,,,,upstream has it; the mocap root does not\n"  # neither pinned nor found
ROW_MISSING = "resources/131_04.bvh,walk,plain,,,,,,\n"  # pinned below, but no such file
MISSING_PIN = "resources/131_04.bvh"
RULE_STYLE = "michael-jackson-styled"  # what cmu_bvh11's label rule gives every file


def cmu_manifest(folder: Path, table: str | None, *, rule: bool = True, pin_table: bool = True,
                 extra_pins: tuple[str, ...] = ()) -> Path:
    """The shipped cmu_bvh11 manifest in ``folder`` with ``labels_table: cmu_bvh11.labels.csv`` (the table's text
    written beside it unless None), without its label rule unless ``rule``; ``extra_pins`` are pinned too."""
    text = CMU.read_text()
    start, stop = text.index("label_rule:\n"), text.index("gait_contents:\n")
    pinned = f"  sha256: {'a' * 64}\n" if pin_table else ""
    block = f"labels_table:\n  path: {TABLE}\n{pinned}"
    text = text[:start] + (text[start:stop] if rule else "") + block + text[stop:]
    text += "".join(f"- path: {p}\n  sha256: {'b' * 64}\n" for p in extra_pins)
    path = folder / "cmu_bvh11.yaml"
    if table is not None:
        (folder / TABLE).write_text(table)
        if pin_table:
            text = text.replace(f"  sha256: {'a' * 64}\n", f"  sha256: {sha256_file(folder / TABLE)}\n")
    path.write_text(text)
    return path


def _ingest(manifests, skeleton, ingest_config) -> SimpleNamespace:
    windows, report = run_ingest(manifests, skeleton, ingest_config, workers=1, progress=False)
    return SimpleNamespace(windows=windows, report=report)


def _labels(windows, file: str) -> set[tuple]:
    return {(w["content"], w["style"], None if w["emotion"] is None else tuple(w["emotion"].tolist()),
             w["label_method"]) for w in windows if w["file"] == file}


@pytest.fixture(scope="module")
def mixed(tmp_path_factory, skeleton, ingest_config):
    """cmu_bvh11 with its label rule and a table: a row for 131_01 (overrides the rule), none for 131_02, a row
    for a file neither pinned nor there and one for a pinned file that is missing; plus the shipped pymo_demo."""
    folder = tmp_path_factory.mktemp("mixed")
    path = cmu_manifest(folder, HEADER + ROW_01 + ROW_GONE + ROW_MISSING, extra_pins=(MISSING_PIN,))
    with pytest.warns(ManifestWarning) as caught:
        manifest = load_manifest(path)
    run = _ingest([manifest, load_manifest(PYMO)], skeleton, ingest_config)
    run.warnings = [str(w.message) for w in caught]
    run.table = folder / TABLE
    return run


@pytest.fixture(scope="module")
def table_only(tmp_path_factory, skeleton, ingest_config):
    """cmu_bvh11 with a table and no label rule (131_02 has no row), and the example: pymo_demo by a table."""
    folder = tmp_path_factory.mktemp("table_only")
    with pytest.warns(ManifestWarning):
        manifest = load_manifest(cmu_manifest(folder, HEADER + ROW_01, rule=False))
    run = _ingest([manifest, load_manifest(EXAMPLE)], skeleton, ingest_config)
    run.table = folder / TABLE
    return run


# --------------------------------------------------------------------------------------------------------------
# Labels and reports through the ingest.


def test_a_row_overrides_the_label_rule_and_files_without_a_row_get_the_rules_label(mixed):
    assert _labels(mixed.windows, "resources/131_01.bvh") == {("walk", "start-walk-stop", (0.0, 0.0, 0.0, 1.0),
                                                                 "actor_intended")}
    assert _labels(mixed.windows, "resources/131_02.bvh") == {("walk", RULE_STYLE, None, None)}


def test_rows_without_a_file_and_files_without_a_row_are_reported(mixed):
    report = mixed.report
    assert report["per_source"]["cmu_bvh11"]["labels_table"] == {
        "path": TABLE, "sha256": sha256_file(mixed.table), "rows": 3, "files_with_row": 2,
        "rows_without_file": [{"line": 3, "file": "resources/131_03.bvh",
                               "why": "neither pinned nor found by the globs"},
                              {"line": 4, "file": MISSING_PIN, "why": "pinned, but no file is in the source folder"}],
        "files_without_row": ["resources/131_02.bvh"], "files_without_row_get": "the label rule's label"}
    assert "labels_table" not in report["per_source"]["pymo_demo"]  # a source without a table: report as before
    assert [(e["path"], e["reason"].split(":")[0]) for e in report["quarantine"]] == [(MISSING_PIN, "missing")]
    assert report["files_seen"] == 4


def test_loading_warns_of_rows_for_unpinned_files_and_pinned_files_without_a_row(mixed):
    manifest = mixed.table.parent / "cmu_bvh11.yaml"
    assert mixed.warnings == [
        f"{mixed.table}:3: file: expected a file the manifest pins (files: in {manifest}), found "
        "'resources/131_03.bvh', which it does not have (the row labels nothing)\n"
        f"{mixed.table}: file: expected a row for each file the manifest pins (files: in {manifest}), found none for "
        "1: 'resources/131_02.bvh' (they get the label rule's label)"]


def test_without_a_label_rule_a_file_without_a_row_is_quarantined(table_only):
    report = table_only.report
    assert _labels(table_only.windows, "resources/131_01.bvh") == {("walk", "start-walk-stop",
                                                                     (0.0, 0.0, 0.0, 1.0), "actor_intended")}
    assert [(e["path"], e["reason"]) for e in report["quarantine"]] == [
        ("resources/131_02.bvh", f"labels table: no row for 'resources/131_02.bvh' in {table_only.table} and no "
                                 "label rule to fall back on; add a row for it")]
    entry = report["per_source"]["cmu_bvh11"]["labels_table"]
    assert entry["files_without_row"] == ["resources/131_02.bvh"] and entry["rows_without_file"] == []
    assert entry["files_without_row_get"] == "quarantined (no label rule)"


def test_the_example_table_labels_pymo_as_the_shipped_rule_does(mixed, table_only):
    """manifests/examples/pymo_demo.yaml (a table, no rule) gives the same windows, labels included, as the
    shipped manifest (a rule); it is the shipped manifest but for the label keys."""
    by_table = [w for w in table_only.windows if w["source"] == "pymo_demo"]
    by_rule = [w for w in mixed.windows if w["source"] == "pymo_demo"]
    assert len(by_table) == len(by_rule) > 0
    for a, b in zip(by_table, by_rule):
        assert a.keys() == b.keys()
        for key in a:
            assert np.array_equal(a[key], b[key]) if isinstance(a[key], np.ndarray) else a[key] == b[key], key
    example, shipped = yaml.safe_load(EXAMPLE.read_text()), yaml.safe_load(PYMO.read_text())
    assert example.pop("labels_table")["path"] == "pymo_demo.labels.csv" and "label_rule" not in example
    shipped.pop("label_rule")
    assert example == shipped


@pytest.mark.usefixtures("mocap")
def test_the_example_pins_to_itself(tmp_path):
    for name in ("pymo_demo.yaml", "pymo_demo.labels.csv"):
        shutil.copy(EXAMPLE.parent / name, tmp_path / name)
    assert emogait(["pin", str(tmp_path / "pymo_demo.yaml"), "--mocap-root", str(MOCAP)]) == 0
    assert (tmp_path / "pymo_demo.yaml").read_bytes() == EXAMPLE.read_bytes()


# --------------------------------------------------------------------------------------------------------------
# emogait pin: the table's sha256.


@pytest.mark.usefixtures("mocap")
def test_pin_fills_in_and_updates_the_tables_sha256(tmp_path, capsys):
    path = cmu_manifest(tmp_path, HEADER + ROW_01, rule=False, pin_table=False)
    before = path.read_text()
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    assert (info.value.key, info.value.expected, info.value.found) == (
        "labels_table.sha256", f"the table's sha256 (`emogait pin {path}` writes it)", "no such key")
    assert emogait(["pin", str(path), "--mocap-root", str(MOCAP)]) == 0
    digest = sha256_file(tmp_path / TABLE)
    assert path.read_text() == before.replace(f"  path: {TABLE}\n", f"  path: {TABLE}\n  sha256: {digest}\n")
    out = capsys.readouterr()
    assert out.out.startswith(f"pinned 2 files and the labels table {TABLE} in {path}\n")
    assert out.err == (f"warning: {tmp_path / TABLE}: file: expected a row for each file the globs find (under the "
                       f"source folder of {path}), found none for 1: 'resources/131_02.bvh' (no label rule to fall "
                       "back on: quarantined at ingest)\n")
    with pytest.warns(ManifestWarning):
        assert load_manifest(path).labels.sha256 == digest
    # a changed table no longer loads until it is pinned again
    (tmp_path / TABLE).write_text(HEADER + ROW_01 + ROW_01.replace("131_01", "131_02"))
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    changed = sha256_file(tmp_path / TABLE)
    line = path.read_text().splitlines().index(f"  sha256: {digest}") + 1
    assert str(info.value) == (f"{path}:{line}: labels_table.sha256: expected {digest} (the pinned sha256 of "
                               f"{tmp_path / TABLE}), found {changed} (the table changed since it was pinned: review "
                               f"it, then `emogait pin {path}`)")
    assert emogait(["pin", str(path), "--mocap-root", str(MOCAP)]) == 0
    assert capsys.readouterr().err == ""  # every file has a row now
    assert load_manifest(path).labels.sha256 == changed
    assert emogait(["pin", str(path), "--mocap-root", str(MOCAP)]) == 0
    assert capsys.readouterr().out.endswith("(unchanged)\n")


@pytest.mark.usefixtures("mocap")
def test_pin_refuses_a_malformed_table(tmp_path, capsys):
    path = cmu_manifest(tmp_path, HEADER + ROW_01.replace(",0,0,0,1,", ",0,0,0,2,"), pin_table=False)
    before = path.read_bytes()
    assert emogait(["pin", str(path), "--mocap-root", str(MOCAP)]) == 2
    assert path.read_bytes() == before
    assert capsys.readouterr().err == (f"{tmp_path / TABLE}:2: happy+sad+angry+neutral: expected weights summing to "
                                       "1, found 0 + 0 + 0 + 2 = 2\n")


# --------------------------------------------------------------------------------------------------------------
# The manifest's labels_table key.


@dataclass(frozen=True)
class BadManifest:
    name: str
    edit: str  # what to do to a table manifest (see the test)
    key: str
    expected: str
    found: str
    at: str | None  # the line of the error: the first line with this text; None: no line


MANIFEST_CASES = [
    BadManifest("no_table_file", "no_table", "labels_table.path", "a labels table (CSV) at {folder}/" + TABLE,
                "no such file", f"  path: {TABLE}"),
    BadManifest("path_leaves_the_folder", "up", "labels_table.path",
                "a path relative to the manifest's folder (not empty, no leading '/', no '..')", f"'../{TABLE}'",
                f"  path: ../{TABLE}"),
    BadManifest("typo_in_key", "typo", "labels_table.sha265", "one of the keys ['path', 'sha256']",
                "unknown key 'sha265' (did you mean 'sha256'?)", f"  sha265: {'a' * 64}"),
    BadManifest("neither_rule_nor_table", "neither", "label_rule",
                "a label rule (label_rule), a labels table (labels_table) or both", "no such key", None),
]


@pytest.mark.parametrize("case", MANIFEST_CASES, ids=lambda c: c.name)
def test_a_bad_labels_table_key_gives_its_named_error(tmp_path, case: BadManifest):
    path = cmu_manifest(tmp_path, None if case.edit == "no_table" else HEADER + ROW_01, rule=False, pin_table=False)
    text = path.read_text().replace(f"labels_table:\n  path: {TABLE}\n", f"labels_table:\n  path: {TABLE}\n"
                                    f"  sha256: {'a' * 64}\n")
    text = {"up": text.replace(f"path: {TABLE}", f"path: ../{TABLE}"),
            "typo": text.replace("  sha256: " + "a" * 64, "  sha265: " + "a" * 64),
            "neither": text.replace(f"labels_table:\n  path: {TABLE}\n  sha256: {'a' * 64}\n", "")}.get(case.edit, text)
    path.write_text(text)
    line = text.splitlines().index(case.at) + 1 if case.at else None
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    err = info.value
    expected = case.expected.replace("{folder}", str(tmp_path))
    assert (err.path, err.key, err.line, err.expected, err.found) == (str(path), case.key, line, expected, case.found)
    assert len(err.problems) == 1, str(err)


# --------------------------------------------------------------------------------------------------------------
# Malformed tables: each gives its problems (line, column, expected, found), all of them at once.


@dataclass(frozen=True)
class BadTable:
    name: str
    text: str
    problems: list[tuple[int | None, str, str, str]]  # (line, key, expected, found)


COLUMNS = str(list(LABEL_COLUMNS))
WEIGHTS = "happy+sad+angry+neutral"


def row(*cells: str, file: str = "resources/131_01.bvh") -> str:
    return f"{file},walk,plain,{','.join(cells)},\n"


TABLE_CASES = [
    BadTable("unknown_column", HEADER.replace("happy", "hapy") + row("1", "0", "0", "0", "actor_intended"),
             [(1, "hapy", f"one of the columns {COLUMNS}", "unknown column 'hapy' (did you mean 'happy'?)"),
              (1, "happy", "a column (a required column)", "no such column")]),
    BadTable("missing_column", HEADER.replace(",label_method", ""), [
        (1, "label_method", "a column (a required column)", "no such column")]),
    BadTable("column_twice", HEADER.replace("description", "style"), [
        (1, "style", "each column once (first as column 3)", "style again")]),
    BadTable("empty", "", [(1, "(header)", f"a header row naming the columns {COLUMNS}", "an empty table")]),
    BadTable("weights_not_summing_to_1", HEADER + row("0.5", "0.5", "0.5", "0", "actor_intended"), [
        (2, WEIGHTS, "weights summing to 1", "0.5 + 0.5 + 0.5 + 0 = 1.5")]),
    BadTable("negative_weight", HEADER + row("1.5", "-0.5", "0", "0", "actor_intended"), [
        (2, "sad", "a weight >= 0", "-0.5")]),
    BadTable("weight_not_a_number", HEADER + row("one", "0", "0", "0", "actor_intended"), [
        (2, "happy", "a number", "'one'")]),
    BadTable("weight_nan", HEADER + row("nan", "0", "0", "1", "actor_intended"), [(2, "happy", "a number", "'nan'")]),
    BadTable("weights_partly_empty", HEADER + row("1", "", "0", "0", "actor_intended"), [
        (2, "sad", f"a number (the weight columns {WEIGHTS} are all numbers or all empty)", "an empty value")]),
    BadTable("unknown_label_method", HEADER + row("1", "0", "0", "0", "guessed"), [
        (2, "label_method", "'actor_intended' or 'style_mapping'", "'guessed'")]),
    BadTable("weights_without_label_method", HEADER + row("1", "0", "0", "0", ""), [
        (2, "label_method", "'actor_intended' or 'style_mapping'", "an empty value")]),
    BadTable("label_method_without_weights", HEADER + row("", "", "", "", "actor_intended"), [
        (2, "label_method", "an empty value (the row has no emotion weights: unlabelled)", "'actor_intended'")]),
    BadTable("two_rows_for_one_file", HEADER + row("1", "0", "0", "0", "actor_intended") + row("", "", "", "", "")
             + row("", "", "", "", ""), [
        (3, "file", "one row per file (first at line 2)", "'resources/131_01.bvh' again"),
        (4, "file", "one row per file (first at line 2)", "'resources/131_01.bvh' again")]),
    BadTable("absolute_path", HEADER + row("", "", "", "", "", file="/data/131_01.bvh"), [
        (2, "file", "a path relative to the source folder (not empty, no leading '/', no '..')",
         "'/data/131_01.bvh'")]),
    BadTable("empty_content", HEADER + "resources/131_01.bvh,,plain,,,,,,\n", [
        (2, "content", "a non-empty string", "an empty value")]),
    BadTable("too_few_fields", HEADER + "resources/131_01.bvh,walk,plain,1,0,0,0,actor_intended\n", [
        (2, "(row)", "9 fields, one per column of the header", "8 fields")]),
    # a quoted description over two lines and a blank line: the next row's line is still right
    BadTable("lines_after_a_multiline_field", HEADER + 'resources/131_01.bvh,walk,plain,,,,,,"two\nlines"\n\n'
             + row("1", "1", "0", "0", "actor_intended", file="resources/131_02.bvh"), [
        (5, WEIGHTS, "weights summing to 1", "1 + 1 + 0 + 0 = 2")]),
    BadTable("not_utf8", HEADER + "resources/131_01.bvh,walk,pl\xe4in,,,,,,\n", [
        (2, "(table)", "UTF-8 text", "the byte 0xe4")]),
]


@pytest.mark.parametrize("case", TABLE_CASES, ids=lambda c: c.name)
def test_a_malformed_table_gives_its_named_errors(tmp_path, case: BadTable):
    file = tmp_path / TABLE
    file.write_bytes(case.text.encode("latin-1"))
    with pytest.raises(ManifestError) as info:
        read_labels_table(file, TABLE)
    err = info.value
    assert [(p.line, p.key, p.expected, p.found) for p in err.problems] == case.problems
    line, key, expected, found = case.problems[0]
    assert str(err).splitlines()[0] == f"{file}{f':{line}' if line else ''}: {key}: expected {expected}, found {found}"


def test_a_malformed_table_stops_the_manifest_from_loading(tmp_path):
    path = cmu_manifest(tmp_path, HEADER + row("1", "0", "0", "0", "actor_intended") + row("", "", "", "", ""))
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    assert str(info.value) == (f"{tmp_path / TABLE}:3: file: expected one row per file (first at line 2), found "
                               "'resources/131_01.bvh' again")


def test_a_good_table_reads_as_written(tmp_path):
    file = tmp_path / TABLE
    file.write_text("\ufeff" + "description,file,label_method,neutral,angry,sad,happy,style,content\r\n"
                    '"a ""quoted"", multi-\nline text",resources/131_01.bvh, style_mapping ,0,0,0.25,0.75,plain,'
                    "walk\r\n"
                    ",resources/131_02.bvh,,,,,,plain,walk\r\n")
    table = read_labels_table(file, TABLE)
    (line1, one), (line2, two) = table.rows["resources/131_01.bvh"], table.rows["resources/131_02.bvh"]
    assert (line1, one.content, one.style, one.emotion, one.label_method, one.description) == (
        2, "walk", "plain", (0.75, 0.25, 0.0, 0.0), "style_mapping", 'a "quoted", multi-\nline text')
    assert (line2, two.emotion, two.label_method, two.description) == (4, None, None, None)
    assert table.sha256 == sha256_file(file) and re.fullmatch(r"[0-9a-f]{64}", table.sha256)
