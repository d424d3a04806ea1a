"""The desktop build's entry point: ``hairdigi.app.cli:main``, as the ``hairdigi`` console script runs it."""
import multiprocessing
import sys

from hairdigi.app.cli import main

if __name__ == "__main__":
    multiprocessing.freeze_support()   # a frozen program's worker processes start through this executable
    sys.exit(main())
