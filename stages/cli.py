"""The `emogait` command: run pipeline stages, preview gaits, pin source manifests."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from stages.common import REPO, SOURCES, load_params, mocap_root


STAGES = {  # subcommand -> (module under stages/, help)
    "ingest": ("ingest", "mocap files -> canonical 60-frame gaits"),
    "annotate": ("annotate", "contacts, phase, movement and affective features"),
    "validate-contacts": ("validate_contacts", "foot events vs the C3D trials' annotated events"),
    "split": ("split", "train/val/test by clip"),
    "train": ("train", "the generator and its ablations"),
    "evaluate": ("evaluate", "the generator on the test split"),
    "synthesize": ("synthesize", "the 5,000-gait plan and its synthetic gaits"),
    "publish": ("publish", "the published dataset directory"),
}


def _cmd_stage(args: argparse.Namespace) -> int:
    import importlib

    module = importlib.import_module(f"stages.{STAGES[args.command][0]}")
    module.main(Path(args.params) if args.params else None)
    return 0


def _cmd_preview(args: argparse.Namespace) -> int:
    from pipeline.io.manifests import ManifestError
    from pipeline.viz.previews import PreviewError
    from pipeline.viz.stick_figures import Motion, render_filmstrip, render_gif
    from stages.preview import bvh_motions, gait_motions

    motions: list[Motion] = []
    try:
        if args.gait:
            motions += gait_motions(Path(args.gaits), args.gait)
        params = load_params(Path(args.params)) if args.params else load_params()
        for bvh in args.bvh or []:
            motions += bvh_motions(Path(bvh), args.source, params, show_source=not args.canonical_only)
    except (PreviewError, ManifestError) as err:
        print(err, file=sys.stderr)
        return 2
    if not motions:
        print("nothing to preview: give --gait ID and/or --bvh FILE", file=sys.stderr)
        return 2
    if args.out.endswith(".gif"):
        render_gif(motions[0], args.out)
    else:
        render_filmstrip(motions, args.out, frames=args.frames)
    print(f"wrote {args.out}")
    return 0


def _cmd_pin(args: argparse.Namespace) -> int:
    """Rewrite a manifest's ``files:`` list with the sha256 of every file its globs find under the mocap root;
    every other line (comments included) stays as it is."""
    from pipeline.io.files import write_text
    from pipeline.io.manifests import pinned_files, with_files

    path = Path(args.manifest)
    root = Path(args.mocap_root) if args.mocap_root else mocap_root(load_params())
    try:
        files = pinned_files(path, root)
    except ValueError as err:  # a ManifestError, or no source folder
        print(err, file=sys.stderr)
        return 2
    text = path.read_text(encoding="utf-8")
    pinned = with_files(text, files)
    if pinned != text:
        write_text(pinned, path)
    print(f"pinned {len(files)} files in {path}{'' if pinned != text else ' (unchanged)'}")
    return 0


def _cmd_export_bvh(args: argparse.Namespace) -> int:
    """Write gaits of a published directory as BVH files on the canonical skeleton."""
    from pipeline.io.bvh_writer import bvh_file_name, write_bvh
    from pipeline.dataset import directory_metadata, gaits_by_id
    from pipeline.core.skeleton import load_skeleton
    from stages.common import SKELETON

    skeleton = load_skeleton(SKELETON)
    meta = directory_metadata(args.dataset)
    if list(meta["joint_names"]) != list(skeleton.names):
        print(f"{args.dataset}: expected the canonical joints {list(skeleton.names)}, found {meta['joint_names']}",
              file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        gaits = gaits_by_id(args.dataset, args.gait_ids, ["rotations", "positions"])
    except KeyError as err:
        print(err.args[0], file=sys.stderr)
        return 2
    for gait_id, gait in gaits.items():
        path = out / bvh_file_name(gait_id)
        write_bvh(path, gait["rotations"].astype(np.float64), gait["positions"][:, 0].astype(np.float64), skeleton,
                  float(meta["fps"]))
        print(f"wrote {path}")
    return 0


def _cmd_audit(args: argparse.Namespace) -> int:
    from stages.audit import main as audit

    audit(Path(args.params) if args.params else None, directory=Path(args.directory), out=Path(args.out))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="emogait", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module, what) in STAGES.items():
        p = sub.add_parser(name, help=f"run the {module} stage outside DVC: {what}")
        p.add_argument("--params", help="params file (default: the repository's params.yaml)")
        p.set_defaults(func=_cmd_stage)
    p = sub.add_parser("preview", help="stick-figure PNG strip (or .gif) of gaits by id and/or BVH clips")
    p.add_argument("--gait", action="append", help="gait id from the gait table (repeatable)")
    p.add_argument("--gaits", default=str(REPO / "data/ingested/gaits.parquet"), help="gait table (Parquet)")
    p.add_argument("--bvh", action="append", help="a BVH file under a source folder of the mocap root (repeatable)")
    p.add_argument("--source", help="source manifest name for --bvh (default: the folder under the mocap root)")
    p.add_argument("--canonical-only", action="store_true", help="for --bvh, skip the source-skeleton row")
    p.add_argument("--params", help="params file (default: the repository's params.yaml)")
    p.add_argument("--frames", type=int, default=8, help="frames per strip")
    p.add_argument("--out", required=True, help="output .png (filmstrip) or .gif (animation of the first motion)")
    p.set_defaults(func=_cmd_preview)
    p = sub.add_parser("export-bvh", help="write gaits of a published dataset as BVH (canonical skeleton)")
    p.add_argument("gait_ids", nargs="+", help="gait ids (the gait_id column)")
    p.add_argument("--dataset", default=str(REPO / "data/published/synthesized_emotive_gaits"),
                   help="published directory")
    p.add_argument("--out", default=".", help="output folder (one <gait id>.bvh per gait)")
    p.set_defaults(func=_cmd_export_bvh)
    p = sub.add_parser("audit", help="label and quality audit of a published directory (HTML, plots, metrics)")
    p.add_argument("directory", help="a published gait directory (ours or a downloaded copy)")
    p.add_argument("--out", default="audit", help="output folder (index.html, metrics.json, *.png)")
    p.add_argument("--params", help="params file for the classifier settings (default: the repository's)")
    p.set_defaults(func=_cmd_audit)
    p = sub.add_parser("pin", help="pin every file a source manifest's globs find (sha256) into the manifest")
    p.add_argument("manifest", help=f"e.g. {SOURCES.relative_to(REPO)}/NAME.yaml")
    p.add_argument("--mocap-root", help="default: params.yaml data.mocap_root")
    p.set_defaults(func=_cmd_pin)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())
