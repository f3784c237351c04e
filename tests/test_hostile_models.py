"""Hostile input to the numbers of a config, the model:/sync:/stop: sections and the files a
config names: no value or file silently builds another model, none ends in a traceback.

Every refusal is one line on stderr, exit code 2, no traceback and no file in the output
folder (the habit of tests/test_hostile_input.py, extended to the keys and files added since).
"""

from __future__ import annotations

import json
import math
import os
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_one_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import AntisyncError, ConfigError
from antisync.execution.compute import FLOAT32_MARGIN, check_float32_threshold
from antisync.physics.graphs import build_graph, omega_matrix
from antisync.plan.config import load_config_text
from antisync.plan.model import Model, drawn_frequencies, node_frequencies, read_frequency_file
from antisync.validation import MAX_INPUT_BYTES, parse_integer, parse_number

runner = CliRunner()
G = "graph: {kind: lollipop, nodes: 6, path: 3}\n"
BODY = G + 'edges: ["2->1"]\nbetas: [0.5]\nrealizations: 20\n'
SMALL = BODY + "dynamics: {t_max: 60}\n"
BIG = 10**400  # a float key given 400 digits used to end in OverflowError
EPS32 = float(np.finfo(np.float32).eps)


def snapshot(folder: Path) -> dict:
    """Every path below ``folder`` with its size and mtime: 'no file touched' is equality."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) if p.is_file() else None
        for p in sorted(folder.rglob("*"))
        if not p.is_fifo()
    }


def refused_everywhere(folder: Path, cfg: Path, overrides=(), message: str = "") -> None:
    """``validate`` and ``run`` of ``cfg`` each print one line and exit 2; nothing is written."""
    sets = [a for o in overrides for a in ("--set", o)]
    before = snapshot(folder)
    assert_one_line(runner.invoke(app, ["validate", str(cfg), *sets]), message)
    assert_one_line(
        runner.invoke(app, ["run", str(cfg), *sets, "--out", str(folder / "o.h5"), "-q"]), message
    )
    assert snapshot(folder) == before


# ---- one number parser ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "value,expected",
    [
        (3, 3.0),
        (-2, -2.0),
        (0.25, 0.25),
        ("1e-3", 1e-3),  # YAML 1.1 reads it as a string
        ("1E3", 1000.0),
        ("-2.5e+2", -250.0),
        (".5", 0.5),
        ("1.", 1.0),
        (" 7 ", 7.0),
        (10**20, 1e20),
        (np.float64(0.1), 0.1),
        (np.float32(0.5), 0.5),
        (np.float16(2.0), 2.0),
        (np.int64(4), 4.0),
        (np.uint8(9), 9.0),
    ],
)
def test_number_parser_reads_every_spelling_of_a_number(value, expected):
    x = parse_number("dynamics.dt", value)
    assert type(x) is float and x == expected


@pytest.mark.parametrize(
    "value,hint",
    [
        (BIG, "(too large)"),
        (-BIG, "(too large)"),
        (True, ""),
        (False, ""),
        (np.bool_(True), ""),
        ("nan", ""),
        (".nan", ""),
        ("inf", ""),
        ("-.inf", ""),
        (math.nan, ""),
        (np.float32("inf"), ""),
        ("", ""),
        ("1,5", "decimal comma"),
        ("0x10", "decimal digits"),
        ("1_000", "decimal digits"),
        ("1:30", "decimal digits"),  # base 60 in YAML 1.1
        ("010", "leading zeros"),  # octal in YAML 1.1
        ("\u22121", "ASCII"),  # unicode minus
        ("1\u00a0", "ASCII"),  # non-breaking space
        ("\uff11", "ASCII"),  # fullwidth digit, which float() reads
        ("1.5x", ""),
        ("e3", ""),
        (None, ""),
        ([1.0], ""),
        ({"a": 1}, ""),
    ],
)
def test_number_parser_refuses_with_the_key(value, hint):
    with pytest.raises(ConfigError, match=r"^model\.inertia must be ") as err:
        parse_number("model.inertia", value)
    assert hint in str(err.value) and "\n" not in str(err.value)
    assert len(str(err.value)) < 200  # a 400-digit value is shortened


@pytest.mark.parametrize(
    "value,expected",
    [
        (7, 7),
        ("12", 12),
        ("1e6", 10**6),
        (2.0e3, 2000),
        (np.int32(5), 5),
        (np.float64(8.0), 8),
        (10**30, 10**30),
    ],
)
def test_integer_parser(value, expected):
    n = parse_integer("seed", value, 0, 10**40, "0..10**40")
    assert type(n) is int and n == expected


@pytest.mark.parametrize(
    "value", [3.7, "1e23", 1e23, True, np.bool_(False), "010", "1_000", "0x10", -1, None, "x"]
)
def test_integer_parser_refuses(value):
    with pytest.raises(ConfigError, match=r"^seed must be an integer in 0\.\.10\*\*40, got "):
        parse_integer("seed", value, 0, 10**40, "0..10**40")


# ---- every numeric key, old and new ---------------------------------------------------------
#: (override prefix, key, template): the template puts the value where the key lives
NUMERIC_KEYS = [
    ("dynamics.dt", "{v}"),
    ("dynamics.t_max", "{v}"),
    ("dynamics.threshold", "{v}"),
    ("lambda.dbeta", "{v}"),
    ("lambda.hybrid_cut", "{v}"),
    ("histogram.tau_max", "{v}"),
    ("histogram.bins", "{v}"),
    ("histogram.betas", "[{v}]"),
    ("betas", "[{v}]"),
    ("realizations", "{v}"),
    ("seed", "{v}"),
    ("keep_pairs", "{v}"),
    ("linear.realizations", "{v}"),
    ("model.phase_lag", "{v}"),
    ("model.inertia", "{v}"),
    ("model.damping", "{v}"),
    ("model.frequencies", "[{v}, 0, 0, 0, 0, 0]"),
    ("model.frequencies", "{{distribution: normal, sd: {v}}}"),
    ("model.frequencies", "{{distribution: normal, sd: 0.1, mean: {v}}}"),
    ("model.frequencies", "{{distribution: uniform, width: {v}}}"),
    ("sync.threshold", "{v}"),
    ("sync.fraction", "{v}"),
    ("sync.tolerance", "{v}"),
    ("stop.first_look", "{v}"),
    ("stop.tolerance", "{v}"),
    ("dynamics.precision", "{v}"),
]


def _overrides(key: str, template: str, text: str) -> list[str]:
    out = [f"{key}={template.format(v=text)}"]
    if key.startswith("stop."):
        out.insert(0, "stop.when=signs-resolved")
    if key == "sync.fraction":
        out.insert(0, "sync.criterion=relative")
    return out


@pytest.mark.parametrize("key,template", NUMERIC_KEYS)
def test_a_huge_integer_at_any_numeric_key_is_one_line(tmp_path, monkeypatch, key, template):
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL)
    name = key.split(".")[-1] if key != "model.frequencies" else "model.frequencies"
    refused_everywhere(tmp_path, cfg, _overrides(key, template, str(BIG)), name)


def _yaml_text(value) -> str:
    """A value as YAML flow text (strings double-quoted, so YAML cannot read them otherwise)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    if isinstance(value, list):
        return "[" + ", ".join(_yaml_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_yaml_text(v)}" for k, v in value.items()) + "}"
    return json.dumps(value) if isinstance(value, str) else str(value)


bad_numbers = st.one_of(
    st.integers(min_value=10**309, max_value=10**420),
    st.integers(min_value=-(10**420), max_value=-(10**309)),
    st.booleans(),
    st.sampled_from([math.nan, math.inf, -math.inf]),
    st.sampled_from(["1,5", "0x10", "1_000", "010", "1:30", "\u22120.5", "0.5\u00a0", "\uff15", "", "0.5x"]),
    st.lists(st.floats(0.1, 0.5), min_size=2, max_size=2),
    st.just({"a": 1}),
)


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(entry=st.sampled_from(NUMERIC_KEYS), value=bad_numbers)
def test_any_bad_number_at_any_key_is_one_line_and_writes_nothing(tmp_path_factory, entry, value):
    """Huge integers, bools, NaN/inf, numbers in another notation, lists, mappings: at every
    numeric key (old and new sections alike) ``validate`` and ``run`` print one line."""
    key, template = entry
    folder = tmp_path_factory.mktemp("bad")
    cfg = folder / "c.yaml"
    cfg.write_text(SMALL + f"output: {folder / 'results' / 'o.h5'}\n")
    refused_everywhere(folder, cfg, _overrides(key, template, _yaml_text(value)))


typed_values = st.one_of(
    st.sampled_from([np.float64(0.002), np.float32(0.002), np.int64(1), np.int32(2), 0.002, 1]),
    st.sampled_from([np.float64("nan"), np.bool_(True), np.float32("inf"), BIG, "1e-3", "2"]),
)


@settings(max_examples=50, deadline=None, derandomize=True)
@given(entry=st.sampled_from(NUMERIC_KEYS[:-1]), value=typed_values)
def test_typed_and_numpy_values_are_numbers_or_one_clear_error(entry, value):
    """A Python caller's values (numpy scalars included): a valid config whose numbers are
    plain Python numbers, or one line naming the key."""
    key, template = entry
    if "{v}" != template:  # only scalar keys take typed values here
        return
    values = {key: value}
    if key.startswith("stop."):
        values["stop.when"] = "signs-resolved"
    try:
        cfg = load_config_text(SMALL, values=values)
    except AntisyncError as exc:
        assert str(exc).startswith(key) or key in str(exc), str(exc)
        assert "\n" not in str(exc)
        return
    if key == "sync.threshold":  # another spelling of dynamics.threshold, moved there
        key = "dynamics.threshold"
    section, _, field = key.rpartition(".")
    holder = getattr(cfg, {"lambda": "lambda_"}.get(section, section)) if section else cfg
    got = getattr(holder, field)
    assert type(got) in (int, float), (key, value, type(got))
    assert got == float(value)


# ---- YAML's other number forms --------------------------------------------------------------
@pytest.mark.parametrize(
    "text,message",
    [
        ("seed: 010\n", "seed must be an integer"),  # YAML 1.1: octal 8
        ("seed: 0x10\n", "seed must be an integer"),  # YAML 1.1: 16
        ("realizations: 1_000\n", "realizations must be an integer"),
        ("dynamics:\n  t_max: 1:30\n", "dynamics.t_max must be a number, got '1:30'"),  # YAML 1.1: 90
        ("dynamics:\n  dt: 1,5\n", "decimal comma"),
        ("model:\n  phase_lag: \u22120.3\n", "model.phase_lag must be"),
        ("dynamics:\n  dt: 0.01\u00a0\n", "dynamics.dt must be"),
        ("model:\n  frequencies: [0.1, -0.1, 0, 0, 0, 0x1]\n", "model.frequencies must be"),
    ],
)
def test_yaml_numbers_in_another_notation_are_refused(tmp_path, monkeypatch, text, message):
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    base = G + 'edges: ["2->1"]\nbetas: [0.5]\n'
    cfg.write_text(base + text, encoding="utf-8")
    refused_everywhere(tmp_path, cfg, (), message)


def test_exponents_without_a_dot_are_numbers_everywhere():
    """``1e-3`` in ``model.frequencies`` was refused ('must be finite numbers, got '1e-3''),
    while ``betas`` read it: one parser reads it at every key, quoted or not."""
    cfg = load_config_text(SMALL + "model: {frequencies: [1e-3, -1e-3, 2E-3, 0, '-2e-3', 0]}\n")
    assert cfg.model.frequencies == (1e-3, -1e-3, 2e-3, 0.0, -2e-3, 0.0)
    cfg = load_config_text(SMALL, ["dynamics.dt=1e-3", "model.inertia=2E0", "sync.tolerance=1e-4"])
    assert (cfg.dynamics.dt, cfg.model.inertia, cfg.sync.tolerance) == (1e-3, 2.0, 1e-4)


# ---- stop.* needs stop.when -------------------------------------------------------------------
@pytest.mark.parametrize(
    "stop", ["{first_look: 100}", "{tolerance: 0.01}", "{when: never, first_look: 100}", "{first_look: auto}"]
)
def test_stop_keys_without_a_rule_are_one_line(tmp_path, monkeypatch, stop):
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL + f"stop: {stop}\n")
    refused_everywhere(tmp_path, cfg, (), "needs stop.when")


def test_stop_keys_with_a_rule_are_valid():
    cfg = load_config_text(SMALL + "stop: {when: signs-resolved, first_look: 10, tolerance: 0.01}\n")
    assert cfg.stop.first_look == 10 and cfg.stop.tolerance == 0.01


# ---- special and absurd files ------------------------------------------------------------------
def _invoke_with_deadline(args, fifo: Path | None, seconds: float = 120.0):
    """``runner.invoke`` in a thread; if it has not returned after ``seconds`` (blocked on a
    FIFO), open the FIFO for writing so that the reader gets EOF, and fail."""
    box = {}
    thread = threading.Thread(target=lambda: box.update(res=runner.invoke(app, args)), daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        if fifo is not None:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
            os.close(fd)
        thread.join(30)
        pytest.fail(f"antisync {args[0]} hung on {fifo}")
    return box["res"]


def _special(tmp_path: Path, kind: str) -> Path:
    if kind == "dev-zero":
        return Path("/dev/zero")
    if kind == "fifo":
        p = tmp_path / "pipe"
        os.mkfifo(p)
        return p
    if kind == "folder":
        p = tmp_path / "folder"
        p.mkdir()
        return p
    p = tmp_path / "huge.txt"  # sparse: MAX_INPUT_BYTES + 1 bytes that take no disk
    with open(p, "wb") as fh:
        fh.truncate(MAX_INPUT_BYTES + 1)
    return p


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
@pytest.mark.parametrize(
    "kind,message",
    [
        ("dev-zero", "is a character device"),
        ("fifo", "is a FIFO"),
        ("folder", "is a folder"),
        ("huge", "MiB"),
    ],
)
@pytest.mark.parametrize("role", ["edge list", "frequency file"])
def test_special_files_as_inputs_are_one_line(tmp_path, monkeypatch, kind, message, role):
    """/dev/zero used ~3 GB and ended in a MemoryError; a FIFO hung."""
    monkeypatch.chdir(tmp_path)
    special = _special(tmp_path, kind)
    if role == "edge list":
        text = f"graph: {{kind: edgelist, path: {special}}}\nrealizations: 20\n"
    else:
        text = SMALL + f"model: {{frequencies: {{file: {special}}}}}\n"
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    fifo = special if kind == "fifo" else None
    before = snapshot(tmp_path)
    assert_one_line(_invoke_with_deadline(["validate", str(cfg)], fifo), message)
    res = _invoke_with_deadline(["run", str(cfg), "--out", str(tmp_path / "o.h5"), "-q"], fifo)
    assert_one_line(res, message)
    assert snapshot(tmp_path) == before


# ---- frequency files ----------------------------------------------------------------------------
FREQS = [0.5, -0.25, 0.125, 0.0, -1.5e-3, 1.125]
PLAIN = "".join(f"{x!r}\n" for x in FREQS)


def _freq_config(tmp_path: Path, data: bytes) -> Path:
    (tmp_path / "p.txt").write_bytes(data)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL + "model: {frequencies: {file: p.txt}}\n")
    return cfg


@pytest.mark.parametrize(
    "data",
    [
        PLAIN.encode("utf-8-sig"),  # a byte-order mark
        PLAIN.encode("utf-16"),  # UTF-16 with its byte-order mark
        PLAIN.replace("\n", "\r\n").encode(),
        "".join(f"\t{x!r}  # node\n\n" for x in FREQS).encode(),
        "".join(f"\u00a0{x!r}\u00a0\n" for x in FREQS).encode(),  # non-breaking spaces around
        ("# P_i\n" + PLAIN.replace("0.125", "1.25e-1")).encode(),
    ],
)
def test_frequency_files_in_other_encodings_read_the_same_numbers(tmp_path, data):
    (tmp_path / "p.txt").write_bytes(data)
    values = node_frequencies(Model(frequencies={"file": str(tmp_path / "p.txt")}), 6)
    assert values.tolist() == FREQS


@pytest.mark.parametrize(
    "data,message",
    [
        (b"0.1 0.2\n" * 6, "p.txt:1: expected one number per line (one line per node), got 2 values"),
        (b"0.1,0.2,0.3,0.4,0.5,0.6\n", "p.txt:1: '0.1,0.2,0.3,0.4,0.5,0.6' is not a number"),
        (b"0.1\n0.2\n1,5\n0\n0\n0\n", "p.txt:3: '1,5' is not a number"),
        (b"0.1\n0x10\n0\n0\n0\n0\n", "p.txt:2: '0x10' is not a number"),
        (b"0.1\n1_000\n0\n0\n0\n0\n", "p.txt:2: '1_000' is not a number"),
        ("0.1\n\u22120.5\n0\n0\n0\n0\n".encode(), "p.txt:2:"),
        (b"0.1\n0.5abc\n0\n0\n0\n0\n", "p.txt:2: '0.5abc' is not a number"),
        (b"0.1\nnan\n0\n0\n0\n0\n", "p.txt:2: 'nan' is not a finite number"),
        (b"0.1\n1e308\n0\n0\n0\n0\n", "p.txt:2: '1e308' is not a finite number in"),
        (PLAIN.encode("utf-16-le"), "NUL characters"),  # UTF-16 without its mark
        (b"0.1\n0.\xe9\n", "is not UTF-8 text"),
        (b"0.1\n-0.1\n", "has 2 values; the graph has 6 nodes: give one number per line"),
    ],
)
def test_bad_frequency_files_are_one_line_naming_the_line(tmp_path, monkeypatch, data, message):
    monkeypatch.chdir(tmp_path)
    refused_everywhere(tmp_path, _freq_config(tmp_path, data), (), message)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(lines=st.lists(st.text(max_size=6), min_size=1, max_size=8))
def test_any_frequency_file_is_its_numbers_or_one_clear_error(tmp_path_factory, lines):
    path = tmp_path_factory.mktemp("freq") / "p.txt"
    path.write_text("\n".join(lines), encoding="utf-8")
    try:
        values = read_frequency_file(path)
    except AntisyncError as exc:
        assert "\n" not in str(exc)
        return
    # what was read is exactly what float() makes of the ASCII tokens, in order
    text = path.read_text(encoding="utf-8-sig")
    tokens = [t for line in text.splitlines() for t in line.split("#", 1)[0].split()]
    assert all(t.isascii() for t in tokens)
    assert values.tolist() == [float(t) for t in tokens]


# ---- edge lists ------------------------------------------------------------------------------------
EDGES = "1 2 0.5\n2 3 2\n3 4\n4 1 1.5e-1\n"


@pytest.mark.parametrize(
    "data",
    [
        EDGES.encode("utf-8-sig"),
        EDGES.encode("utf-16"),
        EDGES.replace(" ", "\t").encode(),
        EDGES.replace(" ", "\u00a0").encode(),
        EDGES.replace("\n", "\r\n").encode(),
        ("# a comment\n" + EDGES.replace("0.5", "5e-1")).encode(),
    ],
)
def test_edge_lists_in_other_encodings_build_the_same_graph(tmp_path, data):
    """A byte-order mark made node '\\ufeff1' apart from node 1 (another graph, silently)."""
    (tmp_path / "plain.edges").write_text(EDGES)
    (tmp_path / "g.edges").write_bytes(data)
    ref = build_graph({"kind": "edgelist", "path": str(tmp_path / "plain.edges")})
    g = build_graph({"kind": "edgelist", "path": str(tmp_path / "g.edges")})
    assert sorted(g.nodes) == sorted(ref.nodes) == [1, 2, 3, 4]
    assert np.array_equal(omega_matrix(g), omega_matrix(ref))


@pytest.mark.parametrize(
    "text,message",
    [
        ("1 2\n2 3\n01 3\n", "g.edges:3: node label '01' is the integer 1 written another way"),
        ("1 2\n+2 3\n", "node label '+2' is the integer 2"),
        ("1 2\n-0 1\n", "node label '-0' is the integer 0"),
        ("1 2\n2 1_0\n", "node label '1_0' is the integer 10"),
        ("1 2\n2 \u0663\n", "is the integer 3"),  # an Arabic-Indic digit
        ("1 2\n2 3.0\n", "node label '3.0' is a number but not an integer"),
        ("1, 2\n2, 3\n", "contains ','"),
        ("1 2 0x10\n", "weight '0x10' is not a number"),
        ("1 2 1_000\n", "weight '1_000' is not a number"),
        ("1 2 1,5\n", "weight '1,5' is not a number"),
        ("1 2 \u22121\n", "is not a number"),
        ("1 2 0.5 x\n", "expected 'u v' or 'u v weight'"),
        ("1 2 0.5x\n", "weight '0.5x' is not a number"),
        ("1\x002\n", "NUL characters"),
        ("1 2\x07\n", "control character U+0007"),
    ],
)
def test_edge_lists_that_would_build_another_graph_are_one_line(tmp_path, monkeypatch, text, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "g.edges").write_text(text, encoding="utf-8")
    cfg = tmp_path / "c.yaml"
    cfg.write_text("graph: {kind: edgelist, path: g.edges}\nrealizations: 20\n")
    refused_everywhere(tmp_path, cfg, (), message)


def test_edge_list_in_utf16_without_a_mark_is_one_line(tmp_path):
    (tmp_path / "g.edges").write_bytes(EDGES.encode("utf-16-le"))
    with pytest.raises(AntisyncError, match="NUL characters"):
        build_graph({"kind": "edgelist", "path": str(tmp_path / "g.edges")})


# ---- drawn frequencies -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "dist", [{"distribution": "normal", "sd": 0.1}, {"distribution": "uniform", "width": 0.2}]
)
@pytest.mark.parametrize("mean", [1e6, -3e12, 1e17])
def test_drawn_frequencies_keep_their_spread_whatever_the_mean(dist, mean):
    """``mean + sd z`` rounded the spread before the mean was removed (1e6 + 0.1 z keeps ten of
    z's digits, 1e17 + 0.1 z none). The rotating frame does not depend on the mean, so the
    frequencies are those of the small-mean draw, bit for bit."""
    ks = np.arange(200)
    small = drawn_frequencies(Model(frequencies={**dist, "mean": 0.0}), 3, ks, 6)
    large = drawn_frequencies(Model(frequencies={**dist, "mean": mean}), 3, ks, 6)
    assert np.array_equal(large, small)
    assert np.abs(small.mean(axis=1)).max() < 1e-15
    assert 0.05 < small.std() < 0.2


def test_a_run_with_a_large_mean_frequency_is_the_small_mean_run():
    from antisync.execution.compute import simulate_job
    from antisync.plan.jobs import make_job

    base = G + "betas: [0.5]\ndynamics: {t_max: 60, dt: 0.01}\nrealizations: 30\nmodel: {frequencies: "
    sims = [
        simulate_job(
            make_job(load_config_text(base + f"{{distribution: normal, sd: 0.3, mean: {m}}}}}\n")), 0, 30
        )
        for m in (0.0, 1e16)  # 1e16 + 0.3 z rounds to multiples of 2: no spread left
    ]
    assert np.array_equal(sims[0].steps0, sims[1].steps0)
    assert np.array_equal(sims[0].steps, sims[1].steps)


@pytest.mark.parametrize(
    "model",
    [
        "{frequencies: {distribution: normal, sd: 1e308}}",
        "{frequencies: {distribution: uniform, width: 1e300}}",
        "{frequencies: {distribution: normal, sd: 1, mean: 1e300}}",
        "{frequencies: [1e308, -1e308, 0, 0, 0, 0]}",
        "{frequencies: {distribution: normal, sd: -0.1}}",
    ],
)
def test_absurd_frequencies_are_refused_not_warned_about(tmp_path, monkeypatch, model):
    """``sd: 1e308`` printed numpy RuntimeWarnings (inf - inf) and ran on NaN frequencies."""
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL + f"model: {model}\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        refused_everywhere(tmp_path, cfg, (), "must be a number in")
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


# ---- second-order stability: NaN-safe, and no false alarm ---------------------------------------
@pytest.mark.parametrize("inertia", ["1e-110", "1e-200", "1e-320"])
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_an_inertia_too_small_to_integrate_is_one_line(tmp_path, monkeypatch, inertia, integrator):
    """``inertia: 1e-110`` with RK4: the growth overflowed to NaN, passed the check, and the run
    ended as 'nothing synchronized' with the frequency hint."""
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    dt = 0.001 if integrator == "euler" else 0.01
    cfg.write_text(
        BODY + f"model: {{inertia: {inertia}}}\ndynamics: {{integrator: {integrator}, dt: {dt}}}\n"
    )
    refused_everywhere(tmp_path, cfg, (), "model.inertia must be at least")


@pytest.mark.parametrize(
    "graph",
    [
        "{kind: lollipop, nodes: 6, path: 3}",
        "{kind: barbell, m1: 5, m2: 2}",
        "{kind: atlas, index: 105}",
        "{kind: networkx, generator: karate_club_graph}",
    ],
)
@pytest.mark.parametrize("damping", ["1e-6", "1e-10"])
def test_the_zero_eigenvalue_is_no_instability(tmp_path, graph, damping):
    """The Laplacian's zero computed as -1e-16 gave the rate +1e-16/damping and "amplifies a mode
    near synchrony by 1 per step" for a stable RK4 step of a lightly damped model."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(
        f"graph: {graph}\nbetas: []\nedges: all\nrealizations: 10\n"
        f"model: {{inertia: 1.0, damping: {damping}}}\ndynamics: {{integrator: rk4, dt: 0.01, t_max: 5}}\n"
    )
    res = runner.invoke(app, ["validate", str(cfg)])
    assert res.exit_code == 0, res.output


def test_an_unstable_step_names_the_largest_stable_dt(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(BODY + "model: {inertia: 1, damping: 0.01}\ndynamics: {dt: 0.01, t_max: 60}\n")
    res = runner.invoke(app, ["validate", str(cfg)])
    assert_one_line(res, "dynamics.dt must be below ~")
    bound = float(res.stderr.split("below ~")[1].split()[0])
    cfg.write_text(
        BODY + f"model: {{inertia: 1, damping: 0.01}}\ndynamics: {{dt: {bound * 0.99}, t_max: 60}}\n"
    )
    assert runner.invoke(app, ["validate", str(cfg)]).exit_code == 0


# ---- float32 thresholds ---------------------------------------------------------------------------
@pytest.mark.parametrize("n", [2, 6, 30, 100, 1000])
def test_float32_threshold_bound_on_both_sides(n):
    floor = FLOAT32_MARGIN * n * EPS32
    check_float32_threshold(1.0 - floor * 1.01, n)
    with pytest.raises(ConfigError, match="too close to 1 for dynamics.precision float32"):
        check_float32_threshold(1.0 - floor * 0.99, n)


@pytest.mark.parametrize(
    "graph,ok,refused",
    [
        ("{kind: lollipop, nodes: 6, path: 3}", 0.9999, 0.99999),  # bound 0.99993
        ("{kind: lollipop, nodes: 30, path: 3}", 0.9996, 0.9997),  # bound 0.999642
    ],
)
def test_float32_thresholds_it_cannot_resolve_are_one_line(tmp_path, monkeypatch, graph, ok, refused):
    """tau0 in float32 was 1% off at 0.999999 and 42% at 0.99999999999 (lollipop(6,3)), without
    a word. Both sides of the bound, through validate and run; nothing is written."""
    monkeypatch.chdir(tmp_path)
    cfg = tmp_path / "c.yaml"
    body = f"graph: {graph}\nedges: ['2->1']\nbetas: [0.5]\nrealizations: 20\n"
    cfg.write_text(body + f"dynamics: {{precision: float32, threshold: {refused}}}\n")
    refused_everywhere(tmp_path, cfg, (), "too close to 1 for dynamics.precision float32")
    cfg.write_text(body + f"dynamics: {{precision: float32, threshold: {ok}}}\n")
    res = runner.invoke(app, ["validate", str(cfg)])
    assert res.exit_code == 0, res.output
