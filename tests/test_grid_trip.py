"""The engineer's N-1 (antisync/grids/trip.py): a line trip from the operating point, after a
fault, against an independent integration (scipy's Radau on the same swing equation, fault and
trip), the critical clearing time against an independent bisection, and the CLI's bad input."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.grids.errors import GridError
from antisync.grids.lines import grid_bridges, lines_of
from antisync.grids.load import load_grid_config
from antisync.grids.trip import critical_clearing, operating_point, read_contingencies, trip_lines

REPO = Path(__file__).resolve().parent.parent
IEEE14 = REPO / "configs" / "ieee14_grid.yaml"
DT = 0.005
T_MAX = 12.0
TOL = 1e-3


#: Radau's results by (grid, start, line, fault, share, window): each reference is integrated once and
#: shared by the tests and the methods that compare against it
_REFERENCES: dict = {}


def _reference(grid, line, t_clear, theta0, share=1.0, settle=False, t_max=T_MAX):
    """Radau (rtol 1e-10) on the dense swing equation: the fault (every line at bus a out)
    until ``t_clear``, then the grid without ``a-b`` (with ``share`` < 1: ``a-b`` at ``1 -
    share`` of its K) for ``t_max`` after the trip, sampled on a grid of DT. Settling is the
    frequency criterion with inertia (docs/models.md): every ``|theta_i' - mean|`` and every
    ``|g_i - mean g|``, ``g_i = (P_i + coupling_i) / D_i``, below TOL. Returns (settles, max
    |theta'|), or with ``settle`` the time after the trip from the first grid time past the
    last one out of the band."""
    arrays = (grid.p, grid.omega, grid.inertia, grid.damping, theta0)
    key = (tuple(np.asarray(a, dtype=float).tobytes() for a in arrays), tuple(line), t_clear, share, t_max)
    if key not in _REFERENCES:
        _REFERENCES[key] = _integrate_reference(grid, line, t_clear, theta0, share, t_max)
    settles, worst, settle_time = _REFERENCES[key]
    return settle_time if settle else (settles, worst)


def _integrate_reference(grid, line, t_clear, theta0, share, t_max):
    """:func:`_reference`'s integration: ``(settles, max |theta'|, time to settle)``."""
    a, b = line
    n = len(grid.labels)
    p = grid.p
    m = np.broadcast_to(np.asarray(grid.inertia, dtype=float), (n,))
    d = np.broadcast_to(np.asarray(grid.damping, dtype=float), (n,))
    second = m > 0
    fault = grid.omega.copy()
    fault[a, :] = fault[:, a] = 0.0
    post = grid.omega.copy()
    post[a, b] *= 1.0 - share
    post[b, a] *= 1.0 - share

    def rates(theta, nu, k):
        """The rates of ``theta`` and ``nu`` and ``g``, at the columns of ``theta`` and ``nu``
        (``(n,)`` or ``(n, times)``)."""
        diff = np.sin(theta[None, ...] - theta[:, None, ...])
        force = p.reshape((n,) + (1,) * (theta.ndim - 1)) + np.einsum("ij,ij...->i...", k, diff)
        shape = (n,) + (1,) * (theta.ndim - 1)
        sec, mm, dd = second.reshape(shape), m.reshape(shape), d.reshape(shape)
        dth = np.where(sec, nu, force / dd)
        dnu = np.where(sec, (force - dd * nu) / np.where(sec, mm, 1.0), 0.0)
        return dth, dnu, force / dd

    def rhs(k):
        return lambda t, y: np.concatenate(rates(y[:n], y[n:], k)[:2])

    end = t_clear + t_max
    times = np.arange(int(round(end / DT)) + 1) * DT
    y0 = np.concatenate([theta0, np.zeros(n)])
    segments = [(fault, 0.0, t_clear), (post, t_clear, end)] if t_clear > 0 else [(post, 0.0, end)]
    worst, last_out = 0.0, -1
    for k, t0, t1 in segments:
        grid_t = times[(times >= t0) & (times < t1)] if t1 < end else times[times >= t0]
        sol = solve_ivp(rhs(k), (t0, t1), y0, method="Radau", rtol=1e-10, atol=1e-10, dense_output=True)
        assert sol.success
        if grid_t.size:
            y = sol.sol(grid_t)
            dth, _, g = rates(y[:n], y[n:], k)
            worst = max(worst, float(np.max(np.abs(dth))))
            spread = np.maximum(
                np.max(np.abs(dth - dth.mean(axis=0)), axis=0), np.max(np.abs(g - g.mean(axis=0)), axis=0)
            )
            out = np.flatnonzero(spread >= TOL)
            if out.size:
                last_out = int(round(grid_t[out[-1]] / DT))
        y0 = sol.y[:, -1]
    return last_out < len(times) - 1, worst, max((last_out + 1) * DT - t_clear, 0.0)


def _reference_settle(grid, line, t_clear, theta0):
    """Radau's time to settle after the trip, on the grid of DT (the first grid time after the
    last one with a deviation at or above the band)."""
    return _reference(grid, line, t_clear, theta0, settle=True)


@pytest.fixture(scope="module")
def ieee14():
    grid = load_grid_config(IEEE14)
    lines = lines_of(grid.omega, grid.labels, None)
    bridges = grid_bridges(grid.omega)
    return grid, [line for line in lines if line not in bridges]


#: the integrators of a trip: RK4 at the step DT, Rodas4 under tight tolerances from it
METHODS = {"rk4": {}, "rodas4": {"integrator": "rodas4", "rtol": 1e-8, "atol": 1e-8}}


@pytest.mark.parametrize("method", list(METHODS))
def test_a_trip_after_a_fault_is_radau_s_integration(ieee14, method):
    """Settling verdicts identical and the maximum frequency deviation within 1e-4 of Radau's,
    for a short and a long fault on lines of IEEE 14 (some settle, some do not), by RK4 and by
    Rodas4 (whose maximum is over its steps' interpolants, Radau's over the grid of DT: the
    peaks between grid times are far below 1e-4 higher at DT)."""
    grid, lines = ieee14
    theta0 = operating_point(grid)
    picked = lines[::4]
    verdicts = []
    for t_clear in (0.1, 0.6):
        trips = trip_lines(
            grid, picked, t_clear=t_clear, t_max=T_MAX, dt=DT, tolerance=TOL, theta0=theta0, **METHODS[method]
        )
        for line, trip in zip(picked, trips, strict=True):
            settles, worst = _reference(grid, line, t_clear, theta0)
            assert trip.settles == settles, (line, t_clear)
            assert abs(trip.max_frequency - worst) < 1e-4, (line, t_clear, trip.max_frequency, worst)
            if settles:
                assert abs(trip.settle_time - _reference_settle(grid, line, t_clear, theta0)) <= 2 * DT
            verdicts.append(settles)
    assert any(verdicts) and not all(verdicts)  # both verdicts are compared


#: Radau's verdicts of IEEE 14's first line by fault duration (the scan test's, both methods)
_RADAU_VERDICTS: dict = {}


@pytest.mark.parametrize("method", list(METHODS))
def test_the_critical_clearing_time_is_an_independent_scan_s(ieee14, method):
    """The CCT by definition (the longest fault with every shorter scanned one survived), against
    Radau's verdicts on the same scan: every 0.05 s, then every 0.01 s in the first failing
    interval."""
    grid, lines = ieee14
    theta0 = operating_point(grid)
    line = lines[0]
    scan, tol, window = 0.05, 1e-2, 20.0
    cct, _ = critical_clearing(
        grid,
        [line],
        cct_max=1.5,
        cct_tol=tol,
        cct_scan=scan,
        t_max=window,
        dt=DT,
        tolerance=TOL,
        **METHODS[method],
    )

    def survives(t_clear):
        key = round(t_clear, 9)
        if key not in _RADAU_VERDICTS:  # shared by both methods
            _RADAU_VERDICTS[key] = _reference(grid, line, t_clear, theta0, t_max=window)[0]
        return _RADAU_VERDICTS[key]

    assert survives(1e-9)
    k = 1
    while survives(k * scan):
        k += 1
    lo = (k - 1) * scan
    while lo + tol < k * scan - 1e-9 and survives(lo + tol):
        lo += tol
    assert 0 < cct[0] < 1.5  # a real scan, not a clamp
    assert abs(cct[0] - lo) <= 1e-9, (cct, lo)


def test_the_critical_clearing_time_is_the_same_for_every_cct_max_and_every_shorter_fault_survives(ieee14):
    """IEEE 14 line 1-2 at the config's dt: the verdicts near the boundary switch more than once
    when the settling window counted from the fault's start (settles after a 0.766 s fault, not
    after 0.768, again after 0.7695), and a bisection landed on 0.7695 or 0.7666 by its first
    midpoint. The scan gives one CCT whatever --cct-max, and every fault below it settles."""
    grid, _ = ieee14
    index = {str(v): i for i, v in enumerate(grid.labels)}
    line = (index["1"], index["2"])
    kw = {"t_max": 20.0, "dt": 0.02, "tolerance": TOL}
    ccts = [critical_clearing(grid, [line], cct_max=top, **kw)[0][0] for top in (1.0, 5.0)]
    assert ccts[0] == ccts[1] and 0.7 < ccts[0] < 0.8
    below = np.concatenate([np.linspace(0.01, ccts[0], 40), ccts[0] - np.array([1e-4, 5e-4, 1e-3])])
    trips = trip_lines(grid, [line] * below.size, t_clear=below, **kw)
    assert all(t.settles for t in trips)
    (after,) = trip_lines(grid, [line], t_clear=ccts[0] + 1e-3, **kw)
    assert not after.settles


def test_t_max_is_the_window_after_the_trip(ieee14):
    """--t-max counts from the trip: line 4-5 cleared after a 4.575 s fault settles within the
    default 20 s after it (a window from the fault's start left it 15.4 s), and the time to
    settle is on the trip's clock: the same trip after a longer window settles at the same time."""
    grid, _ = ieee14
    index = {str(v): i for i, v in enumerate(grid.labels)}
    line = (index["4"], index["5"])
    kw = {"dt": 0.02, "tolerance": TOL, "t_clear": 4.575}
    (short,) = trip_lines(grid, [line], t_max=20.0, **kw)
    (long,) = trip_lines(grid, [line], t_max=40.0, **kw)
    assert short.settles and 0 < short.settle_time < 20.0
    assert abs(long.settle_time - short.settle_time) < 1e-9


def test_settling_with_inertia_needs_the_g_condition_too():
    """The trip's criterion is the frequency criterion with inertia: a window that ends where
    every ``|theta_i' - mean|`` is already in the band but some ``|g_i - mean g|`` is not
    (Radau says where: IEEE 14 at damping 0.5, underdamped, so ``g = theta' + theta''`` swings
    wider than ``theta'``) is not settled; a window past both settles when ``g`` enters."""
    grid = load_grid_config(IEEE14, ["model.damping=0.5"])
    theta0 = operating_point(grid)
    line, t_clear, n = (0, 1), 0.1, len(grid.labels)
    m = np.asarray(grid.inertia, dtype=float) * np.ones(n)
    d = np.asarray(grid.damping, dtype=float) * np.ones(n)
    fault = grid.omega.copy()
    fault[0, :] = fault[:, 0] = 0.0
    post = grid.omega.copy()
    post[0, 1] = post[1, 0] = 0.0

    def rhs(k):
        def f(t, y):
            force = grid.p + np.sum(k * np.sin(y[None, :n] - y[:n, None]), axis=1)
            return np.concatenate([y[n:], (force - d * y[n:]) / m])

        return f

    y0 = np.concatenate([theta0, np.zeros(n)])
    s1 = solve_ivp(rhs(fault), (0, t_clear), y0, method="Radau", rtol=1e-10, atol=1e-10)
    times = t_clear + np.arange(1, 8001) * 0.005
    s2 = solve_ivp(
        rhs(post), (t_clear, times[-1]), s1.y[:, -1], t_eval=times, method="Radau", rtol=1e-10, atol=1e-10
    )
    th = s2.y[n:]
    g = (grid.p[:, None] + np.sum(post[:, :, None] * np.sin(s2.y[None, :n] - s2.y[:n, None]), axis=1)) / d[
        :, None
    ]
    dev_th = np.max(np.abs(th - th.mean(axis=0)), axis=0)
    dev_g = np.max(np.abs(g - g.mean(axis=0)), axis=0)
    last_th, last_g = times[np.flatnonzero(dev_th >= TOL)[-1]], times[np.flatnonzero(dev_g >= TOL)[-1]]
    # g leaves the band later: a window ending where only g is out of it tells
    between = (times > last_th + 0.1) & (times < last_g)
    assert between.any()
    end = times[between][np.argmax(dev_g[between])]
    assert dev_g[times == end][0] > 1.2 * TOL
    for method in METHODS.values():
        kw = {"t_clear": t_clear, "dt": DT, "tolerance": TOL, "theta0": theta0, **method}
        (trip,) = trip_lines(grid, [line], t_max=end - t_clear, **kw)
        assert not trip.settles, method
        (trip,) = trip_lines(grid, [line], t_max=last_g - t_clear + 2.0, **kw)
        assert trip.settles and abs(trip.settle_time - (last_g - t_clear)) < 2 * 0.005, (trip, last_g)


def test_no_fault_trip_of_every_line_settles_where_the_post_trip_grid_locks(ieee14):
    grid, lines = ieee14
    trips = trip_lines(grid, lines, t_max=T_MAX, dt=DT, tolerance=TOL)
    for t in trips:
        assert t.t_clear == 0.0 and t.max_angle > 0
        if t.settles:
            assert t.post_locked and 0 <= t.settle_time <= T_MAX


def test_a_grid_without_an_operating_point_is_refused():
    grid = load_grid_config(IEEE14, ["model.frequencies=[40, -40, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]"])
    with pytest.raises(GridError, match="no operating point"):
        operating_point(grid)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--lines", "1-9"], "not a line of the grid"),
        (["--lines", "7-8"], "is a bridge"),
        (["--t-clear", "0"], "--t-clear must be a finite fault duration"),
        (["--t-clear", "inf"], "--t-clear must be a finite fault duration"),
        (["--t-max", "inf"], "--t-max must be a finite positive number"),
        (["--cct", "--cct-max", "inf"], "--cct-max"),
        (["--cct", "--cct-max", "0.0005"], "--cct-max must be a finite fault duration of at least 0.001 s"),
        (["--cct", "--cct-scan", "0.0001"], "--cct-scan must be in"),
        (["--set", "dynamics.dt=2.0"], "dynamics.dt = 2 is unstable for the second-order model"),
        (["--t-max", "1e300"], "steps of dynamics.dt = 0.02: at most 1e+07"),
        (["--t-clear", "1e300"], "a fault of 1e+300 s is 5e+301 steps"),
        (["--cct", "--cct-max", "1e300"], "the CCT scan would hold 1e+302 faults"),
        (["--cct", "--cct-max", "1e6", "--cct-scan", "1e5"], "choose --cct-scan in"),
        (["--set", "dynamics.integrator=euler"], "a line trip integrates by rk4 or rodas4"),
        (["--removal"], "--removal is not an option of --trip"),
        (["--beta", "0.5"], "--beta is not an option of --trip"),
        (["--realizations", "10"], "--realizations is not an option of --trip"),
        (["--seed", "3"], "--seed is not an option of --trip"),
        (["--top", "3"], "--top is not an option of --trip"),
        (["--islanding"], "--islanding is not an option of --trip"),
        (["--by", "psync"], "--by is not an option of --trip"),
        (["--cct-max", "2"], "--cct-max sets the critical clearing times' search: add --cct"),
        (["--cct-scan", "0.1"], "--cct-scan sets the critical clearing times' search: add --cct"),
        (["--set", "model.frequencies=[40, -40, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]"], "no operating point"),
        (["--contingencies", "missing.txt"], "cannot read it"),
        (["--contingencies", "{dir}/c.txt"], "line 2: expected 'label from to share'"),
        (["--contingencies", "{dir}/bus.txt"], "1-9 is not a line of the grid"),
        (["--contingencies", "{dir}/share.txt"], "the share must be a number in (0, 1]"),
        (["--contingencies", "{dir}/ok.txt", "--lines", "2-3"], "no contingency of the table is on a line"),
        (["--contingencies", "{dir}/ok.txt"], "--contingencies is for the line trips"),
    ],
)
def test_bad_trip_input_is_one_line_exit_2_and_touches_nothing(tmp_path, args, message):
    out = tmp_path / "t.json"
    old = '{"format": "antisync-trip"}'
    out.write_text(old)  # an earlier table, replaceable with --overwrite
    (tmp_path / "c.txt").write_text("# label from to share\nA 1 2\n")
    (tmp_path / "bus.txt").write_text("A 1 9 1\n")
    (tmp_path / "share.txt").write_text("A 1 2 0\n")
    (tmp_path / "ok.txt").write_text("A 1 2 1\n")
    args = [a.format(dir=tmp_path) for a in args]
    trip = [] if "--contingencies is for" in message else ["--trip", "--out", str(out), "--overwrite"]
    res = CliRunner().invoke(app, ["grid", str(IEEE14), *trip, *args])
    assert res.exit_code == 2, res.output
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert out.read_text() == old


def test_cli_trip_writes_its_table_and_figure(tmp_path):
    out = tmp_path / "t.json"
    res = CliRunner().invoke(
        app,
        [
            "grid",
            str(IEEE14),
            "--trip",
            "--lines",
            "1-2,2-3",
            "--t-clear",
            "0.1",
            "--cct",
            "--t-max",
            "10",
            "--set",
            f"dynamics.dt={DT}",
            "--out",
            str(out),
            "--figure",
            str(tmp_path / "t.png"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads(out.read_text())
    assert doc["format"] == "antisync-trip" and [r["line"] for r in doc["lines"]] == [["1", "2"], ["2", "3"]]
    assert all(0 <= r["cct"] <= 1.0 for r in doc["lines"])
    assert doc["integrator"] == "rk4" and doc["rtol"] is None
    again = CliRunner().invoke(app, ["grid", str(IEEE14), "--trip", "--out", str(out)])
    assert again.exit_code == 2 and "--overwrite" in again.output


def test_report_draws_a_trip_table_from_its_file_alone(tmp_path):
    """``antisync report T.json`` of a trip table: its figure from the network the table keeps
    (no config) and index.md with the table; a JSON file of another kind, and a trip table
    without its network, are one line and exit 2 with nothing written."""
    out = tmp_path / "t.json"
    args = ["grid", str(IEEE14), "--trip", "--lines", "1-2,2-3,4-5", "--t-clear", "0.1", "--cct"]
    res = CliRunner().invoke(app, [*args, "--t-max", "12", "--set", f"dynamics.dt={DT}", "--out", str(out)])
    assert res.exit_code == 0, res.output
    folder = tmp_path / "report"
    res = CliRunner().invoke(app, ["report", str(out), "--out", str(folder)])
    assert res.exit_code == 0, res.output
    name = json.loads(out.read_text())["grid"]
    assert (folder / f"{name}_trips.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    index = (folder / "index.md").read_text()
    assert "| 4-5 | yes |" in index and "| 2-3 | NO |" in index and "CCT (s)" in index
    other = tmp_path / "other.json"
    other.write_text('{"format": "something-else"}')
    doc = json.loads(out.read_text())
    del doc["network"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    for path, words in ((other, "not a table antisync report draws"), (old, "no 'network'")):
        res = CliRunner().invoke(app, ["report", str(path), "--out", str(tmp_path / "x")])
        assert res.exit_code == 2 and words in res.output and len(res.output.strip().splitlines()) == 1, (
            res.output
        )
    assert not (tmp_path / "x").exists()


def test_cli_trip_of_a_rodas4_config_is_rodas4_s_and_says_so(ieee14, tmp_path):
    """A config whose integrator is rodas4 (the stiff grids') trips by Rodas4 under its rtol and
    atol, the table records them, and the rows are :func:`trip_lines`' with the same settings;
    --resume of the finished table under RK4 names the integrator that differs."""
    grid, _ = ieee14
    out = tmp_path / "t.json"
    sets = [
        "--set",
        "dynamics.integrator=rodas4",
        "--set",
        "dynamics.rtol=1e-7",
        "--set",
        "dynamics.atol=1e-7",
    ]
    args = ["grid", str(IEEE14), "--trip", "--lines", "1-2,2-3", "--t-clear", "0.2", "--t-max", "10"]
    res = CliRunner().invoke(app, [*args, *sets, "--set", f"dynamics.dt={DT}", "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert (doc["integrator"], doc["rtol"], doc["atol"]) == ("rodas4", 1e-7, 1e-7)
    index = {str(v): i for i, v in enumerate(grid.labels)}
    lines = [(index["1"], index["2"]), (index["2"], index["3"])]
    kw = dict(t_clear=0.2, t_max=10.0, dt=DT, tolerance=TOL, integrator="rodas4", rtol=1e-7, atol=1e-7)
    for row, trip in zip(doc["lines"], trip_lines(grid, lines, **kw), strict=True):
        assert row["max_frequency"] == trip.max_frequency and row["settles"] == trip.settles
    again = CliRunner().invoke(app, [*args, "--set", f"dynamics.dt={DT}", "--out", str(out), "--resume"])
    assert again.exit_code == 2 and "integrator" in again.output, again.output


def test_a_contingency_table_trips_its_rows_and_a_circuit_keeps_the_rest_of_its_line(ieee14, tmp_path):
    """The rows of a contingency table (tools/grid_case.py writes the official one of
    ACTIVSg2000): a row that opens a whole line is that line's trip, bit for bit; one that
    opens one circuit of several (share 0.5) leaves the line at half its K, as Radau on that
    grid says; a row opening a whole bridge is skipped and listed, half of it is tripped."""
    from antisync.grids.trip import trip_report

    grid, lines = ieee14
    theta0 = operating_point(grid)
    (tmp_path / "c.txt").write_text(
        "# label from to share\nA 1 2 1\nB 1 2 0.5  # a circuit\nC 7 8 1\nD 7 8 0.5\n"
    )
    table = read_contingencies(tmp_path / "c.txt", grid)
    assert [(label, share) for label, _, share in table] == [("A", 1.0), ("B", 0.5), ("C", 1.0), ("D", 0.5)]
    kw = {"t_max": 20.0, "dt": DT, "tolerance": TOL}
    report = trip_report(grid, contingencies=table, **kw)
    assert report["contingencies"] and report["bridges_skipped"] == [["7", "8"]]
    rows = {r["label"]: r for r in report["lines"]}
    assert sorted(rows) == ["A", "B", "D"] and rows["B"]["share"] == 0.5
    (plain,) = trip_lines(grid, [lines[0]], theta0=theta0, **kw)
    assert plain.line == (1, 2)
    assert plain.settles  # within 20 s of the trip
    for key in ("settles", "settle_time", "max_frequency", "max_angle", "post_locked"):
        assert rows["A"][key] == getattr(plain, key)
    for label, line in (("B", lines[0]), ("D", (6, 7))):
        settles, worst = _reference(grid, line, 0.0, theta0, share=0.5, t_max=20.0)
        assert rows[label]["settles"] == settles and abs(rows[label]["max_frequency"] - worst) < 1e-4
    assert rows["B"]["max_frequency"] < rows["A"]["max_frequency"]  # half the line stays


def test_the_official_activsg2000_table_reads_as_lines_of_the_grid():
    """configs/activsg2000_grid_contingencies.txt: the case's 3,190 branch outages, each on a
    line of the converted grid, 947 of them one circuit of several (share below 1)."""
    grid = load_grid_config(REPO / "configs" / "activsg2000_grid.yaml")
    table = read_contingencies(REPO / "configs" / "activsg2000_grid_contingencies.txt", grid)
    shares = np.array([share for _, _, share in table])
    assert len(table) == 3190 and len({label for label, _, _ in table}) == 3190
    assert int((shares < 1).sum()) == 947 and shares.min() > 0


def test_trips_in_tasks_resume_from_their_journal_and_refuse_other_work(ieee14, tmp_path):
    """IEEE 14's 19 trips in tasks of 16 (two tasks) with critical clearing times: the journal's
    rows equal a run without one bit for bit; a run after a task file is lost redoes that task
    only (the other file is left as it was); a journal of other work is one line."""
    from antisync.grids.removal_journal import TripJournal
    from antisync.grids.trip import TRIPS_PER_TASK, trip_report

    grid, lines = ieee14
    assert len(lines) > TRIPS_PER_TASK  # more than one task
    kw = {
        "t_max": 6.0,
        "dt": DT,
        "tolerance": TOL,
        "cct": True,
        "cct_max": 0.5,
        "cct_tol": 0.05,
        "cct_scan": 0.1,
    }
    plain = _text(trip_report(grid, **kw))
    folder = tmp_path / "t.json.partial"
    assert _text(trip_report(grid, journal=folder, **kw)) == plain
    files = sorted(folder.glob("task_*.npz"))
    assert [f.name for f in files] == ["task_0_16.npz", f"task_16_{len(lines) - 16}.npz"]
    kept = files[0].stat().st_mtime_ns
    files[1].unlink()
    assert _text(trip_report(grid, journal=folder, **kw)) == plain
    assert files[0].stat().st_mtime_ns == kept and files[1].exists()
    # a journal of other work: refused before any integration, its files left as they are
    with pytest.raises(GridError, match=r"another trip run \(t_max: 6\.0 -> 7\.0\)"):
        trip_report(grid, journal=folder, **{**kw, "t_max": 7.0})
    assert sorted(folder.glob("task_*.npz")) == files
    # a task file tagged for another grid is dropped and its trips integrated again
    other = TripJournal(tmp_path / "other", {"x": 1})
    other.save(0, np.zeros((16, 6)))
    (tmp_path / "other" / "task_0_16.npz").replace(files[0])
    assert _text(trip_report(grid, journal=folder, **kw)) == plain  # its zeros were not merged


def _numbers(path) -> dict:
    """A trip table's file without what says where and when it ran (the command, the time, the
    config with its executor): the work and its results."""
    doc = json.loads(path.read_text())
    return {k: v for k, v in doc.items() if k not in ("command", "written", "config")}


def _text(report: dict) -> str:
    """A report as its JSON text (``nan`` rows compare equal)."""
    return json.dumps(report, sort_keys=True)


def test_cli_trip_on_dask_equals_the_local_run_and_resumes(tmp_path):
    """``--trip --workers 2`` (a LocalCluster) writes the local run's table; an interrupted run's
    journal (its first task kept) is finished by ``--resume``, which also leaves a finished
    table as it is."""
    from antisync.grids.trip import trip_report

    base = ["grid", str(IEEE14), "--trip", "--t-clear", "0.1", "--t-max", "6", "--set", f"dynamics.dt={DT}"]
    local, dask = tmp_path / "local.json", tmp_path / "dask.json"
    res = CliRunner().invoke(app, [*base, "--out", str(local)])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(app, [*base, "--workers", "2", "--out", str(dask)])
    assert res.exit_code == 0, res.output
    assert _numbers(dask) == _numbers(local)
    assert not (tmp_path / "dask.json.partial").exists()  # the journal goes with the table
    # an interrupted run: a journal holding the first task, no table yet
    grid = load_grid_config(IEEE14)
    part = tmp_path / "resumed.json.partial"
    trip_report(grid, t_clear=0.1, t_max=6.0, dt=DT, tolerance=TOL, journal=part)
    (part / f"task_16_{len(json.loads(local.read_text())['lines']) - 16}.npz").unlink()
    out = tmp_path / "resumed.json"
    again = CliRunner().invoke(app, [*base, "--out", str(out)])
    assert again.exit_code == 2 and "--resume" in again.output and not out.exists()
    res = CliRunner().invoke(app, [*base, "--out", str(out), "--resume"])
    assert res.exit_code == 0, res.output
    assert _numbers(out) == _numbers(local) and not part.exists()
    done = CliRunner().invoke(app, [*base, "--out", str(out), "--resume"])
    assert done.exit_code == 0 and "nothing to resume" in done.output
    # --resume on a finished table of other arguments: one line, the table left as it is
    kept = out.read_text()
    for other, says in (
        (["--t-max", "7"], "t_max: 6.0 -> 7.0"),
        (["--lines", "1-2"], "trips: 19 in the table, 1"),
    ):
        res = CliRunner().invoke(app, [*base, *other, "--out", str(out), "--resume"])
        assert res.exit_code == 2 and says in res.output and len(res.output.strip().splitlines()) == 1
        assert out.read_text() == kept


def test_rk4_checks_its_step_on_the_fault_s_transient():
    """IEEE 39 line 16-17 after a 1 s fault swings to ~337 rad/s: RK4 at the shipped dt = 0.0025
    advances a phase by 0.8 rad a step, so the trip is integrated again at dt / 2 and the peak's
    error estimated by step doubling; the estimate is within a factor 1.5 of the error against
    Rodas4 at rtol 1e-10, and at dt = 0.005 (error above 1%) the table says so."""
    from antisync.grids.trip import format_trips, trip_report

    grid = load_grid_config(REPO / "configs" / "ieee39_grid.yaml")
    kw = {"t_clear": 1.0, "t_max": 20.0, "tolerance": TOL}
    index = {str(v): i for i, v in enumerate(grid.labels)}
    line = (index["16"], index["17"])
    (exact,) = trip_lines(grid, [line], dt=0.0025, integrator="rodas4", rtol=1e-10, atol=1e-10, **kw)
    report = trip_report(grid, [(16, 17)], dt=0.0025, **kw)
    (row,) = report["lines"]
    error = abs(row["max_frequency"] - exact.max_frequency)
    assert 0.01 * exact.max_frequency > error > 0.001 * exact.max_frequency  # resolved to ~1%
    assert error / 1.5 < row["max_frequency_error"] < 1.5 * error
    assert "resolved worse than 1%" not in format_trips(report)
    coarse = trip_report(grid, [(16, 17)], dt=0.005, **kw)
    assert "resolved worse than 1% (worst: line 16-17" in format_trips(coarse)


def test_a_trip_table_is_strict_json_with_provenance_and_resume_compares_the_grid_s_data(tmp_path):
    """The trip table's JSON has no NaN token (a trip that does not settle: ``null``), records
    its format version, antisync's version, the command, the config, its clock and criterion;
    ``--resume`` of the finished table with other data (``model.damping``) is refused naming the
    grid's data, the table left as it is."""
    out = tmp_path / "t.json"
    base = ["grid", str(IEEE14), "--trip", "--lines", "1-2,4-5", "--t-max", "5", "--set", f"dynamics.dt={DT}"]
    res = CliRunner().invoke(app, [*base, "--out", str(out)])
    assert res.exit_code == 0, res.output
    text = out.read_text()
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert any(r["settle_time"] is None and not r["settles"] for r in doc["lines"])
    assert (
        doc["format_version"] == 2 and doc["version"] and isinstance(doc["command"], str) and doc["written"]
    )
    assert (
        doc["config"]["name"] == "ieee14_grid"
        and "from the trip" in doc["clock"]
        and "g_i" in doc["criterion"]
    )
    res = CliRunner().invoke(app, [*base, "--set", "model.damping=2.0", "--out", str(out), "--resume"])
    assert (
        res.exit_code == 2 and "the grid's data" in res.output and len(res.output.strip().splitlines()) == 1
    )
    assert out.read_text() == text


@pytest.mark.parametrize(
    ("damage", "says"),
    [
        (lambda d: d["lines"][0].update(cct="soon"), "row 1's cct is 'soon', not a number"),
        (lambda d: d["lines"][0].update(settles="yes"), "row 1's settles is 'yes', not true or false"),
        (lambda d: d["network"].update(inertia=[1.0]), "14 nodes but 1 inertia values"),
        (lambda d: d.update(format_version=99), "format_version 99 is not one this antisync reads"),
    ],
)
def test_report_refuses_a_damaged_trip_table_in_one_line_leaving_nothing(tmp_path, damage, says):
    out = tmp_path / "t.json"
    args = ["grid", str(IEEE14), "--trip", "--lines", "1-2", "--cct", "--cct-scan", "0.2", "--t-max", "5"]
    res = CliRunner().invoke(app, [*args, "--set", f"dynamics.dt={DT}", "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    damage(doc)
    out.write_text(json.dumps(doc))
    res = CliRunner().invoke(app, ["report", str(out)])
    assert res.exit_code == 2 and says in res.output and len(res.output.strip().splitlines()) == 1, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]


@pytest.mark.parametrize("method", list(METHODS))
def test_a_grid_without_inertia_trips_as_radau_says(method):
    """A first-order grid (no bus with inertia; a damping other than 1 is refused there, as
    every first-order model has none): the kernels take its injections and rows of K as the
    model kernels' first order does; verdicts, peaks within 1e-4 and settle times within two
    steps of Radau's on the dense equation. K and P halved stand for the damping 2 this test
    used to give (the same trajectories, twice as slow)."""
    grid = load_grid_config(IEEE14, ["model.inertia=0", "model.damping=1.0"])
    grid = dataclasses.replace(grid, omega=grid.omega / 2, p=grid.p / 2)
    theta0 = operating_point(grid)
    kw = {"t_max": T_MAX, "dt": DT, "tolerance": TOL, "theta0": theta0, **METHODS[method]}
    verdicts = []
    for line, t_clear in (((0, 1), 0.1), ((0, 1), 0.4), ((3, 4), 0.4)):
        (trip,) = trip_lines(grid, [line], t_clear=t_clear, **kw)
        settles, worst = _reference(grid, line, t_clear, theta0)
        assert trip.settles == settles and abs(trip.max_frequency - worst) < 1e-4, (line, t_clear)
        if settles:
            assert abs(trip.settle_time - _reference_settle(grid, line, t_clear, theta0)) <= 2 * DT
        verdicts.append(settles)
    assert any(verdicts) and not all(verdicts)


# -- the table's accuracy check ------------------------------------------------------------------


def _settles(grid, lines, faults, settings):
    from antisync.grids.trip import _integrate

    return np.isfinite(_integrate(grid, lines, np.asarray(faults, dtype=float), None, **settings)[0][:, 0])


def test_a_trip_table_checks_its_first_trips_at_a_finer_setting(ieee14):
    """Every trip table integrates its first trips again (RK4 at dt / 2, Rodas4 at its
    tolerances / 10) and keeps the record: IEEE 14 with RK4 at DT passes (settle times within
    1e-4 s, frequency peaks and largest angles within 1e-4 relative); Rodas4 at rtol = atol =
    1e-2 moves the settle times by tenths of a second and fails, a WARNING under the table
    naming the tolerances to use."""
    from antisync.grids.trip import format_trips, trip_report
    from antisync.grids.trip_check import TRIP_CHECK_TRIPS

    grid, lines = ieee14
    named = [(grid.labels[a], grid.labels[b]) for a, b in lines[:6]]
    fine = trip_report(grid, named, t_clear=0.2, t_max=20.0, dt=DT)
    check = fine["accuracy_check"]
    assert check["passed"] and check["starts"] == TRIP_CHECK_TRIPS and check["dt"] == DT
    assert check["lines"] == [f"{grid.labels[a]}-{grid.labels[b]}" for a, b in lines[:TRIP_CHECK_TRIPS]]
    assert check["changed"] == 0 and check["largest_dtau"] < 1e-4
    assert check["peak_change"] < 1e-4 and check["angle_change"] < 1e-4
    assert "Step checked: the first 4 trips again at dt / 2 = 0.0025: 0 changed verdict" in format_trips(fine)
    coarse = trip_report(
        grid, named, t_clear=0.2, t_max=20.0, dt=DT, integrator="rodas4", rtol=1e-2, atol=1e-2
    )
    check = coarse["accuracy_check"]
    assert not check["passed"] and check["jumped"] >= 2 and check["largest_dtau"] > 0.1, check
    assert check["rtol"] == 1e-2 and check["refine"] == 10.0
    text = format_trips(coarse)
    assert "WARNING: Tolerances checked: the first 4 trips again at rtol = 0.001, atol = 0.001" in text
    assert "run again at dynamics.rtol = 0.001, dynamics.atol = 0.001" in text
    json.dumps(coarse, allow_nan=False)  # the record is plain JSON


def test_the_cct_check_tests_the_scan_s_boundary_and_flags_a_wrong_cct(ieee14):
    """With --cct the check integrates the CCT (survived) and the first failing scanned fault
    (failed) of the lines with the shortest CCTs at the finer setting: at the table's own
    setting these verdicts hold by construction (here at the same step, for the lines whose CCT
    is below cct_max), and a CCT moved by 0.05 s above the true one is flagged, the line
    named."""
    from antisync.grids.trip import _integrate, critical_clearing, operating_point
    from antisync.grids.trip_check import boundary_sample, check_trips, first_failure

    # the boundary checked is the shortest CCTs' (below cct_max), else the table's first trips
    ccts = np.array([1.5, 0.4, 1.5, 0.2, 0.9, 0.4, 0.3])
    np.testing.assert_array_equal(boundary_sample(ccts, 1.5), [3, 6, 1, 5])
    np.testing.assert_array_equal(boundary_sample(np.full(6, 1.5), 1.5), [0, 1, 2, 3])

    grid, lines = ieee14
    spec = {"cct_max": 1.5, "cct_tol": 1e-3, "cct_scan": 0.01}
    theta0 = operating_point(grid)
    settings = {"t_max": T_MAX, "dt": DT, "tolerance": TOL, "theta0": theta0, "threads": None}
    settings.update(integrator="rk4", rtol=1e-6, atol=1e-6)
    cct, _ = critical_clearing(grid, lines, **spec, **{k: v for k, v in settings.items()})
    short = [e for e in range(len(lines)) if 0 < cct[e] < spec["cct_max"]][:4]
    assert len(short) >= 2, cct
    fails = [first_failure(cct[e], spec["cct_tol"], spec["cct_scan"], spec["cct_max"]) for e in short]
    assert all(cct[e] < f <= cct[e] + spec["cct_tol"] + 1e-12 for e, f in zip(short, fails, strict=True))
    picked = [lines[e] for e in short]
    np.testing.assert_array_equal(_settles(grid, picked, cct[short], settings), True)
    np.testing.assert_array_equal(_settles(grid, picked, fails, settings), False)
    values = np.full((len(short), 7), np.nan)
    values[:, :3] = _integrate(grid, picked, 0.0, None, **settings)[0]
    values[:, 4] = cct[short]
    shares = np.ones(len(short))
    record = check_trips(_integrate, grid, picked, 0.0, shares, values, settings, spec)
    assert record["passed"] and record["cct"]["changed"] == 0, record
    values[0, 4] += 0.05  # a CCT beyond the boundary: its fault fails at every setting
    record = check_trips(_integrate, grid, picked, 0.0, shares, values, settings, spec)
    a, b = picked[0]
    assert not record["passed"] and record["cct"]["moved_lines"] == [f"{grid.labels[a]}-{grid.labels[b]}"]


# -- the engineer's N-1 of a law (antisync grid --trip) -------------------------------------------

#: A six-bus ring with a chord, second order (tests/test_laws.py's removal ring), its injections
#: 1.6 times the removal's and its damping 0.5 so that its critical clearing times fall inside the
#: scan, two of them with a second window (the verdicts switch back).
RING_LINKS = [[i, (i + 1) % 6, 2.0] for i in range(6)] + [[0, 3, 1.0]]
RING_P = [1.0, -1.0, 0.5, -0.5, 0.8, -0.8]
STRESSED_P = [1.6 * p for p in RING_P]


def _ring(model: dict) -> dict:
    return {
        "name": "ring6",
        "graph": {"kind": "inline", "links": RING_LINKS},
        "model": model,
        "sync": {"criterion": "frequency", "tolerance": 1e-3},
        "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.02, "t_max": 80.0},
        "realizations": 24,
        "seed": 11,
    }


def test_a_laws_trip_is_the_builtin_models():
    """``antisync grid --trip --cct`` with the swing law on the stressed ring: every verdict, post-
    trip lock, critical clearing time and second window is the built-in model's, and the times,
    frequency peaks and angles agree to 1e-10 relative (measured 5e-12: the law's operating
    point, found by integration, is the built-in Newton state's to ~1e-12). The law's RK4 runs on
    its circle form, the built-in kernels' ``(cos, sin, nu)`` steps: from the same operating
    point the two tables agree to 1e-12 (measured 6e-14 on the times, 0 to 1.6e-15 on the
    peaks and angles)."""
    import antisync
    from antisync.grids.load import grid_from_config
    from antisync.grids.trip import LAW_CRITERION
    from antisync.plan.config import config_from_mapping

    builtin = {"frequencies": STRESSED_P, "inertia": 1.0, "damping": 0.5}
    swing = {"law": "swing", "params": {"P": STRESSED_P, "m": 1.0, "gamma": 0.5}}
    want = antisync.grid.trip(_ring(builtin), cct=True, cct_max=1.6, t_max=40.0, t_clear=0.3)
    got = antisync.grid.trip(_ring(swing), cct=True, cct_max=1.6, t_max=40.0, t_clear=0.3)
    assert got.table["law"] == "swing" and got.table["criterion"] == LAW_CRITERION
    cct = [r["cct"] for r in want.records]
    assert min(cct) < 1.6 and sum(r["cct_again"] is not None for r in want.records) == 2  # at the boundary
    for a, b in zip(got.records, want.records, strict=True):
        for key in ("line", "settles", "post_locked", "cct", "cct_again"):
            assert a[key] == b[key], (a["line"], key)
        for key in ("settle_time", "max_frequency", "max_angle"):
            assert a[key] == pytest.approx(b[key], rel=1e-10, abs=1e-12), (a["line"], key)
    assert got.table["accuracy_check"]["passed"]

    # the kernels alone, from the built-in operating point (the law's: the same turned by one angle)
    grids = [grid_from_config(config_from_mapping(_ring(m)), law=True) for m in (builtin, swing)]
    theta = operating_point(grids[0])
    y = operating_point(grids[1])
    np.testing.assert_allclose(y[:6] - y[0], theta - theta[0], atol=1e-9)
    assert np.abs(y[6:]).max() < 1e-9  # at rest
    lines = [(0, 3), (1, 2), (4, 5)]
    rows = [
        [
            [t.settle_time, t.max_frequency, t.max_angle]
            for t in trip_lines(g, lines, t_clear=0.3, t_max=40.0, dt=0.02, theta0=start)
        ]
        for g, start in zip(grids, (theta, np.concatenate([theta, np.zeros(6)])), strict=True)
    ]
    np.testing.assert_allclose(rows[1], rows[0], rtol=1e-12)


def test_a_laws_rodas4_trip_is_the_builtin_models():
    """The swing law's trip by Rodas4 (the stiff grids' integrator) on the stressed ring after a
    0.3 s fault, every line: every verdict and post-trip lock is the built-in Rodas4's, at rtol =
    atol = 1e-8 the frequency peaks and angles within 1e-7 relative and the times to settle
    within 1e-4 s (each controls its own error on its own coordinates: the steps differ), and
    the law's Rodas4 agrees with its RK4 as closely."""
    import antisync

    def table(model, integrator):
        cfg = _ring(model)
        cfg["dynamics"].update(
            integrator=integrator, **({"rtol": 1e-8, "atol": 1e-8} if integrator == "rodas4" else {})
        )
        return antisync.grid.trip(cfg, t_max=40.0, t_clear=0.3).records

    swing = {"law": "swing", "params": {"P": STRESSED_P, "m": 1.0, "gamma": 0.5}}
    want = table({"frequencies": STRESSED_P, "inertia": 1.0, "damping": 0.5}, "rodas4")
    for got in (table(swing, "rodas4"), table(swing, "rk4")):
        assert sum(r["settles"] for r in want) >= 5
        for a, b in zip(got, want, strict=True):
            assert (a["line"], a["settles"], a["post_locked"]) == (b["line"], b["settles"], b["post_locked"])
            assert a["settle_time"] == pytest.approx(b["settle_time"], abs=1e-4, nan_ok=True), a["line"]
            for key in ("max_frequency", "max_angle"):
                assert a[key] == pytest.approx(b[key], rel=1e-7), (a["line"], key)


def _stuart_landau_reference(omega, w, z0, line, t_clear, t_max, dt, tol):
    """An independent Stuart-Landau trip: ``z' = (1 + i omega - |z|^2) z + sum_k w_jk (z_k - z_j)``
    in complex numbers by scipy's DOP853 at ``rtol = atol = 1e-11`` (bus ``a``'s links at 0 until
    ``t_clear``, then the line out), read on the grid of ``dt``: ``(settles, max |phase'|,
    time to settle after the trip)`` where the phase's rate is ``Im(conj(z) z') / |z|^2`` and
    settling is every rate within ``tol`` of their mean from a grid time on."""
    a, b = line
    fault, post = w.copy(), w.copy()
    fault[a, :] = fault[:, a] = 0.0
    post[a, b] = post[b, a] = 0.0

    def rates(z, k):
        return (1 + 1j * omega[:, None] - np.abs(z) ** 2) * z + k @ z - k.sum(axis=1)[:, None] * z

    def rhs(k):
        def f(_t, y):
            z = y[:n] + 1j * y[n:]
            dz = rates(z[:, None], k)[:, 0]
            return np.concatenate([dz.real, dz.imag])

        return f

    n = omega.size
    end = t_clear + t_max
    times = np.arange(int(round(end / dt)) + 1) * dt
    y0 = np.concatenate([z0.real, z0.imag])
    worst, last_out = 0.0, -1
    for k, t0, t1 in ((fault, 0.0, t_clear), (post, t_clear, end)):
        grid_t = times[(times >= t0) & (times < t1)] if t1 < end else times[times >= t0]
        sol = solve_ivp(rhs(k), (t0, t1), y0, method="DOP853", rtol=1e-11, atol=1e-11, dense_output=True)
        assert sol.success
        y = sol.sol(grid_t)
        z = y[:n] + 1j * y[n:]
        rate = (np.conj(z) * rates(z, k)).imag / np.abs(z) ** 2
        worst = max(worst, float(np.abs(rate).max()))
        out = np.flatnonzero(np.abs(rate - rate.mean(axis=0)).max(axis=0) >= tol)
        if out.size:
            last_out = int(round(grid_t[out[-1]] / dt))
        y0 = sol.y[:, -1]
    return last_out < len(times) - 1, worst, max((last_out + 1) * dt - t_clear, 0.0)


def test_a_stuart_landau_trip_is_an_independent_integrations():
    """A law whose phase is no state (``atan2(y, x)``) and whose frequency is its phase's rate:
    Stuart-Landau oscillators on the ring with spread frequencies, each line tripped after a
    0.4 s fault at its first node (which then turns at its own frequency and amplitude). From
    the law's operating point, every verdict is that of an independent complex-valued DOP853
    integration, the frequency peak within 1e-4 of it (read on its grid of dt) and the time to
    settle within two steps."""
    from antisync.grids.load import grid_from_config
    from antisync.plan.config import config_from_mapping

    omegas = np.array([0.3, -0.3, 0.2, -0.2, 0.1, -0.1])
    cfg = _ring({"law": "stuart-landau", "params": {"omega": list(omegas)}})
    cfg["dynamics"]["dt"] = 0.01
    grid = grid_from_config(config_from_mapping(cfg), law=True)
    y0 = operating_point(grid)
    z0 = y0[:6] + 1j * y0[6:]
    lines = [(0, 3), (1, 2), (3, 4), (4, 5)]
    trips = trip_lines(grid, lines, t_clear=0.4, t_max=30.0, dt=0.01, tolerance=1e-3, theta0=y0)
    verdicts = []
    for line, trip in zip(lines, trips, strict=True):
        settles, worst, settle_time = _stuart_landau_reference(
            omegas, grid.omega, z0, line, 0.4, 30.0, 0.01, 1e-3
        )
        assert trip.settles == settles, line
        assert abs(trip.max_frequency - worst) < 1e-4, (line, trip.max_frequency, worst)
        if settles:
            assert abs(trip.settle_time - settle_time) <= 0.02, (line, trip.settle_time, settle_time)
        verdicts.append(settles)
    assert any(verdicts)


def test_cli_trip_of_a_law_writes_its_table_and_refuses_what_it_cannot_run(tmp_path):
    """``antisync grid CONFIG --trip`` with a law config writes the table (its law named) and
    finishes a ``--resume`` of it; a resume with other law values, Euler (which under-resolves
    the swing) and a parameter drawn per realization (no one operating point) are refused in
    one line, exit 2, before any integration, the table left as it is (the static indicators'
    refusal: its own test above)."""
    import yaml

    cfg = tmp_path / "ring.yaml"
    mapping = _ring({"law": "swing", "params": {"P": STRESSED_P, "m": 1.0, "gamma": 0.5}})
    cfg.write_text(yaml.safe_dump(mapping))
    out = tmp_path / "t.json"
    args = ["grid", str(cfg), "--trip", "--lines", "0-3,1-2", "--t-clear", "0.3", "--t-max", "40"]
    res = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["law"] == "swing" and [r["line"] for r in doc["lines"]] == [["0", "3"], ["1", "2"]]
    assert doc["config"]["model"]["law"]["name"] == "swing" and doc["integrator"] == "rk4"
    old = out.read_text()
    again = CliRunner().invoke(app, [*args, "--out", str(out), "--resume"])
    assert again.exit_code == 0 and "is complete" in again.output, again.output
    for extra, words in (
        (["--trip", "--resume", "--set", "model.params.gamma=0.6"], "the grid's data"),  # the law's values
        (["--trip", "--set", "dynamics.integrator=euler"], "a law's line trip integrates by rk4 or rodas4"),
        # a parameter drawn per realization: a trip has one operating point
        (
            ["--trip", "--set", "model.params.gamma={distribution: uniform, width: 0.2, mean: 0.5}"],
            "gamma drawn per realization; a line trip needs one operating point",
        ),
    ):
        replace = [] if "--resume" in extra else ["--overwrite"]
        res = CliRunner().invoke(app, [*args, *extra[1:], "--out", str(out), *replace])
        assert res.exit_code == 2 and words in res.output, (extra, res.output)
        assert "Traceback" not in res.output and len(res.output.strip().splitlines()) == 1
        assert out.read_text() == old


def test_a_laws_trip_reads_its_edge_parameters_on_the_grids_links(tmp_path, monkeypatch):
    """A law with a phase lag per link (an edge parameter read from a file, each link its own):
    every locked state the trip table looks for (the operating point, each tripped line's post-
    trip network) reads the lags in the order of the links it integrates, the tripped line kept
    in its place at weight 0 (a pattern without it would shift every later link's lag onto its
    neighbour's, silently)."""
    import yaml
    from test_laws import LINK_LAG

    import antisync
    from antisync.kernels import law_locked

    (tmp_path / "law.yaml").write_text(yaml.safe_dump(LINK_LAG))
    lag = {frozenset((u, v)): 0.05 * (k + 1) for k, (u, v, _) in enumerate(RING_LINKS)}
    (tmp_path / "lags.txt").write_text("".join(f"{min(e)} {max(e)} {a}\n" for e, a in lag.items()))
    cfg = _ring(
        {
            "law": str(tmp_path / "law.yaml"),
            "params": {"omega": [0.2, -0.2, 0.1, -0.1, 0.05, -0.05]},
            "edge_params": {"alpha": {"file": str(tmp_path / "lags.txt")}},
        }
    )
    calls, real = [], law_locked.locked_state

    def spy(law, values, edges, indptr, indices, weights, *, t_max):
        calls.append((edges.copy(), np.array(indptr), np.array(indices), np.array(weights)))
        return real(law, values, edges, indptr, indices, weights, t_max=t_max)

    monkeypatch.setattr(law_locked, "locked_state", spy)
    got = antisync.grid.trip(cfg, lines="0-3,1-2", t_clear=0.2, t_max=40.0)
    assert [r["line"] for r in got.records] == [["0", "3"], ["1", "2"]]
    assert all(r["settles"] and r["post_locked"] for r in got.records)
    out = []
    for edges, indptr, indices, weights in calls:
        rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
        want = [lag[frozenset((int(i), int(j)))] for i, j in zip(rows, indices, strict=True)]
        np.testing.assert_array_equal(edges[0], want)
        out.append({frozenset((int(rows[q]), int(indices[q]))) for q in np.flatnonzero(weights == 0)})
    assert out == [set(), {frozenset((0, 3))}, {frozenset((1, 2))}]
