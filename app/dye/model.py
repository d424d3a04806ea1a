"""The Dye panel's model, free of Qt: the session's estimated captures, the pairs, the saved dyes, and the
work behind them (reading the records, characterising, previews and shade cards).

The science is ``inference/dye.py`` and ``inference/dye_card.py``. The model is a ``PanelModel``
(``app/models/``): widgets subscribe to its events (``model.events.preview.connect(callback)``) and run
its works in their workers; nothing here reads a file, renders or fits on the caller's thread.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.app.models.events import EventGroup, Status
from hairdigi.app.models.panel import PanelModel
from hairdigi.app.models.work import Work
from hairdigi.render.domain.dye_record import DyeRecord
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import EstimateRecord, read_record, write_record
from hairdigi.render.domain.session_folder import SessionFolder, capture_id_of

__all__ = ["DyeModel", "DyeSettings", "Events", "Listing", "Characterised", "CaptureCrop", "PreviewPass",
           "HairstylePass", "Card", "dye_path", "session_records", "capture_crop"]


@dataclass(frozen=True)
class DyeSettings:
    """The sizes and samples of the Dye panel's renders (tests make them small)."""

    preview_size: int = 128
    preview_spp: int = 16
    hairstyle: str = "wavy"
    hairstyle_size: int = 192
    hairstyle_spp: int = 8
    card_size: int = 64           # inference.dye_card's CARD_SIZE and CARD_SPP
    card_spp: int = 16


# --- files: where dyes are saved, which captures hold an estimate ---------------------------------------
def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", name.strip()).strip("-.") or "dye"


def _saved_name(path: Path) -> str | None:
    """The name of the dye saved at ``path`` (None: no such file, or not a dye record)."""
    try:
        return read_record(path, DyeRecord).name if path.exists() else None
    except RecordError:
        return ""


def dye_path(folder: Path, name: str) -> Path:
    """Where the dye ``name`` is saved: its name as a file name, numbered (``-2``, ``-3``...) where that file
    holds another dye ("Copper 7.4" and "Copper/7.4" both read ``Copper-7.4``), so no dye is ever written
    over by another; the same name again replaces its own file (the dye characterised again)."""
    name = name.strip()
    slug = _slug(name)[:80]
    path = folder / f"{slug}.json"
    n = 2
    while path.exists() and _saved_name(path) != name:
        path = folder / f"{slug}-{n}.json"
        n += 1
    return path


def session_records(folder: Path) -> list[Path]:
    """The session's captures whose result record holds an estimate (``hair``)."""
    found = []
    for path in SessionFolder(folder).result_records():
        try:   # a regular file of bounded size (a FIFO among the captures never hangs the panel)
            record = read_record(path, EstimateRecord)
        except RecordError:
            continue
        if record.hair is not None:
            found.append(path)
    return found


def saved_dyes(folder: Path) -> list[Path]:
    """The dyes saved in ``folder`` (their shade cards' tables left out)."""
    if not folder.is_dir():
        return []
    return [p for p in sorted(folder.glob("*.json")) if not p.name.endswith("-card.json")]


def capture_crop(record_path: Path) -> np.ndarray | None:
    """The captured swatch (8-bit sRGB) of a session capture's record, cropped to its swatch area."""
    import cv2   # deferred: OpenCV takes ~0.3 s; only this step needs it

    try:
        record = read_record(record_path, EstimateRecord)
        image_path = record_path.with_name(record.capture) if record.capture else None
        image = cv2.imread(str(image_path)) if image_path is not None and image_path.is_file() else None
    except (OSError, RecordError):
        return None
    if image is None:
        return None
    x, y, w, h = record.swatch_roi or (0, 0, image.shape[1], image.shape[0])
    return np.ascontiguousarray(image[y:y + h, x:x + w, ::-1])


# --- events and payloads -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Listing:
    """The estimated captures and saved dyes, read off the model's thread."""

    generation: int
    records: tuple[Path, ...]
    dyes: tuple[Path, ...]


@dataclass(frozen=True)
class Characterised:
    """A dye measured from the pairs and saved at ``path``; ``listing`` holds it among the dyes."""

    generation: int
    dye: DyeRecord
    path: Path
    listing: Listing

    @property
    def text(self) -> str:
        dye = self.dye
        lift = (f"lift {dye.lift:.2f} ({dye.lift_low:.2f}–{dye.lift_high:.2f})" if dye.lift_measured
                else f"lift {dye.lift:.2f}, assumed (one base)")
        return (f"{dye.name}: deposit σa ({', '.join(f'{x:.3f}' for x in dye.deposit_sigma_a)}), {lift}; "
                f"residual ΔE2000 ≤ {dye.residual_de2000_max:.2f}; saved {self.path.name}"
                + "".join(f"\n⚠ {w}" for w in dye.warnings))


@dataclass(frozen=True)
class CaptureCrop:
    generation: int
    rgb: np.ndarray | None


@dataclass(frozen=True)
class PreviewPass:
    generation: int
    swatch: np.ndarray
    colour: dict
    params: object            # HairParams of the prediction

    @property
    def text(self) -> str:
        p, c = self.params, self.colour
        return (f"predicted {c['srgb']}  L*a*b* {c['lab'][0]:.1f} {c['lab'][1]:.1f} {c['lab'][2]:.1f}; "
                f"Table 1: dye {tuple(round(x) for x in p.dye_rgb)} at {p.dye_concentration:.2f}, "
                f"melanin {p.melanin_concentration:.2f}")


@dataclass(frozen=True)
class HairstylePass:
    generation: int
    rgb: np.ndarray


@dataclass(frozen=True)
class Card:
    generation: int
    path: Path
    rgb: np.ndarray | None     # the PNG as written, read back off the model's thread


class Events(EventGroup):
    """The model's events; each carries the new value of the state it names."""

    EVENTS = {"records": list,                    # of Path: the estimated captures offered (the session's, then others')
              "dyes": list,                       # of Path: the saved dyes
              "pairs": list,                      # of (natural base, dyed) Paths to characterise
              "characterised": Characterised,     # a dye measured and saved (records and dyes already updated)
              "capture": CaptureCrop,             # the capture a dye is previewed on, cropped to its swatch
              "preview": PreviewPass,             # the predicted twin, its colour and its Table 1 parameters
              "hairstyle": HairstylePass,
              "card": Card,                       # a shade card, written and read back
              "status": str}                      # one line (what runs now, or what went wrong and the fix)


# --- the model -----------------------------------------------------------------------------------------
class DyeModel(PanelModel):
    """The Dye panel's state for the session in ``folder``, and the work that updates it."""

    Events = Events

    def __init__(self, folder: str | Path, settings: DyeSettings | None = None) -> None:
        super().__init__()
        self.folder = Path(folder)
        self.dyes_folder = SessionFolder(self.folder).dyes
        self.settings = settings or DyeSettings()
        self.extra: list[Path] = []              # records from other sessions, added by the user
        self.records: list[Path] = []
        self.dyes: list[Path] = []
        self.pairs: list[tuple[Path, Path]] = []
        self.characterised: Characterised | None = None
        self.crop: CaptureCrop | None = None
        self.preview: PreviewPass | None = None
        self.hairstyle: HairstylePass | None = None
        self.card: Card | None = None

    def name(self, path: Path) -> str:
        """A record's name in the lists: its capture id, with its session's name when of another session."""
        path = Path(path)
        stem = capture_id_of(path)
        return stem if self.folder in path.parents else f"{path.parent.parent.name}/{stem}"

    # -- the records and dyes ------------------------------------------------------------------
    def add_records(self, paths) -> None:
        """Offer records of other sessions too (read by the next :meth:`reload_work`)."""
        self._owner()
        self.extra += [Path(p) for p in paths if Path(p) not in self.extra and self.folder not in Path(p).parents]

    def reload_work(self) -> Work:
        """Re-read the session's estimated captures and the saved dyes."""
        generation = self._bump("listing")
        folder, dyes_folder, extra = self.folder, self.dyes_folder, tuple(self.extra)

        def run():
            return Listing(generation, tuple(session_records(folder)) + extra, tuple(saved_dyes(dyes_folder)))
            yield  # noqa: unreachable: makes this a generator
        return Work("dye records", run)

    def _apply_listing(self, listing: Listing) -> None:
        if not self._current("listing", listing.generation):
            return
        self.records, self.dyes = list(listing.records), list(listing.dyes)
        self.events.records.emit(self.records)
        self.events.dyes.emit(self.dyes)

    # -- characterise ----------------------------------------------------------------------------
    def add_pair(self, base: Path | None, dyed: Path | None) -> bool:
        self._owner()
        if base is None or dyed is None or Path(base) == Path(dyed):
            self.show_status("choose a base and a different dyed capture")
            return False
        self.pairs.append((Path(base), Path(dyed)))
        self.events.pairs.emit(list(self.pairs))
        return True

    def clear_pairs(self) -> None:
        self._owner()
        self.pairs = []
        self.events.pairs.emit([])

    def characterise_work(self, name: str) -> Work | None:
        """Measure the dye ``name`` from the pairs and save it in ``dyes/``; None (and a status line) when
        there is nothing to measure yet. A dye error (a pair no dye explains, ...) is a status line."""
        self._owner()
        name = name.strip()
        if not self.pairs or not name:
            self.show_status("add at least one pair and give the dye a name")
            return None
        generation = self._bump("characterise")
        stale = self._stale("characterise", generation)
        pairs, folder, dyes_folder, extra = list(self.pairs), self.folder, self.dyes_folder, tuple(self.extra)
        self.show_status(f"characterising {name}…")

        def run():
            # deferred: loads colour-science (~1 s); the panel's listing needs none
            from hairdigi.inference import dye as D

            yield Status(f"characterising {name}: reading {2 * len(pairs)} records")
            try:
                samples = [(D.load_sample(b), D.load_sample(d)) for b, d in pairs]
                if stale():
                    return None
                yield Status(f"characterising {name}: the fit and its Monte Carlo intervals")
                dye = D.characterise(samples, name)
            except D.DyeError as exc:
                return Status(str(exc))
            if stale():
                return None
            path = dye_path(dyes_folder, name)
            write_record(path, dye)
            # read after the save, as of the listing asked for last: one asked for later still wins
            listing = Listing(self._generation["listing"], tuple(session_records(folder)) + extra,
                              tuple(saved_dyes(dyes_folder)))
            return Characterised(generation, dye, path, listing)
        return Work("characterise", run)

    def _apply_characterised(self, done: Characterised) -> None:
        if not self._current("characterise", done.generation):
            return
        self.characterised = done
        self._apply_listing(done.listing)
        self.show_status(f"saved {done.path}")
        self.events.characterised.emit(done)

    # -- preview and shade card -----------------------------------------------------------------
    def preview_work(self, dye: Path | None, target: Path | None, dose: float) -> Work | None:
        """Apply the dye saved at ``dye`` to the capture ``target`` at ``dose``: the capture's swatch, the
        predicted twin, then the predicted hairstyle. A newer preview stops this one at its next pass."""
        self._owner()
        if dye is None or target is None:
            self.show_status("characterise or choose a dye, and a capture to preview it on")
            return None
        generation = self._bump("preview")
        stale = self._stale("preview", generation)
        s = self.settings
        dye, target, dose = Path(dye), Path(target), float(dose)

        def run():
            # deferred: loads colour-science (~1 s) and Mitsuba; the panel's listing needs neither
            from hairdigi.inference.dye import DyeError, apply, describe_colour, load_sample
            from hairdigi.render.renderer import SceneSpec, default_renderer

            yield CaptureCrop(generation, capture_crop(target))
            try:
                pred = apply(read_record(dye, DyeRecord), load_sample(target), dose)
            except (DyeError, RecordError) as exc:
                return Status(str(exc))
            if stale():
                return None
            yield Status("rendering the predicted twin…")
            renderer = default_renderer()
            swatch = renderer.render(pred.sigma_a, SceneSpec("swatch", framing="crop"), s.preview_size,
                                     s.preview_spp, 0).srgb
            yield PreviewPass(generation, swatch, describe_colour(pred.linear_rgb), pred.params)
            if stale():
                return None
            yield Status(f"rendering the predicted hairstyle ({s.hairstyle})…")
            style = renderer.render(pred.sigma_a, SceneSpec(s.hairstyle), s.hairstyle_size, s.hairstyle_spp, 0).srgb
            return HairstylePass(generation, style)
        return Work("dye preview", run)

    def _apply_crop(self, crop: CaptureCrop) -> None:
        if self._current("preview", crop.generation):
            self.crop = crop
            self.events.capture.emit(crop)

    def _apply_preview(self, p: PreviewPass) -> None:
        if self._current("preview", p.generation):
            self.preview = p
            self.events.preview.emit(p)

    def _apply_hairstyle(self, p: HairstylePass) -> None:
        if self._current("preview", p.generation):
            self.hairstyle = p
            self.show_status("preview ready")
            self.events.hairstyle.emit(p)

    def card_work(self, dye: Path | None) -> Work | None:
        """The shade card of the dye saved at ``dye``: PNG, PDF and table beside it, the PNG read back."""
        self._owner()
        if dye is None:
            self.show_status("characterise or choose a dye first")
            return None
        generation = self._bump("card")
        s, dye = self.settings, Path(dye)
        out = dye.with_name(f"{dye.stem}-card.png")
        self.show_status(f"rendering the shade card of {dye.stem}…")

        def run():
            # deferred: loads OpenCV and colour-science (~1 s); the panel's listing needs neither
            import cv2

            from hairdigi.inference.dye_card import shade_card

            try:
                record = read_record(dye, DyeRecord)
            except RecordError as exc:
                return Status(str(exc))
            png = shade_card(record, out, size=s.card_size, spp=s.card_spp)[0]
            bgr = cv2.imread(str(png))
            return Card(generation, Path(png), None if bgr is None else np.ascontiguousarray(bgr[..., ::-1]))
            yield  # noqa: unreachable: makes this a generator
        return Work("shade card", run)

    def _apply_card(self, card: Card) -> None:
        if self._current("card", card.generation):
            self.card = card
            self.show_status(f"shade card: {card.path} (and its PDF)")
            self.events.card.emit(card)

    _HANDLERS = {Listing: _apply_listing, Characterised: _apply_characterised, CaptureCrop: _apply_crop,
                 PreviewPass: _apply_preview, HairstylePass: _apply_hairstyle, Card: _apply_card}
