"""What antisync ships as data: the paper's printed numbers and the example configs.

The numbers the paper prints live in ``data/paper_values.yaml``, the configs in
``data/configs/`` (``configs/`` in a checkout is a link to it).

Both are kept once, inside the package: the tests, ``antisync paper`` and its README read
them from here, so an installed wheel or a bare clone has them too.

Example
-------
>>> from antisync.paper.reference import paper_values
>>> paper_values()["lollipop_6_3"]["mean_F_beta_0.5"]["2->1"]
1.181
"""

from __future__ import annotations

import functools
from importlib import resources

import yaml

from antisync.errors import ConfigError

__all__ = ["config_path", "paper_table1", "paper_values"]


@functools.cache
def paper_values() -> dict:
    """The parsed ``paper_values.yaml``: Sec. 3.1's lollipop, Table 1, the 6-node atlas counts."""
    text = resources.files("antisync").joinpath("data/paper_values.yaml").read_text()
    return yaml.safe_load(text)


def paper_table1() -> list[tuple[int, float, float, float]]:
    """Table 1 rows ``(graph, <tau0>, max Lambda^KM, <F_0.5>)``, graphs 1..7."""
    return [tuple(row) for row in paper_values()["table_1"]["rows"]]


def config_path(name: str):
    """A config shipped with antisync (``configs/`` in a checkout), e.g. ``lollipop6``.

    Returns a path-like :class:`importlib.resources.abc.Traversable`; ``str()`` of it is a file
    path for an installed package or a checkout.
    """
    folder = resources.files("antisync").joinpath("data/configs")
    path = folder.joinpath(f"{name}.yaml")
    if not path.is_file():
        names = sorted(p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml"))
        raise ConfigError(f"no shipped config {name!r}; shipped: {', '.join(names)}")
    return path
