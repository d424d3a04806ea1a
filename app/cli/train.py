"""``hairdigi train``: the encoder, trained on one or more datasets (resumable; needs the train extra)."""
from __future__ import annotations

import argparse
from dataclasses import replace

from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import SEED


def add_parser(sub) -> None:
    p = sub.add_parser("train", help="train the encoder on a dataset (resumable; needs the train extra)")
    p.add_argument("--dataset", required=True, nargs="+", help="one or more dataset folders (one image size)")
    p.add_argument("--out", required=True, help="run folder: checkpoint, history, curve")
    p.add_argument("--epochs", type=v.int_in(1, v.MAX_EPOCHS), default=100)
    p.add_argument("--batch-size", type=v.int_in(1, v.MAX_BATCH), default=32)
    p.add_argument("--lr", type=v.float_in(0.0, 10.0, low_open=True), default=2e-3)
    p.add_argument("--width", type=v.int_in(1, v.MAX_WIDTH), default=16)
    p.add_argument("--blocks", type=v.int_in(1, v.MAX_BLOCKS), default=4)
    p.add_argument("--input-size", type=v.int_in(v.MIN_INPUT_SIZE, v.MAX_INPUT_SIZE), default=48)
    p.add_argument("--threads", type=v.int_in(1, v.MAX_THREADS), default=2)
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--appearance-weight", type=v.float_in(0.0, 1e6), default=None,
                   help="weight of the fibre-colour loss term (default 4; 0: L2 on the parameters alone)")
    p.add_argument("--blur-max", type=v.float_in(0.0, 100.0), default=None,
                   help="largest augmentation blur in px (default 1.5; 0: none)")
    p.add_argument("--epochs-now", type=v.int_in(1, v.MAX_EPOCHS), default=None, help="stop after this many epochs; run again to resume")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: loads torch (the train extra); training is left out of the desktop build (hairdigi.inference.training)
    from hairdigi.inference.training.network import EncoderConfig
    from hairdigi.inference.training.train import TrainConfig, train

    config = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, threads=args.threads,
                         seed=args.seed)
    if args.appearance_weight is not None:
        config = replace(config, appearance_weight=args.appearance_weight)
    if args.blur_max is not None:
        config = replace(config, blur_max=args.blur_max)
    history = train(args.dataset, args.out, EncoderConfig(args.width, args.blocks, args.input_size), config,
                    epochs_now=args.epochs_now)
    last = history["epochs"][-1]
    print(f"trained {history['parameters']} parameters for {last['epoch']} epochs: validation MSE "
          f"{last['val_mse']:.5f}; checkpoint and curve in {args.out}")
    return 0
