"""``hairdigi model-card``: the model card, from a training run and its evaluations."""
from __future__ import annotations

import argparse
import csv
import json
import shutil
from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser("model-card", help="write the model card from a run and its evaluation")
    p.add_argument("--run", required=True)
    p.add_argument("--model", default="resources/models/encoder.onnx")
    p.add_argument("--evaluation", required=True, help="evaluation.json from hairdigi evaluate (its "
                   "uncertainty.json is copied beside the model)")
    p.add_argument("--variants", help="encoder_bench.csv from hairdigi bench encoder")
    p.add_argument("--convergence", help="convergence.csv from hairdigi evaluate --convergence")
    p.add_argument("--refine-bench", help="refine_bench.csv from hairdigi bench refine")
    p.add_argument("--rig", help="rig_evaluation.json from hairdigi evaluate --rig (the chain against the truth)")
    p.add_argument("--out", default="resources/models/encoder.md")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: loads colour-science; training is left out of the desktop build (hairdigi.inference.training)
    from hairdigi.inference.training.report import model_card

    def table(path):
        if not path:
            return None
        with open(path) as f:
            return [{k: (v if k == "model" else float(v)) for k, v in row.items()} for row in csv.DictReader(f)]

    evaluation = json.loads(Path(args.evaluation).read_text())
    rig_set = json.loads(Path(args.rig).read_text()) if args.rig else None
    path = model_card(args.model, args.run, evaluation, args.out, table(args.variants), table(args.convergence),
                      table(args.refine_bench), rig_set)
    intervals = Path(args.evaluation).with_name("uncertainty.json")
    if intervals.exists():   # the measured intervals ship beside the model they were measured for
        shutil.copyfile(intervals, Path(args.out).with_name("uncertainty.json"))
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0
