"""The SLURM example of docs/dask.md, built for real with dask-jobqueue (no jobs submitted)."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _cluster_call() -> str:
    """The ``cluster = SLURMCluster(...)`` statement of the docs' recommended script."""
    text = (REPO / "docs" / "dask.md").read_text()
    script = re.search(r"```python\n# run_slurm\.py.*?```", text, flags=re.S).group(0)
    return re.search(r"^cluster = SLURMCluster\(\n.*?^\)\n", script, flags=re.S | re.M).group(0)


def test_docs_slurm_cluster_builds_the_job_script_it_describes():
    from dask_jobqueue import SLURMCluster

    namespace = {"SLURMCluster": SLURMCluster}
    exec(_cluster_call(), namespace)  # noqa: S102 -- our own docs
    cluster = namespace["cluster"]
    try:
        script = cluster.job_script()
        assert "#SBATCH -p compute" in script and "#SBATCH -A my-project" in script
        assert "#SBATCH -t 04:00:00" in script and "#SBATCH --mem=60G" in script
        assert "source /path/to/antisync/.venv/bin/activate" in script
        # 32 single-threaded worker processes: one numba thread per antisync task
        assert re.search(r"--nworkers 32\b", script) and re.search(r"--nthreads 1\b", script)
        assert "--lifetime 230m" in script and "--lifetime-stagger 5m" in script
        assert cluster.scheduler_address.startswith("tcp://")
    finally:
        cluster.close()


def test_docs_script_hands_the_client_to_the_executor_and_closes_what_it_made():
    text = (REPO / "docs" / "dask.md").read_text()
    script = re.search(r"```python\n# run_slurm\.py.*?```", text, flags=re.S).group(0)
    assert "with Client(cluster) as client:" in script
    assert "DaskExecutor(client)" in script and "cluster.close()" in script
