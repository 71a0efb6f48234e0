"""Dataset-file writing in a background thread, in order, with a bounded backlog.

A sensor that renders (the event camera) spends much of each frame in code that holds
the GIL (moderngl) or waits for Mesa's threads, while its dataset files (events.txt,
events.h5, PNG frames) are written by code that releases the GIL (numba ``nogil``
formatting, zlib/HDF5 compression, OpenCV's PNG encoder, file I/O). :class:`BackgroundSink`
runs those writes on one worker thread so they overlap with the next frame: the calls
run one at a time in submission order, so the files are byte-identical to writing
inline. At most ``backlog`` calls wait (bounded memory); the first exception of a call is
raised again in the submitting thread by the next :meth:`BackgroundSink.submit` or by
:meth:`BackgroundSink.close`; :meth:`BackgroundSink.abort` stops it for a failed run
before its output folder is removed.

A sink's thread is a daemon (a forgotten sink never blocks the interpreter's exit), so
every live sink is stopped at exit (:func:`stop_all`, an ``atexit`` handler): the
interpreter ends daemon threads by unwinding them when they next take the GIL, and a
thread unwound out of a C++ call that released the GIL (an OpenCV PNG encode, say) aborts
the whole process (``terminate called without an active exception``, exit status 134).
The handler runs before that, while the threads can still finish their running call.
"""

from __future__ import annotations

import atexit
import queue
import threading
import weakref
from collections.abc import Callable
from typing import Any

__all__ = ["EXIT_JOIN_S", "BackgroundSink", "stop_all"]

_STOP = object()

EXIT_JOIN_S = 30.0
"""Longest wait at interpreter exit for one sink's running call (:func:`stop_all`)."""

_LIVE: weakref.WeakSet[BackgroundSink] = weakref.WeakSet()


class BackgroundSink:
    """One writer thread executing submitted calls in order.

    Args:
        name: thread name (shows in profilers).
        backlog: most calls waiting; :meth:`submit` blocks when full.
    """

    def __init__(self, name: str, backlog: int = 32) -> None:
        self._q: queue.Queue[Any] = queue.Queue(maxsize=max(1, int(backlog)))
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._closed = False
        self._aborted = False
        self._thread.start()
        _LIVE.add(self)

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is _STOP:
                return
            if self._error is not None or self._aborted:
                continue  # drain without running: the first error is reported
            fn, args = item
            try:
                fn(*args)
            except BaseException as err:  # handed to the submitting thread
                self._error = err

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        """Queue ``fn(*args)``; raises the error of an earlier call, if any (and stops)."""
        if self._closed:
            msg = "BackgroundSink is closed"
            raise RuntimeError(msg)
        if self._error is not None:
            self.close()
        self._q.put((fn, args))

    def close(self) -> None:
        """Run everything queued, stop the thread, raise the first error of any call."""
        if not self._closed:
            self._closed = True
            self._q.put(_STOP)
            self._thread.join()
        err, self._error = self._error, None
        if err is not None:
            raise err

    def abort(self, timeout: float | None = None) -> None:
        """Drop the calls still waiting, let the running one finish, stop the thread (for
        a failed run: afterwards nothing writes into its folder any more); no error.
        ``timeout``: wait at most this long for the running call (None: no limit)."""
        if not self._closed:
            self._aborted = True
            self._closed = True
            self._q.put(_STOP)  # (never blocks for long: an aborted thread drains)
        self._thread.join(timeout)
        self._error = None


def stop_all() -> None:
    """Abort every live sink (registered with ``atexit``; see the module docstring)."""
    for sink in list(_LIVE):
        sink.abort(EXIT_JOIN_S)


atexit.register(stop_all)
