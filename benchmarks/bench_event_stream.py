"""The default job's event camera alone: wall, CPU and CPU seconds per stage.

Streams the packaged default job's event camera (DAVIS346, adaptive optical-flow
sampling) over the default landing in the warehouse, as a sensor worker does: every
message of :meth:`EventCamera.messages` is built for both bag flavours (ROS 1 and ROS 2),
events.txt / events.h5 / APS PNGs are written to a temporary folder. Prints wall and
process CPU seconds, and the thread CPU seconds (``time.thread_time``, on whichever
thread runs them) of each stage, measured by wrapping the functions by name:

* ``camera_twist``: the trajectory's pose and twist at the instant;
* ``render``: the GL render + remap (``EventCamera.render`` minus ``camera_twist``);
* ``flow speed``: ``max |flow|`` from the rendered depth (sampling);
* ``ESIM``: ``EventGenerator.update``; ``split``: the packet cutter's ``split``;
* ``build``: the message bytes (EventArray packing, CameraInfo, images), both flavours;
* ``files``: events.txt / events.h5 writing (``EventCamera._write_events``).

``--helpers N``: the camera's chains are rendered by N render helper processes as well
(``roslan.sensors.cameras.event_chains``; ``--no-render-here``: only by them); the CPU
then includes the helpers' (reaped children). ``--ab-helpers N`` compares 0 (A) and N (B)
helpers; with ``LP_NUM_THREADS=1`` in the environment each llvmpipe render uses one core,
as the CPU side does on a GPU machine, which shows how the chains scale with processes.

A/B: ``--ab DIR_A DIR_B`` runs this script in fresh interpreters with
``PYTHONPATH=DIR_X/src`` alternately (``--repeat`` times each; e.g. a ``git worktree`` of
the commit before as DIR_A and this checkout as DIR_B) and prints the ratios B/A of the
medians; ``--ab-threads`` compares this checkout without (A, ``--sequential``) and with
(B) the event camera's helper thread. ``--workdir DIR``: the temporary outputs go there.
``--seconds S`` limits the landing to its first S seconds.

    PYTHONPATH=src python benchmarks/bench_event_stream.py [--seconds 5.2]
    python benchmarks/bench_event_stream.py --ab /tmp/base . --repeat 3
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Generator
from pathlib import Path
from typing import Any

STAGES = ("camera_twist", "render", "flow speed", "ESIM", "split", "build", "files")


def _timed(acc: dict[str, float], stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    lock = threading.Lock()

    @functools.wraps(fn)
    def wrapper(*args: Any, **kw: Any) -> Any:
        c0 = time.thread_time()
        try:
            return fn(*args, **kw)
        finally:
            dt = time.thread_time() - c0
            with lock:
                acc[stage] += dt

    return wrapper


def _instrument(acc: dict[str, float]) -> None:
    """Wrap the stage functions (module attributes looked up at call time)."""
    import roslan.sensors.cameras.event as ev
    from roslan.events.model import EventGenerator

    ev.camera_twist = _timed(acc, "camera_twist", ev.camera_twist)  # type: ignore[attr-defined]
    ev.EventCamera.render = _timed(acc, "render", ev.EventCamera.render)  # type: ignore[method-assign]
    ev._Camera.max_flow_speed = _timed(acc, "flow speed", ev._Camera.max_flow_speed)  # type: ignore[method-assign]
    EventGenerator.update = _timed(acc, "ESIM", EventGenerator.update)  # type: ignore[method-assign]
    try:  # (roslan.sensors.cameras.event_stream since 2026-11-26)
        from roslan.sensors.cameras.event_stream import Packetizer
    except ImportError:
        Packetizer = ev._Packetizer  # type: ignore[attr-defined,misc]
    Packetizer.split = _timed(acc, "split", Packetizer.split)  # type: ignore[method-assign]
    ev.EventCamera._write_events = _timed(acc, "files", ev.EventCamera._write_events)  # type: ignore[method-assign]


def run_once(
    seconds: float | None,
    *,
    sequential: bool = False,
    workdir: str | None = None,
    helpers: int = 0,
    render_here: bool = True,
) -> dict[str, Any]:
    """Stream the default event camera once; wall, CPU and per-stage CPU seconds."""
    from roslan.cli.simulate import load_config
    from roslan.io.messages import Flavor, MessageStore
    from roslan.pipeline.context import Context
    from roslan.pipeline.plan import load_checked_scene, make_plan
    from roslan.sensors.cameras import EventCamera, EventCameraConfig

    acc: dict[str, float] = defaultdict(float)
    _instrument(acc)
    cfg, _ = load_config(None)
    cam_cfg = next(s for s in cfg.sensors if s.type == "event_camera")
    cfg = cfg.model_copy(update={"sensors": [cam_cfg]})
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        plan = make_plan(cfg, Path(tmp) / "plan", workers=0)
        checked = load_checked_scene(plan, allow_collision=True)
        traj = checked.traj
        out = Path(tmp) / "out"
        out.mkdir()
        ctx = Context(
            traj,
            out,
            seed=cfg.seed,
            start_time_ns=cfg.output.start_time,
            sensors=cfg.sensors,
            scene_spec=cfg.scene,
            scene=checked.scene,
            render_helpers={cam_cfg.name: helpers},
        )
        ctx.renderer().render  # noqa: B018  (context and scene upload: not timed)
        stores = [MessageStore(Flavor(f)) for f in ("ros1", "ros2")]
        assert isinstance(cam_cfg, EventCameraConfig)
        cam = EventCamera(cam_cfg)
        if sequential:  # everything on this thread (the attribute is new on 2026-11-26)
            cam.pipelined = False
        cam.render_here = render_here
        end = None if seconds is None else round(seconds * 1e9)
        kids0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        w0, c0 = time.perf_counter(), time.process_time()
        n_msgs = n_bytes = 0
        stream = cam.messages(ctx)
        assert isinstance(stream, Generator)
        for msg in stream:
            if end is not None and msg.t_ns > end:
                stream.close()
                break
            b0 = time.thread_time()
            for store in stores:
                n_bytes += len(store.encode(msg.build, msg.msgtype))
            acc["build"] += time.thread_time() - b0
            n_msgs += 1
        cam.close(ctx)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        kids1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu += (kids1.ru_utime + kids1.ru_stime) - (kids0.ru_utime + kids0.ru_stime)
    acc["render"] -= acc["camera_twist"]
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "messages": n_msgs,
        "bytes": n_bytes,
        "frames": cam.stats.get("frames", 0),
        "events": cam.stats.get("events", 0),
        "chains": cam.stats.get("chains", 0),
        "chains_here": cam.stats.get("chains_rendered_here", 0),
        "helpers": helpers,
        "stages": {k: acc[k] for k in STAGES},
    }


def _print(label: str, r: dict[str, Any]) -> None:
    st = "  ".join(f"{k} {v:.2f}" for k, v in r["stages"].items())
    print(
        f"{label}: wall {r['wall_s']:.2f} s, CPU {r['cpu_s']:.2f} s, {r['frames']} frames, "
        f"{r['events']} events, {r['messages']} messages, {r.get('helpers', 0)} helpers "
        f"({r.get('chains_here', 0)} of {r.get('chains', 0)} chains rendered here) | CPU-s: {st}",
        flush=True,
    )


def ab(
    cases: list[tuple[str, str, list[str]]],
    repeat: int,
    seconds: float | None,
    workdir: str | None = None,
) -> None:
    """``cases``: two (label, checkout, extra arguments), run alternately."""
    runs: dict[str, list[dict[str, Any]]] = {c[0]: [] for c in cases}
    for k in range(repeat):
        for label, d, extra in cases if k % 2 == 0 else cases[::-1]:
            env = dict(os.environ, PYTHONPATH=str(Path(d).resolve() / "src"))
            cmd = [sys.executable, __file__, "--json", *extra]
            if seconds is not None:
                cmd += ["--seconds", str(seconds)]
            if workdir is not None:
                cmd += ["--workdir", workdir]
            res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            if res.returncode != 0:
                raise SystemExit(f"{label}: failed\n{res.stderr}")
            r = json.loads(res.stdout.strip().splitlines()[-1])
            runs[label].append(r)
            _print(f"{label} run {k + 1}", r)
    dirs = [c[0] for c in cases]
    a, b = (runs[d] for d in dirs)

    def med(rs: list[dict[str, Any]], key: str) -> float:
        return float(statistics.median(r[key] if key in r else r["stages"][key] for r in rs))

    print(f"medians of {repeat} alternated runs; ratio = {dirs[1]} / {dirs[0]}")
    for key in ("wall_s", "cpu_s", *STAGES):
        ma, mb = med(a, key), med(b, key)
        print(f"  {key:13s} {ma:7.2f} -> {mb:7.2f}  ratio {mb / ma if ma else float('nan'):.3f}")
    same = all(r["bytes"] == a[0]["bytes"] and r["events"] == a[0]["events"] for r in a + b)
    print(f"  same events and message bytes in every run: {same}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=None, help="first S s of the landing")
    ap.add_argument("--ab", nargs=2, metavar="DIR", default=None, help="checkouts A and B")
    ap.add_argument("--repeat", type=int, default=3, help="A/B runs of each")
    ap.add_argument(
        "--sequential", action="store_true", help="no helper thread (ESIM on the render's)"
    )
    ap.add_argument(
        "--ab-threads",
        action="store_true",
        help="A/B of this checkout: sequential (A) vs the helper thread (B)",
    )
    ap.add_argument("--helpers", type=int, default=0, help="render helper processes")
    ap.add_argument(
        "--no-render-here", action="store_true", help="only the helpers render (with --helpers)"
    )
    ap.add_argument("--ab-helpers", type=int, default=None, help="A/B: 0 vs N render helpers")
    ap.add_argument("--json", action="store_true", help="print one JSON line (A/B child)")
    ap.add_argument("--workdir", default=None, help="folder for the temporary outputs")
    args = ap.parse_args()
    if args.workdir is not None:
        Path(args.workdir).mkdir(parents=True, exist_ok=True)
    if args.ab:
        ab([(d, d, []) for d in args.ab], args.repeat, args.seconds, args.workdir)
        return
    if args.ab_threads:
        cases = [("sequential", ".", ["--sequential"]), ("helper thread", ".", [])]
        ab(cases, args.repeat, args.seconds, args.workdir)
        return
    if args.ab_helpers is not None:
        extra = ["--no-render-here"] if args.no_render_here else []
        n = str(args.ab_helpers)
        cases = [("0 helpers", ".", []), (f"{n} helpers", ".", ["--helpers", n, *extra])]
        ab(cases, args.repeat, args.seconds, args.workdir)
        return
    r = run_once(
        args.seconds,
        sequential=args.sequential,
        workdir=args.workdir,
        helpers=args.helpers,
        render_here=not args.no_render_here,
    )
    if args.json:
        print(json.dumps(r))
    else:
        _print("event camera", r)


if __name__ == "__main__":
    main()
