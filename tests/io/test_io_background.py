"""BackgroundSink: calls run in order on one thread; errors come back to the submitter."""

from __future__ import annotations

import subprocess
import sys
import threading

import pytest

from roslan.io.background import BackgroundSink


def test_calls_run_in_submission_order_on_one_other_thread() -> None:
    seen: list[tuple[int, str]] = []
    sink = BackgroundSink("t", backlog=2)  # a small backlog: submit blocks and resumes
    for i in range(200):
        sink.submit(lambda i: seen.append((i, threading.current_thread().name)), i)
    sink.close()
    assert [i for i, _ in seen] == list(range(200))
    assert {name for _, name in seen} == {"t"}
    assert threading.current_thread().name != "t"
    sink.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        sink.submit(print)


def test_first_error_is_raised_by_close_and_later_calls_do_not_run() -> None:
    ran: list[int] = []

    def work(i: int) -> None:
        if i == 3:
            msg = "disk full"
            raise OSError(msg)
        ran.append(i)

    sink = BackgroundSink("t")
    for i in range(3):
        sink.submit(work, i)
    sink.submit(work, 3)
    sink.submit(work, 4)
    with pytest.raises(OSError, match="disk full"):
        sink.close()
    assert ran == [0, 1, 2]


def test_error_is_raised_by_the_next_submit() -> None:
    sink = BackgroundSink("t")
    done = threading.Event()

    def boom() -> None:
        done.set()
        msg = "bad"
        raise ValueError(msg)

    sink.submit(boom)
    done.wait(5)
    for _ in range(100):  # the error is recorded right after the call returns
        if sink._error is not None:
            break
        threading.Event().wait(0.01)
    with pytest.raises(ValueError, match="bad"):
        sink.submit(print, "never")


def test_abort_drops_waiting_calls_and_stops_the_thread() -> None:
    ran: list[int] = []
    gate, started = threading.Event(), threading.Event()

    def work(i: int) -> None:
        started.set()
        gate.wait(5)
        ran.append(i)

    sink = BackgroundSink("t", backlog=8)
    for i in range(5):
        sink.submit(work, i)
    assert started.wait(5)  # call 0 is running, calls 1-4 wait
    threading.Timer(0.05, gate.set).start()
    sink.abort()  # the running call finishes; the four waiting ones never run
    assert ran == [0]
    assert not any(t.name == "t" and t.is_alive() for t in threading.enumerate())
    sink.close()  # no error after an abort
    with pytest.raises(RuntimeError, match="closed"):
        sink.submit(work, 9)


# Ten forked children each leave a sink busy with OpenCV calls (which release the GIL in
# C++) and exit normally; without the exit handler the interpreter unwinds the thread out
# of the C++ call and the child aborts (SIGABRT, "terminate called without an active
# exception"), as unclosed environments did.
_BUSY_AT_EXIT = """
import os, time
import numpy as np, cv2
from roslan.io.background import BackgroundSink
img = np.zeros((400, 400), np.float32)
codes = []
for _ in range(10):
    pid = os.fork()
    if pid == 0:
        sink = BackgroundSink("busy", backlog=1000)
        for _ in range(1000):
            sink.submit(cv2.GaussianBlur, img, (31, 31), 5.0)
        time.sleep(0.05)  # the thread is inside a call
        break  # the child's interpreter exits as a script's does
    codes.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
else:
    print(codes)
"""


def test_a_sink_busy_at_interpreter_exit_exits_cleanly() -> None:
    out = subprocess.run(
        [sys.executable, "-c", _BUSY_AT_EXIT], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[0] == str([0] * 10), out.stderr
    assert "terminate called" not in out.stderr
