# Two commands do all set-up on a fresh Debian 12 machine (run as root):
#   make demo   install what is missing, then run the default scene end to end
#   make test   install what is missing, then run the test-suite
# Both are idempotent: on a warm machine they only check stamps.

SHELL       := /bin/bash
PY_SYS      := /usr/bin/python3
VENV        := .venv
PY          := $(VENV)/bin/python
DEB_PKGS    := python3-dolfinx python3-petsc4py python3-slepc4py python3-gmsh \
               python3-scipy python3-venv libopenblas0-pthread
# numpy<2: Debian's dolfinx/petsc4py are compiled against NumPy 1.x.
# numba ≥ 0.60 from PyPI (Debian's 0.56 refuses numpy 1.26); installed with "numpy<2" so pip keeps 1.x.
# --no-compile: Python compiles what is imported when it is (pip compiling every file of vtk,
# matplotlib and numba took 31 s of a fresh install, 19 s without).
# pytest-xdist: the suite on every core (2 workers: 7 → 3 min on the 2-core CI machine); worksteal:
# an idle worker takes queued tests from the busy one, so the suite does not end on one core.
PIP_PKGS    := "numpy<2" "numba>=0.60" matplotlib pyvista vtk pytest pytest-xdist hypothesis
STAMP_DEB   := $(VENV)/.deb-ok
STAMP_PIP   := $(VENV)/.pip-ok
SCENE       ?= workflow/scenes/quick.toml
OUT         ?= results/demo
PYTEST_ARGS ?=
# Test workers (pytest-xdist), each on one BLAS thread so that workers × threads ≤ cores.
TEST_JOBS   ?= auto
PYTEST      := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(PY) -m pytest -q -n $(TEST_JOBS) --dist worksteal

export PYVISTA_OFF_SCREEN := true
export OMP_NUM_THREADS ?= 2

.PHONY: all install demo test test-slow test-all test-browser bench clean-venv

all: test

install: $(STAMP_PIP)

# Debian packages: install only those dpkg does not report as installed.
$(STAMP_DEB):
	@missing=""; for p in $(DEB_PKGS); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	fi
	@mkdir -p $(VENV) && touch $@

# The venv sees Debian's dolfinx through --system-site-packages.
$(STAMP_PIP): $(STAMP_DEB) pyproject.toml Makefile
	@[ -x $(PY) ] || $(PY_SYS) -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q --no-compile --disable-pip-version-check $(PIP_PKGS)
	$(PY) -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
	@$(PY) -c "import dolfinx, petsc4py, slepc4py, gmsh, scipy, pyvista, numpy; assert int(numpy.__version__.split('.')[0]) < 2"
	@touch $@

demo: install
	$(VENV)/bin/bladewear run $(SCENE) --out $(OUT)

test: install
	$(PYTEST) $(PYTEST_ARGS)

test-slow: install
	$(PYTEST) -m slow $(PYTEST_ARGS)

test-all: install
	$(PYTEST) -m "slow or not slow" $(PYTEST_ARGS)

# The report opened in headless Chromium (Debian's chromium, installed here only:
# `make test` stays quick and leaves the browser tests out).
test-browser: install
	@command -v chromium >/dev/null || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; }
	$(PY) -m pytest -q -m browser -s tests/workflow/test_report_browser.py $(PYTEST_ARGS)

# Benchmarks write their timings and errors under results/bench/.
bench: install
	$(VENV)/bin/bladewear run workflow/scenes/reduction-check.toml --out results/bench/reduction-check
	$(VENV)/bin/bladewear run workflow/scenes/paper-frf.toml --out results/bench/paper-frf
	$(VENV)/bin/bladewear run workflow/scenes/paper-wear.toml --out results/bench/paper-wear
	$(VENV)/bin/bladewear run workflow/scenes/stiff-extreme.toml --out results/bench/stiff-extreme
	$(VENV)/bin/python -m workflow.bench.unworn_point --out results/bench

clean-venv:
	rm -rf $(VENV)
