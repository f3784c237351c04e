"""One equation numbering: every "Eq. N" cited anywhere in the project is in docs/equations.md."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TABLE = REPO / "docs" / "equations.md"
# "Eq. 6", "Eqs. 20-22", "Eqs. 1, 4 and 20", "Eq. (17)", "Eqs. (9)-(12)"
CITATION = re.compile(r"\bEqs?\.\s*((?:\(?\d+\)?(?:\s*(?:-|–|,|and|to)\s*)?)+)")


def _cited(text: str) -> set[int]:
    numbers = set()
    for match in CITATION.finditer(text):
        spec = match.group(1)
        for a, b in re.findall(r"\(?(\d+)\)?\s*[-–]\s*\(?(\d+)\)?", spec):
            numbers.update(range(int(a), int(b) + 1))
        numbers.update(int(n) for n in re.findall(r"\d+", spec))
    return numbers


def _table() -> dict[int, str]:
    rows = re.findall(r"^\|\s*(\d+)\s*\|\s*([^|]+)\|", TABLE.read_text(), flags=re.M)
    return {int(n): label.strip() for n, label in rows}


def test_table_lists_the_papers_25_equations():
    assert sorted(_table()) == list(range(1, 26))


def test_parser_reads_ranges_and_lists():
    assert _cited("Eqs. 20-22 and Eq. (6); Eqs. (9)-(11), Eqs. 1, 4 and 20") == {
        1,
        4,
        6,
        9,
        10,
        11,
        20,
        21,
        22,
    }


def test_every_citation_is_in_the_table():
    table = _table()
    files = [
        p
        for folder in ("antisync", "docs", "configs", "bench", "tests")
        for p in (REPO / folder).rglob("*")
        if p.suffix in (".py", ".md", ".yaml") and "__pycache__" not in p.parts
    ]
    files += [REPO / "README.md"]
    bad = {}
    for p in files:
        if p.name in ("test_equations.py", "equations.md"):
            continue
        unknown = sorted(n for n in _cited(p.read_text(encoding="utf-8")) if n not in table)
        if unknown:
            bad[str(p.relative_to(REPO))] = unknown
    assert not bad, f"equation numbers not in docs/equations.md: {bad}"
