"""``hairdigi bench NAME``: one benchmark of ``app.evaluation.registry.BENCHES``, speed against error."""
from __future__ import annotations

import argparse
import textwrap

from hairdigi.app.cli import validation as v
from hairdigi.app.evaluation.registry import BENCH_OUT, BENCHES


def _listing(columns: int = 79) -> str:
    """The benchmarks and what each measures, for ``bench --help``."""
    width = max(map(len, BENCHES)) + 4
    lines = ["benchmarks:"]
    for name, entry in BENCHES.items():
        text = textwrap.wrap(entry.help, columns - width)
        lines += [f"  {name:{width - 2}s}{text[0]}"] + [" " * width + more for more in text[1:]]
    return "\n".join(lines)


def add_parser(sub) -> None:
    p = sub.add_parser("bench", help="speed against error tables and plots", epilog=_listing(),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("what", choices=tuple(BENCHES))
    p.add_argument("--models", nargs="*", help="encoder: the ONNX models to compare")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=None, help="held-out swatches (encoder: 300, "
                   "refine: 10); dataset: swatches per case (16)")
    p.add_argument("--data", help="encoder, refine: held-out dataset folder to reuse")
    p.add_argument("--model", default=None, help="refine: the encoder giving the prior (default: shipped)")
    p.add_argument("--out", default=BENCH_OUT, help="results folder (previews: out/bench/previews)")
    p.add_argument("--quick", action="store_true", help="a tiny sweep, for tests")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    return BENCHES[args.what].run(args)
