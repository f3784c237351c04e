"""The numbers the paper prints, shipped with the package (``data/paper_values.yaml``).

They are facts to reproduce, kept once, inside the package: the tests, ``antisync paper`` and
its README all read them from here, so an installed wheel or a bare clone has them too.

Example
-------
>>> from antisync.reference import paper_values
>>> paper_values()["lollipop_6_3"]["mean_F_beta_0.5"]["2->1"]
1.181
"""

from __future__ import annotations

import functools
from importlib import resources

__all__ = ["paper_table1", "paper_values"]


@functools.cache
def paper_values() -> dict:
    """The parsed ``paper_values.yaml``: Sec. 3.1's lollipop, Table 1, the 6-node atlas counts."""
    import yaml

    text = resources.files("antisync").joinpath("data/paper_values.yaml").read_text()
    return yaml.safe_load(text)


def paper_table1() -> list[tuple[int, float, float, float]]:
    """Table 1 rows ``(graph, <tau0>, max Lambda^KM, <F_0.5>)``, graphs 1..7."""
    return [tuple(row) for row in paper_values()["table_1"]["rows"]]
