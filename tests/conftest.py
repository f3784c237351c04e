import os
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

#: the generated kernels of user laws (antisync.kernels.law) are written inside the checkout, not
#: in the user's ~/.cache: every worker of a run, and the next run, loads them from there
os.environ.setdefault(
    "ANTISYNC_LAW_CACHE", str(Path(__file__).resolve().parent.parent / "build" / "law-cache")
)

#: numba's OpenMP threads wait for the next parallel kernel without spinning. With the default
#: (active) policy a worker's idle threads spin on the cores the other xdist worker is using, and
#: each of the thousands of short parallel kernels waits a time slice for them: tests/test_laws.py
#: on two workers took 277 s so, 34 s without the spin (and 39 s alone in one process; 2026-12-06,
#: this project's 2-core VM). Read by libgomp when numba first starts its threads, so set before.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


@pytest.fixture(scope="session")
def paper_values():
    """The paper's printed numbers, shipped inside the package (nothing outside the repo is read)."""
    from antisync.paper.reference import paper_values

    return paper_values()


@pytest.fixture
def small_config_text():
    """A tiny but real experiment: the paper's lollipop, two edges, two betas."""
    return """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3"]
betas: [0.5]
realizations: 120
block_size: 20
seed: 3
dynamics: {dt: 0.002, t_max: 60}
"""


#: The files that compile and exercise the model kernels most: `make test` (``--dist loadfile``)
#: sends them to one xdist worker as one unit, one after another, so each model kernel compiles
#: once and the next file loads it from the on-disk cache, instead of both workers compiling the
#: same kernel side by side; every other file is its own unit, as plain ``--dist loadfile``.
#: test_model_crossings.py and test_models_cuda_sim.py (13 tests, about 60 s) stay out: they
#: compile nothing of their own, and run on whichever worker is free from kernels the unit has
#: cached by then (its capability rows compile the model lane drivers in its first minute; in
#: the unit, its worker ran 122 s longer than the other: a fresh clone's compile log, 2026-12-06
#: 21:32).
MODEL_FILES = {
    "test_models.py",
    "test_hostile_models.py",
    "test_model_adjoint.py",
    "test_implicit.py",
    "test_model_start.py",
    "test_laws.py",
}

#: Tests of other files that join :data:`MODEL_FILES`' unit (node ids up to here): the capability
#: table's CPU rows of the generalized model compile the model adjoint and the model lane driver
#: that test_model_adjoint.py and test_hostile_models.py compile too; on the other worker they
#: compiled them a second time, side by side (35 + 56 s of the model adjoint alone).
MODEL_TESTS = ("tests/test_capabilities.py::test_every_cpu_row_runs[model-",)


#: What each unit of work cost a fresh clone's `make test` (worker-seconds, compiling included; the
#: units over 5 s of the compile log's ``.tests`` file, 2026-12-07 15:51): the scheduler hands
#: out the costliest unit left whenever a worker asks for one (longest first), so that the run
#: does not end on one worker finishing a long file while the other is idle. pytest-xdist orders
#: units by their number of tests: test_models_cuda_sim.py (3 tests, 41 s) started last, and one
#: worker ran 21 s after the other had finished. A unit not listed is costed at
#: :data:`SECONDS_PER_TEST` a test. Stale numbers cost only balance, never a result.
UNIT_SECONDS = {
    "models": 349,
    "test_capabilities.py": 87,
    "test_grid_trip.py": 85,
    "test_cuda_sim.py": 52,
    "test_static_fast.py": 29,
    "test_models_cuda_sim.py": 28,
    "test_dask.py": 26,
    "test_store_safety.py": 26,
    "test_paper.py": 26,
    "test_sweeps.py": 26,
    "test_grid_dynamic.py": 25,
    "test_adjoint_lanes.py": 19,
    "test_kernels.py": 18,
    "test_optimize_spectral.py": 18,
    "test_model_crossings.py": 17,
    "test_reliability_hostile.py": 16,
    "test_give_up.py": 15,
    "test_architecture.py": 13,
    "test_activsg10k.py": 11,
    "test_lambda_quantities.py": 10,
    "test_measures_pipeline.py": 10,
    "test_readme.py": 10,
    "test_overwrite_safety.py": 9,
    "test_figures.py": 9,
    "test_optimize.py": 8,
    "test_hostile_input.py": 8,
    "test_large_graphs.py": 8,
    "test_cli.py": 7,
    "test_optimize_window.py": 6,
    "test_numba_compile.py": 6,
    "test_measures.py": 6,
    "test_stopping.py": 5,
}

#: The mean cost of a test in the units under 5 s (the same run: 0.100 s).
SECONDS_PER_TEST = 0.1


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with :data:`MODEL_FILES` and :data:`MODEL_TESTS` as one unit of work,
    the costliest unit first (:data:`UNIT_SECONDS`). (pytest-xdist's own ``--dist loadgroup``
    with ``xdist_group`` markers does the grouping by rewriting each test's node id, which pytest
    9 no longer reads: there the groups were silently ignored and the tests of one file ran on
    both workers.)"""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class ModelFilesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            if Path(path).name in MODEL_FILES or nodeid.startswith(MODEL_TESTS):
                return "models"
            return path

        def _assign_work_unit(self, node) -> None:
            def cost(scope: str) -> float:
                seconds = UNIT_SECONDS.get(Path(scope).name)
                return seconds if seconds is not None else SECONDS_PER_TEST * len(self.workqueue[scope])

            self.workqueue.move_to_end(max(self.workqueue, key=cost), last=False)
            super()._assign_work_unit(node)

    return ModelFilesTogether(config, log)


#: The test suite's time guard: a test whose call runs longer than this (seconds, on two cores
#: beside the other worker) is named at the end of every run, and one not in :data:`KNOWN_SLOW`
#: is marked new, so that a contributor sees what a change added to `make test` (the budget of
#: the whole suite is 8 minutes on two cores: bench/RESULTS.md, "The test suite on two cores").
#: A name, not a failure: speed is measured in bench/, never asserted in tests.
SLOW_TEST_BUDGET = 30.0

#: The tests over :data:`SLOW_TEST_BUDGET` in a fresh clone (f4eb863 + 1e39668, 2026-12-05): most
#: of their time is numba compiling a kernel family the first time a test uses it.
KNOWN_SLOW = (
    "tests/test_capabilities.py::test_every_cpu_row_runs",
    "tests/test_implicit.py::test_a_stiff_grid_matches_rk4_on_the_same_phases",
    "tests/test_grid_trip.py::test_a_trip_after_a_fault_is_radau_s_integration",
    # the first to compile the identical adjoint's one-trajectory driver (30.8 s of its 30.9 s in
    # the compile log of a fresh clone, 2026-12-05 17:18)
    "tests/test_adjoint_lanes.py::test_lanes_equal_one_trajectory_bit_for_bit",
    # the first to compile the paper's model as a law: its Euler and RK4 lane drivers, RK4 on the
    # angles and Rodas4 (48.2 s in a fresh clone, 2026-12-06 07:31)
    "tests/test_laws.py::test_the_papers_model_as_a_law_is_the_builtin",
    # the first to compile the power-grid law, the frequency lanes of kuramoto and swing, and the
    # second harmonic's lanes (31-36 s in a fresh clone, 2026-12-06 20:21)
    "tests/test_laws.py::test_the_ieee39_grid_as_a_law_is_the_builtin",
    "tests/test_laws.py::test_the_frequency_criterion_of_a_law_is_the_builtins",
    "tests/test_laws.py::test_the_lane_driver_is_the_one_trajectory_driver_bit_for_bit",
)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """Name the tests over :data:`SLOW_TEST_BUDGET` (the new ones first)."""
    slow = [
        (rep.duration, rep.nodeid)
        for key in ("passed", "failed")
        for rep in terminalreporter.stats.get(key, [])
        if getattr(rep, "when", None) == "call" and rep.duration > SLOW_TEST_BUDGET
    ]
    if not slow:
        return
    new = [(d, n) for d, n in slow if not n.startswith(KNOWN_SLOW)]
    terminalreporter.write_line(
        f"{len(slow)} test(s) over the {SLOW_TEST_BUDGET:g} s budget, {len(new)} new "
        "(tests/conftest.py KNOWN_SLOW lists the known ones):"
    )
    for duration, nodeid in sorted(slow, key=lambda t: (t[1].startswith(KNOWN_SLOW), -t[0])):
        mark = "" if nodeid.startswith(KNOWN_SLOW) else "NEW "
        terminalreporter.write_line(f"  {mark}{duration:6.1f} s  {nodeid}")


#: ``ANTISYNC_COMPILE_LOG=path make test``: every numba compilation of the run, one line per
#: compile that no other compile encloses (a kernel's callees compile inside it), appended to
#: ``path`` by each xdist worker: ``worker  seconds  function  test``. Where a cold run's time
#: goes, and whether two workers compiled the same kernel
#: (``sort -k3 path | uniq -f2 -D``); bench/specializations.py lists the signatures compiled.
COMPILE_LOG = os.environ.get("ANTISYNC_COMPILE_LOG")


_SESSION_START = time.perf_counter()


def pytest_configure(config):
    if COMPILE_LOG:
        from numba.core import event

        event.register("numba:compile", _compile_log(event.Listener)())


def pytest_runtest_logreport(report):
    """With :data:`COMPILE_LOG`, each test's phases also go to ``COMPILE_LOG.tests`` (``worker
    seconds-since-start duration phase test``, by the worker that ran it): what each worker did
    when, and how long it was busy (the wall time of `make test` is its busier worker's)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if COMPILE_LOG and worker:
        at = time.perf_counter() - _SESSION_START
        with open(COMPILE_LOG + ".tests", "a") as fh:
            fh.write(f"{worker}\t{at:.2f}\t{report.duration:.2f}\t{report.when}\t{report.nodeid}\n")


def _compile_log(base):
    """The listener of :data:`COMPILE_LOG`, a subclass of numba's ``event.Listener``."""

    class CompileLog(base):
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        depth = 0
        started = 0.0

        def on_start(self, ev):
            if self.depth == 0:
                self.started = time.perf_counter()
            self.depth += 1

        def on_end(self, ev):
            self.depth -= 1
            if self.depth:
                return
            seconds = time.perf_counter() - self.started
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            name = f"{func.__module__}.{func.__qualname__}" if func is not None else "?"
            test = os.environ.get("PYTEST_CURRENT_TEST", "-").split(" ")[0]
            with open(COMPILE_LOG, "a") as fh:
                fh.write(f"{self.worker}\t{seconds:.2f}\t{name}\t{test}\n")

    return CompileLog
