"""The Python API: docs/api.md runs as written, import has no side effects, overrides merge."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import antisync
from antisync.errors import AntisyncError, ConfigError

REPO = Path(__file__).resolve().parent.parent


def test_docs_example_runs_as_written(tmp_path, monkeypatch):
    """Every ```python block of docs/api.md, in order, in one namespace, in an empty folder."""
    blocks = re.findall(r"```python\n(.*?)```", (REPO / "docs" / "api.md").read_text(), flags=re.S)
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for code in blocks:
        exec(compile(code, "docs/api.md", "exec"), namespace)  # noqa: S102 -- our own docs
    assert (tmp_path / "lollipop.h5").exists() and (tmp_path / "fig2.h5").exists()
    # `antisync summary --format json`: one schema for a run file and a sweep file
    from antisync.api import summarize

    run, sweep = summarize(tmp_path / "lollipop.h5"), summarize(tmp_path / "fig2.h5")
    assert set(run) == set(sweep) and (run["kind"], sweep["kind"]) == ("run", "sweep")
    assert run["thresholds"] == [0.99] and run["excluded"] == [] and sweep["symmetry"]


def test_import_changes_nothing_global():
    """No NUMBA_CACHE_DIR, no numba, no h5py: a notebook's other libraries are left alone."""
    code = (
        "import os, sys; import antisync; "
        "print(os.environ.get('NUMBA_CACHE_DIR'), 'numba' in sys.modules, 'h5py' in sys.modules)"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    ).stdout.split()
    assert out == ["None", "False", "False"]


def test_overrides_merge_into_sections_and_are_validated(tmp_path):
    from antisync.plan.sources import resolve_config as _config

    base = {"graph": {"kind": "lollipop", "nodes": 6, "path": 3}, "dynamics": {"t_max": 50.0}}
    cfg = _config(
        base,
        {"dynamics": {"dt": 0.002}, "lambda_": {"method": "orbit"}, "realizations": 10},
        tmp_path / "x.h5",
    )
    assert (cfg.dynamics.dt, cfg.dynamics.t_max) == (0.002, 50.0)  # merged, not replaced
    assert cfg.lambda_.method == "orbit" and cfg.realizations == 10
    assert cfg.output == str(tmp_path / "x.h5")
    assert base["dynamics"] == {"t_max": 50.0}  # the caller's mapping is not modified
    again = _config(cfg, {"seed": 9}, None)
    assert again.seed == 9 and again.dynamics.dt == 0.002
    with pytest.raises(ConfigError, match="realizations must be an integer"):
        _config(base, {"realizations": "many"}, None)
    with pytest.raises(ConfigError, match="does not exist"):
        antisync.run(tmp_path / "missing.yaml")


def test_measures_for_graph_match_the_measures_of_a_run():
    import networkx as nx
    import numpy as np

    from antisync.measures import lambda_rw, lambda_xi2

    g = nx.barbell_graph(3, 1)
    rows = {r["edge"]: r for r in antisync.measures.for_graph(g)}
    omega = nx.to_numpy_array(g, nodelist=sorted(g))
    assert len(rows) == 2 * g.number_of_edges()
    for a, b in [(0, 1), (2, 3), (3, 2)]:
        r = rows[f"{a}->{b}"]
        assert np.isclose(r["lambda_xi2"], lambda_xi2(omega, a, b), atol=1e-12)
        assert np.isclose(r["lambda_rw"], lambda_rw(omega, a, b), atol=1e-12)
    with pytest.raises(AntisyncError, match="connected"):
        antisync.measures.for_graph(nx.Graph([(0, 1), (2, 3)]))
    with pytest.raises(AntisyncError, match="need realizations"):
        antisync.measures.for_graph(g, which=("km",))


def test_numba_cache_is_keyed_by_source_for_antisync_only(tmp_path):
    """antisync's kernels cache under a folder named after a hash of its sources (an edit to
    kernels/core.py must not reuse machine code compiled from the old closures); any other
    numba code in the process caches where numba would cache it anyway."""
    user = tmp_path / "user_mod.py"
    user.write_text("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n")
    code = (
        f"import sys; sys.path.insert(0, {str(tmp_path)!r})\n"
        "from antisync._numba_cache import cache_dir\n"
        "from antisync.physics.phases import initial_phases\n"
        "import user_mod; user_mod.f(1)\n"
        "initial_phases(3, 0, 2, 4)\n"
        "print(cache_dir())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    ).stdout.strip()
    folder = Path(out)
    assert folder.parent == REPO / "antisync" / "__pycache__" and folder.name.startswith("numba-")
    assert any(folder.rglob("phases.*.nbi"))  # antisync's function: in the keyed folder
    assert any((tmp_path / "__pycache__").glob("user_mod.f-*.nbi"))  # the user's: numba's default
    assert not any(folder.rglob("user_mod*"))
