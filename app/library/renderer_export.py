"""An estimate record exported for other renderers: MaterialX (``chiang_hair_bsdf``) or a Blender script."""
from __future__ import annotations

from pathlib import Path

from hairdigi.render.domain.files import refuse_protected
from hairdigi.render.domain.records import EstimateRecord, read_record
from hairdigi.render.interchange import FORMATS, HairLook, look_from_record, write_look


def load_look(path: str | Path, name: str | None = None) -> HairLook:
    """The look of an estimate record (or a dye prediction, which has the same layout)."""
    path = Path(path)
    record = read_record(path, EstimateRecord)
    stem = path.name.removesuffix(".json").removesuffix(".result")
    return look_from_record(record, name or stem, source=path.name)


def export_record(record: str | Path, fmt: str, out: str | Path, blend: str | Path | None = None,
                  name: str | None = None) -> list[Path]:
    """Write the export (and, for Blender with ``blend``, a .blend with the swatch groom); the paths written."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if blend and fmt != "blender":
        raise ValueError("a .blend goes with the blender format")
    refuse_protected((out, blend))   # never over a record, a dye, a capture or a library
    look = load_look(record, name)
    written = [write_look(look, fmt, out)]
    if blend:
        # deferred: the CLI parser imports this module; blender_run only for a .blend export
        from hairdigi.render.blender_run import write_blend

        written.append(write_blend(look, blend))
    return written
