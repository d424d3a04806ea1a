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


def test_a_result_saves_its_table_summary_and_plot_and_prints_them(tmp_path, capsys):
    import csv
    import json

    from hairdigi.app.evaluation.results import Result

    drawn = []
    rows = [{"hair": "copper", "de2000": 0.5}, {"hair": "black", "de2000": 1.25, "error": "none"}]
    result = Result("demo_evaluation", rows, {"n": 2}, text=["2 swatches"], compact=True,
                    plot=lambda r, path: drawn.append(path) or path.write_bytes(b"png"))
    assert result.save(tmp_path / "out") is result
    out = tmp_path / "out"
    assert [p.name for p in result.files] == ["demo_evaluation.csv", "demo_evaluation.json", "demo_evaluation.png"]
    assert list(csv.DictReader(open(out / "demo_evaluation.csv"))) == [
        {"hair": "copper", "de2000": "0.5", "error": ""}, {"hair": "black", "de2000": "1.25", "error": "none"}]
    assert json.loads((out / "demo_evaluation.json").read_text()) == {"summary": {"n": 2}, "rows": rows}
    assert drawn == [out / "demo_evaluation.png"]
    result.print()
    assert capsys.readouterr().out.splitlines() == ["2 swatches", f"demo_evaluation.csv, .json and .png in {out}"]
    bench = Result("render_bench", rows, files=[out / "render_bench.csv", out / "render_bench.png"], note="2 cases")
    assert bench.lines() == [f"wrote {out / 'render_bench.csv'} and {out / 'render_bench.png'} (2 cases)"]
    assert Result("nothing").lines() == []
    assert [p.suffix for p in Result("plain", rows).save(tmp_path / "p").files] == [".csv"]   # no summary, no plot


def test_the_registry_prints_a_result_and_exits_0(monkeypatch, capsys):
    import argparse
    import types

    from hairdigi.app.evaluation.results import Result

    module = types.ModuleType("hairdigi_fake_evaluation")
    module.run = lambda args: Result("x", text=[f"ran {args.n}"])
    module.stop = lambda args: 2
    monkeypatch.setitem(__import__("sys").modules, "hairdigi_fake_evaluation", module)
    assert registry.Entry("x", "x", "hairdigi_fake_evaluation:run").run(argparse.Namespace(n=3)) == 0
    assert capsys.readouterr().out == "ran 3\n"
    assert registry.Entry("x", "x", "hairdigi_fake_evaluation:stop").run(argparse.Namespace()) == 2


def test_one_evaluation_error():
    """Every evaluation and bench raises ``render.domain.errors.EvaluationError``; no second class is defined."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    defined = [p for folder in ("app", "render", "inference", "hardware") for p in (root / folder).rglob("*.py")
               if re.search(r"^class \w*(Evaluation|Bench)\w*Error\b", p.read_text(), re.M)]
    assert [p.relative_to(root).as_posix() for p in defined] == ["render/domain/errors.py"]
