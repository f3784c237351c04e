"""Sign maps of one network under the paper's secant, the derivative and Lambda^tau (issue 28).

Reads two result files of the same config and seed: one run with ``lambda.method:
finite-difference`` (the forward secant of Eq. 17 and the forward Lambda^tau) and one with a
derivative estimator (``adjoint-hybrid``: the derivative d<F>/dbeta and Lambda^tau from
d tau0/d beta). Each quantity's signs are called as ``antisync summary`` calls them (false
discovery rate 0.05 over the file's links, :func:`antisync.stats.multiplicity.fdr_signs`); the script
prints how many links each calls antifragile and fragile and how many change their call
between quantities.

Usage::

    python bench/compare_quantities.py /tmp/karate/fd.h5 /tmp/karate/adh.h5
"""

from __future__ import annotations

import argparse

from antisync.api import summarize
from antisync.stats.multiplicity import fdr_signs


def calls(records: list[dict], key: str) -> dict[str, int]:
    """Every link's sign call of the quantity ``key`` (``lambda_km`` or ``lambda_tau``)."""
    as_km = [
        {
            "graph": r["graph"],
            "edge": r["edge"],
            "lambda_km": r.get(key),
            "lambda_km_ci_low": r.get(f"{key}_ci_low"),
            "lambda_km_ci_high": r.get(f"{key}_ci_high"),
            "lambda_km_ci_level": 0.95,
        }
        for r in records
    ]
    return {r["edge"]: s or 0 for r, s in zip(records, fdr_signs(as_km), strict=True)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("secant_file", help="a finite-difference run")
    ap.add_argument("derivative_file", help="the same config with a derivative estimator")
    args = ap.parse_args()
    fd = summarize(args.secant_file)["records"]
    dv = summarize(args.derivative_file)["records"]
    maps = {
        "forward secant (Eq. 17)": calls(fd, "lambda_km"),
        f"derivative ({dv[0]['lambda_method']})": calls(dv, "lambda_km"),
        "Lambda^tau, forward": calls(fd, "lambda_tau"),
        f"Lambda^tau ({dv[0]['lambda_method']})": calls(dv, "lambda_tau"),
    }
    links = sorted(set.intersection(*(set(m) for m in maps.values())))
    print(f"{len(links)} links; signs at false discovery rate 0.05 over each file's links")
    print(f"{'quantity':<34} {'antifragile':>11} {'fragile':>8} {'unresolved':>10}")
    for name, m in maps.items():
        vals = [m[e] for e in links]
        print(f"{name:<34} {vals.count(1):>11} {vals.count(-1):>8} {vals.count(0):>10}")
    names = list(maps)
    print(f"\n{'pair':<70} {'opposite':>8} {'one only':>8}")
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            opposite = sum(1 for e in links if maps[a][e] * maps[b][e] < 0)
            one = sum(1 for e in links if (maps[a][e] == 0) != (maps[b][e] == 0))
            print(f"{a + ' / ' + b:<70} {opposite:>8} {one:>8}")


if __name__ == "__main__":
    main()
