"""The event camera's post-render work alone, replayed: CPU seconds per stage.

Once renders are spread over processes, the event camera's owner process does only what
follows each render: the flow speed (sampling), ESIM, the packet cuts with their
EventArray packing (both bag flavours), events.txt and events.h5. This script records
those stages' inputs from one stream of the default job's event camera
(``bench_event_stream.run_once``: 963 frames, ~10 M events), then replays each stage
alone on them, without the renderer beside it (less noise than the whole stream), and
prints the thread CPU seconds of each with a digest of its output (equal digests: equal
bytes / values).

    PYTHONPATH=src:benchmarks python benchmarks/bench_event_post.py --record DIR
    PYTHONPATH=src:benchmarks python benchmarks/bench_event_post.py --replay DIR [stages]
    python benchmarks/bench_event_post.py --ab DIR_A DIR_B --data DIR [--repeat 5]

``--ab`` replays in fresh interpreters with ``PYTHONPATH=DIR_X/src`` alternately and
prints the medians and B / A per stage (the recording is made by this checkout when
``DIR/frames.npz`` is missing). Stages: flow, esim, split, txt, h5.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import statistics
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

STAGES = ("flow", "esim", "split", "txt", "h5")
START_NS = 1_700_000_000_000_000_000


def record(data: Path) -> None:
    """Stream the default event camera once, keeping every stage's inputs."""
    import bench_event_stream as bes
    import roslan.sensors.cameras.event as ev
    from roslan.events.model import EventGenerator
    from roslan.sensors.cameras.event_stream import Packetizer

    lums: list[Any] = []
    ts: list[int] = []
    flow: list[Any] = []
    batches: list[tuple[Any, ...]] = []
    splits: list[tuple[int, bool, int]] = []
    update, speed = EventGenerator.update, ev._Camera.max_flow_speed
    write, split = ev.EventCamera._write_events, Packetizer.split

    def rec_update(self: Any, lum: Any, t: int) -> Any:
        lums.append(np.array(lum))
        ts.append(int(t))
        return update(self, lum, t)

    def rec_speed(self: Any, depth: Any, v: Any, w: Any) -> float:
        r = speed(self, depth, v, w)
        flow.append((np.array(depth), np.concatenate([v, w]), r))
        return r

    def rec_write(self: Any, batch: Any) -> None:
        batches.append(tuple(np.array(a) for a in batch))
        write(self, batch)

    def rec_split(self: Any, buf: Any, t: int, *, final: bool) -> Any:
        splits.append((int(t), final, sum(b.size for b in buf)))
        return split(self, buf, t, final=final)

    EventGenerator.update = rec_update  # type: ignore[method-assign]
    ev._Camera.max_flow_speed = rec_speed  # type: ignore[method-assign]
    ev.EventCamera._write_events = rec_write  # type: ignore[method-assign]
    Packetizer.split = rec_split  # type: ignore[method-assign]
    bes.run_once(None, workdir=str(data))
    np.savez(
        data / "frames.npz",
        lums=np.stack(lums),
        ts=np.array(ts),
        depths=np.stack([f[0] for f in flow]),
        vw=np.stack([f[1] for f in flow]),
        speeds=np.array([f[2] for f in flow]),
    )
    with (data / "events.pkl").open("wb") as fh:
        pickle.dump((batches, splits), fh)


def _camera() -> Any:
    from roslan.cli.simulate import load_config
    from roslan.sensors.cameras import EventCamera

    cfg, _ = load_config(None)
    return EventCamera(next(s for s in cfg.sensors if s.type == "event_camera"))


def replay(data: Path, stages: list[str]) -> dict[str, tuple[float, str]]:
    """Each stage alone on the recorded inputs (after one warm-up call): thread CPU
    seconds and a digest of its output."""
    from roslan.events.model import EventBatch

    frames = np.load(data / "frames.npz")
    with (data / "events.pkl").open("rb") as fh:
        raw, splits = pickle.load(fh)
    batches = [EventBatch(*b) for b in raw]
    out: dict[str, tuple[float, str]] = {}
    for stage in stages:
        h = hashlib.sha256()
        c0, extra = _STAGES[stage](frames, batches, splits, h)
        out[stage] = (time.thread_time() - c0 - extra, h.hexdigest()[:16])
    return out


def _flow(frames: Any, batches: Any, splits: Any, h: Any) -> tuple[float, float]:
    from roslan.events.sampling import max_flow_speed

    cam = _camera().camera
    depths, vw = frames["depths"], frames["vw"]
    max_flow_speed(depths[0], cam.K, vw[0, :3], vw[0, 3:], cam.rays)
    c0 = time.thread_time()
    got = [
        max_flow_speed(d, cam.K, q[:3], q[3:], cam.rays) for d, q in zip(depths, vw, strict=True)
    ]
    h.update(np.array(got).tobytes())
    h.update(b"same" if np.array_equal(got, frames["speeds"]) else b"DIFFERENT")
    return c0, 0.0


def _esim(frames: Any, batches: Any, splits: Any, h: Any) -> tuple[float, float]:
    from roslan.events.model import EventGenerator

    lums, ts = frames["lums"], frames["ts"]
    cam = _camera()
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([1, 2])))
    gen = EventGenerator(cam.camera.width, cam.camera.height, cam.params, rng)
    gen.update(lums[0], int(ts[0]))
    gen.update(lums[1], int(ts[1]))
    c0 = time.thread_time()
    kept = [gen.update(lums[i], int(ts[i])) for i in range(2, len(ts))]
    t1 = time.thread_time()
    for b in kept:
        for a in b:
            h.update(a.tobytes())
    return c0, time.thread_time() - t1


def _split(frames: Any, batches: Any, splits: Any, h: Any) -> tuple[float, float]:
    from roslan.events.ros import pack_event_array
    from roslan.io.messages import Flavor
    from roslan.sensors.cameras.event_stream import Packetizer

    cfg = SimpleNamespace(packet_duration=0.001, packet_events=None, topic="/dvs")
    cam = SimpleNamespace(height=260, width=346)
    sensor = SimpleNamespace(config=cfg, camera=cam, optical_frame="dvs_optical")
    ctx = SimpleNamespace(start_time_ns=START_NS, stamp=lambda t: START_NS + t)
    flavors = [SimpleNamespace(flavor=f) for f in Flavor]
    for f in Flavor:
        pack_event_array(f, 0, "dvs", 1, 1, *batches[0])
    pk = Packetizer(sensor, ctx, prebuild=True)  # type: ignore[arg-type]
    pk.flavors = set(Flavor)
    buf: list[Any] = []
    i = 0
    data: list[bytes] = []
    c0 = time.thread_time()
    for t, final, n_buffered in splits:  # the batches as they came, then each cut
        n = sum(b.size for b in buf)
        while n < n_buffered:
            buf.append(batches[i])
            n += batches[i].size
            i += 1
        buf, msgs = pk.split(buf, t, final=final)
        data += [m.build(s) for m in msgs for s in flavors]
    t1 = time.thread_time()
    for d in data:
        h.update(d)
    return c0, time.thread_time() - t1


def _files(kind: str) -> Any:
    def run(frames: Any, batches: Any, splits: Any, h: Any) -> tuple[float, float]:
        import tempfile

        from roslan.events.files import EventH5Writer, EventTextWriter

        def writer(path: Path) -> Any:
            if kind == "txt":
                return EventTextWriter(path)
            return EventH5Writer(path, 346, 260, t_offset_ns=START_NS)

        with tempfile.TemporaryDirectory() as tmp:
            w = writer(Path(tmp) / "warm")
            w.write(batches[0])
            w.close()
            path = Path(tmp) / f"events.{kind}"
            c0 = time.thread_time()
            w = writer(path)
            for b in batches:
                w.write(b)
            w.close()
            t1 = time.thread_time()
            h.update(path.read_bytes())
            return c0, time.thread_time() - t1

    return run


_STAGES = {"flow": _flow, "esim": _esim, "split": _split, "txt": _files("txt"), "h5": _files("h5")}


def ab(dirs: list[str], data: Path, repeat: int, stages: list[str]) -> None:
    runs: dict[str, list[dict[str, Any]]] = {d: [] for d in dirs}
    for k in range(repeat):
        for d in dirs if k % 2 == 0 else dirs[::-1]:
            env = {**os.environ, "PYTHONPATH": f"{d}/src{os.pathsep}{Path(__file__).parent}"}
            cmd = [sys.executable, __file__, "--replay", str(data), "--json", *stages]
            res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            if res.returncode:
                raise SystemExit(f"{d}: failed\n{res.stderr}")
            r = json.loads(res.stdout.strip().splitlines()[-1])
            runs[d].append(r)
            print(d, "  ".join(f"{s} {v[0]:.3f}" for s, v in r.items()), flush=True)
    a, b = dirs
    print(f"medians of {repeat} alternated runs; ratio = {b} / {a}")
    for s in stages:
        ma = statistics.median(r[s][0] for r in runs[a])
        mb = statistics.median(r[s][0] for r in runs[b])
        same = {r[s][1] for r in runs[a] + runs[b]}
        print(
            f"  {s:6s} {ma:6.3f} -> {mb:6.3f}  ratio {mb / ma:.3f}  same output: {len(same) == 1}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--record", type=Path, metavar="DIR")
    ap.add_argument("--replay", type=Path, metavar="DIR")
    ap.add_argument("--ab", nargs=2, metavar="CHECKOUT")
    ap.add_argument("--data", type=Path, metavar="DIR", help="the recording (--ab)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("stages", nargs="*", default=list(STAGES))
    args = ap.parse_args()
    if args.record:
        args.record.mkdir(parents=True, exist_ok=True)
        record(args.record)
    elif args.replay:
        r = replay(args.replay, args.stages)
        if args.json:
            print(json.dumps(r))
        else:
            for s, (cpu, digest) in r.items():
                print(f"{s:6s} {cpu:6.3f} CPU-s  {digest}")
    elif args.ab:
        if args.data is None:
            ap.error("--ab needs --data DIR")
        if not (args.data / "frames.npz").exists():
            args.data.mkdir(parents=True, exist_ok=True)
            record(args.data)
        ab(args.ab, args.data, args.repeat, args.stages)


if __name__ == "__main__":
    main()
