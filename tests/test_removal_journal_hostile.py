"""Hostile input to the removal journal, the merging of parts and line_removal's client (issue 41):
a task file of another run, damaged task files, odd journal folders, malformed or foreign parts,
the documented merge script, and a scheduler address where a Client belongs. Each is refused in
one line or redone; nothing foreign is ever merged."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import HANG_GUARD_S, assert_one_line
from test_grid_dynamic import ring_config
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.grids import removal
from antisync.grids.errors import GridError
from antisync.grids.removal import line_removal
from antisync.grids.removal_file import table_document
from antisync.grids.removal_journal import RemovalJournal, journal_folder
from antisync.report.removal import merge_docs, removal_doc

ROOT = Path(__file__).resolve().parent.parent
ARRAYS = ("status0", "tau0", "status", "tau")
runner = CliRunner()


@pytest.fixture
def small_chunks(monkeypatch):
    """Tasks of 4 realizations and every line: a run of 12 realizations is 3 tasks, each saved
    on its own."""
    monkeypatch.setattr(removal, "CHUNK", 4)
    monkeypatch.setattr(removal, "LINES_PER_TASK", 1000)


def _config(seed: int = 11) -> dict:
    return {**ring_config(realizations=12), "seed": seed}


class _StopAfter:
    """A ``log`` that interrupts the run (as Ctrl-C would) after ``n`` progress messages."""

    def __init__(self, n: int):
        self.n, self.seen = n, 0

    def __call__(self, message: str) -> None:
        self.seen += 1
        if self.seen >= self.n:
            raise KeyboardInterrupt


def _interrupted(cfg, journal: Path, after: int = 1) -> list[Path]:
    """Run ``cfg`` into ``journal`` and stop it after ``after`` tasks; the task files left."""
    with pytest.raises(KeyboardInterrupt):
        line_removal(cfg, journal=journal, log=_StopAfter(after))
    return sorted(journal.glob("task_*.npz"))


def _assert_same(got, want) -> None:
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    assert got.rows == want.rows


# --- 1. a task file of another run is never merged -----------------------------------------------


def test_task_files_of_another_seed_in_the_journal_are_redone_not_merged(tmp_path, small_chunks):
    """Every task file of a run of seed 12 copied into the journal of a run of seed 11 (over the
    one task it had finished, and beside it): the resumed table is seed 11's, array for array."""
    clean = line_removal(_config(11))
    theirs = tmp_path / "seed12.partial"
    line_removal(_config(12), journal=theirs)  # a whole run: every task file is there
    foreign = sorted(theirs.glob("task_*.npz"))
    assert len(foreign) == 3
    mine = tmp_path / "seed11.partial"
    assert [p.name for p in _interrupted(_config(11), mine)] == [foreign[0].name]
    for p in foreign:
        shutil.copy(p, mine / p.name)
    seen = []
    _assert_same(line_removal(_config(11), journal=mine, log=seen.append), clean)
    assert not seen[0].startswith("resumed")  # nothing was read from the foreign files
    # what the journal holds now is seed 11's own work: a second resume reads it all, runs nothing
    seen = []
    _assert_same(line_removal(_config(11), journal=mine, log=seen.append), clean)
    assert seen == [f"resumed: {12 * 8} trajectories read from {mine}"]


def test_a_key_file_edited_to_match_does_not_let_another_runs_tasks_in(tmp_path, small_chunks):
    """Seed 12's journal with its key file replaced by seed 11's: the key now matches, the task
    files' tags do not, so seed 11's table is computed afresh."""
    clean = line_removal(_config(11))
    ours = tmp_path / "ours.partial"
    _interrupted(_config(11), ours)
    theirs = tmp_path / "theirs.partial"
    _interrupted(_config(12), theirs, after=3)
    shutil.copy(ours / RemovalJournal.KEY_FILE, theirs / RemovalJournal.KEY_FILE)
    _assert_same(line_removal(_config(11), journal=theirs), clean)


def test_a_per_node_file_edited_between_kill_and_resume_is_not_merged(tmp_path, small_chunks):
    """The key names a per-node file by path; its content changed after the kill: the old tasks
    (other frequencies) are redone, the table is the new file's."""
    (tmp_path / "p.txt").write_text("1\n-1\n0.5\n-0.5\n0.8\n-0.8\n")
    cfg = _config()
    cfg["model"] = {**cfg["model"], "frequencies": {"file": str(tmp_path / "p.txt")}}
    journal = tmp_path / "j.partial"
    _interrupted(cfg, journal, after=2)
    (tmp_path / "p.txt").write_text("0.5\n-0.5\n1\n-1\n0.3\n-0.3\n")
    _assert_same(line_removal(cfg, journal=journal), line_removal(cfg))


# --- 2. a damaged task file is redone ------------------------------------------------------------


def _truncate_half(p: Path) -> None:
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def _rewrite(p: Path, **changes) -> None:
    """Rewrite the task file ``p`` (its tag kept) with some arrays replaced."""
    with np.load(p) as f:
        arrays = dict(f)
    arrays.update({k: v(arrays) if callable(v) else v for k, v in changes.items()})
    with open(p, "wb") as fh:
        np.savez(fh, **arrays)


def _drop(p: Path, key: str) -> None:
    with np.load(p) as f:
        arrays = {k: v for k, v in f.items() if k != key}
    with open(p, "wb") as fh:
        np.savez(fh, **arrays)


DAMAGE = {
    "truncated to half": _truncate_half,
    "zero bytes": lambda p: p.write_bytes(b""),
    "not a zip": lambda p: p.write_text("hello"),
    "negative realizations": lambda p: _rewrite(p, ks=lambda a: -1 - a["ks"]),
    "realizations out of range": lambda p: _rewrite(p, ks=lambda a: a["ks"] + 100),
    "float line indices": lambda p: _rewrite(p, group=lambda a: a["group"].astype(float)),
    "status of the wrong shape": lambda p: _rewrite(p, status=lambda a: a["status"][:, :2]),
    "tau as strings": lambda p: _rewrite(p, tau=lambda a: a["tau"].astype(str)),
    "an array missing": lambda p: _drop(p, "tau0"),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_task_file_is_redone_on_resume(tmp_path, small_chunks, damage):
    whole = line_removal(_config())
    journal = tmp_path / "j.partial"
    first, second = _interrupted(_config(), journal, after=2)
    DAMAGE[damage](first)
    seen = []
    _assert_same(line_removal(_config(), journal=journal, log=seen.append), whole)
    assert seen[0] == f"resumed: {4 * 8} trajectories read from {journal}"  # the whole one only
    assert first.exists() and second.exists()  # the damaged one redone and saved again
    with np.load(first) as f:
        assert f["status"].shape == (4, 7)


def test_cli_resumes_a_journal_with_a_truncated_and_an_empty_task_file(tmp_path, small_chunks):
    cfg = tmp_path / "g.yaml"
    cfg.write_text(json.dumps(_config()))
    out = tmp_path / "r.json"
    journal = journal_folder(out)
    tasks = _interrupted(_config(), journal, after=3)
    _truncate_half(tasks[0])
    tasks[1].write_bytes(b"")
    res = runner.invoke(app, ["grid", str(cfg), "--removal", "--out", str(out), "--resume", "-q"])
    assert res.exit_code == 0, res.output
    assert not journal.exists()
    reference = table_document(line_removal(_config()))
    assert json.loads(out.read_text())["rows"] == json.loads(json.dumps(reference["rows"]))


# --- odd journal folders ---------------------------------------------------------------------------


def test_odd_journal_folders_are_refused_in_one_line_or_work(tmp_path, small_chunks):
    whole = line_removal(_config())
    # an empty folder: a fresh journal
    empty = tmp_path / "empty.partial"
    empty.mkdir()
    _assert_same(line_removal(_config(), journal=empty), whole)
    # a file where the folder belongs
    a_file = tmp_path / "file.partial"
    a_file.write_text("mine")
    with pytest.raises(GridError, match="is a file, not a removal journal") as exc:
        line_removal(_config(), journal=a_file)
    assert "\n" not in str(exc.value) and a_file.read_text() == "mine"
    # a folder of someone else's files
    other = tmp_path / "other.partial"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(GridError, match="is not a removal journal; move it away"):
        line_removal(_config(), journal=other)
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]
    # a key file that is not JSON: the work is unknown, nothing is deleted
    broken = tmp_path / "broken.partial"
    tasks = _interrupted(_config(), broken)
    (broken / RemovalJournal.KEY_FILE).write_text("{not json")
    with pytest.raises(GridError, match="removal_key.json cannot be read") as exc:
        line_removal(_config(), journal=broken)
    assert "\n" not in str(exc.value) and all(p.exists() for p in tasks)
    # restart=True (--overwrite) discards it
    _assert_same(line_removal(_config(), journal=broken, restart=True), whole)
    # another run's journal names what differs
    with pytest.raises(GridError, match=r"another removal run \(config\.seed: 11 -> 12\)"):
        line_removal(_config(12), journal=broken)
    # a folder named like a task file: left alone, the run goes on
    odd = tmp_path / "odd.partial"
    _interrupted(_config(), odd)
    (odd / "task_9_9_9_9.npz").mkdir()
    _assert_same(line_removal(_config(), journal=odd), whole)
    assert (odd / "task_9_9_9_9.npz").is_dir()


# --- 3. merging parts --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def parts():
    """Two parts of one run (disjoint lines) and a part of another seed."""
    cfg = ring_config(realizations=4)
    a = table_document(line_removal(cfg, lines=[(0, 1), (1, 2)]))
    b = table_document(line_removal(cfg, lines=[(2, 3), (3, 4)]))
    c = table_document(line_removal({**cfg, "seed": 12}, lines=[(4, 5)]))
    return a, b, c


def _without(doc: dict, *path) -> dict:
    doc = json.loads(json.dumps(doc))
    where = doc
    for key in path[:-1]:
        where = where[key]
    del where[path[-1]]
    return doc


def _with(doc: dict, value, *path) -> dict:
    doc = json.loads(json.dumps(doc))
    where = doc
    for key in path[:-1]:
        where = where[key]
    where[path[-1]] = value
    return doc


MALFORMED = [
    (lambda b: _without(b, "summary"), "part 2: not a whole removal table: no 'summary' mapping"),
    (lambda b: _with(b, [1, 2], "summary"), "'summary' is not a mapping"),
    (lambda b: _without(b, "summary", "seed"), "its summary lacks 'seed'"),
    (lambda b: _without(b, "summary", "seconds"), "its summary lacks 'seconds'"),
    (lambda b: _with(b, "11", "summary", "seed"), "summary.seed is '11', not an integer"),
    (lambda b: _without(b, "rows"), "no 'rows' list"),
    (lambda b: _with(b, {"a": 1}, "rows"), "'rows' is not a list"),
    (lambda b: _with(b, [5], "rows"), "row 1 is not a mapping"),
    (lambda b: _without(b, "rows", 0, "p_value"), "row 1 lacks 'p_value'"),
    (lambda b: _without(b, "rows", 1, "label"), "row 2 lacks 'label'"),
    (lambda b: _with(b, "3", "rows", 0, "lost"), "row 1's lost is '3', not a count"),
    (lambda b: _with(b, [2], "rows", 0, "line"), "row 1's line is [2], not two node labels"),
    (lambda b: _with(b, 5, "rows", 0, "n"), "row 2-3 has n = 5"),
    (lambda b: _with(b, -1.0, "rows", 0, "p_value"), "row 1's p_value is -1.0, not a p-value in [0, 1]"),
    (lambda b: _with(b, 5, "rows", 1, "gained"), "row 3-4 has lost + gained = "),
    (lambda b: _with(b, 9, "summary", "lines"), "summary.lines is 9 but it has 2 rows"),
    (lambda b: _with(b, "2-3", "sync_called"), "'sync_called' is not a list of line labels"),
    (lambda b: _with(b, "x", "config"), "'config' is not a mapping"),
    (lambda b: _with(b, "antisync-sweep", "format"), "format 'antisync-sweep' is not a removal table's"),
    (lambda b: 5, "part 2: expected a RemovalTable, its JSON file or that file's mapping, got int"),
]


@pytest.mark.parametrize(("damage", "message"), MALFORMED)
def test_a_malformed_part_is_refused_in_one_line_naming_the_part_and_the_key(parts, damage, message):
    a, b, _ = parts
    with pytest.raises(GridError) as exc:
        merge_docs([a, damage(b)])
    text = str(exc.value)
    assert message in text and "\n" not in text, text


def test_malformed_part_files_are_refused_in_one_line_naming_the_file(tmp_path, parts):
    a, b, _ = parts
    first = tmp_path / "a.json"
    first.write_text(json.dumps(a))
    files = {
        "notjson.json": ("{oops", "cannot read the removal table"),
        "list.json": ("[1, 2]", "not a removal table"),
        "nosummary.json": (json.dumps(_without(b, "summary")), "no 'summary' mapping"),
        "binary.json": (b"\xff\xfe\x00", "cannot read the removal table"),
    }
    for name, (content, message) in files.items():
        path = tmp_path / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        with pytest.raises(GridError) as exc:
            merge_docs([first, path])
        text = str(exc.value)
        assert text.startswith(f"part 2 ({path}): ") and message in text and "\n" not in text, text
    with pytest.raises(GridError, match="does not exist|No such file"):
        merge_docs([first, tmp_path / "missing.json"])
    # removal_doc alone names the file
    with pytest.raises(GridError, match=f"{tmp_path / 'nosummary.json'}: not a whole removal table"):
        removal_doc(tmp_path / "nosummary.json")


def test_merge_docs_takes_a_list_of_parts(tmp_path, parts):
    a, _, _ = parts
    path = tmp_path / "a.json"
    path.write_text(json.dumps(a))
    for bad in (str(path), path, a, 5, []):
        with pytest.raises(GridError, match="list of parts|no removal table to merge"):
            merge_docs(bad)


def test_parts_of_another_seed_or_config_are_refused_naming_the_difference(parts):
    a, b, c = parts
    with pytest.raises(GridError, match=r"part 2 differs from part 1 in seed \(12 against 11\)"):
        merge_docs([a, c])
    for key, value in (("realizations", 8), ("beta", 0.5)):
        other = _with(c, 11, "summary", "seed")
        other = _with(other, value, "summary", key)
        for row in other["rows"]:
            row["n" if key == "realizations" else "beta"] = value
        with pytest.raises(GridError, match=rf"part 2 differs from part 1 in {key}"):
            merge_docs([a, other])
    # the summaries agree, the configs do not: the key that differs is named
    longer = _with(b, 99.0, "config", "dynamics", "t_max")
    with pytest.raises(GridError, match=r"another config than part 1 \(dynamics.t_max: 80.0 -> 99.0\)"):
        merge_docs([a, longer])
    assert merge_docs([a, b])["summary"]["lines"] == 4  # what belongs together still merges


def test_the_documented_merge_script_refuses_parts_of_different_seeds_in_one_line(tmp_path, parts):
    """docs/power_grids.md merges parts with ``python bench/grid_removal.py part1 part2 ...``:
    parts of another seed, or a malformed part, are one line and exit 2, no traceback."""
    a, b, c = parts
    paths = {}
    for name, doc in (("a", a), ("c", c), ("bad", _without(b, "summary"))):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(json.dumps(doc))
    script = str(ROOT / "bench" / "grid_removal.py")
    for second, message in (
        ("c", f"part 2 ({paths['c']}) differs from part 1 ({paths['a']}) in seed (12 against 11)"),
        ("bad", f"part 2 ({paths['bad']}): not a whole removal table: no 'summary' mapping"),
    ):
        res = subprocess.run(
            [sys.executable, script, str(paths["a"]), str(paths[second])],
            capture_output=True,
            text=True,
            timeout=HANG_GUARD_S,
        )
        assert res.returncode == 2, res.stderr
        assert "Traceback" not in res.stderr
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"grid_removal.py: error: {message}"), res.stderr


# --- 4. the Dask client argument ---------------------------------------------------------------------


@pytest.mark.parametrize("client", ["tcp://127.0.0.1:8786", 3, object()])
def test_a_client_that_is_not_a_distributed_client_is_refused_before_any_work(tmp_path, client):
    journal = tmp_path / "j.partial"
    with pytest.raises(GridError) as exc:
        line_removal(ring_config(4), client=client, journal=journal)
    text = str(exc.value)
    assert text.startswith("client must be a distributed.Client, got ") and "\n" not in text
    assert "open Client('tcp://...') yourself or use `antisync grid --scheduler`" in text
    assert not journal.exists()  # refused before anything was made


def test_a_closed_client_is_refused_in_one_line():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as cluster:
        client = Client(cluster, set_as_default=False)
        client.close()
        with pytest.raises(GridError, match="client is a distributed.Client that is closed"):
            line_removal(ring_config(4), client=client)


def test_the_cli_is_one_line_for_a_damaged_journal_it_cannot_read(tmp_path):
    cfg = tmp_path / "g.yaml"
    cfg.write_text(json.dumps(ring_config(4)))
    out = tmp_path / "r.json"
    journal_folder(out).write_text("not a folder")
    res = runner.invoke(app, ["grid", str(cfg), "--removal", "--out", str(out), "--resume"])
    assert_one_line(res, "is a file, not a removal journal")
