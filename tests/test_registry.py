"""The evaluations' and benchmarks' registry (``app.evaluation.registry``): each entry names a function
that exists, each evaluation is a flag of ``hairdigi evaluate``, and the one asked for is the one that runs."""
import importlib

import pytest

from hairdigi.app.cli import main
from hairdigi.app.evaluation import registry

ENTRIES = [*registry.EVALUATIONS.values(), registry.HELD_OUT, *registry.BENCHES.values()]


@pytest.mark.parametrize("entry", ENTRIES, ids=lambda e: e.target)
def test_each_entry_names_a_function(entry):
    module, function = entry.target.split(":")
    assert callable(getattr(importlib.import_module(module), function))
    assert entry.help


def test_each_evaluation_is_a_flag_of_evaluate_and_runs_alone(monkeypatch, capsys, tmp_path):
    ran = []
    monkeypatch.setattr(registry.Entry, "run", lambda entry, args: ran.append(entry.name) or 0)
    monkeypatch.setattr("hairdigi.app.cli.evaluate.use_variant", lambda name: name)
    out = ["--out", str(tmp_path / "evaluation")]
    for name in registry.EVALUATIONS:
        flag = ["--" + name.replace("_", "-")] + (["8,16"] if name == "convergence" else [])
        assert main(["evaluate", *flag, *out]) == 0, capsys.readouterr().err
    assert main(["evaluate", *out]) == 0 and main(["evaluate", "--dye", "--rig", *out]) == 0
    assert ran == [*registry.EVALUATIONS, registry.HELD_OUT.name, "dye"]
    assert main(["evaluate", "--rig", "--cycles", *out]) == 2 and len(ran) == len(registry.EVALUATIONS) + 2
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    for entry in registry.EVALUATIONS.values():   # argparse wraps the help: compare it word for word
        assert " ".join(entry.help.split()) in help_text
