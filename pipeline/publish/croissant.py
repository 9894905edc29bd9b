"""Croissant 1.1 JSON-LD for a published gait directory, and the checks that keep it true.

The document describes the files the directory ships (the Parquet gaits, one file or ``gaits-*.parquet``
shards, and ``gaits.h5``, each with its sha256) and the record set ``gaits`` (every gait), with a field per
Parquet column; where the shards are split into parts (the real gaits, each generator family's), a FileSet and a
record set of the same fields per part.
Fields are derived from the Parquet schema and its ``emogait`` metadata (per-gait array shapes, units), never
from a list of column names, so a column added upstream is described without a change here. The dataset-level
Responsible-AI properties (the Croissant RAI 1.0 vocabulary) say how labels were made.

Why a check of our own beside ``mlcroissant validate``: the validator reads the document, not the data, so a
field naming a column the Parquet file lacks, an array shape that disagrees with the stored list size, or a
stale checksum all pass it; ``croissant_problems`` compares the document with the files.

This module knows the published directory's files and their schema, not how gaits are made, nor DVC.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.dataset import HDF5_NAME, ID_COLUMN, SHARD_GLOB, parquet_files
from pipeline.io.files import schema_meta, sha256_file, write_json

CROISSANT_NAME = "croissant.json"
CONFORMS_TO = "http://mlcommons.org/croissant/1.1"
RECORD_SET = "gaits"
PARQUET_FORMAT = "application/x-parquet"
HDF5_FORMAT = "application/x-hdf5"
SHARDS_ID = "gaits-parquet-shards"

# The Croissant 1.1 context (the spec's Appendix 1, with the https schema.org namespace and the keys
# mlcroissant's validator expects: it warns about any of its standard keys that is missing).
CONTEXT: dict[str, Any] = {
    "@language": "en",
    "@vocab": "https://schema.org/",
    "sc": "https://schema.org/",
    "cr": "http://mlcommons.org/croissant/",
    "rai": "http://mlcommons.org/croissant/RAI/",
    "dct": "http://purl.org/dc/terms/",
    "annotation": "cr:annotation",
    "arrayShape": "cr:arrayShape",
    "citeAs": "cr:citeAs",
    "column": "cr:column",
    "conformsTo": "dct:conformsTo",
    "containedIn": "cr:containedIn",
    "data": {"@id": "cr:data", "@type": "@json"},
    "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "description": {"@container": "@language"},
    "equivalentProperty": "cr:equivalentProperty",
    "examples": {"@id": "cr:examples", "@type": "@json"},
    "excludes": "cr:excludes",
    "extract": "cr:extract",
    "field": "cr:field",
    "fileObject": "cr:fileObject",
    "fileProperty": "cr:fileProperty",
    "fileSet": "cr:fileSet",
    "format": "cr:format",
    "includes": "cr:includes",
    "isArray": "cr:isArray",
    "isLiveDataset": "cr:isLiveDataset",
    "jsonPath": "cr:jsonPath",
    "key": "cr:key",
    "md5": "cr:md5",
    "name": {"@container": "@language"},
    "parentField": "cr:parentField",
    "path": "cr:path",
    "readLines": "cr:readLines",
    "recordSet": "cr:recordSet",
    "references": "cr:references",
    "regex": "cr:regex",
    "repeated": "cr:repeated",
    "replace": "cr:replace",
    "samplingRate": "cr:samplingRate",
    "sdVersion": "cr:sdVersion",
    "separator": "cr:separator",
    "source": "cr:source",
    "subField": "cr:subField",
    "transform": "cr:transform",
    "unArchive": "cr:unArchive",
}

# The dataset-level properties of the Croissant RAI 1.0 vocabulary (http://mlcommons.org/croissant/RAI/1.0).
RAI_PROPERTIES = frozenset({
    "dataCollection", "dataCollectionType", "dataCollectionMissingData", "dataCollectionRawData",
    "dataCollectionTimeframe", "dataPreprocessingProtocol", "dataImputationProtocol", "dataManipulationProtocol",
    "dataReleaseMaintenancePlan", "personalSensitiveInformation", "dataAnnotationProtocol",
    "dataAnnotationPlatform", "dataAnnotationAnalysis", "annotationsPerItem", "annotatorDemographics",
    "machineAnnotationTools", "dataSocialImpact", "dataBiases", "dataLimitations", "dataUseCases",
})


def _data_type(kind: pa.DataType, column: str) -> str:
    """The Croissant atomic data type of an Arrow scalar type."""
    if pa.types.is_string(kind) or pa.types.is_large_string(kind):
        return "sc:Text"
    if pa.types.is_boolean(kind):
        return "sc:Boolean"
    if pa.types.is_integer(kind):
        return "sc:Integer"
    if pa.types.is_floating(kind):
        return "sc:Float"
    if pa.types.is_timestamp(kind):
        return "sc:DateTime"
    if pa.types.is_date(kind):
        return "sc:Date"
    raise TypeError(f"column {column!r}: expected a string, boolean, number, date or timestamp "
                    f"(or a list of them), found {kind}")


def _array_shape(kind: pa.DataType, column: str, shapes: Mapping[str, list[int]]) -> str:
    """The per-gait shape of a list column as Croissant's comma-separated ``arrayShape`` (-1: any length)."""
    if not pa.types.is_fixed_size_list(kind):
        return "-1"
    shape = shapes.get(column, [kind.list_size])
    if math.prod(shape) != kind.list_size:
        raise ValueError(f"column {column!r}: the schema metadata gives shape {shape} "
                         f"({math.prod(shape)} values), the Parquet list holds {kind.list_size}")
    return ",".join(str(n) for n in shape)


def _field(schema_field: pa.Field, source: tuple[str, str], meta: Mapping[str, Any],
           description: str, record_set: str = RECORD_SET) -> dict[str, Any]:
    """The Field of one Parquet column; source: ("fileObject" or "fileSet", the id of the Parquet resource)."""
    name, kind = schema_field.name, schema_field.type
    units = meta.get("units", {}).get(name)
    field: dict[str, Any] = {
        "@type": "cr:Field",
        "@id": f"{record_set}/{name}",
        "name": name,
        "description": f"{description} Units: {units}." if units else description,
    }
    if pa.types.is_list(kind) or pa.types.is_large_list(kind) or pa.types.is_fixed_size_list(kind):
        field["dataType"] = _data_type(kind.value_type, name)
        field["isArray"] = True
        field["arrayShape"] = _array_shape(kind, name, meta.get("shapes", {}))
    else:
        field["dataType"] = _data_type(kind, name)
    field["source"] = {source[0]: {"@id": source[1]}, "extract": {"column": name}}
    return field


def _distribution(directory: Path, files: list[Path]) -> tuple[list[dict[str, Any]], tuple[str, str]]:
    """The FileObjects (and, for shards, the FileSet) of the directory, and the resource the fields read."""
    def file_object(path: Path, encoding: str) -> dict[str, Any]:
        rel = path.relative_to(directory).as_posix()
        return {"@type": "cr:FileObject", "@id": rel, "name": rel, "contentUrl": rel,
                "contentSize": f"{path.stat().st_size} B", "encodingFormat": encoding, "sha256": sha256_file(path)}

    objects = [file_object(f, PARQUET_FORMAT) for f in files]
    if len(files) == 1 and not files[0].match(SHARD_GLOB):
        source = ("fileObject", objects[0]["@id"])
    else:
        objects.append({"@type": "cr:FileSet", "@id": SHARDS_ID, "name": SHARDS_ID,
                        "description": "The Parquet shards of the gait table, read in name order.",
                        "encodingFormat": PARQUET_FORMAT, "includes": SHARD_GLOB})
        source = ("fileSet", SHARDS_ID)
    objects.append(file_object(directory / HDF5_NAME, HDF5_FORMAT))
    return objects, source


def croissant_metadata(directory: Path, *, name: str, description: str, version: str, license: list[str] | str,
                       citation: str, url: str, date_published: str, creators: list[dict[str, str]],
                       rai: Mapping[str, str | list[str]], column_descriptions: Mapping[str, str],
                       parts: Mapping[str, list[str]] | None = None) -> dict[str, Any]:
    """The Croissant 1.1 JSON-LD document of a published gait directory.

    date_published: ISO 8601 date (given, not read from the clock, so the document is reproducible);
    creators: schema.org Person/Organization nodes, e.g. ``{"@type": "sc:Organization", "name": ...}``;
    rai: Croissant RAI 1.0 property (``dataCollection`` or ``rai:dataCollection``, ...) -> text (or texts);
    column_descriptions: Parquet column -> what it holds; every column needs one, and no other key is allowed;
    parts: part name -> its shard files (``gaits-<n>-<part>.parquet``), each described as a FileSet and a record
    set of its own beside ``gaits``.
    Raises ValueError for an undocumented or unknown column, an unknown RAI property, or an array shape in the
    schema metadata that disagrees with the Parquet list size.
    """
    directory = Path(directory)
    files = parquet_files(directory)
    schema = pq.read_schema(files[0])
    meta = schema_meta(schema)
    undocumented = [c for c in schema.names if c not in column_descriptions]
    unknown = sorted(set(column_descriptions) - set(schema.names))
    if undocumented or unknown:
        raise ValueError(f"{files[0]}: column_descriptions must describe exactly the Parquet columns; "
                         f"undocumented: {undocumented}, not in the file: {unknown}")
    if bad := sorted(k for k in rai if k.removeprefix("rai:") not in RAI_PROPERTIES):
        raise ValueError(f"rai: expected Croissant RAI 1.0 properties ({sorted(RAI_PROPERTIES)}), found {bad}")
    distribution, source = _distribution(directory, files)

    def record_set(name: str, source: tuple[str, str], what: str) -> dict[str, Any]:
        rs = {"@type": "cr:RecordSet", "@id": name, "name": name,
              "description": f"One record per gait ({what}); an array field holds its values row-major, of shape "
                            "arrayShape.",
              "field": [_field(f, source, meta, column_descriptions[f.name], name) for f in schema]}
        if ID_COLUMN in schema.names:
            rs["key"] = {"@id": f"{name}/{ID_COLUMN}"}
        return rs

    record_sets = [record_set(RECORD_SET, source, "every gait")]
    for part, shard_files in (parts or {}).items():
        part_id = f"gaits-{part}"
        distribution.insert(-1, {"@type": "cr:FileSet", "@id": part_id, "name": part_id,
                                 "description": f"The Parquet shards of the part '{part}' ({len(shard_files)} files).",
                                 "encodingFormat": PARQUET_FORMAT, "includes": f"gaits-*-{part}.parquet"})
        what = "the real gaits" if part == "real" else f"the synthetic gaits of the generator family {part}"
        record_sets.append(record_set(part, ("fileSet", part_id), what))
    return {
        "@context": copy.deepcopy(CONTEXT),
        "@type": "sc:Dataset",
        "conformsTo": CONFORMS_TO,
        "name": name,
        "description": description,
        "version": version,
        "license": license,
        "citeAs": citation,
        "url": url,
        "datePublished": date_published,
        "creator": creators,
        **{f"rai:{k.removeprefix('rai:')}": v for k, v in rai.items()},
        "distribution": distribution,
        "recordSet": record_sets,
    }


def write_croissant(directory: Path, doc: Mapping[str, Any]) -> Path:
    """Write ``croissant.json`` into the directory: UTF-8, indent 2, newline at the end, atomically.
    Keys keep the document's order, so the same document gives the same bytes."""
    path = Path(directory) / CROISSANT_NAME
    write_json(doc, path, sort_keys=False, ascii_only=False)
    return path


def croissant_problems(directory: Path, doc: Mapping[str, Any]) -> list[str]:
    """Where a Croissant document disagrees with the directory's files, in words (empty: it agrees).

    Checks that every Parquet file and gaits.h5 is a FileObject, every FileObject exists with its sha256, every
    Parquet column has exactly one field, every field's column exists, and every array field's ``arrayShape``
    holds as many values as the Parquet list.
    """
    directory = Path(directory)
    files = parquet_files(directory)
    listed = {item.get("contentUrl") for item in doc.get("distribution", []) if item.get("@type") == "cr:FileObject"}
    problems = [f"{CROISSANT_NAME}: {rel} has no FileObject" for rel in [f.name for f in files] + [HDF5_NAME]
                if rel not in listed]
    for item in doc.get("distribution", []):
        if item.get("@type") != "cr:FileObject":
            continue
        path = directory / item["contentUrl"]
        if not path.is_file():
            problems.append(f"{CROISSANT_NAME}: FileObject {item['@id']!r}: {item['contentUrl']} is missing")
        elif (found := sha256_file(path)) != item.get("sha256"):
            problems.append(f"{CROISSANT_NAME}: FileObject {item['@id']!r}: sha256 {item.get('sha256')}, "
                            f"the file's is {found}")
    schema = pq.read_schema(files[0])
    if RECORD_SET not in [rs.get("@id") for rs in doc.get("recordSet", [])]:
        problems.append(f"{CROISSANT_NAME}: no record set {RECORD_SET!r}")
    for rs in doc.get("recordSet", []):
        problems += _record_set_problems(rs, schema)
    return problems


def _record_set_problems(rs: Mapping[str, Any], schema: pa.Schema) -> list[str]:
    """Where one record set's fields disagree with the Parquet schema."""
    problems = []
    fields = rs.get("field", [])
    columns = [f.get("source", {}).get("extract", {}).get("column") for f in fields]
    for field, column in zip(fields, columns):
        if column not in schema.names:
            problems.append(f"{CROISSANT_NAME}: field {field['@id']!r}: column {column!r} is not in the Parquet "
                            f"file (its columns: {schema.names})")
            continue
        kind = schema.field(column).type
        if field.get("isArray") and pa.types.is_fixed_size_list(kind):
            size = math.prod(int(n) for n in str(field.get("arrayShape", "-1")).split(","))
            if size != kind.list_size:
                problems.append(f"{CROISSANT_NAME}: field {field['@id']!r}: arrayShape {field.get('arrayShape')!r} "
                                f"holds {size} values, the Parquet list {kind.list_size}")
    problems += [f"{CROISSANT_NAME}: record set {rs.get('@id')!r}: Parquet column {c!r} has {columns.count(c)} "
                 f"fields; expected one" for c in schema.names if columns.count(c) != 1]
    return problems
