# All set-up happens here: a fresh machine needs only `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench lint screenshots clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m fisheyemotion demo

test: $(STAMP)
	$(BIN)/python -m pytest -q tests

bench: $(STAMP)
	mkdir -p .benchmarks
	$(BIN)/python -m pytest -q benchmarks --benchmark-only --benchmark-columns=min,median,rounds --benchmark-json=.benchmarks/latest.json
	$(BIN)/python benchmarks/report.py .benchmarks/latest.json

# The HTML report as a reader sees it (headless Chromium, 100 % zoom) -> docs/img/report_<n>.png
screenshots: $(STAMP)
	test -f data/generated/demo/report/report.html || $(MAKE) demo
	command -v chromium >/dev/null || (apt-get update -qq && apt-get install -y -qq chromium)
	$(BIN)/python docs/screenshots.py data/generated/demo/report/report.html

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .benchmarks
