"""One thread budget for the process, from the cores the OS gives it; a bench registry; a parser that
loads neither Mitsuba nor colour-science."""
import json
import subprocess
import sys

import pytest


def run(code: str, env: dict | None = None) -> dict:
    import os

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                         env={**os.environ, **(env or {})})
    return json.loads(out.stdout.strip().splitlines()[-1])


PROBE = ("import json, os, sys\n"
         "{pin}"
         "from hairdigi.app.cli import start_up\n"
         "plan = start_up()\n"
         "from hairdigi.render.variant import select_variant\n"
         "variant = select_variant()\n"
         "import drjit as dr\n"
         "print(json.dumps({{'cores': len(os.sched_getaffinity(0)), 'plan': plan, 'variant': variant,\n"
         "                  'drjit': dr.thread_count(), 'blas': os.environ['OPENBLAS_NUM_THREADS']}}))\n")


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="no CPU affinity on this OS")
def test_the_budget_is_the_cores_the_process_is_given():
    pinned = run(PROBE.format(pin="os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"))
    assert pinned["cores"] == 1 and pinned["plan"]["drjit"] == 1 and pinned["blas"] == "1"
    if pinned["variant"].startswith("llvm"):
        assert pinned["drjit"] == 1                      # Dr.Jit's pool follows the cores given, not the machine's
    free = run(PROBE.format(pin=""))
    assert free["plan"]["drjit"] == free["cores"] and (not free["variant"].startswith("llvm")
                                                         or free["drjit"] == free["cores"])
    fewer = run(PROBE.format(pin=""), {"HAIRDIGI_THREADS": "1"})
    assert fewer["plan"]["drjit"] == 1 and fewer["plan"]["onnxruntime"] == 1


def test_the_parser_loads_neither_mitsuba_nor_colour_science():
    seen = run("import json, sys\nfrom hairdigi.app.cli import main\n"
               "try:\n    main(['render', '--size', 'x'])\nexcept SystemExit:\n    pass\n"
               "print(json.dumps(sorted(m for m in ('mitsuba', 'drjit', 'colour', 'cv2', 'torch') if m in sys.modules)))\n")
    assert seen == []


def test_every_bench_is_in_the_registry_and_on_the_command_line(monkeypatch, capsys, tmp_path):
    from hairdigi.app.cli import main
    from hairdigi.app.evaluation import registry

    BENCHES = registry.BENCHES
    assert {"render", "rig", "encoder", "refine", "dataset", "previews"} <= set(BENCHES)
    # the real entry runs: bench encoder's own check, not a usage error (which would also be exit 2)
    assert main(["bench", "encoder", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == "hairdigi bench: error: bench encoder needs --models A.onnx B.onnx ..."
    # every name is accepted on the command line and runs its own entry of the registry, and only that one
    ran = []
    monkeypatch.setattr(registry.Entry, "run", lambda entry, args: ran.append((entry.name, args.what)) or 0)
    for name in BENCHES:
        assert main(["bench", name, "--out", str(tmp_path)]) == 0, capsys.readouterr().err
    assert ran == [(name, name) for name in BENCHES]
    # a name outside the registry is a usage error, and runs nothing
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "no-such-bench", "--out", str(tmp_path)])
    assert exit_.value.code == 2 and "invalid choice: 'no-such-bench'" in capsys.readouterr().err
    assert len(ran) == len(BENCHES)
