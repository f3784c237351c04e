import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


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
MODEL_FILES = {
    "test_models.py",
    "test_model_crossings.py",
    "test_hostile_models.py",
    "test_model_adjoint.py",
    "test_implicit.py",
    "test_models_cuda_sim.py",
    "test_model_start.py",
}

#: Tests of other files that join :data:`MODEL_FILES`' unit (node ids up to here): the capability
#: table's CPU rows of the generalized model compile the model adjoint and the model lane driver
#: that test_model_adjoint.py and test_hostile_models.py compile too; on the other worker they
#: compiled them a second time, side by side (35 + 56 s of the model adjoint alone).
MODEL_TESTS = ("tests/test_capabilities.py::test_every_cpu_row_runs[model-",)


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with :data:`MODEL_FILES` and :data:`MODEL_TESTS` as one unit of work.
    (pytest-xdist's own ``--dist loadgroup`` with ``xdist_group`` markers does this by rewriting
    each test's node id, which pytest 9 no longer reads: there the groups were silently ignored
    and the tests of one file ran on both workers.)"""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class ModelFilesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            if Path(path).name in MODEL_FILES or nodeid.startswith(MODEL_TESTS):
                return "models"
            return path

    return ModelFilesTogether(config, log)
