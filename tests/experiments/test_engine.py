"""The experiments' engine (cekm_swarm/experiments/engine.py): a quick tracking grid run on a
real Dask scheduler with two workers started here gives the local run's results.json, and
still does when one worker is SIGKILLed while it runs the grid's runs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main
from cekm_swarm.experiments.engine import ClusterAddressError, check_address, on_cluster, run_jobs
from cekm_swarm.runtime.config import free_port

SETUP_S = 60.0  # bounds on waiting for the cluster (never reached on a working one)


def _square(x: int) -> int:
    return x * x


def test_jobs_come_back_in_job_order_in_this_process():
    assert run_jobs(_square, [3, 1, 2], workers=1, progress=False) == [9, 1, 4]


def test_a_cluster_address_must_be_tcp_host_port():
    assert check_address("tcp://10.0.0.2:8786") == "tcp://10.0.0.2:8786"
    for bad in ("10.0.0.2:8786", "tcp://10.0.0.2", "http://h:1", "tcp://:8786"):
        with pytest.raises(ClusterAddressError, match="tcp://HOST:PORT"):
            check_address(bad)
    r = CliRunner().invoke(main, ["experiment", "obstacles", "--cluster", "10.0.0.2:8786", "--out", "x"])
    assert r.exit_code == 2 and "--cluster" in r.output and "tcp://HOST:PORT" in r.output


@pytest.fixture
def dask_cluster(tmp_path):
    """A scheduler on a free loopback port and two one-thread workers without a nanny (a
    worker SIGKILLed stays dead), as processes of their own: (address, {name: Popen})."""
    from distributed import Client

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    procs: dict[str, subprocess.Popen] = {}

    def start(name: str, *argv: str) -> None:
        with open(logs / f"{name}.log", "wb") as out:
            procs[name] = subprocess.Popen([sys.executable, "-m", *argv], stdout=out, stderr=subprocess.STDOUT)

    start("scheduler", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port),
          "--no-dashboard")
    for name in ("a", "b"):
        start(name, "distributed.cli.dask_worker", address, "--name", name, "--nthreads", "1", "--no-nanny",
              "--no-dashboard")
    try:
        with Client(address, timeout=SETUP_S, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=SETUP_S)
        yield address, procs
    finally:
        for p in procs.values():  # nothing of theirs to keep: no graceful close to wait for
            if p.poll() is None:
                p.kill()
            p.wait()


def _grid(out, *engine: str) -> dict:
    """The quick grid's results.json, less its wall time and worker count."""
    r = CliRunner().invoke(main, ["experiment", "tracking", "--grid", "--quick", "--seeds", "2", "--duration", "3",
                                  "--quiet", "--out", str(out), *engine])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "results.json").read_text())
    del doc["wall_seconds"], doc["workers"]
    assert doc["cells"]
    return doc


def _kill_when_busy(address: str, name: str, pid: int, killed: list) -> None:
    """SIGKILL worker ``name`` once the scheduler has given it a run (bounded wait)."""
    from distributed import Client

    with Client(address, timeout=SETUP_S, set_as_default=False) as client:
        end = time.monotonic() + SETUP_S
        while time.monotonic() < end:
            workers = client.scheduler_info()["workers"]
            addr = next((a for a, w in workers.items() if w.get("name") == name), None)
            busy = client.processing(workers=[addr]).get(addr) if addr else None
            if busy:
                os.kill(pid, signal.SIGKILL)
                killed.append(list(busy))
                return
            time.sleep(0.01)


@pytest.mark.slow  # a Dask scheduler and two workers, each a process; three quick grids
def test_a_grid_on_a_dask_cluster_equals_the_local_run_even_with_a_worker_killed(tmp_path, dask_cluster):
    address, procs = dask_cluster
    local = _grid(tmp_path / "local", "--workers", "1")
    assert _grid(tmp_path / "cluster", "--cluster", address) == local
    killed: list = []
    killer = threading.Thread(target=_kill_when_busy, args=(address, "a", procs["a"].pid, killed))
    killer.start()
    try:
        again = _grid(tmp_path / "killed", "--cluster", address)
    finally:
        killer.join()
    assert killed and killed[0], "worker a was never given a run"
    assert procs["a"].wait(timeout=SETUP_S) == -signal.SIGKILL  # it died mid-grid, its runs went to b
    assert again == local


def test_on_cluster_is_undone_after_its_block():
    from cekm_swarm.experiments import engine

    with on_cluster("tcp://h:1"):
        assert engine._CLUSTER.get() == "tcp://h:1"
    assert engine._CLUSTER.get() is None


def _seed_results(out, seeds) -> dict:
    docs = {s: json.loads((out / f"seed-{s}" / "results.json").read_text()) for s in seeds}
    for d in docs.values():  # the wall times aside
        del d["wall_seconds"]
        for net in d["networks"].values():
            del net["seconds"]
    return docs


@pytest.mark.slow  # a local Dask cluster of two worker processes
def test_target_reaching_master_seeds_side_by_side_equal_one_after_the_other(tmp_path):
    args = ["experiment", "target-reaching", "--networks", "R9", "--trials", "2", "--steps", "400",
            "--test-interval", "200", "--targets", "3", "--master-seeds", "2", "--seed", "11", "--quiet"]
    for name, workers in (("one", "1"), ("two", "2")):
        r = CliRunner().invoke(main, [*args, "--workers", workers, "--out", str(tmp_path / name)])
        assert r.exit_code == 0, r.output
    assert _seed_results(tmp_path / "two", (11, 12)) == _seed_results(tmp_path / "one", (11, 12))
