"""The layout rules of the README's "Architecture" section, checked on the source tree:
no import circle between files and no import from a lower layer into a higher one
(:data:`LAYERS`; deferred and type-only imports included), no module over 600 lines, no
function over 120 lines, every package re-exports its public names with ``__all__``, and
no reference to a file outside the repository.

What a file imports (:func:`_imports`) is what Python runs for it: every ``roslan``
module it names anywhere (module level, inside functions, under ``if TYPE_CHECKING:``:
a type-only import still ties the file to the other one), and every package on the way
(``from roslan.a.b import x`` first runs ``roslan/a/__init__.py``, which may import the
file back), except the packages the file itself sits in (they are already being
imported when it runs). A file that imports its own package by name (``from roslan.a
import x`` inside ``roslan/a/m.py``) depends on that ``__init__``."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "roslan"
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 120

LAYERS: tuple[tuple[str, tuple[str, ...], str], ...] = (
    (
        "foundation",
        ("roslan", "roslan.errors", "roslan.limits", "roslan.lazy", "roslan.frames"),
        "the version, exceptions, documented bounds, lazy package loading, rotations",
    ),
    ("io", ("roslan.io",), "bags, messages, atomic files, PNG, text, child processes"),
    ("config", ("roslan.config",), "pydantic base models, units (not the run's config)"),
    ("trajectory", ("roslan.trajectory",), "tau and file trajectories"),
    ("vehicle", ("roslan.vehicle",), "the body and its contact points"),
    ("events", ("roslan.events",), "the event model (ESIM), its files and messages"),
    ("scene", ("roslan.scene",), "scenes: files, built-ins, meshes, clearance, export"),
    ("render", ("roslan.render",), "OpenGL rasterizer, Embree ray caster"),
    ("sensors", ("roslan.sensors",), "the sensor interface, registry and every sensor"),
    ("run config", ("roslan.config.sim",), "the whole simulation YAML (SimConfig)"),
    ("run folder", ("roslan.rundir",), "the output folder's files and their readers"),
    ("figures", ("roslan.plots",), "figures of a run, a trajectory or a scene"),
    ("pipeline", ("roslan.pipeline",), "one run: plan, workers, merge, report"),
    ("many runs", ("roslan.batch",), "sweeps and the paper's dataset"),
    ("viewer", ("roslan.view",), "the Rerun recording of a run folder"),
    ("environment", ("roslan.env",), "the closed-loop Gymnasium environment"),
    ("command line", ("roslan.cli", "roslan.__main__"), "argparse and handlers only"),
)
"""Lowest first: a module may import its own layer and the layers below it, never one
above. An entry names a module or a package (then every module inside it too, but
``roslan`` only its ``__init__``); a module belongs to its longest entry."""


def _modules(root: Path = SRC) -> dict[str, Path]:
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = ["roslan", *path.relative_to(root).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of every node under an ``if TYPE_CHECKING:`` block (never executed)."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip |= {id(n) for n in ast.walk(child)}
    return skip


def _packages_of(name: str, path: Path) -> set[str]:
    """The packages module ``name`` sits in (a package's ``__init__``: itself too)."""
    parts = name.split(".")
    own = parts if path.name == "__init__.py" else parts[:-1]
    return {".".join(own[:i]) for i in range(1, len(own) + 1)}


def _imports(
    path: Path,
    name: str = "",
    modules: dict[str, Path] | None = None,
    *,
    type_checking: bool = True,
) -> set[str]:
    """roslan modules that module ``name`` (file ``path``) imports, anywhere in it (see the
    module docstring): those it names, and the packages on the way to them but its own."""
    modules = MODULES if modules is None else modules
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = set() if type_checking else _type_checking_nodes(tree)
    named: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("roslan"):
            subs = {f"{node.module}.{a.name}" for a in node.names} & modules.keys()
            named |= subs
            if len(subs) < len(node.names):
                named.add(node.module)
        elif isinstance(node, ast.Import):
            named |= {a.name for a in node.names if a.name.startswith("roslan")}
    own = _packages_of(name, path) if name else {"roslan"}
    out = set(named)
    for target in named:
        parts = target.split(".")
        out |= {".".join(parts[:i]) for i in range(1, len(parts))} - own
    return (out & modules.keys()) - {name}


def _graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    return {name: _imports(path, name, modules) for name, path in modules.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _layer(name: str, layers: tuple[tuple[str, tuple[str, ...], str], ...] = LAYERS) -> int:
    """Index in ``layers`` of module ``name`` (-1: in none)."""
    best, depth = -1, -1
    for i, (_, entries, _) in enumerate(layers):
        for e in entries:
            inside = name.startswith(e + ".") and e != "roslan"
            if (name == e or inside) and e.count(".") > depth:
                best, depth = i, e.count(".")
    return best


def _upward(
    graph: dict[str, set[str]], layers: tuple[tuple[str, tuple[str, ...], str], ...] = LAYERS
) -> list[str]:
    """Every import of a higher layer: ``"a (layer) -> b (layer)"``."""
    out = []
    for a in sorted(graph):
        for b in sorted(graph[a]):
            la, lb = _layer(a, layers), _layer(b, layers)
            if lb > la:
                out.append(f"{a} ({layers[la][0]}) -> {b} ({layers[lb][0]})")
    return out


def test_the_cycle_finder_finds_a_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]


def test_imports_include_deferred_and_type_checking_ones(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        "from typing import TYPE_CHECKING\n"
        "import roslan.errors\n"
        "if TYPE_CHECKING:\n"
        "    from roslan.limits import MAX_SEED\n"
        "def f():\n"
        "    from roslan.sensors.registry import config_class\n"
        "class C:\n"
        "    def g(self):\n"
        "        import roslan.vehicle\n",
        encoding="utf-8",
    )
    # the packages on the way count: importing roslan.sensors.registry runs sensors/__init__
    assert _imports(src) == {
        "roslan.errors",
        "roslan.limits",
        "roslan.sensors",
        "roslan.sensors.registry",
        "roslan.vehicle",
    }
    assert _imports(src, type_checking=False) == _imports(src) - {"roslan.limits"}


def _tree(root: Path, files: dict[str, str]) -> dict[str, Path]:
    """A synthetic ``roslan`` source tree under ``root``: its modules by name."""
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return _modules(root)


def test_a_circle_through_a_package_init_is_found(tmp_path: Path) -> None:
    """``p/m.py`` imports ``q/x.py``, which looks clean, but importing it first runs
    ``q/__init__.py``, which imports ``q/y.py``, which imports ``p`` (whose ``__init__``
    imports ``p/m.py``): a circle between files. A file importing its own package by name
    is one too; importing a sibling module through the package is not."""
    mods = _tree(
        tmp_path,
        {
            "__init__.py": "",
            "p/__init__.py": "from roslan.p.m import f\n",
            "p/m.py": "from roslan.q.x import g\n",
            "q/__init__.py": "from roslan.q.y import h\n",
            "q/x.py": "",
            "q/y.py": "from roslan.p import f\n",
            "r/__init__.py": "from roslan.r.s import k\n",
            "r/s.py": "K = 1\ndef k():\n    from roslan.r import K\n",
            "r/t.py": "from roslan.r import s\n",
        },
    )
    graph = _graph(mods)
    assert graph["roslan.p.m"] == {"roslan.q", "roslan.q.x"}
    assert graph["roslan.r.t"] == {"roslan.r.s"}  # (its package is already being imported)
    assert _cycles(graph) == [
        ["roslan.p", "roslan.p.m", "roslan.q", "roslan.q.y"],
        ["roslan.r", "roslan.r.s"],
    ]
    # without the package on the way, the first circle would hide
    hidden = {n: _imports(p, n, mods) - {"roslan.q"} for n, p in mods.items()}
    assert _cycles(hidden) == [["roslan.r", "roslan.r.s"]]


def test_the_layer_checker_finds_an_upward_import(tmp_path: Path) -> None:
    layers = (
        ("low", ("roslan", "roslan.low"), ""),
        ("mid", ("roslan.mid",), ""),
        ("mid top", ("roslan.mid.top",), ""),
        ("high", ("roslan.high",), ""),
    )
    mods = _tree(
        tmp_path,
        {
            "__init__.py": "",
            "low/__init__.py": "",
            "low/a.py": "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    from roslan.mid.b import B\n",
            "mid/__init__.py": "",
            "mid/b.py": "from roslan.low.a import A\nfrom roslan.mid.c import C\n",
            "mid/c.py": "def f():\n    from roslan.mid.top import T\n",
            "mid/top.py": "from roslan.mid.b import B\n",
            "high.py": "import roslan.low.a\nfrom roslan.mid import top\n",
        },
    )
    assert [_layer(n, layers) for n in sorted(mods)] == [0, 3, 0, 0, 1, 1, 1, 2]
    assert _upward(_graph(mods), layers) == [
        "roslan.low.a (low) -> roslan.mid (mid)",
        "roslan.low.a (low) -> roslan.mid.b (mid)",
        "roslan.mid.c (mid) -> roslan.mid.top (mid top)",
    ]


def test_no_import_cycles() -> None:
    """No circle between files, counting deferred and type-only imports and the package
    ``__init__`` files an import runs: a deferred import only hides a circle until the
    function runs."""
    assert _cycles(_graph(MODULES)) == []


def test_every_module_has_a_layer() -> None:
    """A new package gets its place in :data:`LAYERS` (and the README's Architecture)."""
    assert [n for n in MODULES if _layer(n) < 0] == []


def test_no_upward_imports() -> None:
    """Lower layers never import higher ones (deferred and type-only imports included):
    what a lower layer needs from above is handed to it (a protocol, an argument)."""
    assert _upward(_graph(MODULES)) == []


@pytest.mark.parametrize("name", sorted(MODULES))
def test_module_and_function_sizes(name: str) -> None:
    text = MODULES[name].read_text(encoding="utf-8")
    assert len(text.splitlines()) <= MAX_MODULE_LINES
    long = [
        f"{node.name} ({node.end_lineno - node.lineno + 1} lines)"
        for node in ast.walk(ast.parse(text))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno is not None
        and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    ]
    assert long == []


@pytest.mark.parametrize("name", sorted(n for n, p in MODULES.items() if p.name == "__init__.py"))
def test_packages_declare_their_public_names(name: str) -> None:
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    declared = [
        node
        for node in tree.body
        if isinstance(node, ast.Assign | ast.AnnAssign)
        and any(
            isinstance(t, ast.Name) and t.id == "__all__"
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
        )
    ]
    assert declared, f"{name} has no __all__"


OUTSIDE = re.compile(r"(?<!docs/)\b(DESIGN|STYLE)\.md|\.\./shared|\b[Ii]ssues? #?\d+")


def test_no_references_outside_the_repository() -> None:
    hits = [
        f"{path.relative_to(SRC.parent)}:{i}: {line.strip()}"
        for path in MODULES.values()
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if OUTSIDE.search(line)
    ]
    assert hits == []


@pytest.mark.parametrize("package", ["roslan.io", "roslan.plots"])
def test_lazy_packages_resolve_every_public_name(package: str) -> None:
    """The PEP 562 packages load each name in ``__all__`` from its module on first use,
    and an unknown name is an AttributeError naming the package."""
    import subprocess
    import sys

    code = (
        f"import sys, {package} as p\n"
        "for n in p.__all__: getattr(p, n)\n"
        "try:\n    p.no_such_name\nexcept AttributeError as e:\n    print(e)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert f"module {package!r} has no attribute 'no_such_name'" in out


# ------------------------------------------------------------ the seams (guide: architecture)
_POOLS = ("ProcessPoolExecutor", "multiprocessing.Pool", "multiprocessing.pool", "WorkerPool")


def _sensor_violations(path: Path) -> list[str]:
    """What a sensor module must not import: the pipeline (its ``Context`` above all) or
    any process pool."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names = {a.name for a in node.names}
            if node.module.startswith("roslan.pipeline") or (
                "Context" in names and (node.module.startswith("roslan.pipeline"))
            ):
                out.append(f"from {node.module} import {', '.join(sorted(names))}")
            full = {f"{node.module}.{n}" for n in names} | names | {node.module}
            out += [f"from {node.module} import {p}" for p in _POOLS if p in full]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("roslan.pipeline") or a.name in _POOLS:
                    out.append(f"import {a.name}")
        elif isinstance(node, ast.Attribute) and ast.unparse(node) in _POOLS:
            out.append(ast.unparse(node))
    return out


def test_the_sensor_checker_finds_a_context_and_a_pool(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(
        "from roslan.pipeline.context import Context\n"
        "from concurrent.futures import ProcessPoolExecutor\n"
        "import multiprocessing\n"
        "def f():\n    return multiprocessing.Pool(2)\n",
        encoding="utf-8",
    )
    found = _sensor_violations(bad)
    assert "from roslan.pipeline.context import Context" in found
    assert "from concurrent.futures import ProcessPoolExecutor" in found
    assert "multiprocessing.Pool" in found


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n.startswith("roslan.sensors")))
def test_no_sensor_imports_the_pipeline_context_or_a_process_pool(name: str) -> None:
    assert _sensor_violations(MODULES[name]) == []


def _type_branches(path: Path) -> list[str]:
    """Branches on a sensor's type in a module: a comparison with a ``.type`` attribute,
    or any registered type name written as a string."""
    from roslan.sensors.registry import SENSOR_TYPES

    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(s, ast.Attribute) and s.attr == "type" for s in sides):
                out.append(ast.unparse(node))
        elif isinstance(node, ast.Constant) and node.value in SENSOR_TYPES:
            out.append(repr(node.value))
    return out


def test_the_branch_checker_finds_type_branches(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(
        "def f(s):\n    if s.type == 'imu':\n        return 1\n    return s.type in ('laser',)\n",
        encoding="utf-8",
    )
    assert sorted(_type_branches(bad)) == sorted(
        ["s.type == 'imu'", "'imu'", "s.type in ('laser',)", "'laser'"]
    )


def test_the_observation_has_no_per_type_branches() -> None:
    """env/observe.py only gathers the observers each SensorSpec declares."""
    assert _type_branches(MODULES["roslan.env.observe"]) == []


_CACHES = ("lru_cache", "cache", "functools.lru_cache", "functools.cache")
_HOLDS_SCENE = re.compile(r"\b(Scene|SceneObject|Renderer|RayCaster|SceneBackends)\b")


def _scene_caches(path: Path) -> list[str]:
    """Module-level caches that may hold a scene strongly: a cached function taking or
    returning one, or a module-level container of them that is not a weak one."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            cached = [
                d
                for d in node.decorator_list
                if ast.unparse(d.func if isinstance(d, ast.Call) else d) in _CACHES
            ]
            sig = " ".join(
                ast.unparse(a.annotation) for a in node.args.args if a.annotation is not None
            ) + (" " + ast.unparse(node.returns) if node.returns is not None else "")
            if cached and _HOLDS_SCENE.search(sig):
                out.append(f"cached function {node.name}({sig})")
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            ann = ast.unparse(node.annotation)
            if _HOLDS_SCENE.search(ann) and "Weak" not in ann:
                out.append(f"{node.target.id}: {ann}")
    return out


def test_the_cache_checker_finds_a_strong_scene_cache(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(
        "from functools import lru_cache\n"
        "@lru_cache(maxsize=4)\ndef f(scene: Scene) -> int:\n    return 1\n"
        "_BY_NAME: dict[str, Scene] = {}\n"
        "_OK: weakref.WeakKeyDictionary[Scene, RayCaster] = weakref.WeakKeyDictionary()\n",
        encoding="utf-8",
    )
    assert _scene_caches(bad) == ["cached function f(Scene int)", "_BY_NAME: dict[str, Scene]"]


def test_no_module_level_cache_holds_a_scene() -> None:
    found = {name: _scene_caches(path) for name, path in MODULES.items()}
    assert {k: v for k, v in found.items() if v} == {}
