"""``hairdigi dataset``: the synthetic swatch dataset, rendered locally or on a Ray cluster (resumable)."""
from __future__ import annotations

import argparse
from pathlib import Path

from hairdigi.app.cli import CliError
from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import DEPTH, SEED, SIZE, SPP, STRANDS, VARIANT_HELP, WORKERS
from hairdigi.render.domain.bounds import VARIANT_CHOICES
from hairdigi.render.domain.files import cache_dir


def add_parser(sub) -> None:
    p = sub.add_parser("dataset", help="render the synthetic swatch dataset (resumable)")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=4000)
    p.add_argument("--size", type=SIZE, default=64)
    p.add_argument("--spp", type=SPP, default=16,
                   help="16: the linear mean is within about 1%% of 512 spp (resources/models/encoder-notes.md)")
    p.add_argument("--store", choices=("linear16", "srgb8"), default="linear16",
                   help="linear16: linear float16 radiance (the capture chain is applied in training)")
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--swatch-model", choices=("layered", "today"), default="layered",
                   help="layered: fibres that never meet (the default); today: the first swatch")
    p.add_argument("--appearance", choices=("random", "fixed"), default="random",
                   help="random: shine, fibre spread and greys drawn per swatch; fixed: uniform hair, shine 0.3")
    p.add_argument("--strands", type=STRANDS, default=None)
    p.add_argument("--depth", type=DEPTH, default=None)
    p.add_argument("--shard-size", type=v.int_in(1, v.MAX_SHARD_SIZE), default=50)
    p.add_argument("--workers", type=WORKERS, default=2,
                   help="local: worker processes; ray without --address: CPUs of the local Ray instance")
    p.add_argument("--out", help="dataset folder (default: in the cache, $HAIRDIGI_CACHE or ~/.cache/hairdigi)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: a process pool here; ray: one Ray task per shard (needs hairdigi[cluster])")
    p.add_argument("--address", help="ray: the cluster to use (auto, HOST:6379, ray://HOST:10001; "
                   "default: a local Ray instance for this run)")
    p.add_argument("--variant", choices=VARIANT_CHOICES, default="auto",
                   help=VARIANT_HELP + "; recorded in the manifest, and a resume must use the same")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: training is a developer install, left out of the desktop build (hairdigi.inference.training)
    from hairdigi.inference.training.dataset import DatasetConfig, generate
    # deferred: loads Mitsuba and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.render.renderer import defaults_for

    # record the resolved strand count and depth, so the manifest stays true if the defaults change
    config = DatasetConfig(n=args.n, size=args.size, spp=args.spp, seed=args.seed,
                           strands=args.strands or defaults_for("swatch").strands,
                           max_depth=args.depth or defaults_for("swatch").max_depth, shard_size=args.shard_size,
                           store=args.store, swatch_model=args.swatch_model, appearance=args.appearance)
    if args.address and args.backend != "ray":
        raise CliError("--address names a Ray cluster: use it with --backend ray")
    # datasets of the first swatch and fixed appearance keep their folder names
    tags = "" if (args.swatch_model, args.appearance) == ("today", "fixed") else f"-{args.swatch_model}-{args.appearance}"
    out = Path(args.out) if args.out else (cache_dir() / "datasets" /
                                          f"swatch-s{args.seed}-{args.size}px-{args.spp}spp-{args.store}{tags}")
    generate(config, out, workers=args.workers, backend=args.backend, address=args.address, variant=args.variant)
    print(f"dataset complete: {config.n} swatches in {out}")
    return 0
