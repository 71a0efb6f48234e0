"""The two parts of a saved ``.rrd`` file that rerun-sdk stamps itself, made canonical.

:func:`roslan.view.recording.build_recording` gives every chunk, row id and chunk id a
value that depends on the run alone. Two parts of the file are written by rerun-sdk
after that and differ between two saves of the same recording:

* the row id of the **store-info message** (the first message of the stream): a TUID of
  the wall clock and a random increment;
* the **schema of the footer's manifest** (the recording's columns): its fields come in a
  hash set's order.

:func:`canonicalize_envelope` rewrites both in place: the row id becomes (the run's start
time, 0) and the schema's fields are sorted (control, index, data columns, each by
name; every field's metadata by key). Nothing else changes (the manifest's SHA-256 of
the schema does not depend on the fields' order: rerun writes the same one for any
order); the footer's Arrow schema is re-encoded by pyarrow (so the bytes are those of
the installed pyarrow), and its length, the ``End`` message header and the stream footer
(offset, size, xxHash32 checksum) follow. The layout is that of RRD format 0.41 (a
12-byte stream header ``RRF2``; length-prefixed protobuf messages; a 32-byte stream
footer ending in ``RRF2FOOT``); a file of another layout is left as written, valid but
not byte-reproducible, and the function says why.

The wire format is read here with a few lines of protobuf decoding rather than rerun's
generated classes: rerun-sdk does not expose them to Python.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable
from pathlib import Path

__all__ = ["canonicalize_envelope"]

_HEADER = 12  # b"RRF2", the writer's version (4 bytes), encoding options (4 bytes)
_MSG_HEADER = struct.Struct("<QQ")  # kind, length
_KIND_END, _KIND_STORE_INFO = 0, 1
_STREAM_FOOTER = struct.Struct("<QQI8sI")  # offset, size, checksum, b"RRF2FOOT", version
_FOOTER_MAGIC = b"RRF2FOOT"
_FOOTER_CHECKSUM_SEED = 7850921  # rerun's seed of the xxHash32 of the footer payload
_KIND_RANK = {b"control": 0, b"index": 1, b"data": 2}


class _Layout(Exception):
    """The file is not laid out as this module knows."""


def _varint(b: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if i >= len(b) or shift > 63:
            raise _Layout("truncated varint")
        c = b[i]
        i += 1
        value |= (c & 0x7F) << shift
        shift += 7
        if c < 0x80:
            return value, i


def _put_varint(n: int) -> bytes:
    out = bytearray()
    while True:
        if n < 0x80:
            out.append(n)
            return bytes(out)
        out.append((n & 0x7F) | 0x80)
        n >>= 7


# A protobuf message as its fields in file order: (number, wire type, raw bytes of the
# whole field, payload). Payload: the value of a varint, the bytes of anything else.
_Field = tuple[int, int, bytes, "int | bytes"]


def _fields(b: bytes) -> list[_Field]:
    out: list[_Field] = []
    i = 0
    while i < len(b):
        start = i
        key, i = _varint(b, i)
        number, wire = key >> 3, key & 7
        value: int | bytes
        if wire == 0:
            value, i = _varint(b, i)
        elif wire == 1:
            value, i = b[i : i + 8], i + 8
        elif wire == 5:
            value, i = b[i : i + 4], i + 4
        elif wire == 2:
            n, i = _varint(b, i)
            value, i = b[i : i + n], i + n
        else:
            raise _Layout(f"protobuf wire type {wire}")
        if i > len(b):
            raise _Layout("truncated protobuf field")
        out.append((number, wire, b[start:i], value))
    return out


def _bytes_field(number: int, payload: bytes) -> bytes:
    return _put_varint(number << 3 | 2) + _put_varint(len(payload)) + payload


def _replace(b: bytes, number: int, edit: Callable[[bytes], bytes]) -> bytes:
    """``b`` with every length-delimited field ``number`` replaced by ``edit(payload)``."""
    out = []
    for n, wire, raw, value in _fields(b):
        if n == number and wire == 2 and isinstance(value, bytes):
            out.append(_bytes_field(n, edit(value)))
        else:
            out.append(raw)
    return b"".join(out)


def _canonical_schema(ipc: bytes) -> bytes:
    """An Arrow IPC schema message with its fields (and all metadata) in a fixed order."""
    import pyarrow as pa

    schema = pa.ipc.read_schema(pa.py_buffer(ipc))

    def sorted_meta(meta: dict[bytes, bytes] | None) -> dict[bytes, bytes] | None:
        return None if meta is None else dict(sorted(meta.items()))

    def key(f: pa.Field) -> tuple[int, str]:
        kind = (f.metadata or {}).get(b"rerun:kind", b"data")
        return _KIND_RANK.get(kind, len(_KIND_RANK)), f.name

    fields = [f.with_metadata(sorted_meta(f.metadata)) for f in sorted(schema, key=key)]
    canonical = pa.schema(fields, metadata=sorted_meta(schema.metadata))
    return bytes(canonical.serialize().to_pybytes())


def _canonical_footer(footer: bytes) -> bytes:
    # RrdFooter: 1 = manifests; RrdManifest: 2 = sorbet schema; SorbetSchema: 1 = Arrow
    # IPC schema message. Everything else is kept byte for byte.
    def manifest(m: bytes) -> bytes:
        return _replace(m, 2, lambda s: _replace(s, 1, _canonical_schema))

    if not any(n == 1 for n, *_ in _fields(footer)):
        raise _Layout("footer without a manifest")
    return _replace(footer, 1, manifest)


def _store_info_row_id(head: bytes, stamp_ns: int) -> tuple[int, bytes]:
    """Where the store-info message's row id (two fixed64) is, and its canonical bytes."""
    kind, length = _MSG_HEADER.unpack_from(head, _HEADER)
    if kind != _KIND_STORE_INFO:
        raise _Layout(f"first message of kind {kind}")
    body_at = _HEADER + _MSG_HEADER.size
    body = head[body_at : body_at + length]
    if len(body) != length:
        raise _Layout("truncated store-info message")
    i = 0
    for number, wire, raw, value in _fields(body):
        if number == 1 and wire == 2 and isinstance(value, bytes):
            inner = _fields(value)
            if [(n, w) for n, w, *_ in inner] != [(1, 1), (2, 1)]:
                raise _Layout("store-info row id is not (time_ns, inc)")
            at = body_at + i + len(raw) - len(value)
            return at, struct.pack("<BQBQ", 0x09, stamp_ns, 0x11, 0)
        i += len(raw)
    raise _Layout("store-info message without a row id")


def canonicalize_envelope(path: Path, stamp_ns: int) -> str | None:
    """Make the store-info row id and the footer's manifest schema of the rrd file
    ``path`` canonical, in place. Returns ``None`` when done, else why the file was left
    as written (valid, but not byte-reproducible): not the RRD 0.41 layout this function
    knows, or no ``xxhash`` module to checksum the new footer with."""
    try:
        import xxhash
    except ImportError:
        return "the xxhash module is missing (pip install 'roslan[view]')"

    def checksum_of(b: bytes) -> int:
        return int(xxhash.xxh32_intdigest(b, seed=_FOOTER_CHECKSUM_SEED))

    unknown = "the installed rerun-sdk writes an RRD layout other than 0.41's"
    with path.open("r+b") as f:
        size = f.seek(0, os.SEEK_END)
        if size < _HEADER + _MSG_HEADER.size + _STREAM_FOOTER.size:
            return unknown
        f.seek(0)
        head = f.read(4096)
        f.seek(size - _STREAM_FOOTER.size)
        offset, length, checksum, magic, version = _STREAM_FOOTER.unpack(f.read())
        if head[:4] != b"RRF2" or magic != _FOOTER_MAGIC or version != 1:
            return unknown
        if offset + length + _STREAM_FOOTER.size != size or offset < _MSG_HEADER.size:
            return unknown
        f.seek(offset - _MSG_HEADER.size)
        end_kind, end_length = _MSG_HEADER.unpack(f.read(_MSG_HEADER.size))
        footer = f.read(length)
        if end_kind != _KIND_END or end_length != length or checksum_of(footer) != checksum:
            return unknown
        try:
            row_id_at, row_id = _store_info_row_id(head, stamp_ns)
            new = _canonical_footer(footer)
        except _Layout as e:
            return f"{unknown} ({e})"
        f.seek(row_id_at)
        f.write(row_id)
        f.seek(offset - _MSG_HEADER.size)
        f.write(_MSG_HEADER.pack(_KIND_END, len(new)))
        f.write(new)
        f.write(_STREAM_FOOTER.pack(offset, len(new), checksum_of(new), _FOOTER_MAGIC, version))
        f.truncate()
    return None
