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
