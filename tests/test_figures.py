"""The report's figures as a reader sees them (issue 30): file names from the config's name,
one histogram figure per job with a visible line tau(beta) = tau0 and axes fitted to the data,
resolved links drawn unlike unresolved ones, no empty or repeated measure panels.

Real result files from tiny runs through the CLI, real matplotlib (Agg)."""

import re

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.patches import FancyArrowPatch  # noqa: E402
from typer.testing import CliRunner  # noqa: E402

from antisync.cli.app import app  # noqa: E402
from antisync.report.figures import (  # noqa: E402
    file_stem,
    hist_limit,
    job_stems,
    plot_graph,
    plot_histograms,
)
from antisync.report.links import link_figures, link_signs, plot_resolved_map  # noqa: E402
from antisync.report.measures import measure_figures  # noqa: E402
from antisync.stats.summary import job_records  # noqa: E402
from antisync.store import read_views  # noqa: E402

runner = CliRunner()

# the paper's lollipop: 2->1 antifragile, 2->3 fragile, 1->2 exactly neutral (W unchanged);
# histograms at two damages, so the histogram figure has a row per link and a column per beta
SMALL = """
name: "l6 fig's"
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3", "1->2"]
betas: [0.3, 0.5]
histogram: {betas: [0.3, 0.5]}
measures: [km, xi2]
realizations: 160
block_size: 20
seed: 3
dynamics: {dt: 0.002, t_max: 60}
"""
# a graph whose networkx name has an apostrophe and spaces ("Zachary's Karate Club"), in a
# config named with a space; 34 nodes: the large-graph figures
KARATE = """
name: my net
graph: {kind: networkx, generator: karate_club_graph}
edges: ["0->31", "31->0", "33->32", "32->33"]
betas: []
measures: [km, xi2, rw]
realizations: 40
block_size: 20
seed: 2
dynamics: {dt: 0.002, t_max: 60}
"""


def _run(tmp, name: str, text: str):
    cfg = tmp / f"{name}.yaml"
    cfg.write_text(text)
    out = tmp / f"{name}.h5"
    res = runner.invoke(app, ["run", str(cfg), "--out", str(out), "--quiet", "--threads", "1"])
    assert res.exit_code == 0, res.output
    return out


def _report(path, folder):
    res = runner.invoke(app, ["report", str(path), "--out", str(folder), "--quiet"])
    assert res.exit_code == 0, res.output
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("small"), "small", SMALL)


@pytest.fixture(scope="module")
def karate(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("karate"), "karate", KARATE)


def _texts(fig) -> list[str]:
    """Every title, suptitle, legend and free text of ``fig``."""
    out = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
    return [t for t in out if t]


# ---- names ---------------------------------------------------------------------------------
def test_file_stem_keeps_only_safe_characters():
    assert file_stem("Zachary's Karate Club") == "Zachary_s_Karate_Club"
    assert file_stem("my net") == "my_net"
    assert file_stem("path_graph(4)") == "path_graph_4"
    assert file_stem("../x") == "x" and file_stem("'") == "run"
    assert re.fullmatch(r"[A-Za-z0-9_.-]+", file_stem("a/b\\c d:e*f?"))


def test_files_are_named_after_the_config_not_the_graph(karate, small, tmp_path):
    (view,) = read_views(karate)
    assert view.graph == "Zachary's Karate Club"  # what the files used to be named after
    names = _report(karate, tmp_path / "k")
    assert {"my_net_lambda_sorted.png", "my_net_top_links.png", "my_net_measure_pairs.png"} <= set(names)
    assert all(re.fullmatch(r"[A-Za-z0-9_.-]+", n) for n in names), names
    names = _report(small, tmp_path / "s")
    assert {"l6_fig_s_graph.png", "l6_fig_s_F_beta.png", "l6_fig_s_histograms.png", "index.md"} <= set(names)
    assert job_stems(read_views(small), "a b") == {"lollipop_6_3": "a_b"}
    assert job_stems(read_views(small)) == {"lollipop_6_3": "lollipop_6_3"}  # no name: the job's


# ---- the (tau0, tau(beta)) histograms ------------------------------------------------------
def test_one_histogram_figure_with_a_panel_per_link_and_beta(small, tmp_path):
    names = _report(small, tmp_path)
    assert [n for n in names if "hist" in n] == ["l6_fig_s_histograms.png"]
    (view,) = read_views(small)
    ks = list(range(len(view.hist_variants)))
    assert len(ks) == 6  # 3 links x 2 betas
    fig = plot_histograms(view, ks)
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>" and ax.get_visible() and ax.images]
    assert len(panels) == 6
    assert sorted(ax.get_title() for ax in panels) == sorted(
        f"{view.edges[int(view.variant_edge[v])]}, $\\beta$ = {view.variant_beta[v]:g}"
        for v in view.hist_variants
    )
    # shared axes fitted to the data: below the histogram's range, covering 99.5% of both times
    limit = hist_limit(view.hist, view.tau_max_hist)
    assert limit < view.tau_max_hist
    width = view.tau_max_hist / view.hist.shape[1]
    inside = int(np.ceil(limit / width))
    for h in view.hist:
        assert h[:inside, :inside].sum() >= 0.995 * h.sum()
    for ax in panels:
        assert ax.get_xlim() == pytest.approx((0, limit)) and ax.get_ylim() == pytest.approx((0, limit))
        # the line tau(beta) = tau0 runs across the whole panel, dark and dashed
        (diag,) = [ln for ln in ax.lines if np.allclose(ln.get_xdata(), ln.get_ydata())]
        assert list(diag.get_xdata()) == pytest.approx([0, limit])
        assert diag.get_linestyle() == "--"
        r, g, b, _ = to_rgba(diag.get_color())
        assert r + g + b < 0.5, "the line must be dark, not white"
        assert any("faster after damage" in t.get_text() for t in ax.texts)
    assert any("below the dashed line" in t for t in _texts(fig))
    plt.close(fig)


# ---- resolved and unresolved links ---------------------------------------------------------
def _arrow_styles(ax) -> dict[str, tuple]:
    """``{link: (dashed, colour, width)}`` of the arrows ``ax`` draws for each link."""
    out = {}
    for p in ax.patches:
        if isinstance(p, FancyArrowPatch) and (p.get_gid() or "").startswith("link "):
            dashed = p.get_linestyle() in ("--", "dashed")
            out[p.get_gid()[5:]] = (dashed, tuple(np.round(p.get_edgecolor(), 3)), p.get_linewidth())
    return out


def test_graph_draws_resolved_and_unresolved_links_differently(small):
    (view,) = read_views(small)
    recs = job_records(view)
    first = {r["edge"]: r for r in recs}
    signs = dict(zip(first, link_signs(list(first.values()), "lambda_km"), strict=True))
    assert signs["2->1"] == 1 and signs["2->3"] == -1 and signs["1->2"] == 0
    fig, ax = plt.subplots()
    plot_graph(view, ax)
    styles = _arrow_styles(ax)
    assert set(styles) == {"2->1", "2->3", "1->2"}
    assert not styles["2->1"][0] and not styles["2->3"][0] and styles["1->2"][0]
    assert styles["1->2"][1] not in (styles["2->1"][1], styles["2->3"][1])
    assert styles["1->2"][2] < min(styles["2->1"][2], styles["2->3"][2])
    # three links: each value written on its arrow
    assert {t.get_text() for t in ax.texts} >= {f"{first[e]['lambda_km']:+.3f}" for e in ("2->1", "2->3")}
    plt.close(fig)


def test_top_links_mark_resolution_and_never_say_zero_most(karate):
    (view,) = read_views(karate)
    recs = list({r["edge"]: r for r in job_records(view)}.values())
    figs = dict((suffix, fig) for fig, suffix in link_figures(view, recs, k=2))
    assert set(figs) == {"lambda_sorted", "top_links", "map", "measure_pairs"}
    for fig in figs.values():
        for text in _texts(fig):
            assert not re.search(r"\b0 most", text), text
    signs = dict(zip((r["edge"] for r in recs), link_signs(recs, "lambda_km"), strict=True))
    net, forest = figs["top_links"].axes[:2]
    styles = _arrow_styles(net)
    assert styles, "the strongest links are drawn"
    for edge, (dashed, _, _) in styles.items():
        assert dashed == (signs[edge] == 0), (edge, signs[edge])
    # every drawn link has its interval on the right, a hollow marker where it is not resolved
    assert {t.get_text() for t in forest.get_yticklabels()} == set(styles)
    hollow = [ln for ln in forest.lines if ln.get_marker() == "o" and ln.get_markerfacecolor() == "white"]
    assert len(hollow) == sum(1 for e in styles if not signs[e])
    assert forest.collections, "intervals drawn"
    for fig in figs.values():
        plt.close(fig)


def test_map_draws_every_resolved_link_and_no_other(karate):
    """The map: one arrow per link whose sign is resolved, red or blue by that sign, wider for
    a larger |Lambda|; capped at ``most`` links of largest |Lambda|, as its title says."""
    (view,) = read_views(karate)
    recs = list({r["edge"]: r for r in job_records(view)}.values())
    # the drawing, not the statistics, is tested: the two links of largest |Lambda| get
    # intervals that exclude zero, the others wide ones (at 40 realizations which links a run
    # resolves is chance)
    recs = sorted(recs, key=lambda r: abs(r["lambda_km"]))
    wide = 10 * abs(recs[-1]["lambda_km"])
    for r in recs:
        low, high = sorted((0.9 * r["lambda_km"], 1.1 * r["lambda_km"])) if r in recs[-2:] else (-wide, wide)
        r["lambda_km_ci_low"], r["lambda_km_ci_high"] = low, high
    signs = dict(zip((r["edge"] for r in recs), link_signs(recs, "lambda_km"), strict=True))
    value = {r["edge"]: r["lambda_km"] for r in recs}
    resolved = {e for e, s in signs.items() if s}
    assert 2 <= len(resolved) < len(recs)
    fig, ax = plt.subplots()
    plot_resolved_map(view, recs, "lambda_km", ax)
    styles = _arrow_styles(ax)
    assert set(styles) == resolved
    colours = {signs[e]: colour for e, (_, colour, _) in styles.items()}
    assert len(colours) == len({signs[e] for e in resolved}), "one colour per sign"
    by_size = sorted(resolved, key=lambda e: abs(value[e]))
    assert styles[by_size[-1]][2] > styles[by_size[0]][2]
    assert f"all {len(resolved)} links of {len(recs)}" in ax.get_title()
    plt.close(fig)
    fig, ax = plt.subplots()
    plot_resolved_map(view, recs, "lambda_km", ax, most=1)
    assert set(_arrow_styles(ax)) == {by_size[-1]}
    assert f"the 1 largest of {len(resolved)}" in ax.get_title()
    plt.close(fig)


# ---- Fig. 5 --------------------------------------------------------------------------------
def test_fig5_has_no_empty_panel_and_says_what_was_not_computed(small, karate, tmp_path):
    notes: list[str] = []
    figs = dict((stem, fig) for fig, stem in measure_figures(read_views(small), notes=notes))
    fig = figs["fig5_measures"]
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 1  # only xi2 was computed beside km: (b), Lambda^KM on the y axis
    (ax,) = panels
    assert ax.get_title().startswith("(b)") and ax.get_ylabel() == r"$\Lambda^{(\mathrm{KM})}$"
    assert ax.lines and not any("not computed" in t.get_text() for t in ax.texts)
    assert any("linear" in n and "rw" in n for n in notes), notes
    plt.close(fig)
    _report(small, tmp_path / "s")
    index = (tmp_path / "s" / "index.md").read_text()
    assert "not computed" in index and "fig5_measures.png" in index
    # a large graph's measure_pairs already shows Fig. 5's panels: no repeat
    names = _report(karate, tmp_path / "k")
    assert "my_net_measure_pairs.png" in names and "fig5_measures.png" not in names
