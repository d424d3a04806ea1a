"""Every evaluation (``hairdigi evaluate --NAME``) and every benchmark (``hairdigi bench NAME``), one
registry of each: an entry names its function as ``module:function``, imported only when it runs, so
that building the command line's parser loads none of them."""
from __future__ import annotations

import argparse
import importlib
from dataclasses import dataclass

from hairdigi.app.evaluation.results import Result

#: Where the benchmarks' results go by default (``bench --out``).
BENCH_OUT = "out/bench"


@dataclass(frozen=True)
class Entry:
    """One evaluation or benchmark: its name on the command line, what it does, and its function
    (``module:function``, called with the parsed arguments, returning a ``results.Result`` or, where it
    stops before measuring anything, the exit status)."""

    name: str
    help: str
    target: str

    def run(self, args: argparse.Namespace) -> int:
        """Call the function; a ``Result`` it returns is printed (its lines, then the files it wrote), exit 0."""
        module, function = self.target.split(":")
        answer = getattr(importlib.import_module(module), function)(args)
        if isinstance(answer, Result):
            answer.print()
            return 0
        return answer


def _modes(*entries: Entry) -> dict[str, Entry]:
    return {e.name: e for e in entries}


_MODES = "hairdigi.app.evaluation.modes"

#: ``evaluate``'s modes by their flag's name (``--cycles``: ``cycles``), in the order they are chosen:
#: the first whose flag is given runs (``--dye --rig`` is the dye protocol on the simulated rig).
EVALUATIONS: dict[str, Entry] = _modes(
    Entry("dye", "instead: dyes characterised on two natural bases, predicted on the third (--n: dyes, default 12)",
          f"{_MODES}:dye"),
    Entry("rig", "instead: the whole chain on the simulated rig (calibrate, capture live and RAW, estimate) against "
          "the hidden truth; --rig-random N random hidden swatches beside the hard cases; --ship writes the chain's "
          "colour interval into the model", f"{_MODES}:rig"),
    Entry("appearance", "instead: hidden swatches with random shine, fibre spread and greys through the simulated "
          "rig, judged in the rig view, each light alone and a scene the estimate never saw (--rig-random N random "
          "swatches beside the named cases; --ship writes the appearance's intervals)", f"{_MODES}:appearance"),
    Entry("cycles", "instead: swatches of another strand generator rendered in Blender Cycles (HAIRDIGI_BLENDER), "
          "estimated, and rendered back in Cycles: the fit and a transfer judged in another renderer (--rig-random N "
          "random swatches beside the hard cases; --spp: Cycles samples, 128 or more)", f"{_MODES}:cycles"),
    Entry("structures", "instead: hidden hairs in every physical swatch structure (render.swatch_family: deposited, "
          "tilted, loose, ...), estimated as shipped, mapped to the family and with the structure read, and judged on "
          "their own strands at the rig and away (--rig-random N random hairs beside the hard cases; --blender: "
          "hidden swatches in Cycles)", f"{_MODES}:structures"),
    Entry("spectral", "instead: hidden spectral hairs (melanins, Table 1 dyes and banded dyes) through a spectral "
          "simulated rig (real cameras' sensitivities, white LEDs, the chart's measured spectra), judged by the CIE "
          "observer under daylight, tungsten and a shop LED, at the rig and away", f"{_MODES}:spectral"),
    Entry("instrument", "instead: hidden swatches on structures hairdigi did not build, captured on the simulated rig "
          "and estimated in the default mode; their instrument readings (d/8 SCI, d/8 SCE, 45/0; D65, 10°) against a "
          "virtual instrument's spectral render of the truth; random hairs beside the hard cases: --rig-random N; "
          "--ship writes the readings' interval", f"{_MODES}:instrument"),
    Entry("readings", "instead: a lab's instrument readings (hairdigi library readings) against hairdigi's of the same "
          "swatches in --library: per swatch ΔE2000, the bias in L*, a*, b* and a Bland-Altman plot",
          f"{_MODES}:readings"),
    Entry("convergence", "instead: estimate the first --sweep-n swatches from inputs rendered at these spp",
          f"{_MODES}:convergence"),
    Entry("prepare_only", "render the held-out set and the truth's judge renders only (no model needed); resumable",
          f"{_MODES}:prepare_held_out"),
)

#: ``evaluate`` without a mode: the encoder and the refinement on clean held-out swatches.
HELD_OUT = Entry("", "the estimate on clean held-out swatches, judged against the truth", f"{_MODES}:held_out")


def chosen_evaluation(args: argparse.Namespace) -> Entry:
    """The evaluation ``args`` asks for: the first mode whose flag is given, else the held-out one."""
    return next((e for name, e in EVALUATIONS.items() if getattr(args, name, None)), HELD_OUT)


_BENCH = "hairdigi.app.evaluation.bench"

#: Every benchmark of ``hairdigi bench``, by name, in the order ``bench --help`` lists them.
BENCHES: dict[str, Entry] = _modes(
    Entry("render", "renderer defaults: strands, spp and depth against error and time", f"{_BENCH}:bench_render"),
    Entry("rig", "chart detection and ΔE2000 over simulated poses, noise and casts", f"{_BENCH}:bench_rig"),
    Entry("encoder", "ONNX encoders side by side: latency and error on held-out swatches", f"{_BENCH}:bench_encoder"),
    Entry("refine", "refinement by synthesis: render size, spp and iterations against error and time",
          f"{_BENCH}:bench_refine"),
    Entry("check-spp", "the refinement's check renders at the rig's swatch area: their spp against the error left",
          f"{_BENCH}:bench_check_spp"),
    Entry("estimate-speed", "each estimate's time in a fresh process: the first of a session and the later ones "
                            "(--quick: one case, two captures)",
          "hairdigi.app.evaluation.bench_estimate_speed:bench_estimate_speed"),
    Entry("layouts", "the check renders over strand layouts: how far a new layout moves the answer",
          f"{_BENCH}:bench_layouts"),
    Entry("dataset", "dataset rendering, the local pool and a local Ray instance: swatches per second",
          f"{_BENCH}:bench_dataset"),
    Entry("previews", "the app's previews: spp x denoiser x guides x size against error", f"{_BENCH}:bench_previews"),
    Entry("library", "find in a library of --n swatches, SQLite and PostgreSQL",
          "hairdigi.app.evaluation.bench_library:bench_library"),
    Entry("memory", "peak memory of the largest inputs", "hairdigi.app.evaluation.bench_memory:bench_memory"),
    Entry("shine", "shine read from the rig's lights one at a time, and what it buys elsewhere",
          f"{_BENCH}:bench_shine"),
    Entry("spread", "fibre spread against uniform fibres, as the single-light means see them",
          f"{_BENCH}:bench_spread"),
    Entry("fibres", "fibre groups of a varied swatch: render time and colour against the finest split",
          f"{_BENCH}:bench_fibres"),
    Entry("atlas", "the shipped atlas against rendering each region's tables: cost and colour apart (no --quick: "
                   "also a fresh session's first capture with and without it)", f"{_BENCH}:bench_atlas"),
    Entry("structure-reading", "the family's mean against continuous readings of the structure, on members left "
                               "out and structures outside the family",
          "hairdigi.app.evaluation.bench_structure_reading:bench_structure_reading"),
    Entry("family", "every physical swatch structure at equal sigma_a, against the layered swatch",
          f"{_BENCH}:bench_family"),
    Entry("streaks", "the swatch area's texture (streaks along the fibres) by physical structure, live, RAW and tilted",
          f"{_BENCH}:bench_streaks"),
    Entry("renderers", "every family structure at equal sigma_a in Mitsuba and in Blender Cycles (HAIRDIGI_BLENDER)",
          f"{_BENCH}:bench_renderers"),
    Entry("structure", "the swatch's fibre structure: today's swatch against a layered one, fibre counts, lights",
          f"{_BENCH}:bench_structure"),
    Entry("spectral", "the RGB fast path against the spectral render under daylight, tungsten and shop lights",
          f"{_BENCH}:bench_spectral"),
    Entry("repeatability", "one swatch lifted and laid down again: hairdigi's instrument reading's spread beside an "
                           "8 mm instrument spot's (--quick: two hairs, three placements)",
          "hairdigi.app.evaluation.bench_repeatability:bench_repeatability"),
    Entry("instrument", "the instrument tables: spp and layouts against the curve's noise, and a reading's cost",
          "hairdigi.app.evaluation.bench_instrument:bench_instrument"),
    Entry("genicam", "a GenICam camera's frame rate and capture latency",
          "hairdigi.app.evaluation.bench_genicam:bench_genicam"),
)
