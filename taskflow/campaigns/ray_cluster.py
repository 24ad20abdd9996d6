"""A multi-node Ray cluster on one machine (:class:`LocalRayCluster`): a head node and worker nodes as
separate ``ray start`` processes, what ``ray start`` on several machines does, for the tests and the
benchmark of the ``ray`` backend (:mod:`taskflow.campaigns.backends`)."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from taskflow.campaigns.backends import BackendError


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class LocalRayCluster:
    """A Ray cluster of separate ``ray start --block`` processes on this machine: a head node with no CPU
    (it schedules nothing) and ``nodes`` worker nodes of ``cpus_per_node`` CPUs each — what ``ray start
    --head`` on one machine and ``ray start --address HEAD`` on the others make.  Every port is chosen
    free, and the cluster has its own temporary directory, so it does not clash with another cluster.
    Each node is its own process group, ended by :meth:`stop` (SIGTERM, then SIGKILL).  The cluster uses
    Ray's token authentication with a token of its own: a driver connects with :attr:`env` in its
    environment (:meth:`driver_env` sets it in this process)."""

    def __init__(self, nodes: int = 2, cpus_per_node: int = 1, object_store_mb: int = 80) -> None:
        self.nodes, self.cpus_per_node, self.object_store_mb = nodes, cpus_per_node, object_store_mb
        self.procs: list[subprocess.Popen[bytes]] = []
        self.temp_dir = tempfile.mkdtemp(prefix="tfray-", dir="/tmp")  # short: Ray's socket paths must fit
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        # Ray's token authentication with a token of this cluster's own: a driver needs ``env`` to connect
        self.env = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32), "RAY_USAGE_STATS_ENABLED": "0"}

    def _start(self, head: bool) -> None:
        ray_exe = str(Path(sys.executable).with_name("ray"))
        worker_lo = free_port()
        cmd = [ray_exe, "start", "--block", "--disable-usage-stats", "--node-ip-address", "127.0.0.1",
               f"--object-store-memory={self.object_store_mb * 1024 * 1024}",
               f"--node-manager-port={free_port()}", f"--object-manager-port={free_port()}",
               f"--dashboard-agent-listen-port={free_port()}", f"--dashboard-agent-grpc-port={free_port()}",
               f"--runtime-env-agent-port={free_port()}", f"--metrics-export-port={free_port()}",
               f"--worker-port-list={','.join(str(worker_lo if i == 0 else free_port()) for i in range(8))}"]
        if head:
            cmd += ["--head", f"--port={self.port}", "--num-cpus=0", "--include-dashboard=false",
                    f"--temp-dir={self.temp_dir}"]
        else:
            cmd += [f"--address={self.address}", f"--num-cpus={self.cpus_per_node}"]
        log = open(Path(self.temp_dir) / f"node-{len(self.procs)}.log", "wb")  # noqa: SIM115 - the node writes it until stopped
        env = dict(os.environ, **self.env)
        self.procs.append(subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                                           env=env))

    def start(self, timeout: float = 60.0) -> LocalRayCluster:
        """Start the head, then the worker nodes one at a time, each awaited until the cluster counts its
        CPUs; a worker node whose start fails (a raylet that does not register with the head within
        Ray's 30 s, which a loaded machine can exceed) is started again, twice at most."""
        try:
            self._start(head=True)
            self._wait_port(timeout)
            for k in range(1, self.nodes + 1):
                for _attempt in range(3):
                    self._start(head=False)
                    if self._wait_cpus(k * self.cpus_per_node, timeout, self.procs[-1]):
                        break
                    _kill_group(self.procs[-1].pid, signal.SIGKILL)
                    self.procs.pop().wait()
                else:
                    raise BackendError(f"Ray worker node {k} did not join in 3 attempts: {self._logs()}")
        except BaseException:
            self.stop()
            raise
        return self

    def _logs(self) -> str:
        return "".join(f"\n--- {f.name}:\n" + f.read_text(errors="replace")[-1500:]
                       for f in sorted(Path(self.temp_dir).glob("node-*.log")))

    def _wait_port(self, timeout: float) -> None:
        t0 = time.monotonic()
        while True:
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1.0):
                    return
            except OSError:
                if self.procs[0].poll() is not None or time.monotonic() - t0 > timeout:
                    raise BackendError(f"the Ray head did not start: see {self.temp_dir}/node-0.log") from None
                time.sleep(0.2)

    def _wait_cpus(self, want: int, timeout: float, node: subprocess.Popen[bytes]) -> bool:
        """Whether the cluster counts ``want`` CPUs before ``timeout`` s pass or ``node`` exits."""
        code = ("import ray, time, sys\n"
                f"ray.init(address='{self.address}', logging_level='ERROR', log_to_driver=False)\n"
                "t0 = time.monotonic()\n"
                f"while ray.cluster_resources().get('CPU', 0) < {want}:\n"
                f"    if time.monotonic() - t0 > {timeout}: sys.exit(1)\n"
                "    time.sleep(0.2)\n")
        # a separate driver: this process may then connect to the cluster itself
        probe = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 env=dict(os.environ, **self.env))
        while probe.poll() is None:
            if node.poll() is not None:  # the node gave up
                probe.kill()
                probe.wait()
                return False
            time.sleep(0.2)
        return probe.returncode == 0

    def stop(self) -> None:
        """End every node's process group (SIGTERM, then SIGKILL after 5 s) and remove the temp dir."""
        for p in reversed(self.procs):
            _kill_group(p.pid, signal.SIGTERM)
        t0 = time.monotonic()
        for p in reversed(self.procs):
            try:
                p.wait(timeout=max(0.1, 5.0 - (time.monotonic() - t0)))
            except subprocess.TimeoutExpired:
                pass
        for p in self.procs:
            _kill_group(p.pid, signal.SIGKILL)
            p.wait()
        self.procs.clear()
        shutil.rmtree(self.temp_dir, ignore_errors=True)

    @contextlib.contextmanager
    def driver_env(self) -> Iterator[None]:
        """This process's environment set to connect to the cluster, restored afterwards."""
        saved = {k: os.environ.get(k) for k in self.env}
        os.environ.update(self.env)
        try:
            yield
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v

    def __enter__(self) -> LocalRayCluster:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()


def _kill_group(pgid: int, sig: int) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass
