"""Source manifests: what a mocap source is, which files it has (pinned by sha256) and how to read them.

Adding a mocap source means adding a manifest under ``manifests/sources/``; nothing here names a source.
Every manifest is checked against the schema below when it is loaded: a malformed one raises ``ManifestError``,
which names the file, the line, the key (a dotted path such as ``label_rule.emotions[0].emotion``), what was
expected and what was found, before any data is read. A source's labels come from its file names (``label_rule``),
from a side table with one row per file (``labels_table``, a CSV checked the same way: file, line, column,
expected, found), or both. This module knows YAML, CSV and file layout, never the data inside the mocap files.
"""

from __future__ import annotations

import csv
import difflib
import fnmatch
import io
import math
import os
import re
import types
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from pipeline.core.emotions import EMOTIONS, SOURCE_LABEL_METHODS
from pipeline.io.files import sha256_bytes, sha256_file

AXES_TO_Y_UP = {
    # Rows map source (x, y, z) to canonical (x, y, z), right-handed, Y up.
    "+Y": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "+Z": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
}
FORMATS = ("bvh", "c3d")  # the readers under pipeline/io/readers
CONTACT_POINTS = ("left_heel", "left_toe", "right_heel", "right_toe")  # a marker set's `contacts` keys
PELVIS_POINTS = ("left_asis", "right_asis", "sacrum")  # a marker set's `pelvis` keys
WEIGHT_TOLERANCE = 1e-9  # affine weights must sum to 1 within this (as retargeting and the marker rules check)
EMOTION_TOLERANCE = 1e-6  # emotion weights must sum to 1 within this (a table's 0.333333 x 3 passes)
LABEL_COLUMNS = ("file", "content", "style", *EMOTIONS, "label_method", "description")  # a labels table's columns
OPTIONAL_LABEL_COLUMNS = ("description",)


# --------------------------------------------------------------------------------------------------------------
# The schema. Rules that pydantic types cannot say (a regex that compiles, weights summing to 1) raise ``_bad``.


def _bad(expected: str, found: str, sub: tuple[Any, ...] = ()) -> PydanticCustomError:
    """A schema violation in our words. ``found`` is a description (``_show(value)`` for a value); ``sub``
    extends the key's location (an entry inside the checked value, e.g. one joint of a joint map)."""
    return PydanticCustomError("manifest", "expected {expected}", {"expected": expected, "found": found, "sub": sub})


def _show(value: Any) -> str:
    if isinstance(value, str):
        return repr(value if len(value) <= 100 else value[:97] + "...")
    if isinstance(value, bool):
        return f"{value!r} (a boolean)"
    if value is None:
        return "an empty value"
    if isinstance(value, (dict, list)) and len(repr(value)) <= 80:
        return repr(value)
    if isinstance(value, dict):
        keys = list(value)
        return f"a mapping with keys {keys[:8]}{' ...' if len(keys) > 8 else ''}"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    return repr(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _text(value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise _bad("a non-empty string", _show(value))
    return value


def _source_name(value: str) -> str:
    if not re.fullmatch(r"[a-z0-9_]+", value):
        raise _bad("a source name of lowercase letters, digits and '_'", _show(value))
    return value


def _affine(value: Any, what: str) -> dict[str, float]:
    """{name: weight} with number weights summing to 1: an affine combination (a virtual point)."""
    if not isinstance(value, dict) or not value:
        raise _bad(what, _show(value))
    for name, weight in value.items():
        if not isinstance(name, str) or not _is_number(weight):
            raise _bad(f"{what} (names with number weights)", f"{_show(name)}: {_show(weight)}")
    total = sum(value.values())
    if abs(total - 1.0) > WEIGHT_TOLERANCE:
        raise _bad(f"{what} whose weights sum to 1", f"weights {list(value.values())} summing to {total:g}")
    return value


def _joint_map(value: Any) -> Any:
    """{canonical joint: a source joint name, or {source point: weight} (a virtual joint)}."""
    what = "a source joint name or a mapping {source point: weight}"
    if not isinstance(value, dict) or not value:
        raise _bad("a mapping {canonical joint: source joint or {source point: weight}}", _show(value))
    for joint, rule in value.items():
        try:
            if isinstance(rule, dict):
                _affine(rule, what)
            elif not isinstance(rule, str) or not rule.strip():
                raise _bad(what, _show(rule))
        except PydanticCustomError as err:
            raise _bad(err.context["expected"], err.context["found"], sub=(joint,)) from None
    return value


def _marker_rule(value: Any) -> Any:
    """A marker, {marker: weight} (weights sum to 1) or [alternatives] (see pipeline.ingest.markers)."""
    what = "a marker name, a mapping {marker: weight} or a list of alternatives"
    if isinstance(value, str):
        return _text(value)
    if isinstance(value, list) and value:
        for alternative in value:
            _marker_rule(alternative)
        return value
    if isinstance(value, dict):
        return _affine(value, "a mapping {marker: weight}")
    raise _bad(what, _show(value))


def _canonical_rule(value: Any) -> Any:
    """A marker rule, or one of the joint-centre forms that only the canonical rules have."""
    if isinstance(value, dict) and "hip_centre" in value:
        if set(value) != {"hip_centre"} or value["hip_centre"] not in ("left", "right"):
            raise _bad("{hip_centre: left} or {hip_centre: right}", _show(value))
    elif isinstance(value, dict) and "lateral" in value:
        if set(value) != {"lateral", "medial_offset_m"} or not _is_number(value["medial_offset_m"]):
            raise _bad("{lateral: marker rule, medial_offset_m: number}", _show(value))
        _marker_rule(value["lateral"])
    elif isinstance(value, dict) and "joints" in value:
        if set(value) != {"joints"}:
            raise _bad("{joints: {canonical joint: weight}}", _show(value))
        _affine(value["joints"], "a mapping {canonical joint: weight}")
    else:
        _marker_rule(value)
    return value


def _regex(value: str) -> str:
    try:
        re.compile(value)
    except re.error as err:
        raise _bad("a valid regular expression", f"{value!r} ({err})") from None
    return value


def _hex(digits: int, what: str):
    pattern = re.compile(f"[0-9a-f]{{{digits}}}")

    def check(value: str) -> str:
        if not pattern.fullmatch(value):
            raise _bad(f"{what} ({digits} lowercase hexadecimal digits)", f"{value!r} ({len(value)} characters)")
        return value

    return check


def _relative_to(folder: str):
    def check(value: str) -> str:
        if not value.strip() or value.startswith("/") or ".." in value.split("/"):
            raise _bad(f"a path relative to {folder} (not empty, no leading '/', no '..')", _show(value))
        return value

    return check


_relative_path = _relative_to("the source folder")


def _file_url(value: str) -> str:
    if "{path}" not in value:
        raise _bad("a URL template containing {path}", _show(value))
    return value


def _fps(value: Any) -> Any:
    if value == "from_file" or (_is_number(value) and value > 0):
        return value
    raise _bad("'from_file' or a positive number", _show(value))


def _positive(value: float) -> float:
    if not value > 0:
        raise _bad("a positive number", _show(value))
    return value


def _non_negative(value: float) -> float:
    if not value >= 0:
        raise _bad("a number >= 0", _show(value))
    return value


def _emotion(value: list[float]) -> list[float]:
    if len(value) != 4 or any(v < 0 for v in value) or abs(sum(value) - 1.0) > EMOTION_TOLERANCE:
        raise _bad("4 non-negative weights (happy, sad, angry, neutral) summing to 1", str(value))
    return value


Text = Annotated[str, AfterValidator(_text)]
Seconds = Annotated[float, AfterValidator(_non_negative)]
RelativePath = Annotated[str, AfterValidator(_relative_path)]
JointMap = Annotated[Any, AfterValidator(_joint_map)]
MarkerRule = Annotated[Any, AfterValidator(_marker_rule)]
CanonicalRule = Annotated[Any, AfterValidator(_canonical_rule)]


class _Schema(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class Upstream(_Schema):
    repository: Text
    commit: Annotated[str, AfterValidator(_hex(40, "a git commit id"))]
    file_url: Annotated[str, AfterValidator(_file_url)]


Sha256 = Annotated[str, AfterValidator(_hex(64, "a sha256 digest"))]


class PinnedFile(_Schema):
    path: RelativePath
    sha256: Sha256


class LabelsTableRef(_Schema):
    """``labels_table``: a CSV with one row per file, beside the manifest or below its folder (so the pipeline's
    dependency on the manifests folder covers it), pinned by sha256 (``emogait pin`` writes it; a table that no
    longer matches its pin stops the manifest from loading).

    Columns (header row, any order): ``file`` (path relative to the source folder, as ``files:`` names it),
    ``content``, ``style``, one weight column per emotion in ``EMOTIONS`` order (happy, sad, angry, neutral):
    four numbers >= 0 summing to 1, or all four empty for an unlabelled file, then ``label_method`` (one of
    ``SOURCE_LABEL_METHODS``; empty exactly when the weights are), and ``description`` (free text, optional).
    A file's row overrides the label rule for that file; a file without a row gets the label rule's label, or,
    where the manifest has no label rule, is quarantined at ingest. Rows for files the source does not have and
    files without a row are reported (warnings on load, the ingest report's ``labels_table`` per source).
    """

    path: Annotated[str, AfterValidator(_relative_to("the manifest's folder"))]
    sha256: Sha256 | None = None  # required when the manifest is loaded; `emogait pin` fills it in


class EmotionRule(_Schema):
    when: dict[str, str]
    emotion: Annotated[list[float], AfterValidator(_emotion)]
    label_method: Literal[SOURCE_LABEL_METHODS]


class LabelRule(_Schema):
    pattern: Annotated[str, AfterValidator(_regex)]
    fixed: dict[str, str] = {}
    content_map: dict[str, str] = {}
    emotions: list[EmotionRule] = []
    rationale: Text | None = None

    @model_validator(mode="after")
    def _conditions_name_fields(self) -> LabelRule:
        fields = set(re.compile(self.pattern).groupindex) | set(self.fixed)
        for k, entry in enumerate(self.emotions):
            for name in entry.when:
                if name not in fields:  # a condition on a field no file has never holds
                    raise _bad(f"a field the label rule gives (pattern groups and fixed: {sorted(fields)})",
                               _show(name), sub=("emotions", k, "when", name))
        return self


class MarkerSet(_Schema):
    name: Text
    requires: Annotated[list[Text], Field(min_length=1)]
    contacts: dict[Literal[CONTACT_POINTS], MarkerRule]
    pelvis: dict[Literal[PELVIS_POINTS], MarkerRule] | None = None
    canonical: dict[str, CanonicalRule] | None = None
    canonical_note: Text | None = None

    @model_validator(mode="after")
    def _every_contact_point(self) -> MarkerSet:
        missing = [p for p in CONTACT_POINTS if p not in self.contacts]
        if missing:
            raise _bad(f"a rule for each of {list(CONTACT_POINTS)}", f"none for {missing}", sub=("contacts",))
        return self


class SourceSpec(_Schema):
    """One source manifest (manifests/sources/<name>.yaml). Keys ending in ``_note`` are free text for people.

    Labels: ``label_rule`` (a file-name regex; conditions on its groups give the emotion) and/or ``labels_table``
    (a CSV, one row per file; see ``LabelsTableRef``). At least one is required; where both are given, a file's
    table row wins and the rule labels the files without a row.
    """

    name: Annotated[str, AfterValidator(_source_name)]
    title: Text
    format: Literal[FORMATS]
    upstream: Upstream
    licence: Text
    attribution: Text
    globs: Annotated[list[RelativePath], Field(min_length=1)]
    units: Text
    unit_scale_m: Annotated[float, AfterValidator(_positive)]
    up_axis: Literal[tuple(AXES_TO_Y_UP)]
    fps: Annotated[Any, AfterValidator(_fps)]
    root_offset: Literal["add", "ignore"] = "add"
    root_offset_note: Text | None = None
    joint_map: JointMap | None = None
    joint_map_overrides: dict[str, JointMap] = {}
    joint_map_note: Text | None = None
    label_rule: LabelRule | None = None
    labels_table: LabelsTableRef | None = None
    gait_contents: Annotated[list[Text], Field(min_length=1)]
    content_note: Text | None = None
    min_clip_seconds: Seconds = 0.0
    max_gap_seconds: Seconds | None = None
    marker_sets: Annotated[list[MarkerSet], Field(min_length=1)] | None = None
    files: list[PinnedFile] = []

    @model_validator(mode="after")
    def _consistent(self) -> SourceSpec:
        if self.label_rule is None and self.labels_table is None:
            raise _bad("a label rule (label_rule), a labels table (labels_table) or both", "no such key",
                       sub=("label_rule",))
        if self.format == "bvh" and self.joint_map is None:
            raise _bad("a joint map (a BVH source maps its joints onto the canonical ones)", "no such key",
                       sub=("joint_map",))
        if self.format == "c3d" and self.marker_sets is None:
            raise _bad("marker sets (a C3D source says which markers are heel, toe and pelvis)", "no such key",
                       sub=("marker_sets",))
        for name in self.joint_map_overrides:
            if "/" in name:
                raise _bad("a file name (an override applies to files of that name)", _show(name),
                           sub=("joint_map_overrides", name))
        first: dict[str, int] = {}
        for k, entry in enumerate(self.files):
            if entry.path in first:
                raise _bad("each file pinned once", f"{entry.path!r} again (first at files[{first[entry.path]}])",
                           sub=("files", k, "path"))
            first[entry.path] = k
        return self


# --------------------------------------------------------------------------------------------------------------
# Errors: pydantic's locations and types -> file, line, dotted key, expected, found.


@dataclass(frozen=True)
class Problem:
    key: str  # dotted path, e.g. "label_rule.emotions[0].emotion"; "(document)" for the document as a whole
    line: int | None  # 1-based line of the key (of the closest enclosing key when the key is missing)
    expected: str
    found: str


def _described(path: str, problems: Sequence[Problem]) -> str:
    return "\n".join(f"{path}{f':{p.line}' if p.line else ''}: {p.key}: expected {p.expected}, found {p.found}"
                     for p in problems)


class ManifestError(ValueError):
    """A manifest (or its labels table) that does not follow the schema. ``str(err)``: one line per problem,
    ``<file>:<line>: <key>: expected <...>, found <...>``; the first problem's parts are attributes. In a labels
    table the key is the column (``happy+sad+angry+neutral`` for the weights' sum)."""

    def __init__(self, path: str | Path, problems: Sequence[Problem]):
        self.path, self.problems = str(path), list(problems)
        first = self.problems[0]
        self.key, self.line, self.expected, self.found = first.key, first.line, first.expected, first.found
        super().__init__(_described(self.path, self.problems))


class ManifestWarning(UserWarning):
    """Something that does not stop a run but is likely a mistake: a labels-table row for a file the manifest does
    not pin, pinned files without a row. ``str``: as ManifestError's."""

    def __init__(self, path: str | Path, problems: Sequence[Problem]):
        self.path, self.problems = str(path), list(problems)
        super().__init__(_described(self.path, self.problems))


def _key(part: Any) -> str:
    text = str(part)
    return text if re.fullmatch(r"[A-Za-z0-9_\-]+", text) else repr(text)


def _dotted(loc: Sequence[Any]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else f"{'.' if out else ''}{_key(part)}"
    return out


_TYPE_WORDS = {
    "string_type": "a string", "float_type": "a number", "int_type": "an integer", "bool_type": "true or false",
    "list_type": "a list", "dict_type": "a mapping", "model_type": "a mapping", "model_attributes_type": "a mapping",
}


def _unwrap(annotation: Any) -> Any:
    """The type under Annotated[...] and an Optional."""
    while True:
        if get_origin(annotation) is Annotated:
            annotation = get_args(annotation)[0]
        elif get_origin(annotation) in (Union, types.UnionType):
            options = [a for a in get_args(annotation) if a is not type(None)]
            if len(options) != 1:
                return annotation
            annotation = options[0]
        else:
            return annotation


def _schema_at(loc: Sequence[Any]) -> type[BaseModel] | None:
    """The schema class whose keys live at ``loc`` (to list them for an unknown key), or None."""
    current: Any = SourceSpec
    for part in loc:
        current = _unwrap(current)
        if isinstance(current, type) and issubclass(current, BaseModel) and part in current.model_fields:
            current = current.model_fields[part].annotation
        elif get_origin(current) is list and isinstance(part, int):
            current = get_args(current)[0]
        elif get_origin(current) is dict:
            current = get_args(current)[1]
        else:
            return None
    current = _unwrap(current)
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _problem(error: dict[str, Any], lines: _Lines) -> Problem:
    kind, ctx, value = error["type"], error.get("ctx") or {}, error.get("input")
    loc = [p for p in error["loc"] if p != "[key]"]
    if kind == "manifest":
        loc += list(ctx["sub"])
        expected, found = ctx["expected"], ctx["found"]
    elif kind == "missing":
        expected, found = "a value (a required key)", "no such key"
    elif kind == "extra_forbidden":
        schema = _schema_at(loc[:-1])
        known = sorted(schema.model_fields) if schema else []
        close = difflib.get_close_matches(str(loc[-1]), known, n=1)
        expected = f"one of the keys {known}"
        found = f"unknown key {str(loc[-1])!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
    elif kind == "literal_error":
        expected, found = ctx["expected"], _show(value)
    elif kind == "too_short":
        expected, found = f"at least {ctx['min_length']} item", _show(value)
    elif "[key]" in error["loc"]:
        expected, found = f"{_TYPE_WORDS.get(kind, 'a string')} as each key", _show(value)
    else:
        expected, found = _TYPE_WORDS.get(kind, error["msg"].removeprefix("Input should be ")), _show(value)
    return Problem(_dotted(loc), lines.line(loc), expected, found)


class _Lines:
    """Line numbers of the keys of a YAML text, and its duplicate keys (which YAML loaders silently merge)."""

    def __init__(self, text: str):
        self.root = yaml.compose(text, Loader=yaml.SafeLoader)
        self.duplicates: list[tuple[list[Any], int, int]] = []  # (location, first line, repeated line)
        self._find_duplicates(self.root, [])

    def _find_duplicates(self, node: Any, loc: list[Any]) -> None:
        if isinstance(node, yaml.MappingNode):
            first: dict[str, int] = {}
            for key, value in node.value:
                if key.value in first:
                    self.duplicates.append((loc + [key.value], first[key.value], key.start_mark.line + 1))
                first.setdefault(key.value, key.start_mark.line + 1)
                self._find_duplicates(value, loc + [key.value])
        elif isinstance(node, yaml.SequenceNode):
            for k, item in enumerate(node.value):
                self._find_duplicates(item, loc + [k])

    def line(self, loc: Sequence[Any]) -> int | None:
        """The line of the deepest key of ``loc`` that the file has."""
        node, line = self.root, None
        for part in loc:
            if isinstance(node, yaml.MappingNode):
                match = next(((k, v) for k, v in node.value if k.value == str(part)), None)
                if match is None:
                    break
                line, node = match[0].start_mark.line + 1, match[1]
            elif isinstance(node, yaml.SequenceNode) and isinstance(part, int) and part < len(node.value):
                node = node.value[part]
                line = node.start_mark.line + 1
            else:
                break
        return line


def check_manifest(text: str, path: str | Path, *, pins: bool = True) -> dict[str, Any]:
    """The manifest's document, checked against the schema, its labels table there (and, with pins, matching its
    pinned sha256); raises ManifestError. ``pins=False`` leaves the ``files:`` list and the table's sha256
    unchecked (``emogait pin`` rewrites them). The table's rows are checked by ``read_labels_table``."""
    path = Path(path)
    try:
        doc = yaml.safe_load(text)
        lines = _Lines(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        raise ManifestError(path, [Problem("(document)", mark.line + 1 if mark else None, "valid YAML",
                                           f"a syntax error: {getattr(err, 'problem', None) or err}")]) from None
    if not isinstance(doc, dict):
        raise ManifestError(path, [Problem("(document)", 1, "a mapping of manifest keys", _show(doc))])
    problems = [Problem(_dotted(loc), repeated, f"each key once (first at line {first})", f"{_key(loc[-1])} again")
                for loc, first, repeated in lines.duplicates]
    checked = {k: v for k, v in doc.items() if pins or k != "files"}
    if not pins and isinstance(doc.get("labels_table"), dict):
        checked["labels_table"] = {k: v for k, v in doc["labels_table"].items() if k != "sha256"}
    try:
        SourceSpec.model_validate(checked)
    except ValidationError as err:
        problems += [_problem(e, lines) for e in err.errors(include_url=False)]
    if not problems and doc["name"] != path.stem:
        problems.append(Problem("name", lines.line(["name"]), f"{path.stem!r} (the manifest's file name)",
                                _show(doc["name"])))
    if not problems and doc.get("labels_table") is not None:
        problems += _table_pin_problems(doc["labels_table"], path, lines, pins)
    if problems:
        raise ManifestError(path, problems)
    return doc


def _table_pin_problems(ref: dict[str, Any], path: Path, lines: _Lines, pins: bool) -> list[Problem]:
    """The labels table is a file; with ``pins``, its sha256 is pinned and matches it."""
    table = path.parent / ref["path"]
    if not table.is_file():
        return [Problem("labels_table.path", lines.line(["labels_table", "path"]),
                        f"a labels table (CSV) at {table}", "no such file")]
    if not pins:
        return []
    if "sha256" not in ref:
        return [Problem("labels_table.sha256", lines.line(["labels_table"]),
                        f"the table's sha256 (`emogait pin {path}` writes it)", "no such key")]
    found = sha256_file(table)
    if found != ref["sha256"]:
        return [Problem("labels_table.sha256", lines.line(["labels_table", "sha256"]),
                        f"{ref['sha256']} (the pinned sha256 of {table})",
                        f"{found} (the table changed since it was pinned: review it, then `emogait pin {path}`)")]
    return []


# --------------------------------------------------------------------------------------------------------------
# Labels tables: one CSV row per file (``labels_table``).


@dataclass(frozen=True)
class LabelsTable:
    """A source's labels table, read and checked. ``rows``: source-relative file path -> (the CSV line of its
    row, its label)."""

    path: str  # as the manifest names it (relative to the manifest's folder)
    file: Path  # where it was read
    sha256: str
    rows: dict[str, tuple[int, Label]]

    def coverage(self, files: Iterable[str]) -> tuple[list[tuple[int, str]], list[str]]:
        """(rows naming none of ``files``: (line, file), by line; the ``files`` without a row, sorted)."""
        files = set(files)
        return (sorted((line, f) for f, (line, _) in self.rows.items() if f not in files),
                sorted(files - set(self.rows)))


def _rows(text: str) -> Iterable[tuple[int, list[str]]]:
    """(first line, fields) of each non-blank CSV record; a quoted field may span lines."""
    reader = csv.reader(io.StringIO(text, newline=""))
    start = reader.line_num + 1
    for fields in reader:
        if any(f.strip() for f in fields):
            yield start, fields
        start = reader.line_num + 1


def _header_problems(header: list[str], line: int) -> list[Problem]:
    problems, first = [], {}
    for k, column in enumerate(header):
        if column in first:
            problems.append(Problem(_key(column), line, f"each column once (first as column {first[column] + 1})",
                                    f"{column} again"))
        elif column not in LABEL_COLUMNS:
            close = difflib.get_close_matches(column, LABEL_COLUMNS, n=1)
            problems.append(Problem(_key(column), line, f"one of the columns {list(LABEL_COLUMNS)}",
                                    f"unknown column {column!r}" + (f" (did you mean {close[0]!r}?)" if close else "")))
        first.setdefault(column, k)
    problems += [Problem(c, line, "a column (a required column)", "no such column")
                 for c in LABEL_COLUMNS if c not in first and c not in OPTIONAL_LABEL_COLUMNS]
    return problems


def _row_label(cells: dict[str, str], line: int, problems: list[Problem]) -> Label | None:
    """The label a row gives; None after adding its problems."""
    before = len(problems)
    for column in ("content", "style"):
        if not cells[column]:
            problems.append(Problem(column, line, "a non-empty string", "an empty value"))
    method = cells["label_method"]
    weights = [cells[e] for e in EMOTIONS]
    emotion = None
    if not any(weights):
        if method:
            problems.append(Problem("label_method", line, "an empty value (the row has no emotion weights: "
                                    "unlabelled)", _show(method)))
    elif not all(weights):
        empty = next(e for e, w in zip(EMOTIONS, weights) if not w)
        problems.append(Problem(empty, line, f"a number (the weight columns {'+'.join(EMOTIONS)} are all numbers "
                                "or all empty)", "an empty value"))
    else:
        values = []
        for name, text in zip(EMOTIONS, weights):
            try:
                value = float(text)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                problems.append(Problem(name, line, "a number", _show(text)))
            elif value < 0:
                problems.append(Problem(name, line, "a weight >= 0", text))
            values.append(value)
        if len(problems) == before and abs(sum(values) - 1.0) > EMOTION_TOLERANCE:
            problems.append(Problem("+".join(EMOTIONS), line, "weights summing to 1",
                                    f"{' + '.join(weights)} = {sum(values):g}"))
        if method not in SOURCE_LABEL_METHODS:
            problems.append(Problem("label_method", line, " or ".join(map(repr, SOURCE_LABEL_METHODS)),
                                    _show(method) if method else "an empty value"))
        emotion = tuple(values)
    if len(problems) > before:
        return None
    return Label(content=cells["content"], style=cells["style"], emotion=emotion, label_method=method or None,
                 fields={}, description=cells.get("description") or None)


def read_labels_table(file: Path, name: str) -> LabelsTable:
    """A labels table (see ``LabelsTableRef``), every row checked; ``name``: the path as the manifest gives it.
    Raises ManifestError naming the CSV file, the line, the column, what was expected and what was found."""
    data = file.read_bytes()
    try:
        text = data.decode("utf-8-sig")  # a byte-order mark is what spreadsheet programs write
    except UnicodeDecodeError as err:
        raise ManifestError(file, [Problem("(table)", data.count(b"\n", 0, err.start) + 1, "UTF-8 text",
                                           f"the byte {data[err.start]:#04x}")]) from None
    try:
        records = list(_rows(text))
    except csv.Error as err:
        raise ManifestError(file, [Problem("(table)", None, "CSV text", str(err))]) from None
    if not records:
        raise ManifestError(file, [Problem("(header)", 1, f"a header row naming the columns {list(LABEL_COLUMNS)}",
                                           "an empty table")])
    line, header = records[0]
    header = [c.strip() for c in header]
    problems = _header_problems(header, line)
    if problems:
        raise ManifestError(file, problems)
    rows: dict[str, tuple[int, Label]] = {}
    for line, fields in records[1:]:
        if len(fields) != len(header):
            problems.append(Problem("(row)", line, f"{len(header)} fields, one per column of the header",
                                    f"{len(fields)} fields"))
            continue
        cells = {c: v.strip() for c, v in zip(header, fields)}
        path = cells["file"]
        try:
            _relative_path(path)
        except PydanticCustomError as err:
            problems.append(Problem("file", line, err.context["expected"], err.context["found"]))
            continue
        if path in rows:
            problems.append(Problem("file", line, f"one row per file (first at line {rows[path][0]})",
                                    f"{path!r} again"))
            continue
        label = _row_label(cells, line, problems)
        if label is not None:
            rows[path] = (line, label)
    if problems:
        raise ManifestError(file, problems)
    return LabelsTable(path=name, file=file, sha256=sha256_bytes(data), rows=rows)


def _coverage_problems(table: LabelsTable, files: Iterable[str], fallback: bool, pinned: str) -> list[Problem]:
    """Rows for files not among ``files`` (described by ``pinned``), and ``files`` without a row (10 named)."""
    unused, unrowed = table.coverage(files)
    problems = [Problem("file", line, f"a file {pinned}", f"{path!r}, which it does not have (the row labels "
                        "nothing)") for line, path in unused]
    if unrowed:
        named = ", ".join(map(repr, unrowed[:10])) + (f" and {len(unrowed) - 10} more" if len(unrowed) > 10 else "")
        problems.append(Problem("file", None, f"a row for each file {pinned}",
                                f"none for {len(unrowed)}: {named} ("
                                + ("they get the label rule's label)" if fallback else
                                   "no label rule to fall back on: quarantined at ingest)")))
    return problems


# --------------------------------------------------------------------------------------------------------------
# Loaded manifests.


@dataclass(frozen=True)
class FileEntry:
    path: str  # relative to the source folder (= the upstream repository path)
    sha256: str


@dataclass(frozen=True)
class Label:
    content: str
    style: str
    emotion: tuple[float, float, float, float] | None
    label_method: str | None
    fields: dict[str, str]  # the label rule's named fields (pattern groups and fixed); {} for a table row
    description: str | None = None  # a table row's free text


@dataclass(frozen=True)
class SourceManifest:
    name: str
    format: str
    doc: dict[str, Any]  # as written in the file, checked against SourceSpec
    files: tuple[FileEntry, ...]
    labels: LabelsTable | None = None  # the labels table, where the manifest names one

    @property
    def globs(self) -> list[str]:
        return list(self.doc["globs"])

    @property
    def unit_scale_m(self) -> float:
        return float(self.doc["unit_scale_m"])

    @property
    def up_axis(self) -> str:
        return self.doc["up_axis"]

    @property
    def root_offset(self) -> str:
        return self.doc.get("root_offset", "add")

    @property
    def min_clip_seconds(self) -> float:
        return float(self.doc.get("min_clip_seconds", 0.0))

    @property
    def max_gap_seconds(self) -> float | None:
        """Interior marker gaps up to this long are filled (C3D sources); None when the manifest sets none."""
        value = self.doc.get("max_gap_seconds")
        return None if value is None else float(value)

    @property
    def marker_sets(self) -> list[dict[str, Any]]:
        return list(self.doc.get("marker_sets") or [])

    @property
    def gait_contents(self) -> set[str]:
        return set(self.doc.get("gait_contents", []))

    def joint_map(self, rel_path: str) -> dict[str, Any]:
        overrides = self.doc.get("joint_map_overrides") or {}
        return overrides.get(Path(rel_path).name, self.doc["joint_map"])

    def upstream_url(self, rel_path: str) -> str:
        return self.doc["upstream"]["file_url"].format(path=rel_path)

    def label(self, rel_path: str) -> Label:
        """Content, style and emotion: the file's row of the labels table, else from the file name by the label
        rule. Raises ValueError (its message says which of the two failed)."""
        if self.labels is not None and rel_path in self.labels.rows:
            return self.labels.rows[rel_path][1]
        rule = self.doc.get("label_rule")
        if rule is None:  # the schema requires a rule or a table: this manifest has a table
            raise ValueError(f"labels table: no row for {rel_path!r} in {self.labels.file} and no label rule to "
                             f"fall back on; add a row for it")
        name = Path(rel_path).name
        match = re.match(rule["pattern"], name)
        if match is None:
            raise ValueError(f"label rule: file name {name!r} does not match the label pattern {rule['pattern']!r}")
        fields = {k: v for k, v in match.groupdict().items() if v is not None}
        fields.update(rule.get("fixed", {}))
        content = rule.get("content_map", {}).get(fields.get("content", "unknown"), fields.get("content", "unknown"))
        style = fields.get("style", "unknown")
        emotion = method = None
        for entry in rule.get("emotions", []):
            if all(fields.get(k) == v for k, v in entry["when"].items()):
                emotion = tuple(float(x) for x in entry["emotion"])
                method = entry["label_method"]
                break
        return Label(content=content, style=style, emotion=emotion, label_method=method, fields=fields)


def load_manifest(path: str | Path) -> SourceManifest:
    """A source manifest, checked against the schema (ManifestError names the file, line, key, expected, found),
    with its labels table read and checked. Rows for files the manifest does not pin and pinned files without a
    row are a ``ManifestWarning`` (ingest reports them again, against the files it finds)."""
    path = Path(path)
    doc = check_manifest(path.read_text(encoding="utf-8"), path)
    files = tuple(FileEntry(f["path"], f["sha256"]) for f in doc.get("files", []))
    labels = None
    if doc.get("labels_table") is not None:
        labels = read_labels_table(path.parent / doc["labels_table"]["path"], doc["labels_table"]["path"])
        problems = _coverage_problems(labels, (f.path for f in files), doc.get("label_rule") is not None,
                                      f"the manifest pins (files: in {path})")
        if problems:
            warnings.warn(ManifestWarning(labels.file, problems), stacklevel=2)
    return SourceManifest(name=doc["name"], format=doc["format"], doc=doc, files=files, labels=labels)


def load_manifests(folder: str | Path, formats: Sequence[str]) -> list[SourceManifest]:
    """Every manifest in ``folder`` (each checked), those of the given formats, by file name.

    ``formats`` is required: a stage says which readers it runs (e.g. ("bvh", "c3d")), so no source is
    dropped by a default.
    """
    if isinstance(formats, str) or not formats or any(f not in FORMATS for f in formats):
        raise ValueError(f"formats: expected a non-empty list of {list(FORMATS)}, found {formats!r}")
    manifests = [load_manifest(p) for p in sorted(Path(folder).glob("*.yaml"))]
    return [m for m in manifests if m.format in formats]


# --------------------------------------------------------------------------------------------------------------
# Files of a source folder. Symbolic links are followed everywhere: the mocap root, a source folder and any
# folder or file inside it may be a link.


def _matches(parts: Sequence[str], pattern: Sequence[str]) -> bool:
    """pathlib glob semantics per path segment: ``**`` is zero or more folders, others are fnmatch patterns."""
    if not pattern:
        return not parts
    if pattern[0] == "**":
        return _matches(parts, pattern[1:]) or (len(parts) > 1 and _matches(parts[1:], pattern))
    return bool(parts) and fnmatch.fnmatchcase(parts[0], pattern[0]) and _matches(parts[1:], pattern[1:])


def source_files(source_dir: Path, globs: Iterable[str]) -> list[str]:
    """Sorted paths (relative to ``source_dir``, '/'-separated) of the files any of the glob patterns matches.

    As pathlib's glob, but linked folders are followed under ``**`` too; a link back to an enclosing folder
    (a cycle) is not followed.
    """
    patterns = [g.split("/") for g in globs]
    found: set[str] = set()
    enclosing: dict[str, frozenset[str]] = {}  # folder -> real paths of it and the folders above it
    for folder, dirs, names in os.walk(source_dir, followlinks=True):
        real = os.path.realpath(folder)
        above = enclosing.get(os.path.dirname(folder), frozenset())
        if real in above:
            dirs[:] = []
            continue
        enclosing[folder] = above | {real}
        base = Path(folder).relative_to(source_dir).parts
        for name in names:
            parts = (*base, name)
            if os.path.isfile(os.path.join(folder, name)) and any(_matches(parts, p) for p in patterns):
                found.add("/".join(parts))
    return sorted(found)


def list_inputs(manifest: SourceManifest, source_dir: Path) -> list[tuple[str, str | None]]:
    """Every input the run must account for: (relative path, pinned sha256 or None if unpinned).

    The pinned files (present or not) plus any file the globs find that the manifest does not pin.
    """
    pinned = {f.path: f.sha256 for f in manifest.files}
    found = source_files(source_dir, manifest.globs) if source_dir.is_dir() else []
    return sorted({**{p: None for p in found}, **pinned}.items())


def locate_source_file(path: str | Path, mocap_root: Path, sources: Sequence[str]) -> tuple[str, str]:
    """(source name, path relative to its folder) of a file under one of the source folders of a mocap root.

    The file, the root and the source folders may each be reached through symbolic links: the path is first
    taken as written (links kept), then with every link resolved on both sides. Raises ValueError.
    """
    given = Path(os.path.abspath(path))
    real = given.resolve()
    for name in sources:
        folder = mocap_root / name
        for file, base in ((given, Path(os.path.abspath(folder))), (real, folder.resolve())):
            if file.is_relative_to(base) and file != base:
                return name, file.relative_to(base).as_posix()
    raise ValueError(f"{path}: expected a file under a source folder of the mocap root {mocap_root} "
                     f"({', '.join(sources)}), found a file outside them (links resolved: {real})")


# --------------------------------------------------------------------------------------------------------------
# Pinning: the ``files:`` list rewritten from what the globs find, every other byte of the manifest kept.


def pinned_files(manifest_path: str | Path, mocap_root: Path) -> list[FileEntry]:
    """Every file the manifest's globs find under ``mocap_root/<name>``, with its sha256, by path.

    The manifest is checked first, all but its ``files:`` list (the list pinning replaces).
    """
    doc = check_manifest(Path(manifest_path).read_text(encoding="utf-8"), manifest_path, pins=False)
    folder = mocap_root / doc["name"]
    if not folder.is_dir():
        raise ValueError(f"{manifest_path}: expected the source folder {folder}, found no such folder")
    entries = []
    for rel in source_files(folder, doc["globs"]):
        entries.append(FileEntry(rel, sha256_file(folder / rel)))
    return entries


def pinned_labels_table(manifest_path: str | Path,
                        files: Sequence[FileEntry]) -> tuple[FileEntry, ManifestWarning | None] | None:
    """The manifest's labels table (its path as the manifest names it, its sha256) and, if any, a warning naming
    its rows for none of ``files`` (those being pinned) and the ``files`` without a row; None when the manifest
    names no table. The manifest is checked first (all but its pins), then every row: a bad table is not pinned.
    """
    manifest_path = Path(manifest_path)
    doc = check_manifest(manifest_path.read_text(encoding="utf-8"), manifest_path, pins=False)
    ref = doc.get("labels_table")
    if ref is None:
        return None
    table = read_labels_table(manifest_path.parent / ref["path"], ref["path"])
    problems = _coverage_problems(table, (f.path for f in files), doc.get("label_rule") is not None,
                                  f"the globs find (under the source folder of {manifest_path})")
    return FileEntry(ref["path"], table.sha256), ManifestWarning(table.file, problems) if problems else None


def with_files(text: str, files: Sequence[FileEntry]) -> str:
    """The manifest text with its top-level ``files:`` block replaced (appended when it has none).

    The block is the ``files:`` line and the lines under it (indented or list items); comment and blank lines
    right after it belong to what follows and stay.
    """
    return _with_block(text, "files", [{"path": f.path, "sha256": f.sha256} for f in files])


def with_labels_table(text: str, table: FileEntry) -> str:
    """The manifest text with its top-level ``labels_table:`` block replaced by the table's path and sha256
    (comments inside that block are not kept); every other byte stays."""
    return _with_block(text, "labels_table", {"path": table.path, "sha256": table.sha256})


def _with_block(text: str, key: str, value: Any) -> str:
    """``key: value`` (block style) in place of the top-level ``key:`` block, or appended where there is none."""
    block = yaml.safe_dump({key: value}, sort_keys=False, width=120, allow_unicode=True)
    lines = text.splitlines(keepends=True)
    start = next((k for k, line in enumerate(lines) if re.match(rf"{key}\s*:", line)), None)
    if start is None:
        return text + ("" if not text or text.endswith("\n") else "\n") + block
    stop = start + 1
    last = start + 1  # one past the last line that belongs to the block
    while stop < len(lines):
        line = lines[stop]
        if line.startswith((" ", "\t", "-")):
            last = stop + 1
        elif line.strip() and not line.startswith("#"):
            break
        stop += 1
    return "".join(lines[:start]) + block + "".join(lines[last:])
