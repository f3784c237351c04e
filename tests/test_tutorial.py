"""The tutorial notebook (docs/tutorial.ipynb) runs as written, in a fresh kernel.

Executed by nbclient (the dev extra) in an empty folder, so it can neither rot nor lean on
files of the checkout: whatever it reads, it makes.
"""

from __future__ import annotations

from pathlib import Path

import pytest

nbclient = pytest.importorskip("nbclient", reason="the dev extra installs nbclient")
nbformat = pytest.importorskip("nbformat", reason="the dev extra installs nbformat")

NOTEBOOK = Path(__file__).resolve().parent.parent / "docs" / "tutorial.ipynb"


def _text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", []) if o.get("output_type") == "stream")


def test_the_tutorial_runs_and_says_what_it_shows(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert not any(c.get("outputs") for c in nb.cells if c.cell_type == "code"), "ship it unexecuted"
    nbclient.NotebookClient(
        nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    ).execute()
    out = "\n".join(_text(c) for c in nb.cells if c.cell_type == "code")
    assert "15 nodes, 20 links" in out
    assert "resolved of 40" in out and "xi2 has the Kuramoto sign on" in out
    assert "lines ranked" in out  # the power-grid cell (antisync.grid)
    assert (tmp_path / "florentine.h5").is_file() and (tmp_path / "florentine_freq.h5").is_file()
    # the figure cell drew one
    assert any(o.get("output_type") == "display_data" for c in nb.cells for o in c.get("outputs", []))
