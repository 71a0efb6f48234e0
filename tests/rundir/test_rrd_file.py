"""The envelope of a saved .rrd file made canonical (roslan.view.rrd_file): the store-info
row id and the footer manifest's schema. Judged by rerun itself (``check_for_rrd_footer``
verifies the footer's checksum, ``rrd verify`` and ``rrd compare`` read the whole file)
and by pyarrow reading the footer's schema straight from the file's bytes."""

from __future__ import annotations

import shutil
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pyarrow as pa
import pytest

rr = pytest.importorskip("rerun")
pytest.importorskip("xxhash")

from roslan.view.rrd_file import canonicalize_envelope  # noqa: E402

STAMP = 1_700_000_000_123_456_789
# the store-info message's row id: 12 bytes of stream header, 16 of message header, the
# row id's field key and length (2), then two fixed64 fields: tag, time_ns, tag, inc
ROW_ID = slice(30, 48)


def _save(path: Path) -> None:
    """A small recording with many columns (a footer schema in a hash set's order)."""
    rec = rr.RecordingStream("roslan-test", recording_id="fixed", send_properties=False)
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    rec.save(str(path))
    for k in range(12):
        rec.set_time("trajectory_time", duration=0.1 * k)
        rec.log(f"world/series_{k}", rr.Scalars([float(k)]))
        rec.log(f"world/points_{k % 3}", rr.Points3D([[k, 0.0, 1.0]], radii=[0.1]))
    rec.flush()
    rec.disconnect()


def _footer_schema(data: bytes) -> pa.Schema:
    """The footer manifest's Arrow schema: the footer from the 32-byte stream footer's
    offset and size, the schema the first Arrow IPC message in it."""
    offset, size = struct.unpack_from("<QQ", data, len(data) - 32)
    assert data[-12:] == b"RRF2FOOT\x01\x00\x00\x00"
    footer = data[offset : offset + size]
    return pa.ipc.read_schema(pa.py_buffer(footer[footer.index(b"\xff\xff\xff\xff") :]))


def _fields(schema: pa.Schema) -> dict[str, tuple[str, dict[bytes, bytes]]]:
    return {f.name: (str(f.type), dict(f.metadata or {})) for f in schema}


def _rerun_cli() -> str:
    cli = Path(sys.executable).parent / "rerun"
    exe = str(cli) if cli.is_file() else shutil.which("rerun")
    assert exe is not None, "the rerun CLI of rerun-sdk is not installed"
    return exe


@pytest.fixture
def saved(tmp_path: Path) -> tuple[Path, bytes]:
    path = tmp_path / "a.rrd"
    _save(path)
    return path, path.read_bytes()


def test_row_id_and_footer_schema_become_canonical(saved: tuple[Path, bytes]) -> None:
    import rerun_bindings

    path, before = saved
    assert canonicalize_envelope(path, STAMP) is None
    after = path.read_bytes()
    # the row id is (the stamp, 0); the data between it and the footer is untouched
    assert before[ROW_ID.start - 2 : ROW_ID.start] == b"\x0a\x12"  # field 1, 18 bytes
    assert struct.unpack("<BQBQ", after[ROW_ID]) == (0x09, STAMP, 0x11, 0)
    assert struct.unpack("<BQBQ", before[ROW_ID])[0::2] == (0x09, 0x11)
    offset = struct.unpack_from("<Q", before, len(before) - 32)[0]
    assert after[: ROW_ID.start] == before[: ROW_ID.start]
    # the End message's header (kind 0, the footer's length) sits just before the footer
    assert after[ROW_ID.stop : offset - 16] == before[ROW_ID.stop : offset - 16]
    assert struct.unpack_from("<QQ", after, offset - 16) == (0, len(after) - 32 - offset)
    # the footer schema: the same fields, types and metadata, in the canonical order
    old, new = _footer_schema(before), _footer_schema(after)
    assert _fields(new) == _fields(old)
    kinds = [(f.metadata or {})[b"rerun:kind"] for f in new]
    assert kinds[:2] == [b"control", b"index"]
    assert set(kinds[2:]) == {b"data"}
    assert new.names[2:] == sorted(new.names[2:])
    assert len(new) == 2 + 12 + 3 * 2  # row id, time; 12 series; 3 x (positions, radii)
    for f in new:
        assert list(f.metadata) == sorted(f.metadata)
    # rerun checks the new footer's checksum and reads every chunk the same
    assert rerun_bindings.check_for_rrd_footer(str(path))
    keep = path.with_name("before.rrd")
    keep.write_bytes(before)
    for args in (["verify", str(path)], ["compare", str(keep), str(path)]):
        proc = subprocess.run(
            [_rerun_cli(), "rrd", *args], capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 0, proc.stdout + proc.stderr


def test_two_saves_differ_only_where_rerun_stamps_them(tmp_path: Path) -> None:
    """Two recordings of the same rows: their footer schemas come in different orders and
    their store-info row ids differ; made canonical, both are the same."""
    schemas, row_ids = [], []
    for name in ("a.rrd", "b.rrd"):
        path = tmp_path / name
        _save(path)
        raw = path.read_bytes()
        assert canonicalize_envelope(path, STAMP) is None
        done = path.read_bytes()
        schemas.append((_footer_schema(raw).names, _footer_schema(done)))
        row_ids.append((raw[ROW_ID], done[ROW_ID]))
    assert row_ids[0][0] != row_ids[1][0]  # the wall clock, before
    assert row_ids[0][1] == row_ids[1][1]
    assert schemas[0][1].equals(schemas[1][1], check_metadata=True)
    assert schemas[0][1].names == schemas[1][1].names


def test_canonical_is_idempotent(saved: tuple[Path, bytes]) -> None:
    path, _ = saved
    assert canonicalize_envelope(path, STAMP) is None
    once = path.read_bytes()
    assert canonicalize_envelope(path, STAMP) is None
    assert path.read_bytes() == once


@pytest.mark.parametrize(
    "damage",
    [
        pytest.param(lambda b: b[:-5], id="truncated"),
        pytest.param(lambda b: b[:-12] + b"RRF3FOOT" + b[-4:], id="other-footer-magic"),
        pytest.param(lambda b: b[:-16] + bytes([b[-16] ^ 1]) + b[-15:], id="bad-checksum"),
        pytest.param(lambda b: b[:12] + struct.pack("<Q", 2) + b[20:], id="no-store-info"),
        pytest.param(lambda b: b"RRF1" + b[4:], id="other-header"),
    ],
)
def test_an_unknown_layout_is_left_as_written(
    saved: tuple[Path, bytes], damage: Callable[[bytes], bytes]
) -> None:
    path, before = saved
    bad = damage(before)
    path.write_bytes(bad)
    why = canonicalize_envelope(path, STAMP)
    assert why is not None
    assert "layout" in why
    assert path.read_bytes() == bad


def test_without_xxhash_the_file_is_left_as_written(
    saved: tuple[Path, bytes], monkeypatch: pytest.MonkeyPatch
) -> None:
    import builtins

    path, before = saved
    real_import = builtins.__import__

    def no_xxhash(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "xxhash":
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_xxhash)
    why = canonicalize_envelope(path, STAMP)
    assert why is not None
    assert "xxhash" in why
    assert "roslan[view]" in why
    assert path.read_bytes() == before
