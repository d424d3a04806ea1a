"""A lab's own instrument readings of its tresses, imported beside hairdigi's captures of them.

A lab's spectrophotometer exports its readings as a CSV (one row a reading: the tress's id, L*, a*, b*,
and often the geometry) or as CxF3 (ISO 17972; read with colour-science's ``colour-cxf``: each
object's ``ColorCIELab`` values, their colour specification naming the illuminant, the observer and
the geometry). Each reading is keyed by the tress's id, which names a library swatch by its id, its
capture id or a tag (``Library.swatches_of``).

A file is read and checked whole before anything is written (one transaction: ``Library.add_readings``):
a bad file (a column missing, values in other units, a formula, ids the library does not know) gets
one line naming the problem and the fix, and leaves the library as it was.
"""
from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

from hairdigi.app.library.store import Library, LibraryError
from hairdigi.render.domain.files import read_bytes
from hairdigi.render.instrument_geometry import GEOMETRIES, InstrumentError, check_illuminant, check_observer, geometry

MAX_BYTES = 16 << 20
#: Headers a column is recognised by (lower case, spaces and punctuation dropped), as instruments' exports name them.
ALIASES = {
    "id": ("id", "tress", "tressid", "swatch", "swatchid", "sample", "sampleid", "name", "samplename", "specimen"),
    "L": ("l", "lstar", "l*"),
    "a": ("a", "astar", "a*"),
    "b": ("b", "bstar", "b*"),
    "geometry": ("geometry", "mode", "specular", "scisce", "measurementmode"),
    "observer": ("observer", "obs"),
    "illuminant": ("illuminant", "ill", "light"),
}


class ReadingsError(LibraryError):
    """An instrument's file cannot be imported; the message names the problem and the fix."""


@dataclass(frozen=True)
class LabReading:
    """One reading of a tress by the lab's instrument."""

    tress: str
    geometry: str
    lab: tuple[float, float, float]
    observer: str = "10"
    illuminant: str = "D65"
    line: int = 0              # the file's line (CSV) or object (CxF), for messages and the library's key

    def row(self) -> tuple:
        return (self.tress, self.geometry, self.observer, self.illuminant, *self.lab, self.line)


def _key(header: str) -> str:
    return re.sub(r"[^a-z0-9*]", "", header.lower().replace("star", "*"))


def parse_columns(text: str | None) -> dict[str, str]:
    """``--columns id=Tress,L=L*(D65),...`` as {field: header}."""
    out: dict[str, str] = {}
    for part in filter(None, (p.strip() for p in (text or "").split(","))):
        name, _, header = part.partition("=")
        if name not in ALIASES or not header:
            raise ReadingsError(f"--columns {part!r}: give FIELD=HEADER with FIELD one of {', '.join(ALIASES)}")
        out[name] = header
    return out


def _column(headers: list[str], field: str, given: dict[str, str], path: Path, required: bool = True) -> int | None:
    if field in given:
        if given[field] not in headers:
            raise ReadingsError(f"{path.name}: no column {given[field]!r} (its columns: {', '.join(headers)}); "
                                f"fix --columns {field}=...")
        return headers.index(given[field])
    keys = [_key(h) for h in headers]
    for alias in ALIASES[field]:
        if _key(alias) in keys:
            return keys.index(_key(alias))
    if required:
        raise ReadingsError(f"{path.name}: no column for {field} (its columns: {', '.join(headers)}); name it with "
                            f"--columns {field}=HEADER")
    return None


def _number(cell: str, field: str, line: int, path: Path) -> float:
    text = cell.strip()
    if text.startswith(("=", "+", "@")) and not re.fullmatch(r"\+?\d+([.,]\d+)?", text):
        raise ReadingsError(f"{path.name} line {line}: {field} is a formula ({text[:30]!r}), not a value; export the "
                            f"instrument's values, not a spreadsheet's formulas")
    try:
        return float(text.replace(",", ".")) if text.count(",") == 1 and "." not in text else float(text)
    except ValueError:
        raise ReadingsError(f"{path.name} line {line}: {field} is {text[:30]!r}, not a number; fix that cell") from None


def _geometry(text: str | None, default: str, line: int, path: Path) -> str:
    if text is None or not text.strip():
        return default
    value = text.strip()
    short = {"sci": "d/8 SCI", "si": "d/8 SCI", "i": "d/8 SCI", "sce": "d/8 SCE", "se": "d/8 SCE", "e": "d/8 SCE"}
    try:
        return short.get(value.lower()) or geometry(value).name
    except InstrumentError:
        raise ReadingsError(f"{path.name} line {line}: geometry {value!r} is not one of {', '.join(GEOMETRIES)} "
                            f"(or SCI, SCE); fix the cell or leave it out and give --geometry") from None


def check_units(readings: list[LabReading], path: Path) -> None:
    """Readings that are not CIELAB on its usual scales (L* 0-100, a*, b* within ±150) are refused, naming the likely units."""
    if not readings:
        raise ReadingsError(f"{path.name}: no readings in it; check the file")
    for r in readings:
        L, a, b = r.lab
        if not 0.0 <= L <= 100.0 or abs(a) > 150 or abs(b) > 150:
            raise ReadingsError(f"{path.name} line {r.line}: L*a*b* {L:g} {a:g} {b:g} is not CIELAB (L* 0-100, a* and b* "
                                f"within ±150): the file holds other units (XYZ, reflectance %?); export L*a*b*")
    if len(readings) >= 3 and max(r.lab[0] for r in readings) <= 1.0:
        raise ReadingsError(f"{path.name}: every L* is at most 1: the file holds values on 0-1 (Y or reflectance), "
                            f"not L*; export L*a*b*")


def read_csv(path: str | Path, columns: dict[str, str] | None = None, default_geometry: str = "d/8 SCI",
             observer: str = "10", illuminant: str = "D65") -> list[LabReading]:
    """An instrument's CSV export: one reading a row (comma, semicolon or tab separated; UTF-8 or Latin-1)."""
    path = Path(path)
    data = _read_bytes(path)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    try:
        dialect = csv.Sniffer().sniff(text[:4096], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    rows = list(csv.reader(io.StringIO(text), dialect))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise ReadingsError(f"{path.name}: the file is empty; export the instrument's readings with a header row")
    headers = [h.strip() for h in rows[0]]
    given = columns or {}
    idx = {f: _column(headers, f, given, path) for f in ("id", "L", "a", "b")}
    opt = {f: _column(headers, f, given, path, required=False) for f in ("geometry", "observer", "illuminant")}
    opt = {f: None if i in idx.values() and f not in given else i for f, i in opt.items()}   # a column is read once
    default_geometry = geometry(default_geometry).name
    out = []
    for line, row in enumerate(rows[1:], start=2):
        cell = lambda i: row[i] if i is not None and i < len(row) else None   # noqa: E731
        tress = (cell(idx["id"]) or "").strip()
        if not tress:
            raise ReadingsError(f"{path.name} line {line}: no tress id; fill it in or remove the row")
        lab = tuple(_number(cell(idx[f]) or "", f"{f}*", line, path) for f in ("L", "a", "b"))
        try:
            obs = check_observer((cell(opt["observer"]) or observer).strip())
            ill = check_illuminant((cell(opt["illuminant"]) or illuminant).strip())
        except InstrumentError as exc:
            raise ReadingsError(f"{path.name} line {line}: {exc}") from None
        out.append(LabReading(tress, _geometry(cell(opt["geometry"]), default_geometry, line, path), lab, obs, ill, line))
    check_units(out, path)
    return out


def read_cxf(path: str | Path, default_geometry: str = "d/8 SCI") -> list[LabReading]:
    """A CxF3 file's objects: each object's CIELAB values, read with their colour specification's illuminant,
    observer and geometry (a sphere's specular included or excluded, a single angle's 45/0)."""
    import colour_cxf   # deferred: colour_cxf only to read a CxF file

    path = Path(path)
    try:
        doc = colour_cxf.read_cxf(_read_bytes(path))
    except Exception as exc:  # noqa: BLE001 - the XML parser's many errors all mean one thing here
        raise ReadingsError(f"{path.name}: not a CxF3 file ({type(exc).__name__}: {str(exc)[:120]}); export CxF3 "
                            f"or a CSV") from None
    resources = doc.resources
    specs = {}
    if resources is not None and resources.color_specification_collection is not None:
        specs = {s.id: s for s in resources.color_specification_collection.color_specification}
    objects = [] if resources is None or resources.object_collection is None else \
        resources.object_collection.object_value
    out = []
    for k, obj in enumerate(objects, start=1):
        tress = (obj.name or obj.id or "").strip()
        for value in (obj.color_values.choice if obj.color_values is not None else []):
            if type(value).__name__ != "ColorCielab":
                continue
            if not tress:
                raise ReadingsError(f"{path.name} object {k}: no Name or Id to key the tress by; name it")
            geom, obs, ill = _cxf_spec(specs.get(value.color_specification), default_geometry, path, k)
            if None in (value.l, value.a, value.b):
                raise ReadingsError(f"{path.name} object {k} ({tress}): its ColorCIELab lacks L, A or B; fix the file")
            out.append(LabReading(tress, geom, (float(value.l), float(value.a), float(value.b)), obs, ill, k))
    check_units(out, path)
    return out


def _cxf_spec(spec, default_geometry: str, path: Path, k: int) -> tuple[str, str, str]:
    """(geometry, observer, illuminant) of a CxF colour specification; CxF's defaults where it says nothing."""
    geom, obs, ill = geometry(default_geometry).name, "10", "D65"
    if spec is None:
        return geom, obs, ill
    tri = spec.tristimulus_spec
    if tri is not None:
        if tri.observer is not None and tri.observer.value is not None:
            obs = {"2_Degree": "2", "10_Degree": "10"}.get(tri.observer.value.value)
            if obs is None:
                raise ReadingsError(f"{path.name} object {k}: observer {tri.observer.value.value} is not 2° or 10°")
        illum = tri.illuminant_or_custom_illuminant
        if illum is not None and getattr(illum, "value", None) is not None:
            try:
                ill = check_illuminant(illum.value.value)
            except InstrumentError as exc:
                raise ReadingsError(f"{path.name} object {k}: {exc}") from None
    measure = spec.measurement_spec
    choice = None if measure is None or measure.geometry_choice is None else measure.geometry_choice.choice
    name = getattr(choice, "value", None)
    if name == "Specular_Included":
        geom = "d/8 SCI"
    elif name == "Specular_Excluded":
        geom = "d/8 SCE"
    elif type(choice).__name__ == "SingleAngleType":
        geom = "45/0"
    return geom, obs, ill


def _read_bytes(path: Path) -> bytes:
    """The export's bytes (``render.domain.files.read_bytes``: a regular file, refused over ``MAX_BYTES``)."""
    return read_bytes(path, ReadingsError, "an instrument's export", MAX_BYTES,
                      f"more than any instrument export ({MAX_BYTES >> 20} MB); split it", "no such file; check its name")


def read_readings(path: str | Path, columns: dict[str, str] | None = None, default_geometry: str = "d/8 SCI",
                  observer: str = "10", illuminant: str = "D65") -> list[LabReading]:
    """A CSV or CxF export, by its extension (``.cxf``: CxF3; anything else: CSV)."""
    path = Path(path)
    if path.suffix.lower() == ".cxf":
        return read_cxf(path, default_geometry)
    return read_csv(path, columns, default_geometry, observer, illuminant)


def import_readings(library: Library, path: str | Path, allow_unknown: bool = False, **kwargs) -> list[LabReading]:
    """Read ``path`` whole, check every tress id names a swatch of ``library`` (unless ``allow_unknown``), and
    replace that file's readings in one transaction."""
    path = Path(path)
    readings = read_readings(path, **kwargs)
    if not allow_unknown:
        unknown = sorted({r.tress for r in readings if not library.swatches_of(r.tress)})
        if unknown:
            shown = ", ".join(unknown[:5]) + (f" and {len(unknown) - 5} more" if len(unknown) > 5 else "")
            raise ReadingsError(f"{path.name}: {len(unknown)} tress id(s) name no swatch of the library ({shown}); tag "
                                f"each tress's swatch with its id (hairdigi library tag SWATCH ID), or give "
                                f"--allow-unknown to keep them for later")
    library.add_readings([r.row() for r in readings], path.name)
    return readings
