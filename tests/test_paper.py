"""The paper's printed numbers for its lollipop (N=6, L=3), reproduced within 4 standard errors.

Values from ../shared/reference/paper_values.yaml (Sec. 3.1, 1e9 realizations in the paper).
"""

import pytest

from antisync_cli.config import load_config_text
from antisync_cli.runner import run_config
from antisync_cli.summary import records

Z = 4.0  # standard errors


@pytest.fixture(scope="module")
def lollipop_records(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper") / "lollipop.h5"
    cfg = load_config_text(f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
edges: ["2->1", "5->6", "2->3", "1->2"]
betas: [0.5]
realizations: 20000
seed: 2024
output: {out}
""")
    run_config(cfg, progress=False)
    return {r["edge"]: r for r in records(out)}


def test_mean_f_at_half_damage(lollipop_records, paper_values):
    for edge, value in paper_values["lollipop_6_3"]["mean_F_beta_0.5"].items():
        r = lollipop_records[edge]
        assert r["n"] >= 19_990
        assert abs(r["F_mean"] - value) < Z * r["F_se"], (edge, r["F_mean"], r["F_se"], value)


def test_mean_tau0(lollipop_records, paper_values):
    row = next(r for r in paper_values["table_1"]["rows"] if r[0] == 2)  # graph 2 = this lollipop
    r = lollipop_records["2->1"]
    assert abs(r["tau0_mean"] - row[1]) < Z * r["tau0_se"], (r["tau0_mean"], r["tau0_se"])


def test_degree_one_edge_is_exactly_neutral(lollipop_records, paper_values):
    for edge in paper_values["lollipop_6_3"]["lambda_km_zero"]:
        r = lollipop_records[edge]
        assert r["F_mean"] == 1.0 and r["F_se"] == 0.0
        assert r["lambda_km"] == 0.0


def test_signs_of_lambda(lollipop_records):
    assert lollipop_records["2->1"]["lambda_km"] > 0
    assert lollipop_records["2->3"]["lambda_km"] < 0


def test_table1_lambda_max_of_the_lollipop(lollipop_records, paper_values):
    """Table 1, graph 2: Lambda^KM of 2->1 (its most antifragile edge) with the default
    estimator (finite difference, dbeta = 0.01, as in the paper)."""
    row = next(r for r in paper_values["table_1"]["rows"] if r[0] == 2)
    r = lollipop_records["2->1"]
    assert r["lambda_method"] == "finite-difference" and r["lambda_dbeta"] == 0.01
    assert abs(r["lambda_km"] - row[2]) < Z * r["lambda_km_se"], (r["lambda_km"], r["lambda_km_se"])
    assert abs(r["F_mean"] - row[3]) < Z * r["F_se"]
