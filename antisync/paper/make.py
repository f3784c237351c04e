"""Every figure and table of the paper at reduced realizations, into one folder with a README.

:func:`make_paper` runs five experiments (resumable, each one HDF5 file), writes their reports
and a ``README.md`` that shows each figure next to what the paper's caption says:

===============  ==========================================  ================================
file             what                                        paper
===============  ==========================================  ================================
lollipop6        run, lollipop N=6 L=3, every edge           Fig. 1
lollipop6_raw    the same with non-normalized coupling       Fig. 7 (and 7e with lollipop6)
threshold        sweep, 112 six-node graphs, r = .9/.99/.999  Figs. 3, 4, 5, 6, Table 1
lollipop_F       sweep, lollipops L=1, N=4..20, beta grid    Fig. 2a
lollipop_lambda  sweep, the same, Lambda (orbit), repeats      Fig. 2b
===============  ==========================================  ================================

The realizations are fixed (times ``scale``), so two machines give the same numbers; their
cost was measured (CPU seconds per realization, :data:`COST`) and :func:`plan` turns it into
an estimate. The defaults take about 30 minutes on two cores (docs/sweeps.md).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from antisync._version import __version__
from antisync.errors import AntisyncError, ConfigError
from antisync.execution.runner import run_config
from antisync.paper.reference import config_path, paper_table1
from antisync.plan.config import load_config
from antisync.report.figures import _plt, write_file_report
from antisync.report.measures import plot_fig7e
from antisync.report.sweep import write_sweep_report
from antisync.store import git_revision, is_complete, is_sweep_file, records
from antisync.sweeps import load_sweep, run_sweep
from antisync.sweeps.analysis import edge_lambdas, ranking
from antisync.sweeps.results import sweep_summary

__all__ = ["CAPTIONS", "STEPS", "Step", "make_paper", "plan"]


@dataclass(frozen=True)
class Step:
    """One experiment of the paper run.

    ``fixed_s`` and ``per_realization_s`` are measured CPU seconds on one core (screening and
    set-up, and per main-stage realization); ``top_per_realization_s`` per top-stage one.
    """

    name: str
    kind: str  # "run" or "sweep"
    config: str
    overrides: tuple
    realizations: int
    fixed_s: float
    per_realization_s: float
    top_realizations: int = 0
    top_per_realization_s: float = 0.0
    figures: str = ""

    def scaled(self, scale: float) -> tuple[int, int]:
        return (
            max(10, int(round(self.realizations * scale))),
            max(10, int(round(self.top_realizations * scale))) if self.top_realizations else 0,
        )

    def cpu_seconds(self, scale: float = 1.0) -> float:
        m, t = self.scaled(scale)
        return self.fixed_s + self.per_realization_s * m + self.top_per_realization_s * t


# CPU seconds measured with one numba thread at dt = 0.001 (the lane driver of kernels/cpu.py):
# lollipop6 0.23 ms per integration (13 integrations per realization with betas=[]); the
# threshold sweep 0.31 s per realization (3 x 942 integrations: 109 tau0 + 833 orbit
# representatives per threshold) plus 21 s of screening and set-up; lollipops L=1, N=4..20:
# 0.345 s per realization with the 49-beta grid.
STEPS = (
    Step("lollipop6", "run", "lollipop6.yaml", (), 10_000, 2.0, 0.028, figures="Fig. 1"),
    Step(
        "lollipop6_raw",
        "run",
        "lollipop6.yaml",
        ("dynamics.coupling=raw", "name=lollipop6_raw"),
        10_000,
        2.0,
        0.015,
        figures="Fig. 7",
    ),
    # measures for Fig. 5: Lambda^(xi2), Lambda^(RW) and Lambda^(linear) (500 realizations);
    # they took 245 s wall on two cores, mostly on one, so they count twice in fixed_s
    Step(
        "threshold",
        "sweep",
        "threshold.yaml",
        ("top.graphs=7", "measures=[km, xi2, rw, linear]", "linear.realizations=500"),
        5_000,
        510.0,
        0.31,
        top_realizations=50_000,
        top_per_realization_s=0.003,
        figures="Figs. 3, 4, 5, 6, Table 1",
    ),
    # Fig. 2a shows 5 <= N <= 20 (Fig. 2b 4 <= N <= 20)
    Step(
        "lollipop_F",
        "sweep",
        "lollipop_L1.yaml",
        ("repeats=1", "name=lollipop_F", "sweep.nodes=5..20"),
        1_000,
        8.0,
        0.34,
        figures="Fig. 2a",
    ),
    # Fig. 2b with the orbit estimator (the derivative; the variance of the clique link's
    # Lambda drops by ~1e4 at N = 20) and RK4 at dt = 0.04 (the same values as Euler at
    # dt = 0.001 within errors, ten times faster): 10 repeats of 20,000 resolve Lambda > 0 at
    # every N by > 4 standard errors. 0.0026 CPU s per realization summed over N = 4..20.
    Step(
        "lollipop_lambda",
        "sweep",
        "lollipop_L1.yaml",
        (
            "repeats=10",
            "betas=[]",
            "name=lollipop_lambda",
            "lambda.method=orbit",
            "dynamics.integrator=rk4",
            "dynamics.dt=0.04",
        ),
        20_000,
        90.0,
        0.026,
        figures="Fig. 2b",
    ),
)

# What the paper's captions say (shortened), and the numbers it prints.
CAPTIONS = {
    "Fig. 1": "Antifragile response in a lollipop graph with N = 6 nodes. (a) The graph with edges "
    "coloured by Lambda^KM (dbeta = 0.01, 1e7 realizations). (b) <F_beta> against beta for "
    "all edges (1e6 realizations). (c)-(f) Histograms of (tau0, tau(beta)) at beta = 0.5 "
    "for 2->1, 5->6, 6->4 and 2->3 (1e9 realizations); dashed: tau(beta) = tau0. "
    "Text: <F_0.5> = 1.181 (2->1, most antifragile), 1.056 (5->6), 0.836 (2->3, most "
    "fragile); Lambda^KM(1->2) = 0.",
    "Fig. 2": "Antifragility in lollipop graphs with L = 1. (a) <F_beta> against beta, colour = N "
    "(5 <= N <= 20), 1e6 realizations per beta, step 0.02; <F_beta> > 1 throughout, more "
    "so for small graphs. (b) Lambda^KM against N (4 <= N <= 20) for the clique link not "
    "touching the bridge node: squares are the mean of 10 estimates of 1e7 realizations, "
    "error bars their standard deviation (~1e-4). Lambda^KM > 0 and decreases with N, "
    "steeply up to N ~ 15.",
    "Fig. 3": "Lambda^KM (dbeta = 0.01, 1e7 realizations) on every link of the 109 connected "
    "non-isomorphic graphs with N = 6 that synchronize (the 6-ring and the 5-ring plus "
    "one or two edges are excluded), sorted by the sum of their positive Lambda^KM. "
    "Graph 1 is the barbell (two triangles), 2 the lollipop of Fig. 1; graphs 2 and 8 "
    "are lollipops, 3 and 5 trees.",
    "Table 1": "<tau0>, the largest Lambda^KM and <F_0.5> on that link for the first seven graphs "
    "of Fig. 3 (1e9 realizations; Lambda from 1e7).",
    "Fig. 4": "Graphs 1 and 3-7 of Fig. 3 with the nodes a, b of their most antifragile link, and "
    "the histograms of (tau0, tau(0.5)) for damage on a->b: more pairs fall below the "
    "line tau(beta) = tau0.",
    "Fig. 5": "(a) Lambda^KM vs Lambda^linear, (b) Lambda^KM vs Lambda^(xi2), (c) Lambda^RW vs "
    "Lambda^KM, (d) Lambda^(xi2) vs Lambda^RW for the 109 graphs. (b): linear trend with "
    "sign disagreements only for |Lambda^KM| < 0.1.",
    "Fig. 6": "(a) Lambda^KM at r = 0.99 against Lambda^KM at r* = 0.9, 0.99, 0.999 (1e7 "
    "realizations): strongly linear, |Lambda^KM| grows as r -> 1. (b) Lambda^KM(r*) "
    "against Lambda^(xi2) with fits Lambda^KM = gamma Lambda^(xi2) + C, C ~ 0.003; inset: "
    "gamma grows with r*.",
    "Fig. 7": "Non-normalized coupling (Eq. 20) on the lollipop of Fig. 1: (a) edges coloured by "
    "Lambda^KM-NNC (1e7), (b) <F_beta> against beta (1e6), (c)-(d) histograms for 2->1 and "
    "2->3 at beta = 0.5, (e) Lambda^KM against Lambda^KM-NNC: Lambda^KM-NNC < Lambda^KM "
    "for every link except 3->4.",
}

# The paper's realizations (1e7 per Lambda, 1e6 per beta, 1e9 for Table 1 and the
# histograms), one command per experiment; CPU core-hours from the per-integration costs above.
PAPER_PRECISION = """\
# Fig. 1: Lambda^KM at 1e7 per edge (13 integrations per realization, ~8 core-hours),
# <F_beta> at 1e6 (121 per realization, ~8 core-hours), histograms at 1e9 (~580 core-hours)
antisync run configs/lollipop6.yaml --realizations 10000000 --set 'betas=[]' --backend cuda \\
    --out results/fig1_lambda.h5
antisync run configs/lollipop6.yaml --realizations 1000000 --backend cuda --out results/fig1_F.h5
antisync run configs/lollipop6.yaml --realizations 1000000000 --set 'betas=[0.5]' \\
    --set 'edges=["2->1", "5->6", "6->4", "2->3"]' --backend cuda --out results/fig1_hist.h5
# Fig. 7: the same three commands with --set dynamics.coupling=raw (about half the cost)
# Figs. 3-6, Table 1: 1e7 per edge at three thresholds (~860 core-hours), top stage at 1e9 (~830)
antisync sweep configs/threshold.yaml --realizations 10000000 --backend cuda \\
    --set top.graphs=7 --set top.realizations=1000000000 --set 'measures=[km, xi2, rw, linear]'
# Fig. 2a: 1e6 per beta (~95 core-hours); Fig. 2b: 10 x 1e7 (the paper's finite difference,
# ~430 core-hours; add --set lambda.method=orbit for the same derivative at ~1/1000 of that)
antisync sweep configs/lollipop_L1.yaml --realizations 1000000 --set repeats=1 --out results/lollipop_F.h5
antisync sweep configs/lollipop_L1.yaml --realizations 10000000 --set 'betas=[]' \\
    --out results/lollipop_lambda.h5
# on a Dask cluster instead of a GPU (docs/dask.md): replace --backend cuda by --scheduler tcp://HOST:8786
"""

# The paper's Table 1 graphs as networkx atlas indices, with their most antifragile link in
# our labels. 1, 2 and 4 are named by the text (the barbell; the lollipop of Fig. 1; "derived
# from the barbell graph by removing two directed links in one clique"); 3 and 5 are "the trees
# 3 and 5", the only trees whose <tau0> is within 0.2 of the printed ones (the path; a path of
# four with two leaves on one end); 6 ("a clique with three nodes with a structure with four
# nodes") and 7 ("a subgraph with four nodes densely connected to a linear graph with two
# nodes") are the only graphs of those shapes whose <tau0> and max Lambda^KM match
# (docs/sweeps.md, "Table 1: which graph is which"; tests/test_paper.py runs each).
TABLE1_ATLAS = {
    1: (130, "0->1"),
    2: (102, "0->5"),
    3: (83, "0->1"),
    4: (100, "0->1"),
    5: (81, "0->5"),
    6: (150, "0->5"),
    7: (103, "0->5"),
}

PAPER_TABLE1 = paper_table1()  # rank, <tau0>, Lambda^KM max, <F_0.5>: the shipped reference


def plan(scale: float = 1.0, cores: int = 2) -> str:
    """The realizations of every step and the estimated time on ``cores`` cores."""
    lines = [f"{'step':<16} {'realizations':>12} {'top':>8} {'CPU s':>8}  figures"]
    total = 0.0
    for s in STEPS:
        m, t = s.scaled(scale)
        cpu = s.cpu_seconds(scale)
        total += cpu
        lines.append(f"{s.name:<16} {m:>12,} {t or '-':>8} {cpu:>8.0f}  {s.figures}")
    lines.append(
        f"total {total:,.0f} CPU s: about {total / cores / 60:.0f} min on {cores} cores "
        "(plus about 2 min of figures), measured at 0.23 ms per lollipop6 integration"
    )
    return "\n".join(lines)


def make_paper(
    out: str | Path = "results/paper",
    *,
    scale: float = 1.0,
    overwrite: bool = False,
    threads: int | None = None,
    backend: str = "cpu",
    configs: str | Path | None = None,
    only: tuple = (),
    progress: bool | None = None,
    log=print,
) -> Path:
    """Run (or resume) every step and write the reports and ``README.md`` into ``out``.

    Parameters
    ----------
    scale : float
        Multiplies every step's realizations (1: 35 minutes on two cores, measured).
    overwrite : bool
        Start again; by default finished steps are kept and interrupted ones resumed.
    only : tuple of str
        Run only these steps (the README still lists every step that has a file).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # the shipped configs (package data), not the checkout's layout: works from a wheel too
    folder = Path(configs) if configs else Path(str(config_path("lollipop6"))).parent
    if not (folder / "lollipop6.yaml").exists():
        raise ConfigError(f"configs folder {folder} has no lollipop6.yaml; pass configs=")
    log(plan(scale))
    # minutes per step survive reruns: a step that was already finished keeps its first time
    timings_file = out / "timings.json"
    timings = {} if overwrite or not timings_file.exists() else json.loads(timings_file.read_text())
    for step in STEPS:
        if only and step.name not in only:
            continue
        m, t = step.scaled(scale)
        h5 = out / f"{step.name}.h5"
        overrides = list(step.overrides) + [f"realizations={m}", f"output={h5}", f"backend={backend}"]
        if threads:
            overrides.append(f"threads={threads}")
        if t:
            overrides.append(f"top.realizations={t}")
        finished = not overwrite and _finished(h5)
        start = time.perf_counter()
        log(f"== {step.name} ({step.figures}): {m:,} realizations" + (f", top {t:,}" if t else ""))
        if step.kind == "run":
            cfg = load_config(folder / step.config, overrides)
            run_config(cfg, resume=not overwrite, overwrite=overwrite, progress=progress, log=log)
            write_file_report(h5, out / step.name)
        else:
            sw = load_sweep(folder / step.config, overrides)
            run_sweep(sw, output=h5, resume=not overwrite, overwrite=overwrite, progress=progress, log=log)
            write_sweep_report(h5, out / step.name)
        seconds = time.perf_counter() - start
        log(f"   {step.name} done in {seconds / 60:.1f} min" + (" (already finished)" if finished else ""))
        if not finished:  # a finished step keeps its first time (or none, shown as "-")
            timings[step.name] = seconds
            timings_file.write_text(json.dumps(timings, indent=1))
    extra = _extra_figures(out)
    readme = out / "README.md"
    readme.write_text(_readme(out, scale, timings, extra))
    log(f"wrote {readme}")
    return readme


def _finished(h5: Path) -> bool:
    """Whether a step's file is complete (a sweep: every stage), so rerunning it only reports."""
    try:
        return is_complete(h5)
    except AntisyncError:  # missing or unreadable: the step runs (and reports the problem)
        return False


def _extra_figures(out: Path) -> dict:
    """Fig. 7e: Lambda^KM against Lambda^KM-NNC on the lollipop of Fig. 1, each with its 95%
    interval (:func:`antisync.report.measures.plot_fig7e`)."""
    plt = _plt()
    made = {}
    a, b = out / "lollipop6.h5", out / "lollipop6_raw.h5"
    if a.exists() and b.exists():
        km = {r["edge"]: r for r in records(a)}
        nnc = {r["edge"]: r for r in records(b)}
        # the raw-coupling run's Lambda^KM is the normalized one's Lambda^KM-NNC
        recs = [
            {
                **km[e],
                "lambda_km_nnc": nnc[e]["lambda_km"],
                "lambda_km_nnc_ci_low": nnc[e]["lambda_km_ci_low"],
                "lambda_km_nnc_ci_high": nnc[e]["lambda_km_ci_high"],
            }
            for e in km
            if e in nnc
        ]
        fig, ax = plt.subplots(figsize=(6.2, 5.8))
        plot_fig7e(recs, ax)
        ax.set_xlabel(r"$\Lambda^{(\mathrm{KM})}$ (normalized coupling)")
        ax.set_ylabel(r"$\Lambda^{(\mathrm{KM-NNC})}$ (non-normalized)")
        p = out / "fig7e_km_vs_nnc.png"
        fig.savefig(p, dpi=130, bbox_inches="tight")
        plt.close(fig)
        made["fig7e"] = p
    return made


def _paper_graphs(path: Path) -> list[str]:
    """The paper's identifiable Table 1 graphs against ours: rank, <tau0>, max Lambda, <F_0.5>.

    Values come from the top stage (more realizations) when the graph has a top job, else from
    the main stage. When our max Lambda differs from the paper's by more than 4 standard
    errors, the link of ours nearest to the paper's value is named.
    """
    if not path.exists():
        return []
    s = sweep_summary(path)
    if s["family"].get("family") != "atlas":  # TABLE1_ATLAS names graphs G<index>
        return []
    thr = s["ranking_threshold"]
    rows = {r["graph"]: r for r in ranking(s["records"], thr)}
    top = {t["graph"]: t for t in s["top"] if t.get("beta") == 0.5}
    lambdas = edge_lambdas(s["records"], thr)
    out = [
        "| paper graph | ours | our rank | <tau0> ours / paper | max Lambda_KM ours (link) / paper "
        "| <F_0.5> ours / paper |",
        "|:---|:---|---:|:---|:---|:---|",
    ]
    notes = []
    for number, (index, _) in TABLE1_ATLAS.items():
        _, t0, lam, f05 = PAPER_TABLE1[number - 1]
        graph = f"G{index}"
        if graph not in rows:
            continue
        r, t = rows[graph], top.get(graph)
        tau0, tau0_se = (t["tau0_mean"], t["tau0_se"]) if t else (r["tau0_mean"], r["tau0_se"])
        lmax, lmax_se = (t["lambda_km"], t["lambda_km_se"]) if t else (r["lambda_max"], r["lambda_max_se"])
        f = f"{t['F_mean']:.4f} ± {t['F_se']:.4f}" if t else "-"
        out.append(
            f"| {number} | {graph} | {r['rank']} | {tau0:.3f} ± {tau0_se:.3f} / "
            f"{t0} | {lmax:.3f} ± {lmax_se:.3f} ({r['max_edge']}) / {lam:.4g} | {f} / {f05} |"
        )
        if abs(lmax - lam) > 4 * lmax_se:
            (_, edge), v = min(
                ((k, v) for k, v in lambdas.items() if k[0] == graph),
                key=lambda kv: abs(kv[1]["lambda_km"] - lam),
            )
            off = abs(lmax - lam) / lmax_se
            notes.append(
                f"- Paper graph {number}: its max Lambda_KM {lam:.4g} is {off:.0f} "
                f"standard errors from ours on {r['max_edge']}; our link with the nearest value "
                f"is {edge} ({v['lambda_km']:.3f} ± {v['lambda_km_se']:.3f})."
            )
    return (
        [
            "The paper's seven graphs in our sweep (identified in docs/sweeps.md, \"Table 1: which "
            'graph is which"); values from the top stage when the graph is in our top seven. '
            "The ranking sums noisy positive parts, so at low realizations graphs with "
            "heavy-tailed estimates rise:",
            "",
        ]
        + out
        + [""]
        + (notes + [""] if notes else [])
    )


def _se_stats(path: Path) -> str:
    """Typical standard errors of a result file (median and 90th percentile over edges)."""
    recs = sweep_summary(path)["records"] if is_sweep_file(path) else records(path)
    lam = np.array([r["lambda_km_se"] for r in recs if r.get("lambda_km_se") is not None])
    f = np.array([r["F_se"] for r in recs if r.get("F_se") is not None])
    parts = []
    if lam.size:
        parts.append(f"SE(Lambda^KM) median {np.median(lam):.2g}, 90% {np.percentile(lam, 90):.2g}")
    if f.size:
        parts.append(f"SE(<F_beta>) median {np.median(f):.2g}, 90% {np.percentile(f, 90):.2g}")
    return "; ".join(parts)


def _img(out: Path, rel: str, width: int = 700) -> list[str]:
    """An image line for ``rel`` (a path or a glob under ``out``), or a note that it is missing."""
    hits = sorted(out.glob(rel))
    if not hits:
        return [f"*(not produced: {rel} missing)*", ""]
    return [f'<img src="{hits[0].relative_to(out).as_posix()}" width="{width}">', ""]


def _readme(out: Path, scale: float, timings: dict, extra: dict) -> str:
    lines = [
        "# The paper's figures and tables, at reduced realizations",
        "",
        f"Made by `antisync paper --scale {scale:g}` (antisync {__version__}, git "
        f"{git_revision() or 'unknown'}). Each section quotes what the paper's caption says, then "
        "shows ours. Realizations are far below the paper's (1e6-1e9), so compare within the "
        "standard errors given; docs/sweeps.md has the commands for paper precision.",
        "",
        "| step | realizations | figures | standard errors | minutes |",
        "|:---|---:|:---|:---|---:|",
    ]
    for s in STEPS:
        h5 = out / f"{s.name}.h5"
        if not h5.exists():
            continue
        m, t = s.scaled(scale)
        mins = f"{timings[s.name] / 60:.1f}" if s.name in timings else "-"
        lines.append(
            f"| {s.name} | {m:,}" + (f" (top {t:,})" if t else "") + f" | {s.figures} | "
            f"{_se_stats(h5)} | {mins} |"
        )
    lines.append("")

    def section(title: str, body: list[str]) -> None:
        key = title.split(":")[0]
        lines.extend([f"## {title}", "", f"> **Paper:** {CAPTIONS.get(key, '')}", ""] + body)

    # figures are named after the config's name:, e.g. lollipop6_graph.png
    body = _img(out, "lollipop6/*_graph.png", 520) + _img(out, "lollipop6/*_F_beta.png", 560)
    body += ["Histograms at beta = 0.5, every link (paper: (c) 2->1, (d) 5->6, (e) 6->4, (f) 2->3):", ""]
    body += _img(out, "lollipop6/*_histograms.png", 900)
    if (out / "lollipop6.h5").exists():
        recs = {(r["edge"], r["beta"]): r for r in records(out / "lollipop6.h5")}
        body += ["| edge | <F_0.5> ours | paper |", "|:---|---:|---:|"]
        for e, paper in (("2->1", 1.181), ("5->6", 1.056), ("2->3", 0.836)):
            r = recs.get((e, 0.5))
            if r:
                body.append(f"| {e} | {r['F_mean']:.4f} ± {r['F_se']:.4f} | {paper} |")
        r12 = next((r for (e, _), r in recs.items() if e == "1->2"), None)
        if r12:
            body.append(f"\nLambda^KM(1->2) = {r12['lambda_km']:+.4f} (paper: 0, W unchanged).")
        body.append("")
    section("Fig. 1: lollipop N = 6, L = 3", body)

    body = _img(out, "lollipop_F/fig2a_F_beta.png", 560) + _img(
        out, "lollipop_lambda/fig2b_lambda_N.png", 520
    )
    p = out / "lollipop_lambda" / "fig2b_lambda_N.md"
    if p.exists():
        body += [p.read_text(), ""]
    section("Fig. 2: lollipops with L = 1", body)

    body = _img(out, "threshold/fig3_ranking.png", 900)
    p = out / "threshold" / "index.md"
    if p.exists():
        body += ["Screening and symmetry (from threshold/index.md):", ""]
        text = p.read_text().split("## Files")[0].split("\n", 1)[1]  # drop title and file list
        body += [text.replace("## Excluded graphs", "Excluded graphs:").strip(), ""]
    section("Fig. 3: ranking of the six-node graphs", body)

    body = []
    p = out / "threshold" / "table1.md"
    if p.exists():
        body += [
            "Ours (r = 0.99):",
            "",
            p.read_text(),
            "",
            "Paper (graphs numbered by its Fig. 3 ranking, which our ranking need not repeat "
            "at these realizations):",
            "",
            "| rank | <tau0> | Lambda_KM (max) | <F_0.5> |",
            "|---:|---:|---:|---:|",
        ]
        body += [f"| {r} | {t0} | {lam:.4g} | {f} |" for r, t0, lam, f in PAPER_TABLE1]
        body += ["", "Also as [CSV](threshold/table1.csv) and [LaTeX](threshold/table1.tex).", ""]
        body += _paper_graphs(out / "threshold.h5")
    section("Table 1: the first seven graphs", body)
    section("Fig. 4: histograms for the top graphs", _img(out, "threshold/fig4_histograms.png", 640))
    body = _img(out, "threshold/fig5_measures.png", 700)
    section("Fig. 5: Lambda^KM against other measures", body)
    body = _img(out, "threshold/fig6a_thresholds.png", 520) + _img(out, "threshold/fig6b_xi2.png", 520)
    p = out / "threshold" / "fig6b_fits.md"
    body += [p.read_text(), ""] if p.exists() else ["*(Fig. 6b needs antisync.measures.spectral)*", ""]
    section("Fig. 6: thresholds", body)
    body = _img(out, "lollipop6_raw/*_graph.png", 520)
    body += _img(out, "lollipop6_raw/*_F_beta.png", 560)
    body += _img(out, "lollipop6_raw/*_histograms.png", 900)  # (c) 2->1, (d) 2->3 among them
    body += _img(out, "fig7e_km_vs_nnc.png", 480)
    section("Fig. 7: non-normalized coupling", body)
    lines += [
        "## Paper precision",
        "",
        "The same experiments at the paper's realizations (interrupted runs continue with "
        "`--resume`; docs/sweeps.md and docs/cuda.md say more):",
        "",
        "```",
        PAPER_PRECISION.rstrip(),
        "```",
        "",
    ]
    untimed = [s.name for s in STEPS if s.name not in timings]
    lines.append(
        f"\n_Total: {sum(timings.values()) / 60:.1f} min of computing and reports "
        "(each step timed when it ran"
        + (f"; no time recorded for {', '.join(untimed)}" if untimed else "")
        + ")._"
        if timings
        else ""
    )
    return "\n".join(lines) + "\n"
