"""What several commands' arguments share: the numbers' argparse types, ``--variant`` and a rig's spectra."""
from __future__ import annotations

from hairdigi.app.cli import validation as v
from hairdigi.render.domain.bounds import (DEFAULT_STRUCTURE, MAX_DEPTH, MAX_SIZE, MAX_SPP, MAX_STRANDS, MIN_DEPTH,
                                          MIN_SIZE, STRUCTURE_MODES)
from hairdigi.render.instrument_geometry import APERTURE_RANGE_MM, DEFAULT_APERTURE_MM

SIZE, SPP = v.int_in(MIN_SIZE, MAX_SIZE), v.int_in(1, MAX_SPP)
SEED, WORKERS = v.int_in(0, v.MAX_SEED), v.int_in(1, v.MAX_WORKERS)
STRANDS, DEPTH = v.int_in(1, MAX_STRANDS), v.int_in(MIN_DEPTH, MAX_DEPTH)
VARIANT_HELP = "Mitsuba variant (auto: cuda_ad_rgb when Mitsuba finds a GPU, else llvm_ad_rgb, else scalar_rgb)"


def use_variant(name: str | None) -> str:
    """Switch Mitsuba to ``--variant`` (``auto``: the GPU when there is one), loading it: the parser
    loads no Mitsuba, so this runs in the command, before any scene is loaded."""
    # deferred: loads Mitsuba and Dr.Jit; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.render.variant import select_variant

    return select_variant(name)


def add_spectra_arguments(p) -> None:
    """``--spectral``, ``--led`` and ``--sensor``: a rig's declared spectra (``rig`` and ``app``)."""
    p.add_argument("--spectral", action="store_true", help="with --sim: a spectral rig: white LEDs of an SPD "
                   "(--led), the ColorChecker's measured spectra, spectral hair, seen through a camera's "
                   "sensitivities (--sensor)")
    p.add_argument("--led", type=v.illuminant, default=None, help="the rig's LEDs, a named light or a CSV of "
                   "wavelength (nm), power: with --sim --spectral, the simulated LEDs (default LED-B4, a 5109 K "
                   "phosphor LED); on a real rig, with --sensor, its declared LEDs (each record then carries the "
                   "estimate read in the camera's RGB and its colour under daylight, tungsten and a shop LED)")
    p.add_argument("--sensor", type=v.camera_sensitivities, default=None, help="the camera's sensitivities: "
                   "nikon-5100, sigma-sdmerill, cie (the CIE observer, an ideal camera), or a CSV of wavelength (nm), "
                   "r, g, b: with --sim --spectral, the simulated camera (default nikon-5100); on a real rig, with "
                   "--led, its declared camera")


def add_structure_argument(p, what: str = "the swatch's") -> None:
    """``--structure``: how an estimate treats the swatch's physical structure (``estimate``, ``rig``, ``app``)."""
    p.add_argument("--structure", choices=STRUCTURE_MODES, default=None,
                   help=f"{what} physical structure (default {DEFAULT_STRUCTURE}, or the session's rig profile's): "
                   "'family', for a lab's swatch, built another way than hairdigi's: the texture's streaks leave the "
                   "structures that show them; refined on the one the single-light frames read decisively among "
                   "them, else the answer mapped to their mean; 'assumed', hairdigi's own layered swatch (its "
                   "synthetic evaluations); 'read', read from the single-light frames among the structures and "
                   "refined on it. The bench camera's tables are shipped (no render); another camera's render once "
                   "per region. hairdigi evaluate --structures measures each")


def add_declare_argument(p) -> None:
    """``--declare``: write the flags given into the session's rig profile (``rig``)."""
    p.add_argument("--declare", action="store_true", help="write --led, --sensor and --structure into the "
                   "session's rig profile (<session>/rig-profile.json), in place of what it declares; without it a "
                   "session's first run writes the profile, and a flag later overrides it for that command only")


def add_instrument_arguments(p) -> None:
    """``--observer`` and ``--aperture``: how the record's instrument readings are stated (``estimate``, ``rig``)."""
    p.add_argument("--observer", choices=("10", "2"), default="10",
                   help="the record's instrument readings (d/8 SCI, d/8 SCE, 45/0; D65) for the CIE 1964 10° observer "
                        "(default) or the CIE 1931 2°")
    p.add_argument("--aperture", type=v.float_in(*APERTURE_RANGE_MM), default=DEFAULT_APERTURE_MM, metavar="MM",
                   help=f"the instrument's aperture on the swatch's centre, mm ({APERTURE_RANGE_MM[0]:g}-"
                        f"{APERTURE_RANGE_MM[1]:g}; default {DEFAULT_APERTURE_MM:g}): a swatch's mean is the same "
                        f"over any spot, so the reading states it")


def instrument_options(args) -> dict:
    """The instrument readings' options from ``add_instrument_arguments``'s flags."""
    return {"observer": getattr(args, "observer", "10"), "aperture_mm": float(getattr(args, "aperture", 8.0))}
