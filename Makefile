# Scratch Iridescence: one-command setup, tests, demo and benchmarks.
#
# Every target that runs Python depends on `setup`, which creates .venv once
# (pinned versions from pyproject.toml), installs Debian's libllvm19 when no
# libLLVM >= 16 is present (Dr.Jit 1.5's CPU backend crashes with LLVM 15) and, on
# Linux x64, downloads the libLLVM wheel that the extension bundles into wheels/.
# A second run finds the stamp file and the wheel and installs nothing.

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PYTEST := $(PY) -m pytest

.PHONY: setup llvm llvm-wheel node llvm15-for-tests test test-slow test-stress test-blender demo paper extension bench clean help

help:
	@echo "make demo       render the bundled demo scene to out/"
	@echo "make paper      reproduce the paper's scenes into out/paper/; write docs/gallery.md and docs/benchmarks.md"
	@echo "make test       run the test suite (without the slow checks)"
	@echo "make test-slow  run the slow checks only"
	@echo "make test-stress [RUNS=20]  run 'make test' RUNS times in a row beside a CPU burner per core"
	@echo "make test-blender  install the built zips into Blender 4.2.0, 4.2 LTS, 4.5 LTS and 5.x (pip bpy) and run the smoke set"
	@echo "make bench      run the benchmarks in tests/bench"
	@echo "make extension  build the extension zips (one per platform and Blender Python, wheels bundled) into dist/"

setup: $(STAMP) llvm llvm-wheel node

$(STAMP): pyproject.toml
	@version=$$($(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])'); \
	if [ "$$version" != "3.11" ]; then \
	    echo "error: Python 3.11 is required (bpy 5.0 wheels are CPython 3.11 only); found $$version at $(PYTHON)" >&2; \
	    echo "       run 'make PYTHON=/path/to/python3.11 ...'" >&2; exit 1; fi
	@if [ ! -x $(PY) ]; then \
	    echo "creating $(VENV) with $(PYTHON)"; \
	    $(PYTHON) -m venv $(VENV) || { rm -rf $(VENV); echo "error: 'python3 -m venv' failed; on Debian: apt-get install python3.11-venv" >&2; exit 1; }; \
	fi
	$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	@touch $(STAMP)

# Dr.Jit finds the newest libLLVM on the loader path by itself.
llvm:
	@if command -v ldconfig >/dev/null && ! ldconfig -p 2>/dev/null | grep -qE 'libLLVM(-|\.so\.)(1[6-9]|[2-9][0-9])'; then \
	    echo "no libLLVM >= 16 found: installing Debian's libllvm19 (Dr.Jit 1.5 crashes with LLVM 15)"; \
	    sudo=""; [ "$$(id -u)" -eq 0 ] || sudo="sudo"; \
	    $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq libllvm19; \
	fi

# The libLLVM wheel that the Linux x64 extension zip bundles (blender_manifest.toml names it): the tests
# install it the way Blender does and render with it while the system offers only LLVM 15.
llvm-wheel: $(STAMP)
	@if [ "$$(uname -s)-$$(uname -m)" = "Linux-x86_64" ]; then $(PY) .ci/build_extension.py --download-only karellen_llvm_core; fi

# The Flamenco job type's test compiles it with node (tests/farm/test_flamenco.py): Debian's nodejs where apt can,
# else that test skips with the reason.
node:
	@if ! command -v node >/dev/null && command -v apt-get >/dev/null; then \
	    echo "installing Debian's nodejs for the Flamenco job type's test"; \
	    sudo=""; [ "$$(id -u)" -eq 0 ] || sudo="sudo"; \
	    { $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq nodejs; } \
	    || echo "nodejs could not be installed: the Flamenco job type's test will be skipped"; \
	fi

# The LLVM-15 simulation tests (an old libLLVM must be refused, never abort) need a real libLLVM 15.
# Debian 12 images ship it; elsewhere it is installed when apt can, else those tests skip with the reason.
llvm15-for-tests:
	@if [ "$$(uname -s)" = "Linux" ] && ! ls /usr/lib/x86_64-linux-gnu/libLLVM-15.so* >/dev/null 2>&1 \
	    && command -v apt-get >/dev/null; then \
	    echo "installing Debian's libllvm15 for the LLVM-15 simulation tests"; \
	    sudo=""; [ "$$(id -u)" -eq 0 ] || sudo="sudo"; \
	    { $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq libllvm15; } \
	    || echo "libllvm15 could not be installed: the LLVM-15 tests will be skipped"; \
	fi

# pytest exits with 5 when it collected nothing; make treats any non-zero status as failure.
test: setup llvm15-for-tests
	$(PYTEST) -m "not slow"

test-slow: setup llvm15-for-tests
	$(PYTEST) -m slow

# The whole `make test` suite RUNS times in a row with every core kept busy, stopping at the first
# failing run: flaky tests show up here. One summary line per run and overall; logs in out/stress/.
RUNS ?= 20
test-stress: setup
	$(PY) tests/stress.py --runs $(RUNS)

# The extension zips installed, as a user installs them, into each Blender of the version matrix (pip bpy
# modules in out/blender-matrix/, about 1 GB each, kept for the next run) and the smoke set run in each:
# tests/blender/matrix.py; versions and times in docs/testing.md.  Not part of CI (too long): run before
# every release.
test-blender: setup llvm15-for-tests
	$(PY) tests/blender/matrix.py

# Builds the demo plate in code, saves out/demo.blend and renders it through the
# engine into out/demo.exr (linear) and out/demo.png (display-referred).
demo: setup
	@mkdir -p out
	$(PY) -m scratch_iridescence.scenes.demo --output out

# Builds every reproduced figure of the paper (scenes/fig*.py) with the add-on's operators, renders
# each in a fresh process through the engine into out/paper/ (EXR, PNG, .blend, statistics), runs the
# numerical validation and writes docs/gallery.md, docs/benchmarks.md and docs/gallery/*.png.
# docs/gallery.md says how long it takes and lists each picture's time.
paper: setup
	@mkdir -p out/paper
	$(PY) -m scratch_iridescence.scenes.paper --output out/paper --docs docs

# Downloads the wheels named in blender_manifest.toml into wheels/ (once), builds one zip per
# platform and Blender Python (3.11: Blender 4.2-5.0, 3.13: 5.1+) into dist/ and validates them
# with Blender's own tool.
extension: setup
	$(PY) .ci/build_extension.py

bench: setup
	@for b in tests/bench/bench_*.py; do echo "== $$b"; $(PY) $$b; done

clean:
	rm -rf out dist .pytest_cache
