"""Hostile and edge-case input through the CLI entry points, in-process.

Every case must end in exit status 2 with an ``error:`` line that names the file (and the
key where there is one), or succeed; never a traceback, a hang or a memory blow-up. A
corpus of known-bad files (alias bombs, devices, FIFOs, duplicate keys, values past the
documented limits, colliding sensor names...) plus Hypothesis strategies over the config,
scene and sweep schemas.

``roslan simulate`` is stopped right after its pre-flight checks (the point where it
would create its output folder), so a config that passes them costs no simulation.
"""

from __future__ import annotations

import os
import resource
import struct
import time
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import roslan.pipeline.record as run_mod
from roslan.cli import main
from roslan.errors import OutputError

PASSED = "PREFLIGHT-PASSED"
SECONDS = 20.0
"""Longest any single hostile input may take."""

BOMB = """\
a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]
b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]
c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]
d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]
e: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]
f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]
g: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]
h: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]
i: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]
"""

SHORT = "trajectory: {initial: {position: [-1, 0.5, 1.0], descent_rate: 1.0}}\n"


def _png_header(width: int, height: int) -> bytes:
    """A PNG whose IHDR claims width x height (no pixel data)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


@pytest.fixture(autouse=True)
def _stop_before_writing(monkeypatch: pytest.MonkeyPatch) -> None:
    def stop(outdir: Path) -> Path:
        raise OutputError(PASSED)

    monkeypatch.setattr(run_mod, "make_temp", stop)


def _cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    t0 = time.perf_counter()
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse errors
        rc = int(exc.code or 0)
    elapsed = time.perf_counter() - t0
    out = capsys.readouterr()
    text = out.err + out.out
    assert elapsed < SECONDS, f"{argv} took {elapsed:.1f} s"
    assert "Traceback" not in text, text
    return rc, out.err


def _assert_clean_error(rc: int, err: str, *names: str) -> str:
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert lines, err
    first = lines[0]
    for name in names:
        assert name in first, (name, first)
    return first


# --------------------------------------------------------------------------- corpus
def _write(tmp: Path, files: dict[str, str | bytes]) -> None:
    for name, content in files.items():
        p = tmp / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content, encoding="utf-8")


SIM = ["simulate", "job.yaml", "-o", "out", "--quiet", "--no-overview"]
SCENE = ["scene", "info", "scene.yaml"]
BATCH = ["batch", "sweep.yaml", "-o", "batch", "--dry-run"]
SCENE_JOB = SHORT + "scene: scene.yaml\n"
CAM = "{type: camera, name: c, topic: /c, rate: 10, resolution: [64, 48]}"

# (id, files, argv, substrings of the first error line)
CORPUS: list[tuple[str, dict[str, str | bytes], list[str], tuple[str, ...]]] = [
    ("bomb-top", {"job.yaml": BOMB}, SIM, ("job.yaml", "aliases are expanded")),
    (
        "bomb-in-pose",
        {"job.yaml": BOMB + "sensors: [{type: imu, name: i, topic: /i, pose: {position: *i}}]\n"},
        SIM,
        ("job.yaml", "line"),
    ),
    ("bomb-scene", {"scene.yaml": BOMB}, SCENE, ("scene.yaml", "aliases")),
    (
        "bomb-sweep-base",
        {"base.yaml": BOMB, "sweep.yaml": "base: base.yaml\n"},
        BATCH,
        ("base.yaml",),
    ),
    ("recursive-alias", {"job.yaml": "a: &a [*a]\n"}, SIM, ("job.yaml", "recursive")),
    ("deep", {"job.yaml": "a: " + "[" * 3000 + "]" * 3000 + "\n"}, SIM, ("job.yaml", "nested")),
    (
        "duplicate-key",
        {"job.yaml": SHORT + "seed: 1\nseed: 2\n"},
        SIM,
        ("job.yaml", "duplicate key 'seed'"),
    ),
    ("dev-zero", {}, ["simulate", "/dev/zero", "-o", "out"], ("/dev/zero", "device")),
    ("dev-zero-scene", {}, ["scene", "info", "/dev/zero"], ("/dev/zero",)),
    ("dev-zero-sweep", {}, ["batch", "/dev/zero", "-o", "b", "--dry-run"], ("/dev/zero",)),
    ("dev-zero-base", {"sweep.yaml": "base: /dev/zero\n"}, BATCH, ("/dev/zero",)),
    (
        "dev-zero-calibration",
        {
            "job.yaml": SHORT + "sensors: [{type: camera, name: c, topic: /c, rate: 10, "
            "calibration: /dev/zero}]\n"
        },
        SIM,
        ("/dev/zero",),
    ),
    ("folder-config", {"d/x": ""}, ["simulate", "d", "-o", "out"], ("d", "folder")),
    ("not-utf8", {"job.yaml": b"seed: \xff\xfe\n"}, SIM, ("job.yaml", "UTF-8")),
    ("empty", {"job.yaml": ""}, SIM, ("job.yaml", "empty config")),
    (
        "start-time-bool",
        {"job.yaml": SHORT + "output: {start_time: true}\n"},
        SIM,
        ("job.yaml", "start_time", "true/false"),
    ),
    (
        "start-time-inf",
        {"job.yaml": SHORT + "output: {start_time: .inf}\n"},
        SIM,
        ("job.yaml", "start_time"),
    ),
    (
        "start-time-1e12",
        {"job.yaml": SHORT + "output: {start_time: 1e12}\n"},
        SIM,
        ("job.yaml", "start_time"),
    ),
    (
        "start-time-1e30",
        {"job.yaml": SHORT + f"output: {{start_time: {10**30}}}\n"},
        SIM,
        ("job.yaml", "start_time"),
    ),
    (
        "start-time-ros1",
        {"job.yaml": SHORT + "output: {start_time: 7.3e9}\n"},
        SIM,
        ("job.yaml", "ROS 1"),
    ),
    ("k-tiny", {"job.yaml": "trajectory: {k: 1e-300}\n"}, SIM, ("job.yaml", "trajectory.k")),
    (
        "descent-tiny",
        {"job.yaml": "trajectory: {initial: {position: [1, 1, 1], descent_rate: 1e-12}}\n"},
        SIM,
        ("job.yaml", "touchdown time"),
    ),
    ("hold-huge", {"job.yaml": "trajectory: {hold: 1e9}\n"}, SIM, ("job.yaml", "trajectory.hold")),
    (
        "z-huge",
        {"job.yaml": "trajectory: {initial: {position: [1, 1, 1e300], descent_rate: 1}}\n"},
        SIM,
        ("job.yaml", "trajectory.initial.position[2]"),
    ),
    (
        "kappa-tiny",
        {"job.yaml": "trajectory: {kappa: {x: 1e-300}}\n"},
        SIM,
        ("job.yaml", "kappa.x"),
    ),
    (
        "flap-1e9",
        {"job.yaml": "trajectory: {flapping: {frequency: 1e9, heave: 0.1}}\n"},
        SIM,
        ("job.yaml", "flapping.frequency"),
    ),
    ("sample-dt", {"job.yaml": "trajectory: {sample_dt: 1e-9}\n"}, SIM, ("job.yaml", "sample_dt")),
    ("seed-negative", {"job.yaml": SHORT + "seed: -1\n"}, SIM, ("job.yaml", "seed")),
    ("seed-huge", {"job.yaml": SHORT + f"seed: {10**23}\n"}, SIM, ("job.yaml", "seed")),
    ("seed-arg", {"job.yaml": SHORT}, [*SIM, "--seed", "-1"], ("--seed",)),
    ("seed-arg-huge", {"job.yaml": SHORT}, [*SIM, "--seed", str(10**23)], ("--seed",)),
    ("scene-seed", {}, ["scene", "info", "empty", "--seed", "-1"], ("--seed",)),
    ("dataset-seed", {}, ["dataset", "-o", "ds", "--seed", "-5", "--dry-run"], ("--seed",)),
    *[
        (
            f"rate-{kind}",
            {"job.yaml": SHORT + f"sensors: [{{type: {kind}, name: s, topic: /s, rate: 1e9}}]\n"},
            SIM,
            ("job.yaml", "rate"),
        )
        for kind in ("imu", "camera", "depth_camera", "event_camera", "lidar", "sonar", "laser")
    ],
    (
        "gt-rate",
        {"job.yaml": SHORT + "output: {ground_truth_rate: 1e9}\n"},
        SIM,
        ("job.yaml", "ground_truth_rate"),
    ),
    (
        "event-min-rate",
        {
            "job.yaml": SHORT
            + "sensors: [{type: event_camera, name: e, topic: /e, rate: 30, min_rate: 1e9}]\n"
        },
        SIM,
        ("job.yaml", "min_rate"),
    ),
    (
        "event-huge",
        {
            "job.yaml": SHORT + "sensors: [{type: event_camera, name: e, topic: /e, rate: 30, "
            "resolution: [100000, 100000]}]\n"
        },
        SIM,
        ("job.yaml", "resolution"),
    ),
    (
        "messages",
        {
            "job.yaml": "trajectory: {hold: 80000}\noutput: {ground_truth_rate: 1e4}\n"
            "sensors: [{type: imu, name: i, topic: /i, rate: 1e4}]\n"
        },
        SIM,
        ("job.yaml", "messages"),
    ),
    (
        "frame-memory",
        {
            "job.yaml": SHORT + "sensors: [{type: camera, name: c, topic: /c, rate: 10, "
            "resolution: [8192, 8192], render_scale: 2.0}]\n"
        },
        SIM,
        ("job.yaml", "working memory"),
    ),
    (
        "stereo-vs-camera",
        {
            "job.yaml": SHORT
            + "scene: empty\n"
            + "sensors: [{type: stereo_camera, name: st, topic: /st, rate: 10}, "
            "{type: camera, name: st_left, topic: /c, rate: 10}]\n"
        },
        SIM,
        ("job.yaml", "st_left", "collides"),
    ),
    (
        "same-frame-id",
        {
            "job.yaml": SHORT + "sensors: [{type: imu, name: a, topic: /a, frame_id: x}, "
            "{type: imu, name: b, topic: /b, frame_id: x}]\n"
        },
        SIM,
        ("job.yaml", "'x'", "collides"),
    ),
    *[
        (
            f"frame-{frame}",
            {
                "job.yaml": SHORT
                + f"sensors: [{{type: imu, name: a, topic: /a, frame_id: {frame}}}]\n"
            },
            SIM,
            ("job.yaml", "frame_id", "reserved"),
        )
        for frame in ("base_link", "world")
    ],
    (
        "box-huge",
        {
            "scene.yaml": "name: s\n"
            "objects: [{name: b, primitive: {type: box, size: [1e300, 1, 1]}}]\n"
        },
        SCENE,
        ("scene.yaml", "size"),
    ),
    (
        "scale-huge",
        {
            "scene.yaml": "name: s\n"
            "objects: [{name: b, primitive: {type: sphere, radius: 1}, scale: [1e39, 1, 1]}]\n"
        },
        SCENE,
        ("scene.yaml", "scale"),
    ),
    (
        "pose-huge",
        {
            "scene.yaml": "name: s\nobjects: [{name: b, primitive: {type: sphere, radius: 1}, "
            "pose: {position: [1e300, 0, 0]}}]\n"
        },
        SCENE,
        ("scene.yaml", "position"),
    ),
    (
        "png-bomb",
        {
            "t.png": _png_header(100000, 100000),
            "scene.yaml": "name: s\nobjects: [{name: b, primitive: {type: box, size: [1, 1, 1]}, "
            "material: {texture: t.png}}]\n",
        },
        SCENE,
        ("t.png", "pixels"),
    ),
    (
        "obj-corrupt",
        {
            "m.obj": b"\x00\xff garbage \x89\x00" * 50,
            "scene.yaml": "name: s\nobjects: [{name: m, mesh: m.obj}]\n",
        },
        SCENE,
        ("m.obj",),
    ),
    (
        "stl-corrupt",
        {
            "m.stl": b"solid \x00\xff\xfe" * 40,
            "scene.yaml": "name: s\nobjects: [{name: m, mesh: m.stl}]\n",
        },
        SCENE,
        ("m.stl",),
    ),
    (
        "obj-vertex-huge",
        {
            "m.obj": "v 1e300 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n",
            "scene.yaml": "name: s\nobjects: [{name: m, mesh: m.obj}]\n",
        },
        SCENE,
        ("m.obj",),
    ),
    (
        "sweep-log-text",
        {
            "sweep.yaml": "base: {}\n"
            "axes: [{sample: {n: 2, ranges: {seed: {low: 1, high: 5, log: 'false'}}}}]\n"
        },
        BATCH,
        ("sweep.yaml", "log"),
    ),
    (
        "sweep-seed-wrap",
        {
            "sweep.yaml": "base: {}\n"
            f"axes: [{{sample: {{n: 2, ranges: {{seed: [0, {10**23}]}}}}}}]\n"
        },
        BATCH,
        ("sweep.yaml", "seed"),
    ),
    (
        "sweep-grid-huge",
        {"sweep.yaml": "base: {}\naxes: [{grid: {seed: {start: 0, stop: 1, num: 1000000000}}}]\n"},
        BATCH,
        ("sweep.yaml", "num"),
    ),
    (
        "sweep-product-huge",
        {
            "sweep.yaml": "base: {}\naxes:\n"
            + "".join(
                f"  - grid: {{trajectory.kappa.{k}: {{start: 0.1, stop: 1, num: 1000}}}}\n"
                for k in ("x", "y", "roll")
            )
        },
        BATCH,
        ("sweep.yaml", "tasks"),
    ),
    (
        "sweep-sample-huge",
        {"sweep.yaml": "base: {}\naxes: [{sample: {n: 1000000000, ranges: {seed: [0, 9]}}}]\n"},
        BATCH,
        ("sweep.yaml", ".n"),
    ),
    (
        "sweep-name-long",
        {"sweep.yaml": "base: {}\nname: '{index:0300d}'\n"},
        BATCH,
        ("sweep.yaml", "name"),
    ),
    (
        "sweep-name-width",
        {"sweep.yaml": "base: {}\nname: '{index:0999999999d}'\n"},
        BATCH,
        ("sweep.yaml", "name"),
    ),
    (
        "sweep-name-attr",
        {"sweep.yaml": "base: {}\nname: '{index.real.x}'\n"},
        BATCH,
        ("sweep.yaml", "name"),
    ),
    (
        "calibration-huge",
        {
            "cal.yaml": "image_width: 100000\nimage_height: 100000\ncamera_name: c\n"
            "camera_matrix: {rows: 3, cols: 3, data: [5e4, 0, 5e4, 0, 5e4, 5e4, 0, 0, 1]}\n"
            "distortion_model: plumb_bob\n"
            "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n",
            "job.yaml": SHORT + "sensors: [{type: event_camera, name: e, topic: /e, rate: 30, "
            "calibration: cal.yaml}]\n",
        },
        SIM,
        ("job.yaml", "cal.yaml", "pixels"),
    ),
    ("sweep-dup", {"sweep.yaml": "base: {}\nbase: {}\n"}, BATCH, ("sweep.yaml", "duplicate")),
]


@pytest.mark.parametrize(
    ("files", "argv", "expect"), [c[1:] for c in CORPUS], ids=[c[0] for c in CORPUS]
)
def test_hostile_corpus(
    files: dict[str, str | bytes],
    argv: list[str],
    expect: tuple[str, ...],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _write(tmp_path, files)
    monkeypatch.chdir(tmp_path)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    rc, err = _cli(argv, capsys)
    grown_mib = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    first = _assert_clean_error(rc, err, *expect)
    assert PASSED not in first
    assert len(first) < 600  # never a whole value
    assert grown_mib < 400, f"peak memory grew by {grown_mib:.0f} MiB"


def test_fifo_config_does_not_block(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "job.yaml"
    os.mkfifo(fifo)
    rc, err = _cli(["simulate", str(fifo), "-o", str(tmp_path / "out")], capsys)
    _assert_clean_error(rc, err, "job.yaml", "FIFO")


def test_oversized_config_is_refused_without_reading(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    big = tmp_path / "job.yaml"
    with big.open("wb") as fh:  # sparse: 9 GiB claimed, nothing written
        fh.truncate(9 * 1024**3)
    rc, err = _cli(["simulate", str(big), "-o", str(tmp_path / "out")], capsys)
    _assert_clean_error(rc, err, "job.yaml", "limit")


def test_a_valid_job_passes_preflight(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The guard works: a good config reaches the point where it would write."""
    job = tmp_path / "job.yaml"
    job.write_text(SHORT + "sensors: [{type: imu, name: i, topic: /i, rate: 1e3}]\n")
    rc, err = _cli(["simulate", str(job), "-o", str(tmp_path / "out"), "--quiet"], capsys)
    assert rc == 2
    assert PASSED in err


def test_enospc_is_a_clean_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An OSError anywhere (a full disk here) becomes one error line naming the path."""
    import errno

    def full(outdir: Path) -> Path:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(outdir / "landing.bag"))

    monkeypatch.setattr(run_mod, "make_temp", full)
    job = tmp_path / "job.yaml"
    job.write_text(SHORT)
    rc, err = _cli(["simulate", str(job), "-o", str(tmp_path / "out"), "--quiet"], capsys)
    _assert_clean_error(rc, err, "landing.bag", "No space left on device")


# --------------------------------------------------------------------------- fuzz
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**25), max_value=10**25),
    st.sampled_from([0, 1, -1, 0.5, 1e-300, 1e300, 2**63, 2**64, 1e9, 7.3e9]),
)
SCALARS = st.one_of(NUMBERS, st.booleans(), st.none(), st.text(max_size=12))
VALUES = st.recursive(
    SCALARS,
    lambda kids: (
        st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids, max_size=3)
    ),
    max_leaves=8,
)
VECS = st.lists(NUMBERS, min_size=0, max_size=4)

SENSOR_KEYS = {
    "rate": NUMBERS,
    "resolution": st.lists(st.integers(-5, 10**6), max_size=3),
    "frame_id": st.sampled_from(["world", "base_link", "a", "b", "s0", "s1_left", "x y"]),
    "pose": st.fixed_dictionaries({}, optional={"position": VECS, "rpy": VECS}),
    "min_rate": NUMBERS,
    "bogus": VALUES,
}


@st.composite
def sensors(draw: st.DrawFn) -> list[dict[str, Any]]:
    out = []
    for i in range(draw(st.integers(0, 3))):
        kind = draw(
            st.sampled_from(["imu", "camera", "stereo_camera", "event_camera", "lidar", "sonar"])
        )
        s: dict[str, Any] = {
            "type": kind,
            "name": draw(st.sampled_from([f"s{i}", "s0", "s1_left", "st"])),
            "topic": f"/t{i}",
            "rate": 10,
        }
        if kind in ("camera", "stereo_camera", "event_camera"):
            s["resolution"] = [32, 24]
        for key in draw(st.sets(st.sampled_from(sorted(SENSOR_KEYS)), max_size=2)):
            s[key] = draw(SENSOR_KEYS[key])
        out.append(s)
    return out


CONFIGS = st.fixed_dictionaries(
    {"trajectory": st.just({"initial": {"position": [-1, 0.5, 1.0], "descent_rate": 1.0}})},
    optional={
        "seed": NUMBERS,
        "sensors": sensors(),
        "output": st.fixed_dictionaries(
            {},
            optional={
                "start_time": NUMBERS | st.booleans(),
                "ground_truth_rate": NUMBERS,
                "workers": VALUES,
            },
        ),
        "extra": VALUES,
    },
).flatmap(
    lambda cfg: st.fixed_dictionaries(
        {},
        optional={
            "k": NUMBERS,
            "sample_dt": NUMBERS,
            "hold": NUMBERS,
            "kappa": st.fixed_dictionaries({}, optional={"x": NUMBERS, "yaw": NUMBERS}),
            "flapping": st.fixed_dictionaries(
                {}, optional={"frequency": NUMBERS, "heave": NUMBERS}
            ),
            "initial": st.fixed_dictionaries({"position": VECS, "descent_rate": NUMBERS}),
        },
    ).map(lambda traj: {**cfg, "trajectory": {**cfg["trajectory"], **traj}})
)

FUZZ = settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _fuzz_once(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    doc: Any,
    argv: Callable[[Path], list[str]],
) -> None:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, allow_unicode=True), encoding="utf-8")
    args = argv(path)
    rc, err = _cli(args, capsys)
    # a dry run that lists invalid tasks exits 1 (its table names each task's problem)
    assert rc in ((0, 1, 2) if "--dry-run" in args else (0, 2)), err
    assert "Traceback" not in err
    if rc == 2:
        first = _assert_clean_error(rc, err)
        if PASSED not in first and "--seed" not in first:
            assert name in first, first  # every config error names its file


@FUZZ
@given(doc=CONFIGS)
def test_fuzz_config(
    doc: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _fuzz_once(
        tmp_path,
        capsys,
        "job.yaml",
        doc,
        lambda p: ["simulate", str(p), "-o", str(p.parent / "out"), "--quiet"],
    )


PRIMITIVES = st.one_of(
    st.fixed_dictionaries({"type": st.just("box"), "size": VECS}),
    st.fixed_dictionaries({"type": st.just("sphere"), "radius": NUMBERS}),
    st.fixed_dictionaries({"type": st.just("plane"), "size": VECS}),
    st.fixed_dictionaries(
        {
            "type": st.sampled_from(["cylinder", "capsule", "torus"]),
            "radius": NUMBERS,
            "height": NUMBERS,
        }
    ),
)
SCENES = st.fixed_dictionaries(
    {
        "name": st.sampled_from(["s", "a b", ""]),
        "objects": st.lists(
            st.fixed_dictionaries(
                {"name": st.sampled_from(["a", "b", "a b"]), "primitive": PRIMITIVES},
                optional={
                    "scale": VECS,
                    "pose": st.fixed_dictionaries({}, optional={"position": VECS, "rpy": VECS}),
                },
            ),
            max_size=3,
        ),
    },
    optional={"goal": st.fixed_dictionaries({}, optional={"position": VECS}), "lights": VALUES},
)


@FUZZ
@given(doc=SCENES)
def test_fuzz_scene(
    doc: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _fuzz_once(tmp_path, capsys, "scene.yaml", doc, lambda p: ["scene", "info", str(p)])


SWEEPS = st.fixed_dictionaries(
    {
        "base": st.just(
            {"trajectory": {"initial": {"position": [-1, 0.5, 1.0], "descent_rate": 1.0}}}
        )
    },
    optional={
        "name": st.sampled_from(
            [
                "{index:04d}",
                "{index:0300d}",
                "{}",
                "{index!r}",
                "a/{index}",
                "{index:>9999}",
                "run_{index}",
            ]
        ),
        "axes": st.lists(
            st.one_of(
                st.fixed_dictionaries(
                    {
                        "grid": st.dictionaries(
                            st.sampled_from(["seed", "trajectory.k", "nope"]),
                            st.lists(NUMBERS, max_size=3)
                            | st.fixed_dictionaries(
                                {"start": NUMBERS, "stop": NUMBERS, "num": NUMBERS}
                            ),
                            max_size=2,
                        )
                    }
                ),
                st.fixed_dictionaries(
                    {
                        "sample": st.fixed_dictionaries(
                            # small valid sweeps and refused sizes: a valid sweep near
                            # the 100,000-task limit is legitimately slow to dry-run (its
                            # limit is tested in tests/batch/test_batch_sweep.py)
                            {"n": st.integers(-1, 40) | st.integers(100_001, 10**10)},
                            optional={
                                "seed": NUMBERS,
                                "ranges": st.dictionaries(
                                    st.sampled_from(["seed", "trajectory.k"]),
                                    st.lists(NUMBERS, min_size=2, max_size=2)
                                    | st.fixed_dictionaries(
                                        {"low": NUMBERS, "high": NUMBERS},
                                        optional={"log": SCALARS, "integer": SCALARS},
                                    ),
                                    max_size=2,
                                ),
                            },
                        )
                    }
                ),
            ),
            max_size=2,
        ),
    },
)


@FUZZ
@given(doc=SWEEPS)
def test_fuzz_sweep(
    doc: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _fuzz_once(
        tmp_path,
        capsys,
        "sweep.yaml",
        doc,
        lambda p: ["batch", str(p), "-o", str(p.parent / "b"), "--dry-run"],
    )


@pytest.mark.parametrize(
    ("grid", "rc"),
    [
        ({"trajectory.k": {"start": 0.0, "stop": -(2**63) - 1, "num": 2}}, 1),  # tasks invalid
        ({"trajectory.k": {"start": 0.1, "stop": 10**400, "num": 2}}, 2),  # beyond float
        ({"trajectory.k": [0.0]}, 1),  # a valid sweep whose only task is invalid
    ],
)
def test_sweep_grid_extremes(
    grid: dict[str, Any], rc: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Grid bounds outside the float range are refused by name; a dry run whose tasks are
    all invalid lists them and exits 1, never with a traceback."""
    base = {"trajectory": {"initial": {"position": [-1, 0.5, 1.0], "descent_rate": 1.0}}}
    doc = {"base": base, "axes": [{"grid": grid}]}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    got, err = _cli(["batch", str(path), "-o", str(tmp_path / "b"), "--dry-run"], capsys)
    assert got == rc, err
    assert "Traceback" not in err
    if rc == 2:
        first = _assert_clean_error(got, err, "sweep.yaml", "trajectory.k.start/stop")
        assert "finite numbers" in first
