"""The Dask backend: the same numbers on a cluster as locally, a killed worker costs time only,
a bad scheduler address gives one line. The cluster (two single-threaded worker processes)
is started and stopped by these tests: nothing needs to run beforehand."""

from __future__ import annotations

import json
import os
import signal

import numpy as np
import pytest

pytest.importorskip("distributed", reason="the Dask tests need dask.distributed: pip install hexcal[dask]")

from hexcal.cli.main import main
from hexcal.core import preset
from hexcal.simulation import run_paper_experiment
from hexcal.simulation.dask_executor import DaskExecutor, dask_executor

SELECTION = ["study", "selection", "--trials", "6", "--poses", "10,15", "--seed", "3", "--quiet"]


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=50
    ) as local:
        yield local


def _selection_json(tmp_path, name, *options):
    out = tmp_path / name
    assert main([*SELECTION, "--out", str(out), *options]) == 0
    return json.loads((out / "selection.json").read_text())


def test_study_json_identical_with_jobs_and_on_a_cluster(cluster, tmp_path, capsys):
    one = _selection_json(tmp_path, "jobs1", "--jobs", "1")
    two = _selection_json(tmp_path, "jobs2", "--jobs", "2")
    dask = _selection_json(tmp_path, "dask", "--scheduler", cluster.scheduler_address)
    assert one == two == dask
    assert len(one["cells"]) == 6 and all(c["failures"] == 0 for c in one["cells"])
    assert "running on the Dask cluster" in capsys.readouterr().err


def test_a_worker_killed_during_a_run_costs_time_not_results(cluster):
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    options = {"trials": 24, "rng": 5, "chunk_size": 2}
    local = run_paper_experiment(nominal, true, **options)
    with dask_executor(cluster.scheduler_address) as executor:
        pids = executor.client.run(os.getpid)
        victim = next(iter(pids.values()))
        killed = []

        def kill_once(done, total):
            if not killed and done < total:
                os.kill(victim, signal.SIGKILL)  # the nanny starts a new worker
                killed.append(done)

        remote = run_paper_experiment(nominal, true, progress=kill_once, executor=executor, **options)
    assert killed, "the worker was killed before the run ended"
    for name in ("true_vectors", "interior_vectors", "boundary_vectors"):
        np.testing.assert_array_equal(getattr(remote, name), getattr(local, name))
    assert remote.to_dict() == local.to_dict()


def test_the_executor_sizes_chunks_by_the_cluster(cluster):
    with dask_executor(cluster.scheduler_address) as executor:
        assert isinstance(executor, DaskExecutor)
        assert executor.workers >= 1
        assert executor.submit(pow, 2, 10).result(timeout=30) == 1024


def test_a_bad_scheduler_address_gives_one_clear_line(tmp_path, capsys):
    out = tmp_path / "none"
    status = main([*SELECTION, "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and not out.exists()
    assert len(err) == 1 and err[0].startswith("hexcal: error: cannot connect to the Dask scheduler")
    assert "tcp://127.0.0.1:1" in err[0]
