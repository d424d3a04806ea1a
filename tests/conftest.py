"""Shared test setup: headless Qt, a private cache, fixed seeds, and an output folder CI keeps."""
import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

#: Artifacts (screenshots, reports) that CI keeps live here.
TEST_OUTPUT = Path(os.environ.get("HAIRDIGI_TEST_OUTPUT", Path(__file__).resolve().parent.parent / "test-output"))


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HAIRDIGI_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def test_output() -> Path:
    TEST_OUTPUT.mkdir(parents=True, exist_ok=True)
    return TEST_OUTPUT
