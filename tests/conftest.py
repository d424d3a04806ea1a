"""Shared test setup: headless Qt, a private cache, fixed seeds, and an output folder CI keeps."""
import os
import sys
from pathlib import Path

import pytest

# The code installs as one package, `hairdigi`: the checkout's folders must never also import as
# top-level `render`, `app`, ... (two copies of one module). Without the checkout on the path they cannot.
_ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _ROOT]

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# Inside the packages an enum is compared with members, never with its text: the suite (and every process it
# starts) runs strict, so such a comparison raises (render.domain.text_enum; tests/test_text_enum.py proves it)
os.environ.setdefault("HAIRDIGI_STRICT_ENUMS", "1")

#: Artifacts (screenshots, reports) that CI keeps live here.
TEST_OUTPUT = Path(os.environ.get("HAIRDIGI_TEST_OUTPUT", Path(__file__).resolve().parent.parent / "test-output"))


def pytest_collection_modifyitems(items) -> None:
    """Each test's tier in the JUnit report (``packaging/bench/tests/durations.py`` reads it)."""
    for item in items:
        item.user_properties.append(("tier", "slow" if item.get_closest_marker("slow") else "fast"))


#: Cache entries every run starts with: the response curves and shine tables of the views the tests
#: estimate at (the family's curves of the rig's region alone took 10 minutes to render). Small (JSON and
#: npz of a few kB each), keyed by everything they depend on (view, settings, scene, renderer variant), so a
#: change that alters them misses these and renders anew. Made again by ``python tests/data/cache/seed.py``.
CACHE_SEED = Path(__file__).resolve().parent / "data" / "cache"


def _seed(cache: Path) -> None:
    """Copy ``CACHE_SEED``'s entries that ``cache`` lacks (atomically: parallel workers seed one cache)."""
    if os.environ.get("CACHE_SEED_OFF"):      # tests/data/cache/seed.py: a cold run that makes the seed
        return
    for src in sorted(CACHE_SEED.glob("*/*")):
        dst = cache / src.relative_to(CACHE_SEED)
        if src.is_file() and not dst.exists():
            dst.parent.mkdir(parents=True, exist_ok=True)
            tmp = dst.with_name(f".{dst.name}.{os.getpid()}")
            tmp.write_bytes(src.read_bytes())
            os.replace(tmp, dst)


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """One cache for the whole run, never ~/.cache: the simulated rig's light renders, the response curves and
    shine tables are made once. Under pytest-xdist the workers of one run share it: every entry is keyed by
    what it holds and written atomically (``render.domain.files.atomic_path``), so two workers that make the
    same entry at once write the same bytes. A test of the cache itself sets its own. ``HAIRDIGI_TEST_CACHE``
    names one for several runs (CI's two tiers share theirs: ``.ci/run``)."""
    base = tmp_path_factory.getbasetemp()
    cache = Path(os.environ.get("HAIRDIGI_TEST_CACHE") or
                 (base.parent / "shared-cache" if os.environ.get("PYTEST_XDIST_WORKER") else base / "cache"))
    cache.mkdir(parents=True, exist_ok=True)
    _seed(cache)
    os.environ["HAIRDIGI_CACHE"] = str(cache)
    # the swatch library: a private file, and no sessions written before it to import
    os.environ["HAIRDIGI_LIBRARY"] = str(tmp_path_factory.mktemp("library") / "library.sqlite")
    os.environ["HAIRDIGI_SESSIONS"] = str(tmp_path_factory.mktemp("no-sessions"))
    # the app's settings (QSettings) too: parallel workers never share one user's settings file
    os.environ["XDG_CONFIG_HOME"] = str(tmp_path_factory.mktemp("config"))


TINY = dict(n=8, size=32, spp=2, seed=3, strands=150, shard_size=4)


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    from hairdigi.inference.training.dataset import DatasetConfig, generate

    root = tmp_path_factory.mktemp("ds")
    generate(DatasetConfig(**TINY), root, workers=1, progress=False)
    return root


@pytest.fixture(scope="session")
def tiny_model(tiny_dataset, tmp_path_factory):
    """A 2-epoch encoder trained here and exported to ONNX: (run folder, onnx path, parity)."""
    from hairdigi.inference.training.onnx_export import export_onnx, parity
    from hairdigi.inference.training.network import EncoderConfig
    from hairdigi.inference.training.train import TrainConfig, load_trained, train

    run = tmp_path_factory.mktemp("run")
    cfg = TrainConfig(epochs=2, batch_size=4, threads=1, val_fraction=0.25)
    train(tiny_dataset, run, EncoderConfig(width=4, blocks=3, input_size=32), cfg, progress=False)
    model, _ = load_trained(run)
    path = export_onnx(model, run / "encoder.onnx", 32)
    return run, path, parity(model, path, 32)


@pytest.fixture
def test_output() -> Path:
    TEST_OUTPUT.mkdir(parents=True, exist_ok=True)
    return TEST_OUTPUT


@pytest.fixture(scope="session")
def avr_build(tmp_path_factory):
    """The light board's firmware and its simavr harness, built once per run (CI must have the tools)."""
    from hairdigi.hardware.sim_lights import build_firmware, firmware_tools_missing

    reason = firmware_tools_missing()
    if reason:
        (pytest.fail if os.environ.get("CI") else pytest.skip)(f"cannot build the AVR firmware: {reason}")
    return build_firmware(tmp_path_factory.getbasetemp() / "avr-firmware")


@pytest.fixture(scope="session")
def xvfb():
    """A real X server for pyvistaqt (the strand view needs GL on X), shared by the tests that open one.
    Xvfb picks a free display itself (``-displayfd``), so parallel workers and other servers never collide."""
    import select
    import shutil
    import subprocess

    binary = shutil.which("Xvfb")
    assert binary, "Xvfb is missing: the Makefile's system-deps step installs it (apt-get install xvfb)"
    read, write = os.pipe()
    proc = subprocess.Popen([binary, "-displayfd", str(write), "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, pass_fds=(write,))
    os.close(write)
    number = b""
    while not number.endswith(b"\n") and select.select([read], [], [], 60)[0]:   # it writes "N\n" once it listens
        chunk = os.read(read, 16)
        if not chunk:
            break
        number += chunk
    os.close(read)
    assert proc.poll() is None and number.strip().isdigit(), "Xvfb did not start"
    yield f":{number.strip().decode()}"
    proc.terminate()
    proc.wait(5)


@pytest.fixture(params=["python-sim", "avr-firmware"])
def board(request):
    """A light board behind a pty: the Python simulator, or the real firmware in simavr."""
    from hairdigi.hardware.sim_lights import EmulatedFirmwareBoard, SimulatedLightBoard

    if request.param == "python-sim":
        with SimulatedLightBoard() as b:
            yield b
    else:
        with EmulatedFirmwareBoard(request.getfixturevalue("avr_build")) as b:
            yield b
