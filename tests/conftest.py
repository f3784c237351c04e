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


#: The files that compile and exercise the model kernels most (`make test` runs them on one
#: xdist worker, one after another, so each model kernel family compiles once, not on both
#: workers side by side); every other file is its own group, as with --dist loadfile.
MODEL_FILES = {
    "test_models.py",
    "test_model_crossings.py",
    "test_hostile_models.py",
    "test_model_adjoint.py",
    "test_implicit.py",
    "test_models_cuda_sim.py",
}


def pytest_configure(config):
    # pytest-xdist registers its marker only when loaded; without it (-p no:xdist) the groups
    # are plain labels, and --strict-markers must know them
    config.addinivalue_line("markers", "xdist_group(name): tests that --dist loadgroup keeps on one worker")


def pytest_collection_modifyitems(config, items):
    """Group the tests for ``--dist loadgroup`` (see :data:`MODEL_FILES`)."""
    for item in items:
        name = item.path.name
        item.add_marker(pytest.mark.xdist_group("models" if name in MODEL_FILES else name))
