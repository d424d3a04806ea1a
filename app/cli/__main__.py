"""``python -m hairdigi.app.cli``: the command line, as the ``hairdigi`` console script runs it."""
import signal
import sys

from hairdigi.app.cli import interrupted_at_start, main

signal.signal(signal.SIGINT, interrupted_at_start)   # Ctrl-C while the command's modules load: one line, 130
sys.exit(main())
