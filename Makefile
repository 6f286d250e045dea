# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test venv bench clean

# the last step installs Debian's chromium and its driver for the live view's
# browser test (tests/test_view.py): nothing is downloaded at run time
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	test -x /usr/bin/chromium -a -x /usr/bin/chromedriver || \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium chromium-driver || \
	  { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium chromium-driver; }
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/touchswarm run --out demo-out
	@echo "figures and records written to demo-out/"

# two workers: the suite is CPU-bound (numba compiles, MicroPython, runs) and
# each test waits on conditions, never on time, so it holds beside other work
test: $(STAMP)
	$(BIN)/python -m pytest -n 2 --dist worksteal

bench: $(STAMP)
	for b in bench/*.py; do $(BIN)/python $$b; done

clean:
	rm -rf $(VENV) demo-out .pytest_cache
