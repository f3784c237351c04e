"""Small helpers shared by test modules (tests/ is on sys.path, see conftest.py)."""

import contextlib
import json

# How long a test waits for a process of its own before calling it hung. A hang guard, not a
# speed target: a fresh process may first compile every kernel (numba caches by source), and
# CI machines are slower and busier than a workstation (a simulator check that takes 11 s here
# once took over 240 s there).
HANG_GUARD_S = 1800


def comparable(summary: dict) -> dict:
    """The parts of a sweep summary that must be identical between two runs of one sweep
    (screening times and file paths left out), as plain JSON types."""
    out = {k: summary[k] for k in ("records", "top", "excluded", "symmetry", "complete")}
    out["screen"] = [{k: v for k, v in s.items() if k != "seconds"} for s in summary["screen"]]
    out["jobs"] = summary["meta"]["jobs"]
    return json.loads(json.dumps(out))


def assert_one_line(res, message: str = "") -> None:
    """A failed CLI command (typer's CliRunner result) printed one ``antisync: error:`` line
    containing ``message``, exit 2, no traceback."""
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert "Traceback" not in res.output, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
    assert message in lines[0], (message, lines[0])


def datasets(path, group: str = "/") -> dict:
    """Every dataset of the HDF5 file ``path`` below ``group``, by name, as arrays."""
    import h5py

    out = {}

    def keep(name, obj):
        if isinstance(obj, h5py.Dataset):
            out[name] = obj[...]

    with h5py.File(path, "r") as f:
        f[group].visititems(keep)
    return out


class CrashAfter:
    """A local executor that dies after ``n`` chunks, counted over every call of ``run`` (a
    sweep's stages, a stopping rule's looks): ``RuntimeError`` stands for a kill (nothing more
    is written), ``KeyboardInterrupt`` for Ctrl-C (the runner checkpoints first)."""

    def __init__(self, n: int, exc: type = RuntimeError):
        from antisync.execution.executors.local import LocalExecutor

        self.inner = LocalExecutor("cpu", None)
        self.left = n
        self.exc = exc

    def run(self, work):
        for item in self.inner.run(work):
            if self.left == 0:
                raise self.exc("killed")
            self.left -= 1
            yield item

    def describe(self):
        return "crashing"

    def close(self):
        pass


def sweep_cli(folder, name: str, text: str, *options: str):
    """Write the sweep config ``text`` to ``folder/name.yaml`` and run it with ``antisync
    sweep --out folder/name.h5 --quiet``; returns ``(config path, output path)``."""
    from typer.testing import CliRunner

    from antisync.cli.app import app

    cfg, out = folder / f"{name}.yaml", folder / f"{name}.h5"
    cfg.write_text(text)
    res = CliRunner().invoke(app, ["sweep", str(cfg), "--out", str(out), "--quiet", *options])
    assert res.exit_code == 0, res.output
    return cfg, out


@contextlib.contextmanager
def local_cluster_client(workers: int = 2):
    """A real Dask cluster for a test: ``workers`` single-threaded worker processes on the
    loopback address, the dashboard on a free port (``dashboard_address=None`` is distributed's
    default port 8787, which the other xdist worker's cluster may hold: a warning); yields its
    client (not the default one)."""
    from distributed import Client, LocalCluster

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0"
    ) as cluster:
        with Client(cluster, set_as_default=False) as client:
            yield client
