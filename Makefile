# revdem — `make run` and `make test` set everything up on a fresh machine.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out
# test workers (pytest-xdist): one a core this process may use, at most 4
WORKERS ?= $(shell $(PYTHON) -c 'import os; print(min(4, len(os.sched_getaffinity(0))))')
# the peers `make bench` runs beside revdem from ../shared/bench; PEERS= runs revdem alone
PEERS ?= lammps liggghts yade

.PHONY: run test lint bench paper clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/revdem run configs/collision.toml --out $(OUT) --force

test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(WORKERS)

bench: $(STAMP)
	$(BIN)/python benchmarks/fcc_hertz.py --scaling --peers $(PEERS)
	$(BIN)/python benchmarks/crossover.py
	$(BIN)/python benchmarks/order.py
	$(BIN)/python benchmarks/packing.py
	NUMBA_NUM_THREADS=1 $(BIN)/python benchmarks/roofline.py

lint: $(STAMP)
	$(BIN)/ruff check revdem_cli tests benchmarks
	$(BIN)/ruff format --check revdem_cli tests benchmarks

PAPER_CASES := collision collision_shear drop_A drop_B drop_C fcc_triaxial oedometer

paper: $(STAMP)
	mkdir -p scenarios/report
	rm -f $(OUT)/paper/*.checkpoint.h5  # an interrupted make paper's: every case runs afresh
	for case in $(PAPER_CASES); do $(BIN)/revdem run configs/$$case.toml --out $(OUT)/paper -q --force || exit 1; done
	$(BIN)/revdem report $(OUT)/paper --out scenarios/report/hanley2020.md --force
	$(BIN)/revdem run configs/ellipsoid_dt.toml --out scenarios/report -q --force

clean:
	rm -rf $(OUT) .pytest_cache
