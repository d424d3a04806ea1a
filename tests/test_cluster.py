"""The dataset's Ray backend and the Mitsuba variant switch.

A dataset rendered as Ray tasks is bitwise the one the local backend renders; a resumed Ray run
renders only the missing shards; without Ray, ``--backend ray`` is one line saying how to install
it; ``--variant`` switches Mitsuba before any scene is loaded; the quick dataset benchmark writes
its table and figure. Every render is tiny (16², 1 spp, 150 strands), and no Ray process outlives
the module.
"""
import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hairdigi.inference.training.dataset import OPTIONAL_FIELDS, SHARD_FIELDS, DatasetConfig, generate, load, shard_path

REPO = Path(__file__).resolve().parents[1]
TINY = dict(n=6, size=16, spp=1, seed=0, strands=150, shard_size=2)
RAY_TMP = Path("/tmp/ray")


def _env(**extra) -> dict:
    return {**os.environ, "OMP_WAIT_POLICY": "PASSIVE", **extra}


def _shards(root: Path, n_shards: int) -> list[dict]:
    return [dict(np.load(shard_path(root, s))) for s in range(n_shards)]


def _ray_processes(sessions: list[str]) -> list[str]:
    """Processes of the Ray sessions started here: their GCS, raylet and helpers name the session."""
    out = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if any(s in line for s in sessions)]


@pytest.fixture(scope="module", autouse=True)
def _no_ray_left_behind():
    """After the module, no process of a Ray session it started (here or in a subprocess) runs on:
    a leftover raylet would take CPU from other jobs."""
    started = time.time() - 1
    yield
    try:
        import ray
        ray.shutdown()
    except ImportError:
        pass
    sessions = [d.name for d in RAY_TMP.glob("session_2*") if d.is_dir() and d.stat().st_mtime >= started]
    deadline = time.monotonic() + 20
    while _ray_processes(sessions) and time.monotonic() < deadline:
        time.sleep(0.5)
    assert not _ray_processes(sessions), _ray_processes(sessions)


@pytest.fixture(scope="module")
def ray_instance():
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             logging_level=logging.ERROR)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def local_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("local")
    generate(DatasetConfig(**TINY), root, workers=1, progress=False)
    return root


@pytest.mark.slow
def test_ray_dataset_is_bitwise_the_local_one(ray_instance, local_dataset, tmp_path):
    config = DatasetConfig(**TINY)
    generate(config, tmp_path, workers=2, progress=False, backend="ray")
    ray_shards, local_shards = _shards(tmp_path, config.n_shards), _shards(local_dataset, config.n_shards)
    for r, l in zip(ray_shards, local_shards):
        assert list(r) == list(l) == list(SHARD_FIELDS + OPTIONAL_FIELDS)
        for name in SHARD_FIELDS + OPTIONAL_FIELDS:
            assert r[name].dtype == l[name].dtype and np.array_equal(r[name], l[name]), name
    images, params, cameras, manifest = load(tmp_path)
    assert images.shape == (6, 16, 16, 3) and np.array_equal(images, load(local_dataset)[0])
    assert manifest["mitsuba_variant"] == json.loads((local_dataset / "manifest.json").read_text())["mitsuba_variant"]
    assert not list(tmp_path.glob(".*.npz"))


def test_ray_resume_renders_only_the_missing_shard(ray_instance, local_dataset, tmp_path, monkeypatch):
    import hairdigi.inference.training.dataset as dataset

    config = DatasetConfig(**TINY)
    generate(config, tmp_path, workers=2, progress=False, backend="ray")
    kept = {s: shard_path(tmp_path, s).stat().st_mtime_ns for s in (0, 2)}
    shard_path(tmp_path, 1).unlink()
    written = []
    write = dataset.write_shard
    monkeypatch.setattr(dataset, "write_shard", lambda root, shard, arrays: written.append(shard) or
                        write(root, shard, arrays))
    generate(config, tmp_path, workers=2, progress=False, backend="ray")
    assert written == [1]   # the driver writes every shard a task returns: one task ran
    assert {s: shard_path(tmp_path, s).stat().st_mtime_ns for s in (0, 2)} == kept
    again, before = np.load(shard_path(tmp_path, 1)), np.load(shard_path(local_dataset, 1))
    assert all(np.array_equal(again[k], before[k]) for k in SHARD_FIELDS)
    generate(config, tmp_path, workers=2, progress=False, backend="ray")   # complete: nothing to do
    assert written == [1]


def test_ray_backend_without_ray_is_one_line(tmp_path):
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "ray.py").write_text("raise ImportError('No module named ray (simulated)')\n")
    out = tmp_path / "ds"
    proc = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "dataset", "--n", "2", "--size", "16", "--spp", "1",
                           "--strands", "150", "--backend", "ray", "--out", str(out)], cwd=REPO,
                          env=_env(PYTHONPATH=os.pathsep.join([str(fake), str(REPO)])),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'hairdigi[cluster]'" in lines[0], proc.stderr
    assert not out.exists()   # refused before anything was written


def test_address_needs_the_ray_backend(tmp_path):
    from hairdigi.app.cli import main

    assert main(["dataset", "--n", "2", "--size", "16", "--address", "auto", "--out", str(tmp_path / "d")]) == 2


def test_variant_flag_is_on_render_dataset_and_evaluate():
    from hairdigi.app.cli import build_parser

    parser = build_parser()
    assert parser.parse_args(["render", "--params", "p.json", "--out", "o.png"]).variant == "auto"
    for argv in (["render", "--params", "p.json", "--out", "o.png"], ["dataset"], ["evaluate", "--out", "e"]):
        assert parser.parse_args(argv + ["--variant", "scalar_rgb"]).variant == "scalar_rgb"
    args = parser.parse_args(["dataset", "--backend", "ray", "--address", "auto", "--variant", "cuda_ad_rgb"])
    assert (args.backend, args.address, args.variant) == ("ray", "auto", "cuda_ad_rgb")


SCALAR_RUN = """
import json, sys
from hairdigi.app.cli import main
from hairdigi.render.variant import mi
from hairdigi.render.renderer import default_renderer
common = ["dataset", "--n", "2", "--size", "16", "--spp", "1", "--strands", "150", "--shard-size", "1",
          "--variant", "scalar_rgb"]
rc1 = main(common + ["--workers", "1", "--out", sys.argv[1]])     # rendered in this process
rc2 = main(common + ["--workers", "2", "--out", sys.argv[2]])     # in two worker processes
print(json.dumps({"rc": [rc1, rc2], "variant": mi.variant(), "renderer": default_renderer().variant}))
"""


def test_variant_scalar_renders_through_scalar_and_is_recorded(local_dataset, tmp_path):
    """Run in a subprocess: the variant is process-wide, and this one keeps ``llvm_ad_rgb``."""
    here, pool = tmp_path / "here", tmp_path / "pool"
    proc = subprocess.run([sys.executable, "-c", SCALAR_RUN, str(here), str(pool)], cwd=REPO, env=_env(),
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result == {"rc": [0, 0], "variant": "scalar_rgb", "renderer": "scalar_rgb"}
    for root in (here, pool):
        assert json.loads((root / "manifest.json").read_text())["mitsuba_variant"] == "scalar_rgb"
    scalar_here, scalar_pool = load(here)[0], load(pool)[0]
    assert np.array_equal(scalar_here, scalar_pool)    # the workers switched to scalar_rgb too
    llvm = load(local_dataset)[0][:2]                  # the same samples through llvm_ad_rgb
    if json.loads((local_dataset / "manifest.json").read_text())["mitsuba_variant"] != "scalar_rgb":
        assert not np.array_equal(scalar_here, llvm)


def test_a_resume_with_another_variant_is_refused(local_dataset, tmp_path):
    import shutil

    root = tmp_path / "ds"
    shutil.copytree(local_dataset, root)
    shard_path(root, 2).unlink()
    stored = json.loads((root / "manifest.json").read_text())["mitsuba_variant"]
    other = "scalar_rgb" if stored != "scalar_rgb" else "llvm_ad_rgb"
    manifest = json.loads((root / "manifest.json").read_text())
    (root / "manifest.json").write_text(json.dumps({**manifest, "mitsuba_variant": other}))
    with pytest.raises(ValueError, match=f"--variant {other}"):
        generate(DatasetConfig(**TINY), root, workers=1, progress=False)   # this process's variant
    assert not shard_path(root, 2).exists()


@pytest.mark.slow
def test_bench_dataset_quick_writes_csv_and_png(tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "bench"
    proc = subprocess.run([sys.executable, "-m", "hairdigi.app.cli", "bench", "dataset", "--quick", "--out", str(out)],
                          cwd=REPO, env=_env(), capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    import csv

    with open(out / "dataset_bench.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["backend"], r["workers"]) for r in rows] == [("local", "1"), ("local", "2"), ("ray", "1"),
                                                            ("ray", "2")]
    assert all(r["identical"] == "True" and float(r["swatches_per_s"]) > 0 for r in rows)
    assert (out / "dataset_bench.png").stat().st_size > 1000
    assert not (out / ".dataset-bench").exists()
