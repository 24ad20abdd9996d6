"""The Ray backend on a real multi-node Ray cluster on this machine: a head node without CPUs and two
worker nodes of one CPU each, every node its own ``ray start`` process (as on separate machines).  A small
campaign run there gives, trial by trial, what the local pool gives for the same seeds, and the trials'
run directories land where the user asked.  Ray missing: one line naming the command that installs it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from taskflow.campaigns.batch import run_batch
from taskflow.campaigns.ray_cluster import LocalRayCluster

ROOT = Path(__file__).resolve().parents[2]
FAST = str(ROOT / "missions" / "viki_forward.yaml")


@pytest.fixture(scope="module")
def cluster() -> Iterator[LocalRayCluster]:
    c = LocalRayCluster(nodes=2, cpus_per_node=1)
    c.start(timeout=90)
    try:
        with c.driver_env():
            yield c
    finally:
        c.stop()


def test_a_campaign_on_a_two_node_ray_cluster_equals_the_local_pool(tmp_path: Path, cluster: LocalRayCluster) -> None:
    ray_out, pool_out = tmp_path / "ray", tmp_path / "pool"
    on_ray = run_batch(FAST, trials=4, seed=3, max_time=6.0, out=ray_out, keep_runs=True, backend="ray",
                       address=cluster.address)
    on_pool = run_batch(FAST, trials=4, seed=3, max_time=6.0, out=pool_out, workers=1)
    assert [t["seed"] for t in on_ray["trials"]] == [3, 4, 5, 6]
    assert on_ray["trials"] == on_pool["trials"]  # outcome, final state, times, every metric
    assert (ray_out / "batch.json").read_bytes() == (pool_out / "batch.json").read_bytes()
    timing = json.loads((ray_out / "timing.json").read_text())
    assert timing["backend"] == "ray" and timing["workers"] == 2  # the two worker nodes' CPUs
    # the run directories came back from the worker nodes to where they were asked for
    for seed in (3, 4, 5, 6):
        summary = json.loads((ray_out / f"trial-{seed:05d}" / "summary.json").read_text())
        assert summary == {k: v for k, v in on_pool["trials"][seed - 3].items() if k != "condition"}
        assert (ray_out / f"trial-{seed:05d}" / "trace.csv").stat().st_size > 0


def test_without_an_address_a_local_ray_cluster_is_started_and_stopped(tmp_path: Path) -> None:
    on_ray = run_batch(FAST, trials=2, seed=7, max_time=6.0, out=tmp_path / "ray", backend="ray", workers=2)
    on_pool = run_batch(FAST, trials=2, seed=7, max_time=6.0, out=tmp_path / "pool", workers=2)
    assert on_ray["trials"] == on_pool["trials"]
    assert on_ray["timing"]["backend"] == "ray" and on_ray["timing"]["workers"] == 2
    import ray

    assert not ray.is_initialized()


def test_the_ray_backend_without_ray_names_the_install_command(tmp_path: Path) -> None:
    code = ("import sys; sys.modules['ray'] = None\n"  # as if Ray were not installed
            "from taskflow.cli import main; raise SystemExit(main())")
    done = subprocess.run([sys.executable, "-c", code, "batch", FAST, "--trials", "1", "--backend", "ray",
                           "--out", str(tmp_path / "b")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and len(done.stderr.strip().splitlines()) == 1
    assert done.stderr.startswith("taskflow batch: --backend ray needs Ray, which is not installed: "
                                  "pip install 'taskflow[cluster]'")
    # the campaign was set up before the backend: it waits, to be run once Ray is there (or on the pool)
    assert f"taskflow batch --resume {tmp_path / 'b'} runs it" in done.stderr


@pytest.mark.parametrize("address, message", [
    ("127.0.0.1:1", "cannot reach the Ray head at 127.0.0.1:1"),
    ("nohost", "expected HOST:PORT of the Ray head"),
])
def test_an_unreachable_or_malformed_address_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          address: str, message: str) -> None:
    from taskflow.cli import main

    assert main(["batch", FAST, "--trials", "1", "--backend", "ray", "--address", address,
                 "--out", str(tmp_path / "b")]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
