# antisync: `make run` and `make test` work on a fresh machine with Python 3.11, pip and gcc.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
CONFIG ?= configs/lollipop6.yaml
RESULT ?= results/lollipop6.h5

.PHONY: help install run test test-slow test-cuda bench lint format docs clean paper fig1-paper-precision fig3-two-hours

help:
	@echo "make run        set up .venv, run $(CONFIG), write $(RESULT) and figures"
	@echo "make test       set up .venv and run the test suite (fast; slow tests: make test-slow)"
	@echo "make test-cuda  CUDA backend under the simulator, and PTX compilation (no GPU needed)"
	@echo "make bench      speed benchmarks (results go to bench/RESULTS.md by hand)"
	@echo "make paper      every figure and table of the paper at reduced realizations into"
	@echo "                results/paper/ (35 min on 2 cores; resumes when rerun)"
	@echo "make fig1-paper-precision"
	@echo "                Fig. 1's 12 links at the paper's 1e7 realizations (RK4; ~8 min on"
	@echo "                2 cores) into results/fig1_paper_precision.h5"
	@echo "make fig3-two-hours"
	@echo "                Fig. 3's ranking and Table 1 from 1.5M realizations of every six-node"
	@echo "                graph (RK4; ~2 hours on 2 cores) into results/fig3_two_hours/"
	@echo "make docs       the documentation site with the API reference, strict, into site/"
	@echo "make lint       ruff check and ruff format --check (part of make test)"
	@echo "make format     ruff format (rewrites files)"

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev,docs]"
	@touch $(STAMP)

install: $(STAMP)

# --resume: a finished result is kept (no-op), an interrupted one is finished.
run: $(STAMP)
	$(BIN)/antisync run $(CONFIG) --resume
	$(BIN)/antisync summary $(RESULT)
	$(BIN)/antisync report $(RESULT)

# lint and format checks first (seconds), then the suite on every core (pytest-xdist; a file's
# tests stay on one worker, and the files that compile the model kernels most share one worker
# (tests/conftest.py, MODEL_FILES), so those kernels compile once, not on both workers side by
# side; the on-disk cache shares them); pytest's exit 5 (no tests) fails too
# BLAS on one thread per worker: the workers already fill the cores, and OpenBLAS's own threads on
# top of them spin against each other (tests/test_static_fast.py's IEEE 118 table: 345 s beside
# another job with BLAS's default threads, 5.8 s with one)
PYTEST := OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/python -m pytest -n auto --dist loadfile

test: $(STAMP)
	$(BIN)/ruff check antisync tests bench tools
	$(BIN)/ruff format --check antisync tests bench tools
	$(PYTEST)

test-slow: $(STAMP)
	$(PYTEST) -m slow

# the CUDA backend under the numba simulator (most of it part of `make test` too), with the slow
# checks (every kernel lowered to PTX through NVVM, the GPU scripts' code paths); on a GPU
# machine also run: $(BIN)/python bench/gpu_check.py
test-cuda: $(STAMP)
	$(BIN)/python -m pytest -m "slow or not slow" tests/test_cuda_sim.py tests/test_models_cuda_sim.py
	$(BIN)/python bench/ptx_check.py || test $$? -eq 3

bench: $(STAMP)
	$(BIN)/python bench/bench_kernels.py
	$(BIN)/python bench/bench_sizes.py
	$(BIN)/python bench/bench_adjoint.py
	$(BIN)/python bench/bench_passes.py
	$(BIN)/python bench/bench_adaptive.py --realizations 5000
	$(BIN)/python bench/bench_dask.py
	$(BIN)/python bench/bench_implicit.py --starts 100 --timed-starts 16 --radau-starts 8 --skip-rk4-lanes --rtol 1e-4 --atol 1e-4
	$(BIN)/python bench/bench_trip.py --rows 16
	$(BIN)/python bench/removal_give_up.py --lines 4 --starts 200 --check-starts 50 --study-starts 100
	$(BIN)/python bench/bench_design_gradnet.py --skip-textbook
	$(BIN)/python bench/bench_edge_orbits.py

# every warning is an error (mkdocs.yml: strict); the API pages come from the docstrings
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir site

lint: $(STAMP)
	$(BIN)/ruff check antisync tests bench tools
	$(BIN)/ruff format --check antisync tests bench tools

format: $(STAMP)
	$(BIN)/ruff format antisync tests bench tools

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build site *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

paper: $(STAMP)
	$(BIN)/antisync paper --out results/paper

fig1-paper-precision: $(STAMP)
	$(BIN)/antisync run configs/fig1_paper_precision.yaml --resume
	$(BIN)/antisync summary results/fig1_paper_precision.h5 --sort km

fig3-two-hours: $(STAMP)
	$(BIN)/antisync sweep configs/fig3_two_hours.yaml --resume
	$(BIN)/antisync report results/fig3_two_hours.h5 --out results/fig3_two_hours
