"""Where a sweep's tasks run: :class:`LocalBackend` (a process pool, no extra dependency)
and :class:`RayBackend` (``pip install 'mitlc[ray]'``), both retrying tasks whose worker was lost.

A backend is anything with ``describe() -> str`` and ``run(payloads) -> Iterator[(payload, record or
exception)]``: :class:`Backend`.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import sys
import tempfile
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol

from mitlc.errors import InputError
from mitlc.sweep.task import run_task

# ---------------------------------------------------------------- backends


Outcome = tuple[dict, "dict | BaseException"]
"""What a backend yields per task: the payload and its record, or the exception it raised."""


class Backend(Protocol):
    """Where tasks run: :func:`mitlc.sweep.run.run_sweep` needs only these two methods."""

    def describe(self) -> str:
        """One line for the user: where and how many at a time."""
        ...

    def run(self, payloads: Sequence[dict]) -> Iterator[Outcome]:
        """Run every payload (:func:`~mitlc.sweep.task.run_task`), yielding ``(payload, record)`` or
        ``(payload, exception)`` as each finishes, in any order."""
        ...


class WorkerLost(RuntimeError):
    """A task's worker died more often than the retries allow."""


def default_workers() -> int:
    """``min(2, cores)``: the local backend's default number of processes."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(2, cores))


class LocalBackend:
    """A pool of ``workers`` processes on this machine (``concurrent.futures``, spawned interpreters).

    At most ``workers`` tasks are in flight.  When a worker dies (killed, out
    of memory) the pool breaks; the tasks that were in flight are run again in
    a new pool, each at most ``max_retries`` more times.
    """

    name = "local"

    def __init__(
        self, workers: int | None = None, max_retries: int = 3, on_retry: Callable[[dict, int], None] | None = None
    ) -> None:
        self.workers = int(workers or default_workers())
        self.max_retries = int(max_retries)
        self.on_retry = on_retry
        """Called with the payload and the attempt about to start when a lost task is run again."""
        if self.workers < 1:
            raise InputError("--workers must be at least 1", file="--workers")

    def describe(self) -> str:
        return f"local, {self.workers} worker{'s' if self.workers != 1 else ''}"

    def run(self, payloads: Sequence[dict]) -> Iterator[Outcome]:
        import multiprocessing
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        queue = deque(payloads)
        losses: Counter[str] = Counter()
        ctx = multiprocessing.get_context("spawn")
        pool: ProcessPoolExecutor | None = None
        running: dict = {}
        try:
            while queue or running:
                if pool is None:
                    pool = ProcessPoolExecutor(
                        self.workers, mp_context=ctx, initializer=watch_parent, initargs=(os.getpid(),)
                    )
                broken = False
                while queue and len(running) < self.workers and not broken:
                    p = queue.popleft()
                    try:
                        running[pool.submit(run_task, p)] = p
                    except BrokenProcessPool:
                        queue.appendleft(p)
                        broken = True
                if not broken:
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    broken = any(isinstance(f.exception(), BrokenProcessPool) for f in done)
                if broken:  # every task in flight is lost with the pool: wait until all say so
                    wait(running)
                    done = set(running)
                outcomes: list[Outcome] = []
                for fut in done:
                    p = running.pop(fut)
                    exc = fut.exception()
                    if isinstance(exc, BrokenProcessPool):
                        losses[p["key"]] += 1
                        if losses[p["key"]] > self.max_retries:
                            outcomes.append((p, WorkerLost(f"its worker died {losses[p['key']]} times")))
                        else:
                            queue.appendleft(p)
                            if self.on_retry is not None:
                                self.on_retry(p, losses[p["key"]] + 1)
                    else:
                        outcomes.append((p, exc if exc is not None else fut.result()))
                if broken:
                    pool.shutdown(wait=True, cancel_futures=True)
                    pool = None
                else:  # give the idle workers their next tasks before the results are written
                    while queue and len(running) < self.workers:
                        p = queue.popleft()
                        try:
                            running[pool.submit(run_task, p)] = p
                        except BrokenProcessPool:
                            queue.appendleft(p)
                            break
                yield from outcomes
        finally:
            if pool is not None:
                if running:  # stopped early (an interrupt): do not let the workers finish their tasks
                    _terminate_workers(pool)
                pool.shutdown(wait=False, cancel_futures=True)


def watch_parent(parent: int, every_s: float = 0.5) -> None:
    """In a worker: exit as soon as the sweep that started it is gone (killed with -9, it
    cannot tell its workers; they would wait for tasks forever, and with them the
    resource tracker whose pipe they hold)."""
    import threading

    def watch() -> None:
        while True:
            if os.getppid() != parent:  # re-parented: the sweep died
                os._exit(1)
            time.sleep(every_s)

    threading.Thread(target=watch, name="mitlc-watch-parent", daemon=True).start()


def _terminate_workers(pool: Any) -> None:
    """End a process pool's workers now (``terminate_workers`` from Python 3.14; before, its process table)."""
    if hasattr(pool, "terminate_workers"):
        pool.terminate_workers()
        return
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            proc.terminate()
        except (OSError, ValueError):  # already gone
            pass


class RayBackend:
    """Ray tasks (``pip install 'mitlc[ray]'``) on a cluster or on a Ray started for the sweep.

    ``address``: a running cluster (``auto``, ``HOST:6379`` or ``ray://HOST:10001``);
    without it, ``RAY_ADDRESS`` if set, else a new local Ray with ``workers``
    CPUs is started (even if a ``ray start`` cluster runs on this machine) and
    stopped again at the end.  Each task asks for one CPU and
    is retried up to ``max_retries`` times if its worker or node dies.
    """

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None, max_retries: int = 3) -> None:
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        self.workers = int(workers or default_workers())
        self.max_retries = int(max_retries)

    def describe(self) -> str:
        return f"ray at {self.address}" if self.address else f"ray, local, {self.workers} CPUs"

    @staticmethod
    def _import():
        try:
            import ray
        except ImportError:
            raise InputError(
                "the ray backend needs Ray", file="--backend", hint="pip install 'mitlc[ray]' (or use --backend local)"
            ) from None
        return ray

    def check(self) -> None:
        """One line now, before any work, if Ray is not installed or nothing answers at the address."""
        ray = self._import()
        if self.address and not ray.is_initialized():
            probe_ray_address(self.address)

    def run(self, payloads: Sequence[dict]) -> Iterator[Outcome]:
        import logging

        ray = self._import()
        connected_here = False
        if not ray.is_initialized():
            if self.address:
                probe_ray_address(self.address)
            said: list[str] = []
            try:
                if self.address:
                    with _stderr_kept_back() as said:  # Ray's retries warn every second (C++, on fd 2)
                        ray.init(address=self.address, logging_level=logging.WARNING, log_to_driver=False)
                else:
                    # "local": a new Ray for this sweep, even if a `ray start` cluster runs on this machine
                    ray.init(
                        address="local",
                        num_cpus=self.workers,
                        include_dashboard=False,
                        logging_level=logging.WARNING,
                        log_to_driver=False,
                    )
            except (ConnectionError, RuntimeError, ValueError) as exc:
                last = f" (Ray's last word: {said[-1][:300]})" if said else ""
                raise InputError(f"cannot start or reach Ray: {exc}{last}", file="--address") from None
            connected_here = True
        remote = ray.remote(num_cpus=1, max_retries=self.max_retries, retry_exceptions=False)(run_task)
        refs = {}
        try:
            refs = {remote.remote(p): p for p in payloads}
            while refs:
                done, _ = ray.wait(list(refs), num_returns=1)
                for ref in done:
                    p = refs.pop(ref)
                    try:
                        yield p, ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:
                        yield p, exc.cause if isinstance(exc.cause, BaseException) else exc
                    except ray.exceptions.RayError as exc:
                        yield p, exc
        finally:
            for ref in refs:
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # noqa: BLE001 - best effort while stopping
                    pass
            if connected_here:
                ray.shutdown()


@contextlib.contextmanager
def _stderr_kept_back() -> Iterator[list[str]]:
    """Standard error (the file descriptor: Ray's C++ core writes to it directly) goes to a scratch
    file for the block; the list yielded then holds its last line, without the log prefix, for the
    caller to say in its one line when the block failed."""
    said: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as scratch:
            os.dup2(scratch.fileno(), 2)
            try:
                yield said
            finally:
                sys.stderr.flush()
                os.dup2(saved, 2)
                scratch.seek(0)
                lines = [ln.strip() for ln in scratch.read()[-4096:].decode(errors="replace").splitlines()]
                lines = [ln for ln in lines if ln]
                if lines:  # "[2026-12-03 17:21:06,774 W 19768 19768] gcs_client.cc:210: what"
                    said.append(re.sub(r"^\[[^]]*\]\s*\S+:\d+:\s*", "", lines[-1]))
    finally:
        os.close(saved)


PROBE_TIMEOUT_S = 5.0
"""How long :func:`probe_ray_address` waits to connect, and then for an answer."""

_H2_HELLO = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00\x04\x00\x00\x00\x00\x00"
"""HTTP/2's connection preface and an empty SETTINGS frame: a gRPC server (Ray's GCS, its client
server) answers with a SETTINGS frame of its own."""


def probe_ray_address(address: str, timeout: float = PROBE_TIMEOUT_S) -> None:
    """Refuse in one line (``--address: error: ...``) an address where no Ray can answer, before
    ``ray.init``, which retries an unreachable or foreign one for many minutes with a warning
    every few seconds: a host that does not resolve, a port nobody listens on or that does
    not answer within ``timeout`` seconds, or that does not speak gRPC (HTTP/2), as Ray's GCS
    and client server do (not checked with ``RAY_USE_TLS``, gRPC over TLS). ``auto`` and
    ``local`` are Ray's to find.

    >>> probe_ray_address("bogus")
    Traceback (most recent call last):
    ...
    mitlc.errors.InputError: --address: error: the Ray address 'bogus' is not HOST:PORT, ray://HOST:PORT or auto
    """
    if address in ("auto", "local"):
        return
    where = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = where.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"the Ray address {address!r} is not HOST:PORT, ray://HOST:PORT or auto", file="--address")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as conn:
            if os.environ.get("RAY_USE_TLS", "0").lower() not in ("0", "false", ""):
                return
            conn.sendall(_H2_HELLO)
            answer = b""
            while len(answer) < 9:
                chunk = conn.recv(9 - len(answer))
                if not chunk:
                    break
                answer += chunk
    except socket.gaierror as exc:
        why = f"unknown host {host!r} ({exc.strerror})"
        raise InputError(f"cannot reach Ray at {address}: {why}", file="--address") from None
    except TimeoutError:
        raise InputError(f"cannot reach Ray at {address}: no answer within {timeout:g} s", file="--address") from None
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise InputError(f"cannot reach Ray at {address}: {why.lower()}", file="--address") from None
    if len(answer) < 9 or answer[3] != 0x04:  # not a SETTINGS frame: no gRPC server there
        raise InputError(
            f"cannot reach Ray at {address}: the port answers, but not as Ray does (gRPC)", file="--address"
        )
