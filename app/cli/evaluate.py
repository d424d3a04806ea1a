"""``hairdigi evaluate``: the estimate judged against a hidden truth, one mode at a time
(``app.evaluation.registry.EVALUATIONS``: a mode's flag, its help and its function)."""
from __future__ import annotations

import argparse

from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import SIZE, SPP, VARIANT_HELP, WORKERS, add_structure_argument, use_variant
from hairdigi.app.evaluation.registry import EVALUATIONS, chosen_evaluation
from hairdigi.render.domain.bounds import MAX_SPP, VARIANT_CHOICES


def _add_modes(p: argparse.ArgumentParser, *names: str) -> None:
    """The flags of these modes, ``--NAME`` with the registry's help: on or off (``--convergence`` takes spps)."""
    arguments = {"convergence": {"metavar": "SPP,SPP,...", "type": v.int_list_in(1, MAX_SPP)}}
    for name in names:
        flag = "--" + name.replace("_", "-")
        p.add_argument(flag, help=EVALUATIONS[name].help, **arguments.get(name, {"action": "store_true"}))


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="the estimate on clean held-out swatches, judged against the truth")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=300)
    p.add_argument("--size", type=SIZE, default=64, help="held-out render side in pixels")
    p.add_argument("--spp", type=SPP, default=64, help="held-out inputs' samples per pixel (clean: >= 64)")
    _add_modes(p, "prepare_only", "convergence")
    p.add_argument("--sweep-n", type=v.int_in(1, v.MAX_DATASET_N), default=20)
    p.add_argument("--no-refine", action="store_true", help="judge the encoder alone")
    _add_modes(p, "rig")
    p.add_argument("--rig-random", type=v.int_in(0, 200), default=5)
    _add_modes(p, "appearance", "cycles", "structures", "spectral", "instrument", "readings")
    _add_options(p)
    _add_modes(p, "dye")
    p.add_argument("--workers", type=WORKERS, default=2)
    p.add_argument("--data", help="held-out dataset folder (default: in the cache)")
    p.add_argument("--model", default=None)
    p.add_argument("--out", required=True)
    p.add_argument("--variant", choices=VARIANT_CHOICES, default="auto", help=VARIANT_HELP)
    p.set_defaults(func=run)


def _add_options(p: argparse.ArgumentParser) -> None:
    """The flags that go with one mode or a few (``validation.EVALUATE_MODE_FLAGS`` says which)."""
    p.add_argument("--blender", action="store_true", help="with --structures: render the hidden swatches and the "
                   "judge in Blender Cycles (HAIRDIGI_BLENDER)")
    p.add_argument("--hidden-structures", metavar="NAME,NAME,...", help="with --structures: the structures to hide "
                   "hairs in (default: layered and the physical family); with --rig, the hidden swatches' structures, "
                   "one hair after another in turn (default: layered), each judged on its own strands")
    add_structure_argument(p, "with --rig: how the rig sessions' estimates treat the swatch's")
    p.add_argument("--held-out", type=int, metavar="SEED", help="with --structures: in place of the named cases, "
                   "--rig-random N uniform Table 1 hairs and N dark ones (melanin 0.95-1.0) drawn with this seed "
                   "(>= 1), no layouts: a check of rules chosen on the named cases; a run cut short resumes "
                   "from --out. With --spectral: --rig-random N hairs of this seed (Table 1, natural, and band "
                   "dyes on natural bases) in place of the named ones")
    p.add_argument("--default-shine", action="store_true", help="with --cycles: every hidden swatch at the default "
                   "shine, no single-light frames (the renderer and the swatch's structure alone)")
    p.add_argument("--ship", action="store_true", help="with --rig: ship the measured colour interval "
                   "(resources/models/chain_uncertainty.json); with --appearance, the appearance's intervals; with "
                   "--structures, the colour interval of a swatch of unknown structure (structure_uncertainty.json); with "
                   "--spectral, the spectral world's intervals by camera (spectral_uncertainty.json); with --instrument, the instrument "
                   "readings' intervals (instrument_uncertainty.json)")
    p.add_argument("--spectral-rig", metavar="CAMERA,LED", help="with --instrument: a spectral simulated rig, its "
                   "camera's sensitivities (nikon-5100, sigma-sdmerill, cie) and LEDs (LED-B4, ...) declared, in place "
                   "of the RGB one")
    p.add_argument("--lab", metavar="DIR", help="with --instrument: keep the rig sessions in DIR/sessions and write a "
                   "simulated lab's instrument export of the same tresses (DIR/readings.csv), for hairdigi library "
                   "import and hairdigi library readings")
    p.add_argument("--no-variation", action="store_true", help="with --appearance: read the shine only, not the "
                   "fibre spread and greys (what the texture reading adds)")


def run(args: argparse.Namespace) -> int:
    use_variant(args.variant)   # the held-out set's worker processes are given the same one
    return chosen_evaluation(args).run(args)
