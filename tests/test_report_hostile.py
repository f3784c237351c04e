"""Reports and summaries of legal but awkward result files (a hostile-input audit).

- the tail model's interval of Lambda^KM need not contain the estimate: figures draw every
  interval from its ends, never as errors around the estimate (which matplotlib refuses when
  negative);
- a file whose Lambda^KM is undefined (nothing synchronized) or absent (no km) reports, and
  ``summary --sort`` says which measure is missing, why, and which ``--sort`` values apply;
- a refused ``--resume`` names only the keys whose values changed;
- the summary prints one warning line per kind of Lambda^KM warning, however many links.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import antisync
from antisync.cli.app import app
from antisync.errors import StoreError
from antisync.physics.graphs import build_graph
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job
from antisync.report.intervals import interval_segments, record_intervals
from antisync.report.links import plot_vs
from antisync.report.measures import missing_note
from antisync.report.tables import format_records
from antisync.stats.estimators import Z95
from antisync.stats.summary import WARNING_KINDS, warning_kind
from antisync.store import read_views
from antisync.store.layout import read_states
from antisync.store.state import JobState

runner = CliRunner()

# 34 nodes (the large-graph report), one batch of 64 realizations: the tail model's interval of
# some links does not contain their estimate (checked in `outside`)
OUTSIDE = """
name: karate6
graph: {kind: networkx, generator: karate_club_graph}
edges: ["0->31", "31->0", "33->32", "32->33", "0->1", "1->0"]
betas: []
measures: [km, xi2]
realizations: 64
block_size: 64
seed: 6
dynamics: {dt: 0.002, t_max: 60}
"""
# t_max far below any synchronization time: every realization ends NOT_SYNCED_BY_T_MAX
UNSYNCED = """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3"]
betas: [0.5]
measures: [km, xi2]
realizations: 20
block_size: 10
seed: 3
dynamics: {dt: 0.01, t_max: 0.2}
"""
UNSYNCED_LARGE = """
name: karate_unsynced
graph: {kind: networkx, generator: karate_club_graph}
edges: ["0->31", "31->0"]
betas: []
measures: [km]
realizations: 20
block_size: 10
seed: 3
dynamics: {dt: 0.01, t_max: 0.2}
"""
EXACT = """
graph: {kind: lollipop, nodes: 6, path: 3}
measures: [xi2, rw]
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _run(folder, name: str, text: str, *args):
    cfg = folder / f"{name}.yaml"
    cfg.write_text(text)
    out = folder / f"{name}.h5"
    res = invoke("run", cfg, "--out", out, "--quiet", *args)
    assert res.exit_code == 0, res.output
    return out


def _png(path) -> bool:
    return path.is_file() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _one_line_error(res, *needles: str) -> str:
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert "Traceback" not in res.output, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hostile")
    return {
        "outside": _run(folder, "outside", OUTSIDE),
        "unsynced": _run(folder, "unsynced", UNSYNCED),
        "unsynced_large": _run(folder, "unsynced_large", UNSYNCED_LARGE),
        "exact": _run(folder, "exact", EXACT),
    }


def _outside(recs: list[dict]) -> list[dict]:
    return [
        r
        for r in recs
        if r["lambda_km_ci_low"] is not None
        and not r["lambda_km_ci_low"] <= r["lambda_km"] <= r["lambda_km_ci_high"]
    ]


# ---- intervals drawn from their ends ----------------------------------------------------------
def test_interval_segments_are_the_interval_ends():
    # an estimate of 0.05 outside [0.1, 0.4]: the segment is [0.1, 0.4], not 0.05 -/+ anything
    pos, lo, hi = interval_segments(
        [1, 2, 3, 4, 5], [0.1, None, np.nan, -0.2, 0.3], [0.4, 0.2, 0.5, -0.1, 0.2]
    )
    assert pos.tolist() == [1, 4, 5]  # None and NaN ends: no segment
    assert lo.tolist() == [0.1, -0.2, 0.2] and hi.tolist() == [0.4, -0.1, 0.3]
    recs = [
        {"lambda_km": 0.05, "lambda_km_ci_low": 0.1, "lambda_km_ci_high": 0.4, "lambda_km_se": 0.08},
        {"lambda_km": 0.05, "lambda_km_ci_low": None, "lambda_km_ci_high": None, "lambda_km_se": None},
        {"lambda_km_nnc": 0.2, "lambda_km_nnc_se": 0.1},
        {"lambda_xi2": 0.3},
    ]
    lo, hi = record_intervals(recs[:2], "lambda_km")
    assert lo[0] == 0.1 and hi[0] == 0.4 and np.isnan(lo[1]) and np.isnan(hi[1])
    lo, hi = record_intervals(recs[2:3], "lambda_km_nnc")
    assert np.allclose([lo[0], hi[0]], [0.2 - Z95 * 0.1, 0.2 + Z95 * 0.1])
    assert np.isnan(record_intervals(recs[3:], "lambda_xi2")[0]).all()


def test_km_panel_draws_each_stored_interval(files):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    recs = antisync.load(files["outside"]).records
    assert _outside(recs), "the file should hold an estimate outside its own interval"
    fig, ax = plt.subplots()
    plot_vs(recs, "lambda_km", "lambda_xi2", ax)
    segments = {
        (round(float(a[0, 1]), 12), round(float(a[0, 0]), 12), round(float(a[1, 0]), 12))
        for c in ax.collections
        if isinstance(c, LineCollection)
        for a in c.get_segments()
    }
    plt.close(fig)
    want = {
        (round(r["lambda_xi2"], 12), round(r["lambda_km_ci_low"], 12), round(r["lambda_km_ci_high"], 12))
        for r in recs
    }
    assert segments == want


def test_report_of_estimates_outside_their_interval(files, tmp_path):
    res = invoke("report", files["outside"], "--out", tmp_path, "--quiet")
    assert res.exit_code == 0, res.output
    (view,) = read_views(files["outside"])
    for stem in ("lambda_sorted", "top_links", "measure_pairs"):
        assert _png(tmp_path / f"karate6_{stem}.png"), stem  # the config's name
    # its measure_pairs already shows Lambda^KM against Lambda^xi2: no repeat as fig5_measures
    assert not (tmp_path / "fig5_measures.png").exists()


def test_an_estimate_outside_its_interval_is_warned_of(files):
    # a mean outside its own interval is no error of the tail model (it weighs rare large
    # values by their count), but the summary must say so rather than print both silently
    recs = antisync.load(files["outside"]).records
    out = _outside(recs)
    assert out
    for r in out:
        assert warning_kind(r["lambda_km_warning"]) == "mean outside its interval", r["lambda_km_warning"]
        assert f"the mean {r['lambda_km']:+.4g} lies outside" in r["lambda_km_warning"]
        # a sign is called from the interval, never from the mean outside it
        assert not r["sign_resolved"] or r["lambda_km_ci_low"] > 0 or r["lambda_km_ci_high"] < 0
    table = invoke("summary", files["outside"]).stdout
    assert "mean outside its interval" in table or "lies outside its interval" in table


@pytest.mark.parametrize("name", ["unsynced", "unsynced_large"])
def test_report_of_a_file_where_nothing_synchronized(files, name, tmp_path):
    recs = antisync.load(files[name]).records
    assert all(r["lambda_km"] is None and r["lambda_km_ci_low"] is None for r in recs)
    res = invoke("report", files[name], "--out", tmp_path, "--quiet")
    assert res.exit_code == 0, res.output
    names = {p.name for p in tmp_path.iterdir()} - {"index.md"}
    assert names and all(_png(tmp_path / n) for n in names)
    if name == "unsynced":
        assert {"unsynced_graph.png", "unsynced_F_beta.png"} <= names
        # no Fig. 5 panel without Lambda^KM: the index says why instead
        assert "fig5_measures.png" not in names
        index = (tmp_path / "index.md").read_text()
        assert "Lambda^KM is undefined: none of the 20 realizations" in index
    else:  # no measure at all: the sorted panel says why instead of nothing being written
        assert [n for n in names if n.endswith("_lambda_sorted.png")], names
    # a panel without Lambda^KM says it is undefined, not that km was never asked for
    note = missing_note(recs, ("lambda_km", "lambda_rw"))
    assert "Lambda^KM is undefined: none of the 20 realizations" in note.replace("\n", " ")
    assert "rw not computed: add rw to measures" in note and "add km" not in note


# ---- summary --sort on a file without the measure ---------------------------------------------
def test_sort_by_an_undefined_lambda_says_why(files):
    line = _one_line_error(
        invoke("summary", files["unsynced"], "--sort", "km"),
        "cannot sort by km: no record has lambda_km",
        "Lambda^KM is undefined: none of the 20 realizations of unsynced synchronized by t_max",
        "(--sort lambda, xi2)",
    )
    assert "holds no records" not in line
    # the same file sorts by what it has
    res = invoke("summary", files["unsynced"], "--sort", "lambda", "--format", "json")
    assert res.exit_code == 0, res.output
    assert [r["edge"] for r in json.loads(res.stdout)["records"]] == ["2->1", "2->3"]
    for by in ("km", "lambda"):
        line = _one_line_error(
            invoke("summary", files["unsynced_large"], "--sort", by),
            "no --sort applies",
            "none of the 20 realizations of",
        )
        assert "holds no records" not in line
    _one_line_error(
        invoke("summary", files["exact"], "--sort", "km"),
        "cannot sort by km: no record has lambda_km; these records have xi2, rw (--sort lambda, xi2, rw)",
        "was run without km",
    )
    _one_line_error(
        invoke("summary", files["exact"], "--sort", "linear"),
        "no record has lambda_linear; these records have xi2, rw",
        "linear is not among the run's measures",
    )


# ---- resume refusals name what changed --------------------------------------------------------
def test_resume_refusal_names_only_the_changed_keys(files):
    out = files["unsynced"]
    cfg = out.with_suffix(".yaml")
    res = invoke("run", cfg, "--out", out, "--resume", "--set", "seed=4", "--set", "dynamics.t_max=0.3", "-q")
    line = _one_line_error(res, "dynamics.t_max: 0.2 -> 0.3", "seed: 3 -> 4")
    for unchanged in ("realizations", "betas", "histogram", "edges", "graph"):
        assert unchanged not in line.split("was made with a different config")[1], line
    res = invoke("run", cfg, "--out", out, "--resume", "--set", 'edges=["2->1"]', "-q")
    _one_line_error(res, 'edges: ["2->1", "2->3"] -> ["2->1"]')


def test_resume_refusal_names_the_part_of_the_graph_that_changed(files):
    out = files["unsynced"]
    config = load_config(out.with_suffix(".yaml"))
    job = make_job(config)
    # the same nodes and damaged edges, one weight changed: what an unseeded generator does
    graph = build_graph(config.graph)
    a, b = next(iter(graph.edges))
    graph.edges[a, b]["weight"] = 2.0
    other = make_job(config, graph=graph, name=job.name)
    key = json.loads(json.dumps(config.simulation_key()))
    with pytest.raises(StoreError, match=r"\(weights differ from the graph built now") as err:
        read_states(out, {other.name: JobState(other)}, key)
    assert "nodes" not in str(err.value)


# ---- one warning line per kind ------------------------------------------------------------------
def test_warnings_of_one_kind_are_one_line(files):
    recs = antisync.load(files["outside"]).records
    many = []
    for i in range(72):  # e.g. the heavy-tail warning of 72 links, each with its own numbers
        r = dict(recs[i % len(recs)], edge=f"{i}->{i + 1}")
        r["lambda_km_warning"] = (
            f"heavy tail: the interval rests on {i % 9} values beyond |Lambda| = {0.01 * (i + 1):.3g} "
            f"and is {1.6 + i / 100:.1f}x the batch-means one; about {(i + 2) * 1000:,} realizations "
            "would sample 10 of them"
        )
        many.append(r)
    few = dict(recs[0], edge="a->b", lambda_km_warning="only 6 batches: standard error is rough")
    lines = [ln for ln in format_records([*many, few]).splitlines() if ln.startswith("warning: Lambda_KM")]
    assert len(lines) == 2, lines
    heavy = next(ln for ln in lines if "heavy tail" in ln)
    assert heavy.startswith("warning: Lambda_KM of 72 links (0->1, 1->2, 10->11, 11->12, 12->13, ...): ")
    assert "heavy tail, few tail values, e.g. 0->1: heavy tail: the interval rests on 0 values" in heavy
    assert "warning: Lambda_KM of a->b: only 6 batches: standard error is rough" in lines
    # every warning the summary writes has a kind of its own
    texts = [r["lambda_km_warning"] for f in files.values() for r in antisync.load(f).records]
    assert all(warning_kind(w) in WARNING_KINDS for w in texts if w)
    for path in files.values():
        table = invoke("summary", path).stdout.splitlines()
        kinds = [ln for ln in table if ln.startswith("warning: Lambda_KM")]
        assert len(kinds) == len(
            {
                warning_kind(r["lambda_km_warning"])
                for r in antisync.load(path).records
                if r["lambda_km_warning"]
            }
        )


@pytest.mark.parametrize("damage", ["graph: [unclosed", "- a list, not a config\n", "42\n"])
def test_a_damaged_stored_config_is_one_line_everywhere(tmp_path, damage):
    """One decoder of a result file's config (antisync.store.stored_config), one policy: a
    ``config_yaml`` that is not a mapping of config keys makes the file damaged, for the
    summary, the report and the API alike (one line, exit 2; before, the summary left its
    model line out and the API refused)."""
    import h5py

    out = tmp_path / "exact.h5"
    res = antisync.run(
        {"graph": {"kind": "lollipop", "nodes": 5, "path": 2}, "measures": ["xi2", "rw"]}, output=out
    )
    assert res.records
    with h5py.File(out, "r+") as f:
        f.attrs["config_yaml"] = damage
    for args in (["summary", str(out)], ["report", str(out), "--out", str(tmp_path / "fig")]):
        got = runner.invoke(app, args)
        assert got.exit_code == 2, (args, got.output)
        assert "is damaged: its root attribute config_yaml is not" in got.output
        assert len(got.output.strip().splitlines()) == 1 and "Traceback" not in got.output
    with pytest.raises(StoreError, match="config_yaml is not"):
        antisync.summarize(out)
