"""Passes on a Dask cluster (``dask.distributed``): a LocalCluster of worker processes or a scheduler.

Imported only when a farm option is used, so plain renders and ``--help`` never load dask. The
scene (meshes, materials, lights: its description, not the BVH) goes to the cluster once, as a
task's result, and is fetched once per worker; each worker builds embree's scene, the camera's
exit-pupil table and OpenCL program on the first task that needs them and keeps them across tasks
in a cache keyed by content hashes (``checkpoint.content_hash``). A task is a few consecutive
passes (about ``task_samples`` samples) and returns each pass's sums separately, so the client adds
them in pass order (``film.PassFilm``) and the image is bit-identical to an in-process render for
any number of workers, task order or retry. A dead worker's tasks are rerun by Dask. The worker
processes of a LocalCluster started here ignore SIGINT and SIGHUP, which a terminal sends to the
whole process group: this process handles them (finish the tasks in flight, write what is done).
"""

from __future__ import annotations

import ctypes
import dataclasses
import importlib.util
import logging
import os
import signal
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from distributed import Client, Future, LocalCluster, wait
from distributed.security import Security

from realistic.camera.base import Camera, SampleBlock
from realistic.core import validation
from realistic.errors import UserError
from realistic.renderer.checkpoint import content_hash
from realistic.renderer.job import PassResult, PassSettings, RenderJob
from realistic.renderer.memory import check_job_memory
from realistic.renderer.runner import PassRunner
from realistic.renderer.thread_count import default_threads
from realistic.renderer.timing import StageClock
from realistic.scene.intersect import Intersector
from realistic.scene.model import Scene

#: Samples per task by default: 4 passes of 2^18, long enough that the scheduler's cost per task is small
#: against its work (docs/farm.md).
DEFAULT_TASK_SAMPLES = 1 << 20
#: Runners (camera + integrator) and BVHs each worker keeps, most recently used first.
RUNNERS_KEPT = 8
SCENES_KEPT = 2
#: Set in the worker processes of the LocalClusters started here: they ignore terminal signals.
LOCAL_WORKER = "REALISTIC_LOCAL_WORKER"
#: How long a client waits to reach a scheduler before the render is refused.
CONNECT_TIMEOUT = "15s"
#: Where a LocalCluster started here listens (scheduler, workers, dashboard) unless asked otherwise.
LOOPBACK = "127.0.0.1"

_runners: OrderedDict[str, PassRunner] = OrderedDict()
_scenes: OrderedDict[str, Intersector] = OrderedDict()
_lock = threading.Lock()


@contextmanager
def farm_client(workers: int | None = None, scheduler: str | None = None, announce: Callable[[str], object] = print,
                security: Security | None = None, host: str = LOOPBACK) -> Iterator[Client]:
    """A client of the scheduler at ``scheduler``, or of a new LocalCluster of ``workers`` single-
    threaded worker processes (its dashboard link passed to ``announce``), closed on exit.

    Only what the caller names is used: never ``DASK_SCHEDULER_ADDRESS`` or another address from
    the environment, since a scheduler and its workers can run code as this user (the client
    unpickles their results). A ``tls://`` scheduler needs ``security`` (a ``distributed.security.
    Security`` with the CA that signed the cluster's certificates and this client's certificate and
    key), and ``security`` needs a ``tls://`` scheduler. A LocalCluster's scheduler, workers and
    dashboard listen on ``host`` only (loopback unless asked), and it has at most as many
    workers as ``check_local_workers`` allows.
    """
    if scheduler:
        _check_scheme(scheduler, security)
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT, security=security)
        except (OSError, TimeoutError, ValueError) as err:
            raise UserError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
        try:
            yield client
        finally:
            client.close()
        return
    if workers is not None:
        check_local_workers(workers)
    with _terminal_signals_ignored():  # worker processes started now inherit the ignoring
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host=host,
                               dashboard_address=f"{host}:0", silence_logs=logging.ERROR, env={LOCAL_WORKER: "1"})
        client = Client(cluster)
    dashboard = (f"dashboard {client.dashboard_link}" if importlib.util.find_spec("bokeh")
                 else f"dashboard at {client.dashboard_link} once bokeh is installed (the farm extra brings it)")
    announce(f"Dask LocalCluster of {workers} worker processes; {dashboard}")
    try:
        yield client
    finally:
        client.close()
        close_local_cluster(cluster)


def close_local_cluster(cluster: LocalCluster) -> None:
    """Close a LocalCluster, its worker processes stopped. A worker that died and was restarted by
    its nanny during the render can make the cluster's worker-status watcher fail with a KeyError,
    which ``close`` then raises (SpecCluster._update_worker_status looks up a worker it never
    recorded: dask/distributed#5407); the processes are gone by then, so that error is dropped
    rather than turned into a traceback after the render's work."""
    try:
        cluster.close()
    except KeyError:
        pass


def check_local_workers(workers: int) -> int:
    """``workers`` if a LocalCluster here may have that many, else a one-line UserError: at most one
    single-threaded worker process per CPU this process may run on (``default_threads``); more
    only compete for the same CPUs, each with its own interpreter, embree scene and kernels, and
    starting hundreds takes minutes."""
    validation.workers(workers)
    limit = default_threads()
    if workers > limit:
        raise UserError(f"{workers} workers: a LocalCluster here has at most {limit} (one per CPU this process "
                        "may run on); for more, start a Dask cluster on more machines and use --scheduler")
    return workers


def tls_security(ca_file: str, cert: str, key: str) -> Security:
    """Dask's TLS security for a client: the CA file that signed the cluster's certificates, and this
    client's certificate and private key (PEM files); encryption required."""
    for name, path in (("--tls-ca-file", ca_file), ("--tls-cert", cert), ("--tls-key", key)):
        if not os.path.isfile(path):
            raise UserError(f"{name} {path}: not a readable file")
    return Security(tls_ca_file=ca_file, tls_client_cert=cert, tls_client_key=key, require_encryption=True)


def _check_scheme(scheduler: str, security: Security | None) -> None:
    """A ``tls://`` address with security, any other without (one-line UserErrors)."""
    tls = scheduler.lower().startswith("tls://")
    if tls and security is None:
        raise UserError(f"{scheduler}: a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key (in the API, "
                        "a distributed.security.Security)")
    if security is not None and not tls:
        raise UserError(f"{scheduler}: TLS certificates are used with a tls:// scheduler address only")


@contextmanager
def _terminal_signals_ignored() -> Iterator[None]:
    """Ignore SIGINT and SIGHUP while the body runs (main thread only; elsewhere a no-op).

    Ctrl-C and a closed terminal signal the whole foreground process group. Worker processes started
    meanwhile inherit the ignored dispositions (Python installs its KeyboardInterrupt handler only
    where SIGINT is not ignored), so they finish the tasks in flight while this process handles the
    signal and then closes them.
    """
    names = ("SIGINT", "SIGHUP")
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.signal(number, signal.SIG_IGN)
                for number in (getattr(signal, name) for name in names if hasattr(signal, name))}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _runner(scene: Scene, scene_key: str, camera: Camera, runner_key: str, settings: PassSettings) -> PassRunner:
    """This worker's runner for (scene, camera, settings), built on first use."""
    with _lock:
        runner = _runners.get(runner_key)
        if runner is not None:
            _runners.move_to_end(runner_key)
            return runner
        intersector = _scenes.get(scene_key)
        if intersector is None:
            intersector = _scenes[scene_key] = Intersector(scene)
            while len(_scenes) > SCENES_KEPT:
                _scenes.popitem(last=False)
        camera.prepare()
        runner = _runners[runner_key] = PassRunner(scene, camera, settings, StageClock(), intersector)
        while len(_runners) > RUNNERS_KEPT:
            _runners.popitem(last=False)
        if os.environ.get(LOCAL_WORKER):
            _ignore_terminal_signals()
        return runner


def _ignore_terminal_signals() -> None:
    """Ignore SIGINT and SIGHUP in this process, from any thread (C ``signal``, which Python's
    ``signal.signal`` allows only in the main thread): PoCL's LLVM installs handlers for them when it
    compiles a kernel, and those end a local worker on the Ctrl-C meant for the render."""
    libc = ctypes.CDLL(None)
    libc.signal.restype = ctypes.c_void_p
    libc.signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
    for name in ("SIGINT", "SIGHUP"):
        if hasattr(signal, name):
            libc.signal(getattr(signal, name), ctypes.c_void_p(int(signal.SIG_IGN)))


def _scene(scene: Scene) -> Scene:
    """The scene as a task's result, so workers fetch it from each other (once per worker)."""
    return scene


def run_task(scene: Scene, scene_key: str, camera: Camera, runner_key: str, settings: PassSettings,
             passes: list[tuple[int, SampleBlock]]) -> list[PassResult]:
    """A task on a worker: passes (plan index, sample block) of one camera."""
    return _runner(scene, scene_key, camera, runner_key, settings).run(passes)


class DaskPasses:
    """Passes as Dask tasks on ``client``'s workers, a few consecutive passes (about ``task_samples``
    samples) a task (``job.PassExecutor``). Reusable: one job at a time."""

    def __init__(self, client: Client, task_samples: int | None = None) -> None:
        self.client, self.task_samples = client, task_samples
        self.capacity, self.passes_per_task = 2, 1

    def open(self, job: RenderJob, clock: StageClock) -> None:
        """Send the scene to the cluster (once, as a task's result); stage times stay on the workers."""
        self._check_worker_memory(job)
        self.cameras, self.settings = job.cameras, job.settings
        described = dataclasses.replace(job.scene, camera=None)
        self.scene_key = content_hash(described)
        # a task whose definition holds the scene, not scattered data: if the worker holding it dies,
        # the scheduler makes it again from the definition instead of cancelling every pass
        self.scene = self.client.submit(_scene, described, key=f"scene-{self.scene_key}", pure=False)
        self.runner_keys: dict[int, str] = {}  # frame -> its runner's key, as its frame starts
        threads = sum(self.client.nthreads().values())
        self.capacity = max(2, 2 * threads)  # tasks submitted ahead: every worker busy, one queued each
        self.passes_per_task = max(1, (self.task_samples or DEFAULT_TASK_SAMPLES) // job.pass_size)

    def _check_worker_memory(self, job: RenderJob) -> None:
        """Refuse, before anything is sent, a job that would not fit in a worker: each holds the scene,
        a runner and its threads' passes in flight, within its ``memory_limit`` (the smallest of the
        cluster's, and ``job.max_memory_bytes`` if smaller)."""
        workers = self.client.scheduler_info().get("workers", {}).values()
        limits = [int(worker["memory_limit"]) for worker in workers if worker.get("memory_limit")]
        source = "a worker of this cluster may use (its memory_limit)"
        if job.max_memory_bytes is not None and (not limits or job.max_memory_bytes < min(limits)):
            limits, source = [job.max_memory_bytes], "allowed by --max-memory"
        threads = max(self.client.nthreads().values(), default=1)
        check_job_memory(job, threads, min(limits, default=None), limit_source=source)

    def submit(self, frame: int, passes: list[tuple[int, SampleBlock]]) -> Future:
        """A task of frame ``frame``'s passes; its camera is prepared on the worker (``_runner``)."""
        if frame not in self.runner_keys:
            self.runner_keys = {frame: content_hash((self.scene_key, self.cameras[frame], self.settings))}
        return self.client.submit(run_task, self.scene, self.scene_key, self.cameras[frame], self.runner_keys[frame],
                                  self.settings, passes, pure=False)

    def wait_first(self, pending: set) -> set:
        return wait(list(pending), return_when="FIRST_COMPLETED").done

    def finish_in_flight(self, pending: dict) -> list[tuple[int, list[PassResult]]]:
        """(frame, results) of every task submitted (at most ``capacity``, a couple of seconds each)."""
        wait(list(pending))
        return [(frame, future.result()) for future, frame in pending.items()]

    def close(self, finished: bool) -> None:
        """Release the scene (tasks not collected are released with their futures)."""
        self.scene.release()
