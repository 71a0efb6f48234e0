"""Per-instant work of a sensor on a few threads, handed back in submission order.

A frame or scan sensor renders (one OpenGL context: its own thread) or casts, then spends
most of each instant in work that is independent of the other instants and releases the
GIL: lens remap (OpenCV), noise, 8-bit encoding (numba ``nogil``), PNG and ``.npz``
compression (OpenCV, zlib), Embree ray casting. :class:`OrderedPool` runs that work for
instant ``k`` on one of ``threads`` threads while the sensor's own thread goes on to
instant ``k + 1``, and gives the results back strictly in submission order, so every file
and message is the same whatever the number of threads:

* at most ``depth`` calls are in flight (running, waiting, or done and not yet handed
  back): :meth:`OrderedPool.submit` blocks on the oldest beyond that, so memory stays
  flat in the trajectory's length;
* random draws whose count depends on the data (Poisson shot noise) stay in time order:
  each call gets a :class:`Turn`; the code inside ``with turn:`` runs only after every
  earlier call has left its own turn block or ended, so one generator consumed there
  gives the same stream as drawing inline, frame after frame;
* a call's exception is raised again, unchanged (same type and message), on the thread
  that collects its result, in submission order;
* :meth:`OrderedPool.close` (call it in a ``finally``) drops the calls not yet started,
  wakes the ones waiting for their turn and waits for the running ones: afterwards
  nothing writes into the run's folder any more (a failed run removes it next);
* ``threads == 1`` runs every call inline in :meth:`OrderedPool.submit`: no thread at all;
* ``executor``: the calls run on a shared executor instead of the pool's own threads (the
  bags' chunk compression, :class:`~roslan.io.bag_threads.OrderedChunks`); closing the
  pool then cancels its own waiting calls and waits for its running ones, and leaves the
  executor to its owner.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor, wait
from typing import Any, Generic, TypeVar

__all__ = ["OrderedPool", "PoolClosedError", "Turn"]

T = TypeVar("T")


class PoolClosedError(RuntimeError):
    """Raised in a call waiting for its turn when its pool is closed (a failed run)."""


class _Turns:
    """Turn bookkeeping: turn ``k`` may start once every call before ``k`` is past its
    turn (left its turn block, or ended without entering one)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._next = 0  # every call before this index is past its turn
        self._past: set[int] = set()
        self._closed = False

    def wait(self, index: int) -> None:
        with self._cond:
            self._cond.wait_for(lambda: self._closed or self._next == index)
            if self._next != index:
                msg = "the sensor's thread pool was closed"
                raise PoolClosedError(msg)

    def done(self, index: int) -> None:
        with self._cond:
            self._past.add(index)
            while self._next in self._past:
                self._past.discard(self._next)
                self._next += 1
            self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class Turn:
    """``with turn:`` runs its block after the turn blocks of every earlier call of the
    same pool (use it once per call, for the draws of a shared random generator)."""

    __slots__ = ("_index", "_state", "_turns")

    def __init__(self, turns: _Turns, index: int) -> None:
        self._turns = turns
        self._index = index
        self._state = 0  # 0: not entered, 1: inside, 2: past

    def __enter__(self) -> Turn:
        if self._state != 0:
            msg = "a Turn is entered once"
            raise RuntimeError(msg)
        self._turns.wait(self._index)
        self._state = 1
        return self

    def __exit__(self, *exc: object) -> None:
        self._finish()

    def _finish(self) -> None:
        if self._state != 2:
            self._state = 2
            self._turns.done(self._index)


class OrderedPool(Generic[T]):
    """Calls ``fn(turn, *args)`` on ``threads`` threads; results in submission order.

    Args:
        threads: worker threads of its own (1: every call runs inline in :meth:`submit`).
        name: thread name prefix (shows in profilers).
        depth: most calls in flight (default ``2 * threads``; at least ``threads``).
        executor: run the calls on this shared executor instead (``threads`` then only
            sets the default ``depth``); None: the pool's own threads.
    """

    def __init__(
        self, threads: int, name: str, depth: int | None = None, *, executor: Executor | None = None
    ) -> None:
        self.threads = max(1, int(threads))
        self.depth = max(self.threads, int(depth) if depth is not None else 2 * self.threads)
        self._turns = _Turns()
        self._count = 0
        self._pending: deque[Future[T]] = deque()
        self._exec: Executor | None = executor
        self._owned = executor is None and self.threads > 1
        if self._owned:
            self._exec = ThreadPoolExecutor(self.threads, thread_name_prefix=name)
        self._closed = False

    @property
    def inline(self) -> bool:
        """Whether calls run on the submitting thread (``threads == 1``)."""
        return self._exec is None

    @property
    def in_flight(self) -> int:
        """Calls submitted whose results are not yet handed back."""
        return len(self._pending)

    def _call(self, turn: Turn, fn: Callable[..., T], args: tuple[Any, ...]) -> T:
        try:
            return fn(turn, *args)
        finally:
            turn._finish()

    def submit(self, fn: Callable[..., T], *args: Any) -> list[T]:
        """Start ``fn(turn, *args)``; returns the results now ready at the head of the
        queue, in order (waiting for the oldest while ``depth`` calls are in flight).

        Raises:
            Exception: the exception of a call, when its result is due.
        """
        if self._closed:
            msg = "OrderedPool is closed"
            raise RuntimeError(msg)
        turn = Turn(self._turns, self._count)
        self._count += 1
        if self._exec is None:
            return [self._call(turn, fn, args)]
        self._pending.append(self._exec.submit(self._call, turn, fn, args))
        return self._ready(self.depth - 1)

    def finish(self) -> list[T]:
        """Every remaining result, in order (waiting for them)."""
        return self._ready(0)

    def _ready(self, keep: int) -> list[T]:
        out: list[T] = []
        pending = self._pending
        while pending and (len(pending) > keep or pending[0].done()):
            out.append(pending.popleft().result())
        return out

    def close(self) -> None:
        """Stop: drop the calls not started, wake those waiting for their turn, wait for
        the running ones; results not collected are lost. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._turns.close()
        if self._owned and self._exec is not None:
            self._exec.shutdown(wait=True, cancel_futures=True)
        elif self._pending:  # a shared executor: only this pool's calls
            for fut in self._pending:
                fut.cancel()
            wait(self._pending)
        self._pending.clear()
