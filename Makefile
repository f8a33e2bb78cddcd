# make demo  - set up .venv and run the main job on the embedded example data
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

# The embedded example: 60 s of the benchmark flight's error-free IMU (data/example/README.md)
demo: $(VENV)/.run-deps
	@mkdir -p demo-output
	@echo "== strapdown mechanization of 60 s of error-free 200 Hz increments (data/example)"
	$(VENV)/bin/ins mechanize data/example/imu.txt --init-lla 30.44,114.47,1000 \
	    --init-vel 60,0,-0.1438276615812609 \
	    --init-att 0,2.3056392336543654,0.09092974268256818 -o demo-output/example.nav
	@echo "== errors against the simulator's truth (the algorithm's own error; 0 = below print precision)"
	$(VENV)/bin/ins compare demo-output/example.nav data/example/truth.nav

test: $(VENV)/.test-deps
	$(PY) -m pytest -q

bench: $(VENV)/.bench-deps
	$(PY) bench/bench_mechanize.py

clean:
	rm -rf $(VENV) .cache demo-output .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
