# make demo  - set up .venv and run the whole chain on the embedded flight plan
# make test  - set up .venv (with the test extras) and run the test suite
# make bench - speed/accuracy benchmarks with the peers (pyins) side by side
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
PIP     = $(PY) -m pip --disable-pip-version-check -q

.PHONY: demo test bench clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.run-deps: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -e .
	touch $@

$(VENV)/.test-deps: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -e '.[test]'
	touch $(VENV)/.run-deps $@

$(VENV)/.bench-deps: pyproject.toml | $(VENV)/bin/python
	$(PIP) install -e '.[bench]'
	touch $(VENV)/.run-deps $@

# The whole chain on the embedded flight plan (data/flights/demo.toml):
# simulate -> process (filter + smoother, varying lever arm) -> EO -> refine,
# every stage against the simulator's truth; report in demo-output/report.md
demo: $(VENV)/.run-deps
	$(PY) tools/demo.py --plan data/flights/demo.toml --out demo-output

test: $(VENV)/.test-deps
	$(PY) -m pytest -q

bench: $(VENV)/.bench-deps
	for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) .cache demo-output .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
