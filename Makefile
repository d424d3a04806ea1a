# hairdigi: `make demo` sets up and runs the main job; `make test` sets up and runs the tests.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
APT_PACKAGES := libllvm19 xvfb xauth libgl1 libegl1 libglx-mesa0 libgl1-mesa-dri libdbus-1-3 \
	libfontconfig1 libxkbcommon-x11-0 libxcb-icccm4 libxcb-keysyms1 libxcb-cursor0 libxcb-image0 \
	libxcb-render-util0 libxcb-xkb1 libxcb-randr0 libxcb-shape0 libxcb-xinerama0 \
	gcc-avr avr-libc arduino-core-avr simavr libsimavr-dev libelf-dev gcc make pkg-config \
	postgresql libaravis-0.8-0 gir1.2-aravis-0.8 aravis-tools aravis-tools-cli libgirepository1.0-dev libcairo2-dev
export OMP_WAIT_POLICY := PASSIVE

.PHONY: setup system-deps demo app test test-slow bench docs clean

system-deps:  ## Debian packages: libLLVM 19 for Mitsuba's llvm variant, Xvfb and xcb for Qt/VTK, Aravis 0.8 (GenICam cameras, its fake camera) and what PyGObject builds against
	@if dpkg -s $(APT_PACKAGES) >/dev/null 2>&1; then echo "system packages present"; \
	else apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(APT_PACKAGES); fi

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test,train,cluster,genicam,docs]"
	touch $@

setup: system-deps $(VENV)/.installed

demo: setup  ## the main job: the app on the simulated rig, or the headless demo without a display
	@if [ -n "$$DISPLAY" ] || [ -n "$$WAYLAND_DISPLAY" ]; then $(VENV)/bin/hairdigi app --sim; \
	else echo "no display: running the headless demo"; $(VENV)/bin/hairdigi demo --out out/demo; fi

# Both tiers run in parallel on every core (pytest-xdist; each worker has its own cache and X server).
# TEST_WORKERS=1 runs them in one process.
TEST_WORKERS ?= auto
PYTEST := QT_QPA_PLATFORM=offscreen $(PY) -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --durations=30

test: setup  ## the fast tier (what a newcomer runs); pytest's exit 5 (no tests collected) is a failure
	@set -o pipefail; mkdir -p test-output; $(PYTEST) -m "not slow" tests 2>&1 | tee test-output/pytest.log; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "no tests were collected: that is a failure" >&2; exit 1; fi; exit $$rc

test-slow: setup  ## the slow tier: the tests marked slow (long renders, the family's curves, training)
	@set -o pipefail; mkdir -p test-output; $(PYTEST) -m slow tests 2>&1 | tee test-output/pytest-slow.log; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "no slow tests were collected: that is a failure" >&2; exit 1; fi; exit $$rc

docs: setup  ## the manual, warnings as errors, into out/manual (open out/manual/index.html)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict -f packaging/manual/mkdocs.yml -d $(CURDIR)/out/manual

bench: setup
	$(VENV)/bin/hairdigi bench render --out packaging/bench/render

clean:
	rm -rf out test-output
