"""``hairdigi export RECORD.json --format materialx|blender --out FILE``: an estimate for other renderers."""
from __future__ import annotations

import argparse
from pathlib import Path

from hairdigi.app.cli import validation as v
from hairdigi.app.library.renderer_export import export_record
from hairdigi.render.interchange import FORMATS

SUFFIXES = {"materialx": ".mtlx", "blender": ".py"}


def check_export_look(args: argparse.Namespace) -> str:
    """The record is a readable file; the outputs have their format's extension and are none of the inputs
    nor a session's, library's or the package's files (checked before anything is written). The output."""
    v.check_input_file(args.record, "record")
    out = args.out or str(Path(args.record).with_suffix("").with_suffix(SUFFIXES[args.format]))
    inputs = {"record": args.record}
    v.check_distinct({"--out": out, "--blend": args.blend})
    v.check_output_file(out, "--out", (SUFFIXES[args.format],), f"{args.format} ({SUFFIXES[args.format]})", inputs)
    if args.blend:
        v.check_output_file(args.blend, "--blend", (".blend",), "a Blender file", inputs)
        if args.format != "blender":
            raise v.ArgumentError("--blend goes with --format blender")
    return out


def run(args: argparse.Namespace) -> int:
    out = check_export_look(args)
    for path in export_record(args.record, args.format, out, args.blend, args.name):
        print(f"wrote {path}")
    return 0


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="an estimate as MaterialX (chiang_hair_bsdf) or a Blender script")
    p.add_argument("record", help="an estimate record (hairdigi estimate --out, a capture's .result.json) "
                                  "or a dye prediction")
    p.add_argument("--format", choices=FORMATS, required=True)
    p.add_argument("--out", help="file to write (default: the record's name with .mtlx or .py)")
    p.add_argument("--blend", help="blender: also write a .blend with the material on a swatch groom "
                                   "(needs Blender: HAIRDIGI_BLENDER, a Python with bpy, or blender on the PATH)")
    p.add_argument("--name", help="material name (default: from the record's file name)")
    p.set_defaults(func=run)
