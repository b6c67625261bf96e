# `make run`: set up and replay the paper's 700 s reclaim in the browser.
# `make test`: set up and run the whole test suite.
VENV ?= .venv
PYTHON ?= python3
PY := $(VENV)/bin/python

.PHONY: setup run dig reclaim test test-quick bench bench-replay bench-batch bench-gym bench-opcua bench-fmu shadow clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@echo "computing the fuzzy control surface with scikit-fuzzy (once, then cached) ..."
	$(PY) -c "from bwr_twin.control.fuzzy import FuzzySurface; from bwr_twin.control.rulebase import RuleBase; from bwr_twin.shipped import RULE_BASES; FuzzySurface.load(RuleBase.from_toml(RULE_BASES / 'paper_table2.toml'))"
	@echo "compiling the control loop's kernels with numba (once, then cached) ..."
	$(PY) -m bwr_twin.sim.warm
	touch $@

setup: $(VENV)/.installed

run: setup
	$(PY) -m bwr_twin.replay

dig: setup
	$(PY) -m bwr_twin.replay heavy_dig_pile

reclaim: setup
	$(PY) -m bwr_twin.replay heavy_bench_reclaim

test: setup
	$(PY) -m pytest

test-quick: setup
	$(PY) -m pytest -m "not slow and not browser"

bench: setup
	$(PY) tools/bench.py

bench-replay: setup
	$(PY) tools/bench_replay.py

bench-batch: setup
	$(PY) tools/bench_batch.py

bench-gym: setup
	$(PY) tools/bench_gym.py

bench-opcua: setup
	$(PY) tools/bench_opcua.py

shadow: setup
	$(PY) examples/shadow_demo.py

bench-fmu: setup
	$(PY) tools/bench_fmu.py

clean:
	rm -rf out .pytest_cache
