"""The one way roslan reads a user's file: configs, scene files, sweeps, calibration YAML,
meshes and textures.

* Only regular files (a FIFO, a device such as ``/dev/zero`` or a folder is refused before
  it is opened; the open itself never blocks).
* A size cap per kind of file (:data:`MAX_YAML_BYTES`, :data:`MAX_MESH_BYTES`,
  :data:`MAX_IMAGE_BYTES`), checked on the open file, and reading stops at the cap.
* YAML: numbers in exponent notation (``1e-3``) are numbers, as in YAML 1.2; duplicate
  keys are refused; nesting depth (:data:`MAX_YAML_DEPTH`), aliases
  (:data:`MAX_YAML_ALIASES`) and the size of the document once every alias is expanded
  (:data:`MAX_YAML_NODES`) are bounded, so a "billion laughs" file fails at once, in
  little memory; a recursive alias is refused.
* Images: the header's width x height is checked (:data:`MAX_IMAGE_PIXELS`) before any
  pixel is decoded.

Every failure is a :class:`~roslan.errors.ConfigError` (or the subclass the caller asks
for) whose one-line message names the file and, for YAML, the line.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import warnings
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from roslan.errors import ConfigError

__all__ = [
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
    "MAX_MESH_BYTES",
    "MAX_YAML_ALIASES",
    "MAX_YAML_BYTES",
    "MAX_YAML_DEPTH",
    "MAX_YAML_NODES",
    "check_image_header",
    "check_regular_file",
    "os_error_text",
    "parse_yaml",
    "read_text",
]

MAX_YAML_BYTES = 8 * 1024 * 1024
"""Largest config, scene, sweep or calibration YAML file (8 MiB)."""
MAX_MESH_BYTES = 1024 * 1024 * 1024
"""Largest model file (OBJ, glTF/GLB, STL, PLY): 1 GiB."""
MAX_IMAGE_BYTES = 512 * 1024 * 1024
"""Largest texture file: 512 MiB."""
MAX_IMAGE_PIXELS = 8192 * 8192
"""Largest texture (width x height from its header): 64 Mpx."""
MAX_YAML_DEPTH = 64
"""Deepest nesting of mappings/lists in a YAML file."""
MAX_YAML_ALIASES = 10_000
"""Most ``*alias`` references in one YAML file."""
MAX_YAML_NODES = 1_000_000
"""Most values in one YAML document once every alias is expanded."""


class _Refused(yaml.YAMLError):
    def __init__(self, problem: str, mark: Any = None) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


def os_error_text(err: OSError) -> str:
    """``strerror`` of an OSError (``"No space left on device"``), else its text."""
    return err.strerror or str(err)


def check_regular_file(
    path: str | Path, max_bytes: int, error: type[ConfigError] = ConfigError
) -> int:
    """Size of ``path`` in bytes; ``error`` when it is missing, not a regular file or too big."""
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise error(f"{p}: file not found") from None
    except OSError as err:
        raise error(f"{p}: cannot read file: {os_error_text(err)}") from None
    _check_stat(p, st, max_bytes, error)
    return st.st_size


def _check_stat(p: Path, st: os.stat_result, max_bytes: int, error: type[ConfigError]) -> None:
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{p}: is a folder, not a file")
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a FIFO"
            if stat.S_ISFIFO(st.st_mode)
            else "a device"
            if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
            else "a socket"
            if stat.S_ISSOCK(st.st_mode)
            else "not a regular file"
        )
        raise error(f"{p}: {kind}, not a regular file; give a regular file")
    if st.st_size > max_bytes:
        raise error(f"{p}: file is {st.st_size} bytes; the limit is {max_bytes} bytes")


def read_bytes(path: str | Path, max_bytes: int, error: type[ConfigError] = ConfigError) -> bytes:
    """The content of a regular file of at most ``max_bytes`` (never blocks on a FIFO)."""
    p = Path(path)
    check_regular_file(p, max_bytes, error)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as err:
        if err.errno == errno.ENOENT:
            raise error(f"{p}: file not found") from None
        raise error(f"{p}: cannot read file: {os_error_text(err)}") from None
    try:
        _check_stat(p, os.fstat(fd), max_bytes, error)  # the file opened is the file checked
        chunks = []
        left = max_bytes + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as err:
        raise error(f"{p}: cannot read file: {os_error_text(err)}") from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > max_bytes:
        raise error(f"{p}: file grew past the limit of {max_bytes} bytes while being read")
    return data


def read_text(
    path: str | Path, max_bytes: int = MAX_YAML_BYTES, error: type[ConfigError] = ConfigError
) -> str:
    """A UTF-8 text file read with :func:`read_bytes`."""
    data = read_bytes(path, max_bytes, error)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise error(f"{path}: not UTF-8 text (byte {err.start})") from None


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader with duplicate keys refused and depth/alias/expanded-size bounds."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_YAML_ALIASES:
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                msg = f"more than {MAX_YAML_ALIASES} aliases (*name references)"
                raise _Refused(msg, mark)
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                raise _Refused(f"nested deeper than {MAX_YAML_DEPTH} levels", mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_node(self) -> Node | None:
        node: Node | None = super().get_single_node()
        if node is not None:
            _expanded_size(node)
        return node

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, MappingNode):
            seen: set[Any] = set()
            for key_node, _ in node.value:
                if (
                    not isinstance(key_node, ScalarNode)
                    or key_node.tag == "tag:yaml.org,2002:merge"
                ):
                    continue
                key = self.construct_object(key_node)
                try:
                    dup = key in seen
                except TypeError:
                    continue
                if dup:
                    raise ConstructorError(
                        None, None, f"duplicate key {str(key)[:60]!r}", key_node.start_mark
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.2 floats PyYAML (YAML 1.1) reads as text: 1e-3, 1.0e9, 5E+6
_BoundedLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _expanded_size(root: Node) -> int:
    """Number of values in the document with every alias expanded (bounded, cycle-safe)."""
    sizes: dict[int, int] = {}
    busy: set[int] = set()

    def size(node: Node, depth: int) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in busy:
            raise _Refused("recursive alias (a value that contains itself)", node.start_mark)
        if depth > MAX_YAML_DEPTH:
            raise _Refused(
                f"nested deeper than {MAX_YAML_DEPTH} levels once aliases are expanded",
                node.start_mark,
            )
        busy.add(key)
        total = 1
        if isinstance(node, SequenceNode):
            for child in node.value:
                total += size(child, depth + 1)
                if total > MAX_YAML_NODES:
                    break
        elif isinstance(node, MappingNode):
            for k, v in node.value:
                total += size(k, depth + 1) + size(v, depth + 1)
                if total > MAX_YAML_NODES:
                    break
        busy.discard(key)
        if total > MAX_YAML_NODES:
            msg = f"more than {MAX_YAML_NODES} values once aliases are expanded (alias bomb?)"
            raise _Refused(msg, node.start_mark)
        sizes[key] = total
        return total

    return size(root, 0)


def parse_yaml(text: str, source: str | Path, error: type[ConfigError] = ConfigError) -> Any:
    """Parse one YAML document with the bounds above; ``error`` naming ``source`` and the line."""
    loader = _BoundedLoader(text)
    try:
        return loader.get_single_data()
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err)
        raise error(f"{source}: malformed YAML{where}: {str(problem)[:200]}") from None
    except RecursionError:
        raise error(f"{source}: YAML nested too deeply") from None
    finally:
        loader.dispose()


def check_image_header(
    path: str | Path, where: str, error: type[ConfigError] = ConfigError
) -> None:
    """Refuse a texture whose file or header-declared size exceeds the limits (no decoding)."""
    from PIL import Image, UnidentifiedImageError

    check_regular_file(path, MAX_IMAGE_BYTES, error)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                w, h = im.size
    except Image.DecompressionBombError:
        raise error(
            f"{where} = {str(path)!r}: image header declares more than {MAX_IMAGE_PIXELS} pixels"
        ) from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as err:
        raise error(
            f"{where} = {str(path)!r}: not a readable image (PNG, JPEG, ...): {err}"
        ) from None
    if w * h > MAX_IMAGE_PIXELS:
        msg = (
            f"{where} = {str(path)!r}: image of {w}x{h} pixels; "
            f"the limit is {MAX_IMAGE_PIXELS} pixels (e.g. 8192x8192)"
        )
        raise error(msg)
