"""``hairdigi evaluate``'s modes (``registry.EVALUATIONS``): each runs its evaluation, returns its
figures as a ``results.Result`` (the registry prints it; an exit status only where a mode stops before
measuring anything) and, with ``--ship``, writes the table it measured into the model's resources.

The registry imports this module only when an evaluation runs, so the evaluations' modules are imported
here at the top: building the command line's parser loads none of them."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hairdigi.app.evaluation import dye_evaluation, dye_rig
from hairdigi.app.evaluation.appearance_evaluation import AppearanceSet, evaluate_appearance
from hairdigi.app.evaluation.cycles_evaluation import CyclesSet, evaluate_cycles
from hairdigi.app.evaluation.instrument_evaluation import InstrumentSet, evaluate_instrument, ship_intervals
from hairdigi.app.evaluation.readings_comparison import compare_readings
from hairdigi.app.evaluation.results import Result
from hairdigi.app.evaluation.rig import RigSet, evaluate_rig
from hairdigi.app.evaluation.spectral_evaluation import ANSWERS, LIGHTS, VIEWS, SpectralSet, evaluate_spectral
from hairdigi.app.evaluation.structures_evaluation import MODES, StructureSet, evaluate_structures
from hairdigi.app.library.store import open_library
from hairdigi.inference.appearance_reading import UNCERTAINTY
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.estimate import CHAIN_TABLE
from hairdigi.inference.spectral_reading import SPECTRAL_TABLE
from hairdigi.inference.structure import STRUCTURE_TABLE
from hairdigi.inference.training.convergence import convergence_sweep
from hairdigi.inference.training.evaluate import evaluate, prepare_heldout
from hairdigi.render.blender_run import BlenderError, blender_command, probe_blender
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, StructureMode
from hairdigi.render.domain.errors import EvaluationError
from hairdigi.render.domain.files import cache_dir, write_json_atomic
from hairdigi.render.swatch_family import STRUCTURES

#: Fewer predictions than this give no p95 to judge ``evaluate --dye``'s goal by.
MIN_GOAL_PREDICTIONS = 20


def held_out_folder(args: argparse.Namespace) -> Path:
    """``--data``, or the cached held-out set of ``--size`` and ``--spp``."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import DEFAULT_SWATCH_MODEL

    return Path(args.data) if args.data else cache_dir() / "datasets" / (
        f"heldout-s1000003-{args.size}px-{args.spp}spp-linear16-{DEFAULT_SWATCH_MODEL}")


def prepare_held_out(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --prepare-only``: the held-out set and the truth's judge renders, no model."""
    root = prepare_heldout(held_out_folder(args), args.n, args.size, args.spp, args.workers)
    print(f"held-out swatches and the truth's judge renders ready in {root}")
    return 0


def convergence(args: argparse.Namespace) -> Result:
    """``hairdigi evaluate --convergence SPP,...``: the estimate from inputs rendered at each spp."""
    encoder, data = Encoder(args.model), held_out_folder(args)
    prepare_heldout(data, args.n, args.size, args.spp, args.workers)
    spps = [int(v) for v in args.convergence.split(",")]
    rows = convergence_sweep(encoder, data, args.out, spps, args.sweep_n)
    out = Path(args.out)
    return Result("convergence", rows, files=[out / "convergence.csv", out / "convergence.png"], compact=True, text=[
        f"input {r['spp']:4d} spp ({r['render_s']:.2f} s/render): mean-colour ΔE2000 median encoder "
        f"{r['encoder_de_median']:.2f}, refined {r['refined_de_median']:.2f} (p95 "
        f"{r['encoder_de_p95']:.2f} / {r['refined_de_p95']:.2f})" for r in rows])


def held_out(args: argparse.Namespace) -> Result:
    """``hairdigi evaluate``: the encoder and the refinement on clean held-out swatches."""
    summary = evaluate(Encoder(args.model), args.out, n=args.n, size=args.size, spp=args.spp, workers=args.workers,
                       data_root=held_out_folder(args), refine_colour=not args.no_refine)
    result = Result("evaluation", summary=summary)
    a = summary["buckets"]["all"]
    for who in ("encoder", "refined"):
        if f"{who}_mean_colour_de2000" in a:
            de = a[f"{who}_mean_colour_de2000"]
            result.text.append(f"{who}: mean-colour ΔE2000 median {de['median']:.2f}, p95 {de['p95']:.2f}, "
                               f"worst {de['max']:.2f}; L1 {a[f'{who}_l1']['mean']:.2f}")
    result.text.append(f"{summary['n']} held-out swatches (floor ΔE2000 median "
                       f"{a['floor_mean_colour_de2000']['median']:.2f}, L1 {a['floor_l1']['mean']:.2f}); encoder "
                       f"{summary['latency_ms_median_1_thread']:.3f} ms; 68% interval coverage {summary['coverage']}; "
                       f"report in {args.out}")
    return result


def ship(path: Path, table: dict, what: str) -> str:
    """Write a measured table into the model's resources (``evaluate --ship``); the line that says so."""
    write_json_atomic(path, table)
    return f"shipped {what}: {path}"


def _evaluation_files(out: str | Path, stem: str) -> list[Path]:
    """An evaluation's table, summary and plot: ``stem.csv``, ``.json`` and ``.png`` in ``out``."""
    return [Path(out) / f"{stem}.{ext}" for ext in ("csv", "json", "png")]


def rig(args: argparse.Namespace) -> Result | int:
    """``hairdigi evaluate --rig``: the chain against the truth; its figures, the table and the plot it wrote."""
    hidden = tuple(args.hidden_structures.split(",")) if getattr(args, "hidden_structures", None) else ()
    structure = StructureMode(getattr(args, "structure", None) or DEFAULT_STRUCTURE)   # parsed at the edge
    if args.ship and structure is not DEFAULT_STRUCTURE:
        print(f"hairdigi evaluate --rig --ship: the chain's colour interval is measured in the default structure mode "
              f"({DEFAULT_STRUCTURE}), the one every record is made in unless told otherwise; drop --ship or --structure",
              file=sys.stderr)
        return 2
    unknown = _unknown_structure(hidden)
    if unknown:
        print(f"hairdigi evaluate --rig: {unknown}", file=sys.stderr)
        return 2
    s = evaluate_rig(args.out, RigSet(random=args.rig_random, structure=structure, hidden_structures=hidden))
    result = Result("rig_evaluation", summary=s, files=_evaluation_files(args.out, "rig_evaluation"), compact=True)
    say = result.text.append
    r, e = s["refined"], s["encoder_alone"]
    say(f"{s['estimated']} of {s['captures']} captures estimated; against the hidden truth, mean-colour ΔE2000 "
        f"median {r['median']:.2f}, p95 {r['p95']:.2f}, worst {r['worst']:.2f} (encoder alone {e['median']:.2f} / "
        f"{e['p95']:.2f} / {e['worst']:.2f})")
    for source, st in s["by_source"].items():
        if st["n"]:
            say(f"  {source}: median {st['median']:.2f}, p95 {st['p95']:.2f}, worst {st['worst']:.2f} ({st['n']})")
    for case, st in s["by_case"].items():
        if st["n"]:
            say(f"  {case}: median {st['median']:.2f}, worst {st['worst']:.2f}")
    if hidden:
        for name, st in s["by_structure"].items():
            say(f"  {name} swatches: median {st['median']:.2f}, p95 {st['p95']:.2f}, worst {st['worst']:.2f} ({st['n']})")
    twin, took = s.get("twin") or {}, s["estimate_seconds"]
    if twin.get("n") and took.get("n"):
        say(f"the twin against the capture: median {twin['median']:.2f}, p95 {twin['p95']:.2f}; each estimate, from "
            f"the image to the record: median {took['median']:.1f} s, p95 {took['p95']:.1f} s, worst "
            f"{took['worst']:.1f} s")
    held = s.get("stated_intervals_held")
    if held:
        say(f"the intervals the records stated held for {held['p68']:.0%} (68%) and {held['p95']:.0%} (95%) of the "
            f"captures")
    c = s["coverage_held_out"]
    say(f"colour interval fitted on half the hidden swatches holds on the other half: 68% -> {c['p68']:.0%}, "
        f"95% -> {c['p95']:.0%}")
    result.text += [f"blocked: {line}" for line in s["blocked"]]
    if args.ship:
        say(ship(CHAIN_TABLE, s["table"], "the chain's colour interval"))
    return result


def appearance(args: argparse.Namespace) -> Result:
    """``hairdigi evaluate --appearance``: shine and fibre variation judged away from the rig."""
    s = evaluate_appearance(args.out, AppearanceSet(random=args.rig_random, variation=not args.no_variation))
    result = Result("appearance_evaluation", summary=s, files=_evaluation_files(args.out, "appearance_evaluation"),
                    compact=True)
    say = result.text.append
    for mode in ("read", "no light frames"):
        m = s[mode]
        say(f"{mode} ({m['swatches']} swatches), mean-colour ΔE2000 against the truth, median / p95 / worst:")
        for key, label in (("fit", "fit, rig view"), ("each_light", "each light alone"),
                           ("transfer", "transfer: another camera, key light, grey sky"),
                           ("today_fit", "today's world, fit"), ("today_transfer", "today's world, transfer")):
            st = m[key]
            if st["n"]:
                say(f"  {label}: {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}")
        for key, label in (("shine_abs_error", "shine"), ("spread_abs_error", "fibre spread"),
                           ("grey_abs_error", "grey share")):
            st = m[key]
            if st["n"]:
                say(f"  {label} absolute error: {st['median']:.3f} / {st['p95']:.3f} / {st['worst']:.3f}")
        say(f"  capture (4 frames) {m['capture_frames_s']['median']:.2f} s; capture and estimate "
            f"{m['capture_s']['median']:.2f} s (medians)")
    result.text += [f"not estimated: {line}" for line in s["errors"] + s["blocked"]]
    if args.ship:
        say(ship(UNCERTAINTY, s["table"], "the appearance's intervals"))
    return result


def cycles(args: argparse.Namespace) -> Result | int:
    """``hairdigi evaluate --cycles``: swatches rendered in Blender Cycles, estimated, rendered back in Cycles."""
    try:
        probe_blender()   # no Blender, or one that does not run, stops here, before any swatch is made
    except BlenderError as exc:
        print(f"hairdigi evaluate --cycles: error: {exc}", file=sys.stderr)
        return 2
    s = evaluate_cycles(args.out, CyclesSet(random=args.rig_random, size=args.size, spp=args.spp,
                                            shine=not args.default_shine))
    result = Result("cycles_evaluation", summary=s, files=_evaluation_files(args.out, "cycles_evaluation"),
                    compact=True)
    say = result.text.append
    say(f"{s['judged']} of {s['swatches']} Cycles swatches judged; mean-colour ΔE2000 against the truth, "
        f"median / p95 / worst:")
    for mode in ("read", "no light frames"):
        if mode not in s:
            continue
        say(f"  {mode}:")
        for key, label in (("twin_residual", "hairdigi's Mitsuba twin against the input"),
                           ("fit", "the estimate rendered back in Cycles, rig view"),
                           ("transfer", "the same, another camera, a key light and a grey sky"),
                           ("sigma_rel_error", "σa relative error (median channel)")):
            st = s[mode][key]
            if st["n"]:
                say(f"    {label}: {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}")
    for key, label in (("shine_abs_error", "shine absolute error"),
                       ("encoder_sigma_rel_error", "σa relative error, encoder alone")):
        st = s[key]
        if st["n"]:
            say(f"  {label}: {st['median']:.3f} / {st['p95']:.3f} / {st['worst']:.3f}")
    result.text += [f"not judged: {line}" for line in s["errors"]]
    if not s["judged"]:
        result.print()     # the empty figures and the errors first, then the one-line failure
        raise EvaluationError(f"none of the {s['swatches']} Cycles swatches was judged (first error: "
                              f"{(s['errors'] or ['none given'])[0]}); the figures above are empty")
    return result


def structures(args: argparse.Namespace) -> Result | int:
    """``hairdigi evaluate --structures``: hidden hairs in every physical swatch structure, judged on their strands."""
    if args.blender:
        try:
            if blender_command() is None:
                raise BlenderError("no Blender found: set HAIRDIGI_BLENDER to a Python that has bpy")
        except BlenderError as exc:
            print(f"hairdigi evaluate --structures --blender: {exc}", file=sys.stderr)
            return 2
    hidden = tuple(args.hidden_structures.split(",")) if args.hidden_structures else StructureSet.structures
    unknown = _unknown_structure(hidden)
    if unknown:
        print(f"hairdigi evaluate --structures: {unknown}", file=sys.stderr)
        return 2
    s = evaluate_structures(args.out, StructureSet(random=args.rig_random, size=min(args.size, 64), spp=args.spp,
                                                   blender=args.blender, structures=hidden, seed=args.held_out))
    result = Result("structures_evaluation", summary=s, files=_evaluation_files(args.out, "structures_evaluation"),
                    compact=True)
    say = result.text.append
    say(f"{s['judged']} of {s['swatches']} hidden swatches judged ({s['renderer']}); mean-colour ΔE2000 against "
        f"the truth on the hidden strands, median / p95 / worst:")
    for mode in MODES:
        for group, st in s[mode].items():
            if group in ("by_structure", "layout_nuisance"):
                continue
            fit, away = st["fit"], st["transfer"]
            if fit["n"]:
                say(f"  {mode:13s} {group:14s} fit {fit['median']:.2f} / {fit['p95']:.2f} / {fit['worst']:.2f}, "
                    f"transfer {away['median']:.2f} / {away['p95']:.2f} / {away['worst']:.2f}")
        nuisance = s[mode]["layout_nuisance"]
        if nuisance["n"]:
            say(f"  {mode:13s} layout nuisance {nuisance['median']:.2f} / {nuisance['p95']:.2f} / {nuisance['worst']:.2f}")
    result.text += [f"not judged: {line}" for line in s["errors"]]
    if s["judged"] == 0:
        result.print()     # the empty figures and the errors first, then the one-line failure
        raise EvaluationError(f"none of the {s['swatches']} hidden swatches was judged; see the errors above")
    if args.ship:
        say(ship(STRUCTURE_TABLE, s["table"], "the colour interval of a swatch of unknown structure"))
    return result


def spectral(args: argparse.Namespace) -> Result:
    """``hairdigi evaluate --spectral``: hidden spectral hairs through a spectral rig, judged under three lights."""
    config = SpectralSet() if args.held_out is None else SpectralSet(seed=args.held_out, random=args.rig_random)
    s = evaluate_spectral(args.out, config)
    result = Result("spectral_evaluation", summary=s, files=_evaluation_files(args.out, "spectral_evaluation"),
                    compact=True)
    say = result.text.append
    say(f"{s['estimated']} of {s['captures']} spectral-rig captures estimated; mean-colour ΔE2000 against the "
        f"spectral truth (median / p95 / worst), an observer adapted to each light:")
    for answer in ANSWERS:
        for view in VIEWS:
            if answer not in s:
                continue
            cells = [f"{light} {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}"
                     for light in LIGHTS for st in [s[answer][f"{view} {light}"]] if st["n"]]
            say(f"  {answer:8s} answer, {view:4s}: " + "; ".join(cells))
    for answer, held in s.get("stated_p95_held", {}).items():
        say(f"  the record's stated 95% interval held for the {answer} answer in {100 * held:.0f}% of its cases")
    result.text += [f"not estimated: {line}" for line in s["errors"]]
    if args.ship and s.get("table", {}).get("cameras"):
        say(ship(SPECTRAL_TABLE, s["table"], "the spectral world's colour intervals"))
    return result


def dye(args: argparse.Namespace) -> Result:
    """``hairdigi evaluate --dye [--rig]``: the dye held-out protocol (``app/evaluation/dye_evaluation.py``),
    on clean renders or (``--rig``) on simulated-rig captures (``app/evaluation/dye_rig.py``)."""
    config = dye_evaluation.DyeEvalConfig(dyes=args.n if args.n != 300 else dye_evaluation.DyeEvalConfig.dyes,
                                          size=args.size, spp=args.spp)
    if getattr(args, "rig", False):        # --dye --rig: the captures are the simulated rig's
        summary = dye_rig.evaluate_dye_rig(Encoder(args.model), args.out, config)
    else:
        summary = dye_evaluation.evaluate_dye(Encoder(args.model), args.out, config)
    result = Result("dye_eval", summary=summary)
    n = summary.get("prediction_de2000", {}).get("n", 0)
    for line in summary["text"]:
        if n < MIN_GOAL_PREDICTIONS and line.endswith(("met)", "NOT met)")):   # a p95 of a few is no p95
            line = line[:line.rindex(":")] + f": not judged, {n} predictions are too few (under {MIN_GOAL_PREDICTIONS}); raise --n)"
        result.text.append(line)
    return result


def _unknown_structure(names) -> str | None:
    """The one-line reason ``--hidden-structures`` names a structure ``render.swatch_family`` has not, or None."""
    unknown = [name for name in names if name not in STRUCTURES]
    return f"unknown structure {unknown[0]!r}; choose among {', '.join(STRUCTURES)}" if unknown else None


def instrument(args: argparse.Namespace) -> Result | int:
    """``hairdigi evaluate --instrument``: instrument readings through the chain against a virtual instrument."""
    hidden = tuple(args.hidden_structures.split(",")) if getattr(args, "hidden_structures", None) else None
    unknown = _unknown_structure(hidden or ())
    if unknown:
        print(f"hairdigi evaluate --instrument: {unknown}", file=sys.stderr)
        return 2
    world = None
    if getattr(args, "spectral_rig", None):
        camera, _, led = args.spectral_rig.partition(",")
        world = (None if camera in ("", "cie") else camera, led or "LED-B4")
    config = InstrumentSet(random=args.rig_random, world=world, **({} if hidden is None else {"structures": hidden}))
    s = evaluate_instrument(args.out, config, ship=args.ship, lab_dir=getattr(args, "lab", None))
    result = Result("instrument_evaluation", summary=s, files=_evaluation_files(args.out, "instrument_evaluation"),
                    compact=True)
    say = result.text.append
    say(f"{s['swatches']} hidden swatches ({', '.join(config.structures)}) captured on the {s['settings']['rig']} "
        f"rig, estimated in the default mode and read; against a virtual instrument's spectral render of the truth, "
        f"ΔE2000:")
    for geom, st in s["by_geometry"].items():
        if st["n"]:
            bias = s["bias"].get(geom, {})
            say(f"  {geom}: median {st['median']:.2f}, p68 {st['p68']:.2f}, p95 {st['p95']:.2f}, worst "
                f"{st['worst']:.2f} ({st['n']}); bias L* {bias.get('dL', 0):+.2f} a* {bias.get('da', 0):+.2f} "
                f"b* {bias.get('db', 0):+.2f}")
    for name, st in s["by_structure"].items():
        if st["n"]:
            say(f"  on {name} swatches: median {st['median']:.2f}, p95 {st['p95']:.2f} ({st['n']})")
    for source, by_geometry in s["by_source"].items():
        say(f"  {source}: " + "; ".join(f"{g} {st['median']:.2f} / {st['p95']:.2f}" for g, st in by_geometry.items()
                                        if st["n"]))
    result.text += [f"not read: {row['hidden']} ({row['structure']}, {row['source']}): {row['error']}"
                    for row in s["errors"]]
    if args.ship:
        say(f"shipped the instrument readings' intervals: {ship_intervals(s)}")
    return result


def readings(args: argparse.Namespace) -> Result | int:
    """``hairdigi evaluate --readings``: the lab's instrument readings against hairdigi's, with a Bland-Altman plot."""
    with open_library() as library:
        s = compare_readings(library, args.out)
    if not s["by_geometry"]:    # nothing to measure: no tress was read by both
        print("no tress has both a lab reading and a hairdigi capture: import the sessions (hairdigi library import) and "
              "the readings (hairdigi library readings FILE), keyed by the same ids", file=sys.stderr)
        return 1
    result = Result("readings_comparison", summary=s, files=_evaluation_files(args.out, "readings_comparison"),
                    compact=True, note="the .png: the Bland-Altman plot")
    result.text.append(f"{s['tresses']} tresses read by the lab's instrument and by hairdigi:")
    for geom, st in s["by_geometry"].items():
        d = st["de2000"]
        result.text.append(f"  {geom}: ΔE2000 median {d['median']:.2f}, p95 {d['p95']:.2f} ({d['n']}); " + "; ".join(
            f"{c}* bias {st[f'bland_altman_{c}']['bias']:+.2f}, limits {st[f'bland_altman_{c}']['lower']:+.2f} to "
            f"{st[f'bland_altman_{c}']['upper']:+.2f}" for c in ("L", "a", "b")))
    return result
