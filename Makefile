# make demo  - set up .venv and run the whole chain on the embedded flight plan
# make demo-lidar - the LiDAR chain (simulated scanner -> georeference -> strip-check)
# make test  - set up .venv (with the test extras) and run the test suite
# make bench - speed/accuracy benchmarks with the peers (pyins) side by side
# make docs  - API reference and guides (Sphinx) into docs/_build/html, warnings as errors
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
PIP     = $(PY) -m pip --disable-pip-version-check -q

.PHONY: demo demo-lidar test bench docs clean

# What an install builds: the package's metadata and its compiled kernels (setup.py:
# every .pyx is built in place by `pip install -e .`), so an edited kernel is rebuilt.
BUILD_INPUTS = pyproject.toml setup.py $(shell find ins photogrammetry -name '*.pyx' -o -name '*.pxd')

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.run-deps: $(BUILD_INPUTS) | $(VENV)/bin/python
	$(PIP) install -e .
	touch $@

$(VENV)/.test-deps: $(BUILD_INPUTS) | $(VENV)/bin/python
	$(PIP) install -e '.[test]'
	touch $(VENV)/.run-deps $@

$(VENV)/.bench-deps: $(BUILD_INPUTS) | $(VENV)/bin/python
	$(PIP) install -e '.[bench]'
	touch $(VENV)/.run-deps $@

$(VENV)/.lidar-deps: $(BUILD_INPUTS) | $(VENV)/bin/python
	$(PIP) install -e '.[lidar]'
	touch $(VENV)/.run-deps $@

$(VENV)/.docs-deps: $(BUILD_INPUTS) | $(VENV)/bin/python
	$(PIP) install -e '.[docs]'
	touch $(VENV)/.run-deps $@

# The whole chain on the embedded flight plan (data/flights/demo.toml):
# simulate -> process (filter + smoother, varying lever arm) -> EO -> refine,
# every stage against the simulator's truth; report in demo-output/report.md
demo: $(VENV)/.run-deps
	$(PY) tools/demo.py --plan data/flights/demo.toml --out demo-output

# The LiDAR chain on data/flights/lidar_demo.toml (a flight with a [scanner]):
# simulate -> process -> georeference -> strip-check -> georeference calibrated,
# point errors and the recovered boresight against the simulator's truth
demo-lidar: $(VENV)/.lidar-deps
	$(PY) tools/demo_lidar.py --plan data/flights/lidar_demo.toml --out demo-lidar-output

test: $(VENV)/.test-deps
	$(PY) -m pytest -q

bench: $(VENV)/.bench-deps
	for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

docs: $(VENV)/.docs-deps
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html

clean:
	rm -rf $(VENV) .cache demo-output demo-lidar-output .pytest_cache docs/_build docs/api/generated
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
	find ins photogrammetry \( -name '*.so' -o -name '*.c' \) -delete
