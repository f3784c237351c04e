import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def paper_values():
    import yaml

    path = SHARED / "reference" / "paper_values.yaml"
    if not path.exists():
        pytest.fail(f"reference values not found at {path}: the repo must sit beside shared/")
    return yaml.safe_load(path.read_text())


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
