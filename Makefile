# geosyn: `make run` (set up + flagship experiment) and `make test` (set up + test suite).
# Both install the exact versions locked in uv.lock (hashes checked) with uv, itself
# installed from requirements-uv.txt (pinned, hashed) into .venv-uv.
PYTHON  ?= python3
VENV    := .venv
PY      := $(VENV)/bin/python
UVENV   := .venv-uv
UV      := $(UVENV)/bin/uv
STAMP   := $(VENV)/.installed
TSTAMP  := $(VENV)/.installed-test
LATEST  := .venv-latest
# the extras `make test` installs (uv.lock locks every extra)
EXTRAS  := test dev distributed video viewer
# pytest-xdist workers of `make test` (CI's machine has 2 cores): `make test TEST_WORKERS=8`
TEST_WORKERS ?= 2
XDIST   = -n $(TEST_WORKERS) --dist loadgroup
COMMA   := ,
COMMA_EXTRAS := $(subst $(eval) ,$(COMMA),$(EXTRAS))
# uv uses this machine's Python and never downloads an interpreter of its own, and compiles
# the packages' bytecode at install time as pip does (else every process compiles what it
# imports again wherever PYTHONDONTWRITEBYTECODE is set: +20 % CPU for the flagship)
export UV_PYTHON := $(PYTHON)
export UV_PYTHON_DOWNLOADS := never
export UV_COMPILE_BYTECODE := 1

.PHONY: run test test-latest lint lock bench clean browser

$(UV): requirements-uv.txt
	$(PYTHON) -m venv $(UVENV)
	$(UVENV)/bin/python -m pip install --quiet --require-hashes -r requirements-uv.txt
	touch $@

# --locked: refuse to install if uv.lock and pyproject.toml disagree (`make lock` mends it)
# geosyn's own bytecode too (installed editable, uv compiles only the packages): without it
# every process compiles geosyn's ~280 modules again wherever PYTHONDONTWRITEBYTECODE is set
# (+0.35 s to each `geosyn run`, sweep worker and test process)
$(STAMP): pyproject.toml uv.lock $(UV)
	$(UV) sync --locked --quiet
	$(PY) -m compileall -q geosyn
	touch $@

$(TSTAMP): pyproject.toml uv.lock $(UV)
	$(UV) sync --locked --quiet $(addprefix --extra ,$(EXTRAS))
	$(PY) -m compileall -q geosyn
	touch $@ $(STAMP)

# Headless Chromium for tests/test_viewer.py (Debian's packages; installed once, as root).
browser:
	@command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1 || \
	  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    chromium chromium-driver >/dev/null; }

run: $(STAMP)
	$(VENV)/bin/geosyn run panda_push_recovery

test: $(TSTAMP) browser
	$(PY) -m pytest -q --durations=30 $(XDIST)

# The suite against the newest releases the registry offers (not the lock), in its own venv:
# an upstream change is seen here before `make lock` takes it. Not run by CI.
test-latest: $(UV) browser
	rm -rf $(LATEST)
	$(UV) venv --quiet $(LATEST)
	$(UV) pip install --quiet --refresh --python $(LATEST)/bin/python -e ".[$(COMMA_EXTRAS)]"
	@echo "newer than uv.lock:"; $(UV) pip freeze --python $(LATEST)/bin/python --exclude-editable \
	  | sort > $(LATEST)/versions.txt; $(UV) export --frozen --all-extras --no-hashes \
	  --no-emit-project --no-header --no-annotate | sed 's/ ;.*//' | sort \
	  | diff - $(LATEST)/versions.txt | sed -n 's/^> /  /p' || true
	$(LATEST)/bin/python -m pytest -q -p no:cacheprovider $(XDIST)

# Re-resolve uv.lock to the newest releases within pyproject.toml's bounds.
lock: $(UV)
	$(UV) lock --upgrade

lint: $(TSTAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

bench: $(STAMP)
	for b in metric geodesics shaping controllers sim; do echo "== benchmarks/$$b.py"; $(PY) benchmarks/$$b.py || exit 1; done

clean:
	rm -rf $(VENV) $(UVENV) $(LATEST) build *.egg-info
