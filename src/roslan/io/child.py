"""Child interpreters that talk to their parent through a socket pair.

Two kinds of roslan child processes use this: the sensor worker processes
(:mod:`roslan.pipeline.worker`) and the event camera's render helpers
(:mod:`roslan.sensors.cameras.event_chains`). Both follow the same rules:

* a child is a fresh interpreter (``python -c CODE FD PID``), never a ``fork`` of a
  process that may already hold EGL / Embree threads and never a re-import of the
  caller's ``__main__``; it imports what the parent can (its ``sys.path`` is passed as
  ``PYTHONPATH``) and gets its work pickled through the socket (:func:`spawn`);
* it ignores SIGINT (the parent handles Ctrl-C and terminates it), dies with its parent
  (``PR_SET_PDEATHSIG`` on Linux) and gets EPIPE if the parent goes away anyway
  (:func:`child_connection`);
* an exception in the child is sent as an :func:`error_record` and raised again in the
  parent by :func:`raise_error_record`: the same exception type and message where it
  pickles, with the child's traceback text attached as ``__cause__``;
* a child that dies (killed, crashed) is described by :func:`death_message`, and
  :func:`stop_child` ends one for good (SIGTERM, then SIGKILL, reaped).

:class:`ChildProcess` is the parent's handle of one such child (start, send, why it
died, wait for its clean exit, kill), and :func:`end_child` the child's last act (its
connection closed, its output flushed, no interpreter teardown); both kinds of child use
them.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import socket
import subprocess
import sys
import traceback
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any, NoReturn

from roslan.errors import RoslanError

__all__ = [
    "JOIN_TIMEOUT_S",
    "ChildError",
    "ChildProcess",
    "RemoteTraceback",
    "child_connection",
    "death_message",
    "end_child",
    "error_blob",
    "error_record",
    "raise_error_record",
    "spawn",
    "stop_child",
]

JOIN_TIMEOUT_S = 30.0
"""Longest wait for a finished child to exit, and for a terminated one (then SIGKILL)."""


class ChildError(RoslanError):
    """A roslan child process died or broke its protocol (not an error of its own work)."""


class RemoteTraceback(Exception):
    """Carries a child's traceback text as the ``__cause__`` of a re-raised error."""

    def __init__(self, tb: str, where: str = "the worker process") -> None:
        super().__init__(tb)
        self.tb = tb
        self.where = where

    def __str__(self) -> str:
        return f"\n\n(in {self.where})\n{self.tb}"


# ---------------------------------------------------------------------------- parent side
def spawn(
    code: str, what: str, args: Sequence[str] = ()
) -> tuple[subprocess.Popen[bytes], Connection]:
    """Start ``python -c code FD PID *args`` and return it with the parent's end of its
    socket.

    Raises:
        ChildError: the interpreter cannot be started (``what`` names the child).
    """
    parent_sock, child_sock = socket.socketpair()
    conn = Connection(parent_sock.detach())
    child_fd = child_sock.detach()
    env = dict(os.environ)
    # the child imports what this process can (tests, source trees on sys.path)
    env["PYTHONPATH"] = os.pathsep.join(p or os.getcwd() for p in sys.path)
    try:
        proc = subprocess.Popen(
            [sys.executable, "-c", code, str(child_fd), str(os.getpid()), *args],
            pass_fds=(child_fd,),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            env=env,
        )
    except OSError as err:
        conn.close()
        msg = f"cannot start {what} ({sys.executable}): {err}"
        raise ChildError(msg) from err
    finally:
        os.close(child_fd)  # only the child holds its end: its death means EOF here
    return proc, conn


def death_message(proc: subprocess.Popen[bytes], describe: str, doing: str) -> str:
    """``'<describe> was killed by signal 9 <doing>'`` (or exited / is stuck): why a
    child's connection ended early (waits up to :data:`JOIN_TIMEOUT_S` for it)."""
    try:
        code = proc.wait(JOIN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        code = None
    how = (
        "is stuck"
        if code is None
        else f"was killed by signal {-code}"
        if code < 0
        else f"exited with status {code}"
    )
    return f"{describe} {how} {doing}"


def stop_child(proc: subprocess.Popen[bytes], conn: Connection | None) -> None:
    """Stop a child now (SIGTERM, then SIGKILL) and reap it."""
    if conn is not None:
        with contextlib.suppress(Exception):
            conn.close()
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            proc.wait(JOIN_TIMEOUT_S)


class ChildProcess:
    """The parent's handle of one child interpreter (see the module docstring).

    Args:
        code: the child's ``python -c`` program; ``what``: what it is, for messages
            (``'a sensor worker process'``); ``args``: its arguments after ``FD PID``.
    Raises:
        ChildError: the interpreter cannot be started.
    """

    error: type[ChildError] = ChildError
    """The exception a subclass raises for a child that died or exited badly."""

    def __init__(self, code: str, what: str, args: Sequence[str] = ()) -> None:
        self.what = what
        self.proc, self.conn = spawn(code, what, args)

    def describe(self) -> str:
        """Who it is, for messages (subclasses say what it runs)."""
        return f"{self.what} (pid {self.proc.pid})"

    def send(self, obj: Any) -> None:
        """Send one pickled object (OSError: the child is gone)."""
        self.conn.send_bytes(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))

    def died(self, doing: str) -> ChildError:
        """The error of a child whose connection ended early, ``doing`` what."""
        return self.error(death_message(self.proc, self.describe(), doing))

    def join(self) -> None:
        """Wait for a child that finished its work to exit, then close its connection
        (a hung exit is killed: its work was delivered). Raises :attr:`error` for a
        non-zero exit status."""
        try:
            code = self.proc.wait(JOIN_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.kill()
            code = 0
        self.conn.close()
        if code != 0:
            msg = f"{self.describe()} exited with status {code} after finishing"
            raise self.error(msg)

    def kill(self) -> None:
        """Stop the child now (SIGTERM, then SIGKILL) and reap it."""
        stop_child(self.proc, self.conn)


def raise_error_record(rec: Sequence[Any], describe: str, where: str) -> NoReturn:
    """Raise the exception of an :func:`error_record` received from a child."""
    _, exc_blob, type_name, text, tb = rec
    exc: BaseException | None = None
    if exc_blob is not None:
        with contextlib.suppress(Exception):
            exc = pickle.loads(exc_blob)
    if exc is None:
        exc = ChildError(f"{describe} failed: {type_name}: {text}")
    raise exc from RemoteTraceback(tb, where)


# ---------------------------------------------------------------------------- child side
def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to SIGTERM this process when its parent dies; exit if it already has."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG
    if os.getppid() != parent_pid:
        os._exit(1)


def child_connection(argv: Sequence[str] | None = None) -> Connection:
    """In the child (``argv`` = ``FD PID ...``, default ``sys.argv[1:]``): set the signal
    rules of the module docstring and return the connection to the parent."""
    args = list(sys.argv[1:] if argv is None else argv)
    fd, parent_pid = int(args[0]), int(args[1])
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and stops us
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent(parent_pid)
    return Connection(fd)


def end_child(conn: Connection, code: int) -> NoReturn:
    """The child's end: close its connection, flush its output, exit with ``code``
    without interpreter teardown (files are closed; EGL/Embree exit handlers add
    nothing)."""
    with contextlib.suppress(BaseException):
        conn.close()
    with contextlib.suppress(BaseException):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(code)


def error_blob(err: BaseException) -> bytes:
    """The pickled :func:`error_record` of ``err``, ready to send to the parent."""
    return pickle.dumps(error_record(err), protocol=pickle.HIGHEST_PROTOCOL)


def error_record(err: BaseException) -> tuple[Any, ...]:
    """``("error", pickled exception or None, type name, message, traceback text)``."""
    tb = "".join(traceback.format_exception(err))
    blob: bytes | None
    try:
        blob = pickle.dumps(err, protocol=pickle.HIGHEST_PROTOCOL)
        pickle.loads(blob)  # must come back whole in the parent
    except Exception:
        blob = None
    return ("error", blob, type(err).__name__, str(err), tb)
