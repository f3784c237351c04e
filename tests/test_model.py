"""Graphs, coupling conventions and initial phases: structural invariants and closed forms."""

import networkx as nx
import numpy as np
import pytest

from antisync.physics import coupling, graphs
from antisync.physics.phases import initial_phases, phase


def test_lollipop_has_the_papers_labels(paper_values):
    g = graphs.lollipop(6, 3)
    expected = {tuple(sorted(e)) for e in paper_values["lollipop_6_3"]["edges"]}
    assert {tuple(sorted(e)) for e in g.edges} == expected


@pytest.mark.parametrize("n,path", [(4, 1), (6, 3), (20, 1), (7, 5)])
def test_lollipop_structure(n, path):
    g = graphs.lollipop(n, path)
    clique = n - path
    assert g.number_of_edges() == path + clique * (clique - 1) // 2
    assert g.degree[1] == 1  # node 1 is the free end of the stick
    assert nx.is_isomorphic(g, nx.lollipop_graph(clique, path))


def test_barbell_and_atlas():
    assert nx.is_isomorphic(graphs.barbell(3, 0), nx.barbell_graph(3, 0))
    assert sorted(graphs.barbell(3, 0).nodes) == list(range(1, 7))
    g = graphs.atlas(105)
    assert g.graph["name"] == "G105" and g.number_of_nodes() == 6


def test_edgelist_keeps_labels_and_weights(tmp_path):
    p = tmp_path / "g.edges"
    p.write_text("# weighted\na b 2.0\nb c\nc a 0.5\n")
    g = graphs.from_edgelist(p)
    assert set(g.nodes) == {"a", "b", "c"}
    omega = graphs.omega_matrix(g)
    assert omega[0, 1] == 2.0 and omega[0, 2] == 0.5 and omega[1, 2] == 1.0


@pytest.mark.parametrize(
    "text,match",
    [
        ("a b c d\n", "expected 'u v'"),
        ("a b x\n", "not a number"),
        ("a a\n", "self-loop"),
        ("# nothing\n", "no edges"),
    ],
)
def test_edgelist_errors(tmp_path, text, match):
    p = tmp_path / "bad.edges"
    p.write_text(text)
    with pytest.raises(graphs.GraphError, match=match):
        graphs.from_edgelist(p)


def test_disconnected_graph_is_rejected(tmp_path):
    p = tmp_path / "two.edges"
    p.write_text("1 2\n3 4\n")
    with pytest.raises(graphs.GraphError, match="disconnected"):
        graphs.build_graph({"kind": "edgelist", "path": str(p)})


def test_parse_edge():
    g = graphs.lollipop(6, 3)
    assert graphs.parse_edge("2->1", g) == (2, 1)
    with pytest.raises(graphs.GraphError, match="not in the graph"):
        graphs.parse_edge("1->3", g)
    with pytest.raises(graphs.GraphError, match="form 'a->b'"):
        graphs.parse_edge("1-2", g)
    assert len(graphs.all_directed_edges(g)) == 12


def test_damage_changes_row_a_only_eq4():
    """Eq. (4): w_aj = A_aj/(k_a - beta) for j != b, w_ab = (1-beta) A_ab/(k_a - beta)."""
    omega = graphs.omega_matrix(graphs.lollipop(6, 3))
    a, b, beta = 3, 4, 0.3  # link 4->5 in the paper's labels (node 4 has degree 3)
    w0 = coupling.coupling_matrix(omega)
    w = coupling.coupling_matrix(coupling.damaged_omega(omega, a, b, beta))
    changed = np.flatnonzero(np.any(w != w0, axis=1))
    assert changed.tolist() == [a]
    assert np.allclose(w.sum(axis=1), 1.0)
    assert w[a, b] == pytest.approx((1 - beta) / (3 - beta))
    assert w[a, 2] == pytest.approx(1 / (3 - beta))
    assert w[a, 5] == pytest.approx(1 / (3 - beta))


def test_damage_from_degree_one_node_changes_nothing():
    omega = graphs.omega_matrix(graphs.lollipop(6, 3))
    w0 = coupling.coupling_matrix(omega)
    w = coupling.coupling_matrix(coupling.damaged_omega(omega, 0, 1, 0.7))
    assert np.array_equal(w, w0)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_coupling_derivative_matches_finite_difference(kind):
    rng = np.random.default_rng(0)
    omega = graphs.omega_matrix(graphs.lollipop(7, 2)) * rng.uniform(0.5, 2.0, (7, 7))
    omega = (omega + omega.T) / 2
    for a, b in [(1, 2), (3, 4), (2, 1)]:
        if omega[a, b] == 0:
            continue
        for beta in (0.0, 0.4):
            h = 1e-6
            low = coupling.damaged_omega(omega, a, b, beta - h) if beta else omega
            fd = coupling.coupling_matrix(
                coupling.damaged_omega(omega, a, b, beta + h), kind
            ) - coupling.coupling_matrix(low, kind)
            fd /= 2 * h if beta else h
            exact = coupling.coupling_derivative(omega, a, b, kind, beta)
            assert np.allclose(exact, fd, atol=1e-5 if beta == 0 else 1e-8)


def test_csr_roundtrip_and_variants():
    omega = graphs.omega_matrix(graphs.lollipop(6, 3))
    w = coupling.coupling_matrix(omega)
    csr = coupling.to_csr(w)
    dense = np.zeros_like(w)
    rows = np.repeat(np.arange(6), np.diff(csr.indptr))
    dense[rows, csr.indices] = csr.weights
    assert np.array_equal(dense, w)
    vw = coupling.variant_weights(omega, csr, [(1, 0, 0.5), (0, 1, 0.5)])
    assert np.array_equal(vw[1], csr.weights)  # 1->2 leaves W unchanged
    assert vw[0][csr.position(1, 0)] == pytest.approx(0.5 / 1.5)


def test_phases_are_counter_based():
    block = initial_phases(seed=5, first=0, count=50, n_nodes=7)
    again = initial_phases(seed=5, first=20, count=10, n_nodes=7)
    assert np.array_equal(block[20:30], again)  # chunking cannot change a realization
    assert block[3, 4] == phase(5, 3, 4)
    assert not np.array_equal(block, initial_phases(seed=6, first=0, count=50, n_nodes=7))


def test_phases_are_uniform():
    x = initial_phases(seed=11, first=0, count=40_000, n_nodes=5).ravel() / (2 * np.pi)
    assert x.min() >= 0.0 and x.max() < 1.0
    counts = np.histogram(x, bins=20, range=(0, 1))[0]
    expected = x.size / 20
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert chi2 < 45.3  # 99.99% quantile of chi-square with 19 degrees of freedom
    # neighbouring nodes and realizations are uncorrelated
    y = initial_phases(seed=11, first=0, count=40_000, n_nodes=2)
    assert abs(np.corrcoef(y[:, 0], y[:, 1])[0, 1]) < 0.02
