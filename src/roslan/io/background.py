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
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["BackgroundSink"]

_STOP = object()


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
        self._thread.start()
        self._closed = False
        self._aborted = False

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

    def abort(self) -> None:
        """Drop the calls still waiting, let the running one finish, stop the thread (for
        a failed run: afterwards nothing writes into its folder any more); no error."""
        if not self._closed:
            self._aborted = True
            self._closed = True
            self._q.put(_STOP)
            self._thread.join()
        self._error = None
