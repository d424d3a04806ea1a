"""Make the tests' cache seed again (``tests/conftest.py``: ``CACHE_SEED``): both tiers run on one fresh cache,
then its response curves and shine tables (a few kB each) are copied here.

    python tests/data/cache/seed.py        # about 35 minutes on 2 cores
"""
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]

if __name__ == "__main__":
    cache = Path(tempfile.mkdtemp()) / "cache"
    env = {**os.environ, "HAIRDIGI_TEST_CACHE": str(cache), "CACHE_SEED_OFF": "1"}
    for tier in ("test", "test-slow"):
        subprocess.run(["make", "-C", str(ROOT), tier], env=env, check=True)
    shutil.rmtree(HERE / "response", ignore_errors=True)
    shutil.copytree(cache / "response", HERE / "response")
    print(f"{len(list((HERE / 'response').iterdir()))} entries in {HERE / 'response'}", file=sys.stderr)
