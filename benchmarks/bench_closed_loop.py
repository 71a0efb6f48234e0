"""Closed-loop results and cost: landings per policy, and one episode's CPU against simulate.

Run by hand::

    .venv/bin/python benchmarks/bench_closed_loop.py landings --seeds 20
    .venv/bin/python benchmarks/bench_closed_loop.py ablation --seeds 5 --jobs 2
    .venv/bin/python benchmarks/bench_closed_loop.py speed

``landings``: every policy (``--policies``, default all packaged ones) flies ``--seeds``
episodes (seeds ``--first-seed`` on; ``--jobs`` at once) of ``--config`` (default: the
benchmark landing ``BENCH_LANDING``: the realistic event-noise preset, flapping on;
``--initial`` moves its start). It writes the per-episode rows to ``--json``, the results
table between the ``<!-- bench:closed-loop -->`` markers of docs/guide/closed-loop.md,
and ``docs/img/closed_loop.png``: the height gap's time to contact estimated by each
policy that reports one (``policy.estimate``) against the true one over time, the
attitude-estimate error, and the touchdown vertical speeds per policy.

``ablation``: ``tau-events`` on ``roslan/Landing-v0`` with every error source at zero but
one, at 1x and 2x its default, ``--seeds`` seeds per row; all episodes in one pool of
``--jobs`` processes (the 1x rows first), ``--json`` rewritten after each episode (a
stopped run keeps what it flew; run again, it flies only the missing episodes). It
prints the markdown table; it writes no docs.

``speed``: the CPU (user + system, this process and its children) of ``roslan fly`` with
``tau-state`` against ``roslan simulate`` on the same config (same sensors, the
closed-form landing), each writing its OUTDIR.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GUIDE = ROOT / "docs" / "guide" / "closed-loop.md"
FIGURE = ROOT / "docs" / "img" / "closed_loop.png"
MARK = ("<!-- bench:closed-loop -->", "<!-- /bench:closed-loop -->")


def _estimate_ttc(policy: Any) -> float | None:
    """The policy's current estimate of the height gap's time to contact (s), if any."""
    est = getattr(policy, "estimate", None)
    if est is None:
        return None
    tau = getattr(est, "tau", est)
    try:
        value = abs(float(tau))
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _attitude_error(policy: Any, env: Any, t: float) -> float:
    """Angle (rad) between the policy's attitude estimate and the true attitude (flapping
    included) at ``t``; nan when the policy reports none."""
    est = getattr(policy, "estimate", None)
    R = getattr(est, "R_world_body", None)
    if R is None:
        return math.nan
    true = env._traj.state([t]).R_world_body[0]
    c = (float(np.trace(true.T @ np.asarray(R))) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, c)))


def fly_one(config: Any, name: str, seed: int) -> dict[str, Any]:
    """One episode: episode.json's content plus the time series (t, true and estimated
    time to contact of the height gap, attitude-estimate error rad)."""
    from roslan.env import LandingEnv, make_policy

    policy = make_policy(name)
    env = LandingEnv(config, policy_name=name)
    series: list[tuple[float, float, float, float]] = []
    try:
        obs, info = env.reset(seed=seed)
        policy.reset(env.policy_context())
        while True:
            action = policy.act(obs, info)
            st = info["state"]
            z, vz = float(st["gaps"][2]), float(st["rates"][2])
            true_ttc = -z / vz if vz < 0 else math.nan
            est = _estimate_ttc(policy)
            t = float(info["t"])
            att = _attitude_error(policy, env, t)
            series.append((t, true_ttc, math.nan if est is None else est, att))
            obs, _, term, trunc, info = env.step(action)
            if term or trunc:
                ep = dict(info["episode"])
                break
    finally:
        env.close()
    ep["series"] = series
    return ep


def _fly_many(config: Any, name: str, seeds: Any, jobs: int) -> list[dict[str, Any]]:
    """:func:`fly_one` over ``seeds`` in ``jobs`` processes (spawned: an OpenGL context
    never crosses a fork), in seed order."""
    seeds = list(seeds)
    if jobs <= 1:
        out = []
        for seed in seeds:
            out.append(fly_one(config, name, seed))
            _say(name, seed, out[-1])
        return out
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(jobs, mp_context=mp.get_context("spawn")) as pool:
        futures = [pool.submit(fly_one, config, name, seed) for seed in seeds]
        out = []
        for seed, fut in zip(seeds, futures, strict=True):
            out.append(fut.result())
            _say(name, seed, out[-1])
    return out


def _say(label: str, seed: int, ep: dict[str, Any]) -> None:
    print(
        f"{label} seed {seed}: {ep['reason']} success={ep['success']} "
        f"v_z={ep['touchdown_vertical_speed']} v_h={ep['touchdown_horizontal_speed']} "
        f"position error={ep['position_error']}",
        flush=True,
    )


def _landed(ep: dict[str, Any]) -> bool:
    """The issue's criterion: touchdown vertical speed <= 0.5 m/s and no collision."""
    v = ep.get("touchdown_vertical_speed")
    return ep["reason"] == "touchdown" and v is not None and v <= 0.5


def _tau_error(ep: dict[str, Any]) -> float | None:
    """Median |estimate - true| / true over the last 70 % of the descent (None: no
    estimate)."""
    s = np.asarray(ep["series"], dtype=np.float64)
    if s.size == 0 or np.all(np.isnan(s[:, 2])):
        return None
    td = ep.get("touchdown_time") or s[-1, 0]
    keep = (s[:, 0] >= 0.3 * td) & np.isfinite(s[:, 1]) & (s[:, 1] > 0)
    rel = np.abs(s[keep, 2] - s[keep, 1]) / s[keep, 1]
    rel = rel[np.isfinite(rel)]
    return float(np.median(rel)) if rel.size else None


def _stats(values: list[float]) -> str:
    if not values:
        return "-"
    a = np.asarray(values)
    return f"{np.median(a):.3f} [{a.min():.3f}, {a.max():.3f}]"


def table(results: dict[str, list[dict[str, Any]]]) -> str:
    """The markdown results table."""
    rows = [
        "| policy | landed (v_z <= 0.5 m/s, no collision) | success | touchdown v_z m/s "
        "median [min, max] | horizontal m/s | position error m | median tau error, last 70 % "
        "| attitude-estimate error mrad |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, eps in results.items():
        n = len(eps)
        landed = sum(_landed(e) for e in eps)
        ok = sum(bool(e["success"]) for e in eps)
        vz = [
            e["touchdown_vertical_speed"] for e in eps if e["touchdown_vertical_speed"] is not None
        ]
        vh = [
            e["touchdown_horizontal_speed"]
            for e in eps
            if e["touchdown_horizontal_speed"] is not None
        ]
        pos = [e["position_error"] for e in eps if e["position_error"] is not None]
        errs = [x for x in (_tau_error(e) for e in eps) if x is not None]
        err = f"{100 * np.median(errs):.1f} %" if errs else "-"
        att = [x for x in (_attitude_stat(e) for e in eps) if x is not None]
        att_s = f"{1000 * np.median(att):.1f}" if att else "-"
        rows.append(
            f"| `{name}` | {landed}/{n} | {ok}/{n} | {_stats(vz)} | {_stats(vh)} | {_stats(pos)} "
            f"| {err} | {att_s} |"
        )
    return "\n".join(rows)


def figure(results: dict[str, list[dict[str, Any]]], path: Path) -> None:
    """Estimated vs true time to contact over time; touchdown speeds per policy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    has_att = any(
        _attitude_stat(e) is not None for eps in results.values() for e in eps[:1] if e["series"]
    )
    if has_att:
        fig, (ax1, ax3, ax2) = plt.subplots(1, 3, figsize=(15, 4.2), width_ratios=(1.6, 1.2, 1))
        for j, (name, eps) in enumerate(results.items()):
            for i, ep in enumerate(eps[:5]):
                s = np.asarray(ep["series"], dtype=np.float64)
                if s.ndim == 2 and s.shape[1] >= 4 and not np.all(np.isnan(s[:, 3])):
                    label = f"{name} (seeds of the first 5)" if i == 0 else None
                    ax3.plot(s[:, 0], 1000 * s[:, 3], color=f"C{j}", lw=0.8, label=label)
        ax3.set_xlabel("time, s")
        ax3.set_ylabel("attitude-estimate error, mrad")
        ax3.set_title("attitude estimate vs true (flapping included)")
        ax3.set_ylim(bottom=0)
        ax3.legend(fontsize=8)
    else:
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), width_ratios=(1.6, 1))
    drew = False
    for j, (name, eps) in enumerate(results.items()):
        for i, ep in enumerate(eps[:5]):
            s = np.asarray(ep["series"], dtype=np.float64)
            if s.size == 0 or np.all(np.isnan(s[:, 2])):
                continue
            label = f"{name} estimate (seeds 0-4)" if i == 0 else None
            ax1.plot(s[:, 0], s[:, 2], color=f"C{j}", lw=0.9, alpha=0.8, label=label)
            ax1.plot(s[:, 0], s[:, 1], "k--", lw=0.8, label="true" if not drew else None)
            drew = True
    if not drew:
        for name, eps in results.items():
            s = np.asarray(eps[0]["series"], dtype=np.float64)
            ax1.plot(s[:, 0], s[:, 1], lw=1.0, label=f"true ({name})")
    ax1.set_xlabel("time, s")
    ax1.set_ylabel("time to contact of the height gap, s")
    ax1.set_ylim(bottom=0)
    ax1.set_title("time to contact: estimated (first 5 seeds) vs true")
    ax1.legend(fontsize=8)
    names = list(results)
    data = [
        [
            e["touchdown_vertical_speed"]
            for e in results[n]
            if e["touchdown_vertical_speed"] is not None
        ]
        for n in names
    ]
    for i, d in enumerate(data):
        x = np.full(len(d), i) + np.random.default_rng(i).uniform(-0.12, 0.12, len(d))
        ax2.scatter(x, d, s=14, alpha=0.8, color=f"C{i}")
    ax2.axhline(0.5, color="r", lw=0.8, ls=":", label="0.5 m/s")
    ax2.set_xticks(range(len(names)), names, rotation=15)
    ax2.set_ylabel("touchdown vertical speed, m/s")
    ax2.set_title(f"touchdown speeds ({len(next(iter(results.values())))} seeds each)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_table(text: str, header: str) -> None:
    doc = GUIDE.read_text()
    block = f"{MARK[0]}\n{header}\n\n{text}\n{MARK[1]}"
    pattern = re.compile(re.escape(MARK[0]) + ".*?" + re.escape(MARK[1]), re.S)
    if not pattern.search(doc):
        msg = f"{GUIDE}: the markers {MARK} are missing"
        raise SystemExit(msg)
    GUIDE.write_text(pattern.sub(lambda _: block, doc))


def _machine() -> str:
    cpu = platform.processor() or platform.machine()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"{cpu}, {os.cpu_count()} CPUs (shared, load average {load:.1f} at the end), "
        f"{time.strftime('%Y-%m-%d')}"
    )


BENCH_LANDING: dict[str, Any] = {
    # the warehouse marker approached from 2.3 m up and 3 m away (touchdown at 2.3 s),
    # flapping on; a 1 kHz IMU and a 128x96 downward event camera, realistic pixel preset
    "trajectory": {
        "k": 0.5,
        "initial": {"position": [-2.6, 1.2, 2.3], "rpy": [0.05, 0.1, 0.3], "descent_rate": 2.0},
        "hold": 0.1,
        "flapping": {"frequency": 4.5, "heave": 0.008, "pitch": 0.035},
        "goal": {"position": [2.0, -1.0, 0.01], "rpy": [0.0, 0.0, 0.3]},
    },
    "scene": "warehouse",
    "sensors": [
        {"type": "imu", "name": "imu", "rate": 1000.0},
        {
            "type": "event_camera",
            "name": "dvs",
            "rate": 10.0,
            "resolution": [128, 96],
            "preset": "realistic",
            "max_rate": 300.0,
            "pose": {"position": [0.0, 0.0, -0.045], "rpy": [0.0, 1.5707963267948966, 0.0]},
        },
    ],
    "output": {"ground_truth_rate": 50.0},
}
"""The landing of ``landings`` unless ``--config`` is given."""


def landings(args: argparse.Namespace) -> None:
    from roslan.env import POLICIES

    if args.combine:
        results = {}
        for part in args.combine.split(","):
            results.update(json.loads(Path(part).read_text()))
        _report(args, results)
        return
    names = args.policies.split(",") if args.policies else list(POLICIES)
    config: Any = args.config or BENCH_LANDING
    if args.initial:
        config = _moved_start(config, args.initial)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    results = {}
    for name in names:
        results[name] = _fly_many(config, name, seeds, args.jobs)
    Path(args.json).write_text(json.dumps(results))
    _report(args, results)


def _moved_start(config: Any, initial: str) -> dict[str, Any]:
    """``config`` (a YAML path or a dict) with ``trajectory.initial`` replaced by
    ``"x,y,z,roll,pitch,yaw,descent_rate"`` (goal frame; a setting nobody tuned for)."""
    import yaml

    v = [float(x) for x in initial.split(",")]
    if len(v) != 7:
        msg = f"--initial {initial!r}: expected 7 numbers x,y,z,roll,pitch,yaw,descent_rate"
        raise SystemExit(msg)
    cfg: dict[str, Any] = (
        yaml.safe_load(Path(config).read_text()) if isinstance(config, (str, Path)) else config
    )
    cfg = json.loads(json.dumps(cfg))
    cfg["trajectory"]["initial"] = {"position": v[:3], "rpy": v[3:6], "descent_rate": v[6]}
    cfg["trajectory"].pop("approach", None)
    return cfg


def _report(args: argparse.Namespace, results: dict[str, list[dict[str, Any]]]) -> None:
    text = table(results)
    print(text)
    cfg = (args.config or "") + (f" with trajectory.initial {args.initial}" if args.initial else "")
    cfg = cfg or (
        "the benchmark landing (BENCH_LANDING: the warehouse marker from 2.3 m up and 2.9 m "
        "away, closed-form touchdown at 2.3 s, flapping on; 1 kHz IMU and a 128x96 "
        "downward event camera, realistic pixel preset)"
    )
    eps = next(iter(results.values()))
    seeds = [e.get("seed") for e in eps]
    span = f"seeds {seeds[0]}-{seeds[-1]}" if seeds and None not in seeds else "seeds"
    header = f"{len(eps)} seeds per policy ({span}), {cfg}; {_machine()}."
    if not args.no_docs:
        write_table(text, header)
        figure(results, FIGURE)
        print(f"wrote {GUIDE} and {FIGURE}")


ABLATION_SOURCES = (
    ("start-estimate position", "position_sigma"),
    ("start-estimate velocity", "velocity_sigma"),
    ("start-estimate attitude", "attitude_sigma"),
    ("accelerometer turn-on bias", "accelerometer_turn_on_bias_sigma"),
    ("gyroscope turn-on bias", "gyroscope_turn_on_bias_sigma"),
    ("start spread", "start_spread"),
)
"""The error sources of ``ablation``: (label, key in landing.yaml)."""


def ablation_config(key: str | None, scale: float) -> dict[str, Any]:
    """``roslan/Landing-v0``'s config with every error source at zero but ``key`` (at
    ``scale`` times its default; None: all zero)."""
    import yaml

    from roslan.env.landing import DEFAULT_CONFIG

    cfg: dict[str, Any] = yaml.safe_load(Path(DEFAULT_CONFIG).read_text())
    cl = cfg["closed_loop"]
    se = dict(cl["start_estimate"])
    imu = next(s for s in cfg["sensors"] if s["type"] == "imu")
    spread = dict(cl["start_spread"])
    zero_spread = {"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0], "descent_rate": 0.0}
    cl["start_estimate"] = dict.fromkeys(se, 0.0)
    cl["start_spread"] = zero_spread
    defaults = {k: imu[k] for k in ABLATION_SOURCES_IMU}
    for k in ABLATION_SOURCES_IMU:
        imu[k] = 0.0
    if key in se:
        cl["start_estimate"][key] = scale * se[key]
    elif key in defaults:
        imu[key] = scale * defaults[key]
    elif key == "start_spread":
        cl["start_spread"] = {
            "position": [scale * v for v in spread["position"]],
            "rpy": [scale * v for v in spread["rpy"]],
            "descent_rate": scale * spread["descent_rate"],
        }
    cfg["scene"] = "warehouse"
    return cfg


ABLATION_SOURCES_IMU = ("accelerometer_turn_on_bias_sigma", "gyroscope_turn_on_bias_sigma")


def ablation_rows() -> list[tuple[str, str | None, float]]:
    """(label, key, scale) of every ablation row, in table order."""
    rows: list[tuple[str, str | None, float]] = [("none (all zero)", None, 0.0)]
    rows += [(f"{label} {m:g}x", key, m) for label, key in ABLATION_SOURCES for m in (1.0, 2.0)]
    return rows


def ablation(args: argparse.Namespace) -> None:
    """Each error source alone at 1x and 2x its default (``--seeds`` seeds each).

    All episodes go to one pool of ``--jobs`` processes (no core idles at a row's end),
    the 1x rows before the 2x ones (``--first``: these rows before all), and ``--json``
    is rewritten after every episode, so a stopped run leaves every finished episode (a
    rerun flies only the missing ones)."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    out: dict[str, list[dict[str, Any]]] = {}
    if Path(args.json).exists():
        out = json.loads(Path(args.json).read_text())
    rows = ablation_rows()
    order = sorted(rows, key=lambda r: r[2] > 1.0)  # none and 1x first, then 2x
    first = [x.strip() for x in (args.first or "").split(",") if x.strip()]
    labels = [r[0] for r in rows]
    unknown = [x for x in first if x not in labels]
    if unknown:
        raise SystemExit(f"--first: {unknown}: no such row (allowed: {', '.join(labels)})")
    order = sorted(order, key=lambda r: first.index(r[0]) if r[0] in first else len(first))
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    jobs = [
        (label, key, m, seed)
        for label, key, m in order
        for seed in seeds
        if seed not in {e.get("seed") for e in out.get(label, [])}
    ]
    with ProcessPoolExecutor(max(1, args.jobs), mp_context=mp.get_context("spawn")) as pool:
        futures = {
            pool.submit(fly_one, ablation_config(key, m), "tau-events", seed): (label, seed)
            for label, key, m, seed in jobs
        }
        for fut in as_completed(futures):
            label, seed = futures[fut]
            ep = fut.result()
            ep.setdefault("seed", seed)
            out.setdefault(label, []).append(ep)
            out[label].sort(key=lambda e: e["seed"])
            _say(label, seed, ep)
            done = {r[0]: out[r[0]] for r in rows if r[0] in out}
            Path(args.json).write_text(json.dumps(done))
    print(ablation_table({r[0]: out[r[0]] for r in rows if r[0] in out}))


def ablation_table(results: dict[str, list[dict[str, Any]]]) -> str:
    """The markdown ablation table."""
    rows = [
        "| error source (alone) | seeds | success | touchdown v_z m/s median [min, max] "
        "| horizontal m/s | position error m | median tau error | attitude error mrad |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, eps in results.items():
        rows.append(f"| {name} | {len(eps)} | " + _summary_cells(eps) + " |")
    return "\n".join(rows)


def _summary_cells(eps: list[dict[str, Any]]) -> str:
    n = len(eps)
    ok = sum(bool(e["success"]) for e in eps)

    def col(key: str) -> list[float]:
        return [e[key] for e in eps if e.get(key) is not None]

    errs = [x for x in (_tau_error(e) for e in eps) if x is not None]
    err = f"{100 * np.median(errs):.1f} %" if errs else "-"
    att = [x for x in (_attitude_stat(e) for e in eps) if x is not None]
    att_s = f"{1000 * np.median(att):.1f}" if att else "-"
    return (
        f"{ok}/{n} | {_stats(col('touchdown_vertical_speed'))} | "
        f"{_stats(col('touchdown_horizontal_speed'))} | {_stats(col('position_error'))} | "
        f"{err} | {att_s}"
    )


def _attitude_stat(ep: dict[str, Any]) -> float | None:
    """Median attitude-estimate error of an episode (rad; None: no estimate)."""
    s = np.asarray(ep["series"], dtype=np.float64)
    if s.ndim != 2 or s.shape[1] < 4 or np.all(np.isnan(s[:, 3])):
        return None
    return float(np.nanmedian(s[:, 3]))


def _cpu_of(cmd: list[str]) -> float:
    before = os.times()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    after = os.times()
    return (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )


def speed(args: argparse.Namespace) -> None:
    from roslan.env.landing import DEFAULT_CONFIG

    config = str(args.config or DEFAULT_CONFIG)
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        sim = _cpu_of(
            [
                py,
                "-m",
                "roslan",
                "simulate",
                config,
                "-o",
                f"{tmp}/sim",
                "--quiet",
                "--workers",
                "0",
            ]
        )
        fly = _cpu_of(
            [
                py,
                "-m",
                "roslan",
                "fly",
                config,
                "--policy",
                "tau-state",
                "-o",
                f"{tmp}/fly",
                "--quiet",
            ]
        )
    print(
        f"simulate CPU {sim:.1f} s, fly (tau-state, 50 Hz) CPU {fly:.1f} s: ratio {fly / sim:.2f}"
    )
    print(_machine())


def main() -> None:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = p.add_subparsers(dest="what", required=True)
    a = sub.add_parser("landings")
    a.add_argument("--seeds", type=int, default=20)
    a.add_argument("--first-seed", type=int, default=0, help="seeds FIRST..FIRST+N-1")
    a.add_argument("--jobs", type=int, default=1, help="episodes flown at once")
    a.add_argument("--policies", default=None, help="comma-separated (default: all)")
    a.add_argument("--config", default=None, help="YAML (default: roslan/Landing-v0's)")
    a.add_argument("--json", default=str(Path(tempfile.gettempdir()) / "closed_loop.json"))
    a.add_argument("--no-docs", action="store_true", help="print only")
    a.add_argument(
        "--initial", default=None, help="x,y,z,roll,pitch,yaw,descent_rate: another start"
    )
    a.add_argument("--combine", default=None, help="comma-separated --json files: report only")
    a.set_defaults(func=landings)
    c = sub.add_parser("ablation")
    c.add_argument("--seeds", type=int, default=5)
    c.add_argument("--first-seed", type=int, default=0)
    c.add_argument("--jobs", type=int, default=1)
    c.add_argument("--json", default=str(Path(tempfile.gettempdir()) / "ablation.json"))
    c.add_argument("--first", default=None, help="comma-separated row labels to fly first")
    c.set_defaults(func=ablation)
    b = sub.add_parser("speed")
    b.add_argument("--config", default=None)
    b.set_defaults(func=speed)
    args = p.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
