"""What several commands' arguments share: the numbers' argparse types and ``--variant``."""
from __future__ import annotations

from hairdigi.app.cli import validation as v
from hairdigi.render.domain.bounds import MAX_DEPTH, MAX_SIZE, MAX_SPP, MAX_STRANDS, MIN_DEPTH, MIN_SIZE

SIZE, SPP = v.int_in(MIN_SIZE, MAX_SIZE), v.int_in(1, MAX_SPP)
SEED, WORKERS = v.int_in(0, v.MAX_SEED), v.int_in(1, v.MAX_WORKERS)
STRANDS, DEPTH = v.int_in(1, MAX_STRANDS), v.int_in(MIN_DEPTH, MAX_DEPTH)
VARIANT_HELP = "Mitsuba variant (auto: cuda_ad_rgb when Mitsuba finds a GPU, else llvm_ad_rgb, else scalar_rgb)"


def use_variant(name: str | None) -> str:
    """Switch Mitsuba to ``--variant`` (``auto``: the GPU when there is one), loading it: the parser
    loads no Mitsuba, so this runs in the command, before any scene is loaded."""
    from hairdigi.render.variant import select_variant

    return select_variant(name)
