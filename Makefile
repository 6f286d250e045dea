# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint venv bench clean chromium

# the venv: this tree installed editable with everything the tests need
# (the dev extra); no browser, no root
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/touchswarm run --out demo-out
	@echo "figures and records written to demo-out/"

# only the live view's browser test (tests/test_view.py) needs Debian's
# chromium and its driver: installed with apt-get when it can (root), else
# this says how and stops; nothing is downloaded at run time
chromium:
	@test -x /usr/bin/chromium -a -x /usr/bin/chromedriver || \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium chromium-driver 2>/dev/null || \
	  { apt-get update 2>/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium chromium-driver 2>/dev/null; } || \
	  { echo "make test: the live view test (tests/test_view.py) needs /usr/bin/chromium and /usr/bin/chromedriver," >&2; \
	    echo "  and apt-get could not install them here (not root?). Install them once with" >&2; \
	    echo "    sudo apt-get install chromium chromium-driver" >&2; \
	    echo "  then run make test again (make demo and every other target need no browser)." >&2; exit 1; }

# two workers: the suite is CPU-bound (numba compiles, MicroPython, runs) and
# each test waits on conditions, never on time, so it holds beside other work
test: $(STAMP) chromium lint
	$(BIN)/python -m pytest -n 2 --dist worksteal

# pyflakes-level lint and mypy's default checks (rules in pyproject.toml:
# [tool.ruff], [tool.mypy]); run by `make test`
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

# Mesa is bench-only (bench/mesa_baseline.py's per-agent baseline): not a
# runtime or test dependency
bench: $(STAMP)
	$(BIN)/python -m pip install -q 'mesa>=3,<4'
	$(BIN)/python bench/all.py

clean:
	rm -rf $(VENV) demo-out .pytest_cache .mypy_cache .ruff_cache
