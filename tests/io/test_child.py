"""The child-process handle both roslan children use: a clean exit, a bad exit status,
a killed child, an error raised in the child coming back with its type and message."""

from __future__ import annotations

import pickle
import signal

import pytest

from roslan.errors import ConfigError
from roslan.io.child import ChildError, ChildProcess, raise_error_record

# echoes one pickled object back, then exits with the status it was sent (or raises)
_CODE = """
import pickle
from roslan.io.child import child_connection, end_child, error_blob
from roslan.errors import ConfigError
conn = child_connection()
code = 0
try:
    obj = pickle.loads(conn.recv_bytes())
    if obj == "raise":
        raise ConfigError("sensors[0].rate = -1: allowed: > 0")
    conn.send_bytes(pickle.dumps(("echo", obj)))
    code = int(pickle.loads(conn.recv_bytes()))
except BaseException as err:
    code = 1
    conn.send_bytes(error_blob(err))
end_child(conn, code)
"""


class _Test(ChildProcess):
    def __init__(self) -> None:
        super().__init__(_CODE, "a test child")


def test_a_child_echoes_and_exits_cleanly() -> None:
    c = _Test()
    c.send({"a": 1})
    assert pickle.loads(c.conn.recv_bytes()) == ("echo", {"a": 1})
    c.send(0)
    c.join()
    assert c.proc.returncode == 0


def test_a_bad_exit_status_is_a_child_error_naming_it() -> None:
    c = _Test()
    c.send("x")
    c.conn.recv_bytes()
    c.send(3)
    with pytest.raises(ChildError, match=r"a test child \(pid \d+\) exited with status 3"):
        c.join()


def test_an_error_in_the_child_comes_back_with_its_type_and_message() -> None:
    c = _Test()
    c.send("raise")
    rec = pickle.loads(c.conn.recv_bytes())
    with pytest.raises(ConfigError, match=r"sensors\[0\]\.rate = -1") as info:
        raise_error_record(rec, c.describe(), "the test child")
    assert "ConfigError" in str(info.value.__cause__)
    with pytest.raises(ChildError, match="exited with status 1"):
        c.join()


def test_a_killed_child_is_described_by_its_signal() -> None:
    c = _Test()
    c.proc.send_signal(signal.SIGKILL)
    err = c.died("while testing")
    assert "was killed by signal 9 while testing" in str(err)
    c.kill()  # idempotent on a dead child
    assert c.proc.returncode == -9
