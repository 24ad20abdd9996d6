"""Where a batch's trials run: in the batch's own process, a local process pool, or a Ray cluster.

Every backend runs :func:`run_trial` on :class:`TrialJob` values and hands each result to the batch's
``on_result(index, result)`` in the parent process as soon as it arrives (the batch records it
there), so an interrupted batch keeps every trial that finished.  A trial loads the mission itself and
runs it with its own PyBullet DIRECT client in whichever process or node runs it; its result depends on
the mission, the overrides and the seed alone, whatever the backend.

* ``local`` (:class:`InProcessBackend`, one worker) and ``pool`` (:class:`PoolBackend`): the machine's
  processes.  Ctrl-C / SIGTERM: nothing new starts, running workers are terminated.
* ``ray`` (:class:`RayBackend`): one Ray task per trial (one CPU each) on the cluster at ``address``,
  or on a local cluster started for the batch (``workers`` CPUs) when no address is given.  A trial run
  on another node that keeps its run directory writes it in a temporary directory there and sends the
  files back, so the records land where the user asked.  Ray retries a trial whose node is lost.
  Ray is the optional extra ``taskflow[cluster]``.

:class:`~taskflow.campaigns.ray_cluster.LocalRayCluster` starts a cluster of ``ray start`` processes on this
machine, for tests and the benchmark.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

BACKENDS = ("pool", "ray")
RAY_INSTALL = "pip install 'taskflow[cluster]'"

TrialResult = tuple[dict[str, Any], dict[str, Any]]  # (summary, wall-clock timing)
OnResult = Callable[[int, TrialResult], None]


class BackendError(Exception):
    """A backend that cannot run here (Ray missing, a cluster that cannot be reached); says what to do."""


class WorkerLost(BackendError):
    """A worker process or node died mid-trial (killed, out of memory, a node gone for good)."""


class TrialInterrupted(Exception):
    """The trial run in the batch's own process saw Ctrl-C / SIGTERM and stopped itself; :attr:`signum`
    says which."""

    def __init__(self, signum: int = signal.SIGINT) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass(frozen=True)
class TrialJob:
    """One trial: ``mission`` (absolute path) with ``overrides`` at ``seed``; ``run_dir`` is where its run
    directory goes (None: record nothing but the summary)."""

    mission: str
    overrides: tuple[str, ...]
    seed: int
    max_time: float | None = None
    run_dir: str | None = None


def run_trial(job: TrialJob, run_dir: str | None = None) -> TrialResult:
    """Run one trial and return its summary and wall-clock figures (``started``/``ended``: epoch seconds
    around the whole trial, mission loading included; ``cpu_s``: the CPU time the process spent on it, the same
    span — PyBullet steps in this process; ``host``/``pid``: where it ran).  ``run_dir``
    replaces the job's (a Ray worker writes into its own temporary directory)."""
    from taskflow.execution.runtime import run_mission
    from taskflow.mission.loader import load_mission

    started, cpu = time.time(), time.process_time()
    out = job.run_dir if run_dir is None else run_dir
    mission = load_mission(job.mission, list(job.overrides))
    result = run_mission(mission, seed=job.seed, out_dir=out, max_time=job.max_time, record=out is not None,
                         frames_hz=0)  # kept trials hold no camera frames: ~100 KB each, times every trial
    return result.summary, {"seed": job.seed, "wall_time_s": result.timing.get("wall_time_s"),
                            "real_time_factor": result.timing.get("real_time_factor"), "started": started,
                            "ended": time.time(), "cpu_s": time.process_time() - cpu, "host": socket.gethostname(),
                            "pid": os.getpid()}


class Backend(Protocol):
    name: str
    workers: int | None

    def run(self, jobs: list[TrialJob], on_result: OnResult) -> None: ...

    def close(self) -> None: ...


class InProcessBackend:
    """The trials one after another in this process (``--workers 1``): a Ctrl-C reaches the running
    trial, which records its safe stop and is then not counted."""

    name = "pool"
    workers: int | None = 1

    def run(self, jobs: list[TrialJob], on_result: OnResult) -> None:
        from taskflow.execution.runtime import INTERRUPTED, TERMINATED

        for i, job in enumerate(jobs):
            summary, timing = run_trial(job)
            if summary.get("reason") in (INTERRUPTED, TERMINATED):
                raise TrialInterrupted(signal.SIGINT if summary["reason"] == INTERRUPTED else signal.SIGTERM)
            on_result(i, (summary, timing))

    def close(self) -> None:
        pass


def _worker_init() -> None:
    # Ctrl-C reaches every process of the terminal's group: only the parent decides what happens, and
    # ends a worker with SIGTERM (a run in progress then records itself as aborted)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class PoolBackend:
    """A local process pool of ``workers`` processes."""

    name = "pool"

    def __init__(self, workers: int) -> None:
        self.workers: int | None = workers

    def run(self, jobs: list[TrialJob], on_result: OnResult) -> None:
        pool = ProcessPoolExecutor(max_workers=self.workers, initializer=_worker_init)
        futures: dict[Future[TrialResult], int] = {pool.submit(run_trial, job): i for i, job in enumerate(jobs)}
        try:
            pending = set(futures)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    try:
                        result = f.result()
                    except BrokenProcessPool as exc:
                        raise WorkerLost(f"a worker process died ({exc})") from None
                    on_result(futures[f], result)
        except BaseException:
            # stop now: nothing new starts, and the running trials are ended (their workers terminated)
            for proc in list(getattr(pool, "_processes", {}).values()):  # no public API before Python 3.14
                proc.terminate()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)

    def close(self) -> None:
        pass


def _ray_trial(job: TrialJob) -> tuple[TrialResult, dict[str, bytes]]:
    """A trial as a Ray task: with a run directory, run into a temporary one on this node and return its
    files (relative path → bytes) for the driver to write where the user asked."""
    if job.run_dir is None:
        return run_trial(job), {}
    tmp = tempfile.mkdtemp(prefix="taskflow-trial-")
    try:
        result = run_trial(job, run_dir=tmp)
        files = {str(p.relative_to(tmp)): p.read_bytes() for p in sorted(Path(tmp).rglob("*")) if p.is_file()}
        return result, files
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise BackendError(f"--backend ray needs Ray, which is not installed: {RAY_INSTALL}") from None
    return ray


class RayBackend:
    """Trials as Ray tasks on the cluster at ``address`` (``host:port`` of its head, or ``auto``), or on a
    local cluster of ``workers`` CPUs started here (and stopped by :meth:`close`)."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        ray = import_ray()
        self.address = address
        self.workers = workers
        kwargs: dict[str, Any] = {"logging_level": "WARNING", "log_to_driver": False}
        if address is not None and address != "auto":
            _check_reachable(address)  # Ray itself retries an unreachable head for minutes
        try:
            if address is not None:
                ray.init(address=address, **kwargs)
            else:
                ray.init(num_cpus=workers or os.cpu_count() or 1, include_dashboard=False, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            where = f"the Ray cluster at {address}" if address else "a local Ray cluster"
            raise BackendError(f"could not start or reach {where}: {exc}") from None
        if address is not None:
            self.workers = int(ray.cluster_resources().get("CPU", 0)) or None
        self._ray = ray

    def run(self, jobs: list[TrialJob], on_result: OnResult) -> None:
        ray = self._ray
        task = ray.remote(num_cpus=1, max_retries=2)(_ray_trial)
        refs = {task.remote(job): i for i, job in enumerate(jobs)}
        pending = list(refs)
        try:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                for ref in ready:
                    i = refs[ref]
                    try:
                        result, files = ray.get(ref)
                    except (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError,
                            ray.exceptions.LocalRayletDiedError) as exc:
                        raise WorkerLost(f"a Ray worker died after Ray's retries ({type(exc).__name__})") from None
                    run_dir = jobs[i].run_dir
                    if files and run_dir is not None:
                        _write_files(Path(run_dir), files)
                    on_result(i, result)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise

    def close(self) -> None:
        self._ray.shutdown()


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise BackendError(f"--address {address!r}: expected HOST:PORT of the Ray head, e.g. 10.0.0.5:6379")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as exc:
        raise BackendError(f"cannot reach the Ray head at {address} ({exc.strerror or exc}): is "
                           f"'ray start --head --port {port}' running there?") from None


def _write_files(root: Path, files: dict[str, bytes]) -> None:
    """A remote trial's run directory written under ``root``; a name leading outside it (``..``, an
    absolute path: a node is not trusted to say where the driver writes) is a :class:`BackendError`."""
    from taskflow.execution.record_io import RunDirError, inside

    for rel, data in files.items():
        try:
            path = inside(root, rel)
        except RunDirError as exc:
            raise BackendError(f"a remote trial sent a file outside its run directory: {exc}") from None
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


def make_backend(name: str, workers: int, address: str | None = None) -> Backend:
    """The backend ``name`` (one of :data:`BACKENDS`) with ``workers`` local workers."""
    if name == "ray":
        return RayBackend(address, None if address is not None else workers)
    if name != "pool":
        raise BackendError(f"unknown backend {name!r}: one of {', '.join(BACKENDS)}")
    return InProcessBackend() if workers == 1 else PoolBackend(workers)
