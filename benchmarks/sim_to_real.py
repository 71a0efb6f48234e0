"""roslan side by side with real sensors: the figures and tables of docs/realism.md.

Events: a real DAVIS346 recording (AEDAT 4; static camera over a street) against roslan's
pixel model (roslan.events, the shipped ``sensor: davis346`` realistic values) driven by
the recording's own APS frames. IMU: EuRoC MAV V1_02_medium's ground truth flown as a file
trajectory with an ideal IMU against the real ADIS16448, then with EuRoC's Kalibr noise
and a ``vibration:`` block fitted here to the real residual spectrum.

The recordings are not part of roslan. The DAVIS346 file is the test data of the PyPI
packages ``aedat`` 2.3.0 (tests/data/test_data.aedat4) and ``faery`` 0.7.1
(tests/data/davis346.aedat4); the EuRoC files are the dataset's V1_02_medium
``state_groundtruth_estimate0/data.csv`` and ``imu0/data.csv`` (ETH Zurich ASL, Burri et
al., IJRR 2016; https://projects.asl.ethz.ch/datasets/euroc-mav/). Reading AEDAT 4
needs ``pip install aedat`` (or ``pip install 'roslan[realism]'``).

Usage:
  python benchmarks/sim_to_real.py --davis DAVIS.aedat4 --euroc-gt GT.csv --euroc-imu IMU.csv \
      [--out docs/img] [--vibration-yaml OUT.yaml]
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import tempfile
from pathlib import Path

import matplotlib
import numpy as np
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from scipy import ndimage, signal

from roslan.events.fit import DN_BINS, MOVING_FACTOR, static_mask
from roslan.events.model import EventBatch, EventGenerator
from roslan.events.recording import read_recording
from roslan.sensors.cameras import EventCameraConfig
from roslan.sensors.imu import imu_measurements
from roslan.trajectory import TrajectoryConfig, VibrationConfig, make_trajectory
from roslan.trajectory.vibration import VibratingTrajectory

FS = 200.0  # EuRoC IMU rate, Hz
KALIBR = {  # EuRoC imu0/sensor.yaml (ADIS16448)
    "gyroscope_noise_density": 1.6968e-04,
    "gyroscope_random_walk": 1.9393e-05,
    "accelerometer_noise_density": 2.0000e-3,
    "accelerometer_random_walk": 3.0000e-3,
}
BANDS = [(1.0, 10.0)] + [(10.0 + 2.5 * k, 12.5 + 2.5 * k) for k in range(35)] + [(97.5, 99.5)]
"""Bands of the fitted broadband vibration, Hz: 2.5 Hz wide above 10 Hz, which resolves the
rotor harmonics' peaks (every ~17.5 Hz) to within a band."""


def save(fig: plt.Figure, out: Path, name: str) -> None:
    path = out / name
    fig.savefig(path, dpi=80)
    plt.close(fig)
    print(f"wrote {path} ({path.stat().st_size // 1024} kB)")


# ----------------------------------------------------------------------------- events
def simulate_davis(rec, drive: np.ndarray, seed: int = 0) -> EventBatch:
    """roslan's pixel model (shipped davis346 values) over the frames ``drive`` (K, H, W)
    linear intensity at the recording's frame instants."""
    params = EventCameraConfig.model_validate(
        {"type": "event_camera", "name": "dvs", "topic": "/dvs", "rate": 25, "sensor": "davis346"}
    ).model_params()
    gen = EventGenerator(rec.width, rec.height, params, np.random.default_rng(seed))
    out = [gen.update(f, int(t)) for f, t in zip(drive, rec.frame_t_ns, strict=True)]
    return EventBatch.concatenate(out)


def simulate_static_long(rec, level: np.ndarray, seconds: float, seed: int = 1) -> EventBatch:
    """The static image ``level`` (H, W) held for ``seconds`` (the model's rates with small
    Poisson error)."""
    params = EventCameraConfig.model_validate(
        {"type": "event_camera", "name": "dvs", "topic": "/dvs", "rate": 25, "sensor": "davis346"}
    ).model_params()
    gen = EventGenerator(rec.width, rec.height, params, np.random.default_rng(seed))
    steps = np.linspace(0, seconds * 1e9, 201).astype(np.int64)
    return EventBatch.concatenate([gen.update(level, int(t)) for t in steps])


def per_pixel(x, y, p, W, H) -> tuple[np.ndarray, np.ndarray]:
    idx = np.asarray(y, np.int64) * W + np.asarray(x, np.int64)
    on = np.bincount(idx[p == 1], minlength=W * H).reshape(H, W)
    off = np.bincount(idx[p == 0], minlength=W * H).reshape(H, W)
    return on, off


def events_part(path: Path, out: Path) -> None:
    try:
        import aedat  # noqa: F401
    except ImportError:
        sys.exit("--davis reads AEDAT 4 with the aedat package: pip install aedat")
    rec = read_recording(path)
    H, W = rec.height, rec.width
    fr = rec.frames.astype(np.float64)
    mean, std = fr.mean(0), fr.std(0)
    still0 = std < 2.0  # the definition
    still3 = static_mask(rec.frames, 2.0, 3)  # roslan fit-noise's default
    drive = fr / 255.0
    drive[:, still0] = mean[still0] / 255.0  # static pixels: their exact (mean) level
    t0, t1 = int(rec.frame_t_ns[0]), int(rec.frame_t_ns[-1])
    T = (t1 - t0) * 1e-9
    sel = (rec.t_ns >= t0) & (rec.t_ns <= t1)
    real = EventBatch(rec.t_ns[sel], rec.x[sel], rec.y[sel], rec.p[sel])
    sim = simulate_davis(rec, drive)
    LONG = 60.0
    long_ = simulate_static_long(rec, mean / 255.0, LONG)
    r_on, r_off = per_pixel(real.x, real.y, real.p, W, H)
    s_on, s_off = per_pixel(sim.x, sim.y, sim.p, W, H)
    l_on, l_off = per_pixel(long_.x, long_.y, long_.p, W, H)
    print(f"\n## DAVIS346: {path.name}, {W}x{H}, frames {rec.frames.shape[0]}, span {T:.3f} s")
    print(f"real events in span {real.size}, simulated {sim.size}")
    # --- background per APS-level bin
    for name, still in (
        ("APS std < 2 DN, 3 px from moving pixels", still3),
        ("APS std < 2 DN (issue 39)", still0),
    ):
        print(f"\n### Background rate per static pixel ({name}; {int(still.sum())} pixels)")
        print(
            "| APS level (DN) | pixels | real (Hz) | simulated, same span (Hz) "
            "| simulated, 60 s (Hz) | 60 s / real |"
        )
        print("|---|---|---|---|---|---|")
        ok = True
        for lo, hi in itertools.pairwise(DN_BINS):
            b = still & (mean >= lo) & (mean < hi)
            n = int(b.sum())
            rr = (r_on[b].sum() + r_off[b].sum()) / max(n, 1) / T
            ss = (s_on[b].sum() + s_off[b].sum()) / max(n, 1) / T
            ll = (l_on[b].sum() + l_off[b].sum()) / max(n, 1) / LONG
            flag = "" if n >= 1000 else " (< 1,000 px)"
            print(
                f"| {lo:.0f}-{hi:.0f} | {n} | {rr:.4f} | {ss:.4f} | {ll:.4f} "
                f"| {ll / rr if rr else float('nan'):.2f}{flag} |"
            )
            if n >= 1000:
                ok &= bool(rr > 0 and 0.5 <= ll / rr <= 2.0)
        print(f"CHECK background within 2x in every bin of >= 1,000 px: {'PASS' if ok else 'FAIL'}")
    # --- ON/OFF
    print("\n### ON/OFF balance")
    print("| pixels | real ON fraction | simulated ON fraction |")
    print("|---|---|---|")
    for name, m in (
        ("static", still3),
        ("moving region and the rest", ~still3),
        ("all", np.ones_like(still3)),
    ):
        rf = r_on[m].sum() / max(r_on[m].sum() + r_off[m].sum(), 1)
        sf = s_on[m].sum() / max(s_on[m].sum() + s_off[m].sum(), 1)
        print(f"| {name} | {rf:.3f} | {sf:.3f} |")
    # --- hot pixels: counts per static pixel
    rc = (r_on + r_off)[still3]
    sc = (s_on + s_off)[still3]
    print("\n### Events per static pixel over the span (hot-pixel tail)")
    print("| | mean | 99.9th pct | 99.99th pct | max | pixels with >= 3 |")
    print("|---|---|---|---|---|---|")
    for name, c in (("real", rc), ("simulated", sc)):
        q = np.percentile(c, [99.9, 99.99])
        print(
            f"| {name} | {c.mean():.4f} | {q[0]:.0f} | {q[1]:.0f} | {c.max()} | {(c >= 3).sum()} |"
        )

    # --- inter-event intervals of noise events (array-wide, static pixels)
    def static_times(ev: EventBatch) -> np.ndarray:
        keep = still3[np.asarray(ev.y, np.int64), np.asarray(ev.x, np.int64)]
        return np.sort(ev.t[keep]) * 1e-9

    iei_r, iei_s = np.diff(static_times(real)), np.diff(static_times(sim))
    # --- moving region: events per 40 ms window
    moving = ndimage.binary_dilation(std >= MOVING_FACTOR * 2.0, np.ones((7, 7), bool))
    edges = np.arange(t0, t1 + 1, 40_000_000)

    def windows(ev: EventBatch, pol: int) -> np.ndarray:
        m = moving[np.asarray(ev.y, np.int64), np.asarray(ev.x, np.int64)] & (ev.p == pol)
        return np.histogram(ev.t[m], edges)[0]

    w_r = [windows(real, 1), windows(real, 0)]
    w_s = [windows(sim, 1), windows(sim, 0)]
    tot_r, tot_s = w_r[0] + w_r[1], w_s[0] + w_s[1]
    cc = np.corrcoef(tot_r, tot_s)[0, 1]
    print(f"\n### Moving region ({int(moving.sum())} px): events per 40 ms window")
    print(
        f"real mean {tot_r.mean():.0f} (ON {w_r[0].sum()}, OFF {w_r[1].sum()}), simulated mean "
        f"{tot_s.mean():.0f} (ON {w_s[0].sum()}, OFF {w_s[1].sum()}); correlation {cc:.3f}; "
        f"simulated / real {tot_s.sum() / tot_r.sum():.2f}"
    )
    # --- figures
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    e = np.array([0, 2, 5, 10, 15, 20, 30, 40, 60, 80, 100, 120, 160, 200, 256])
    mids, rows = [], []
    for lo, hi in itertools.pairwise(e):
        b = still3 & (mean >= lo) & (mean < hi)
        n = b.sum()
        if n < 200:
            continue
        mids.append((lo + hi) / 2)
        rows.append(
            [
                r_on[b].sum() / n / T,
                r_off[b].sum() / n / T,
                l_on[b].sum() / n / LONG,
                l_off[b].sum() / n / LONG,
                n,
            ]
        )
    rows_a = np.array(rows)
    for k, (lab, c) in enumerate((("ON", "tab:blue"), ("OFF", "tab:red"))):
        shown = np.where(rows_a[:, k] > 0, rows_a[:, k], np.nan)  # no event: not drawn
        ax[0].plot(mids, shown, "o-", color=c, label=f"real {lab}")
        ax[0].plot(mids, rows_a[:, k + 2], "s--", color=c, alpha=0.6, label=f"roslan {lab}")
    ax[0].set(
        yscale="log",
        xlabel="APS level (DN)",
        ylabel="events / s per pixel",
        title="Static-pixel background (bins with no event not drawn)",
    )
    ax[0].legend(fontsize=7)
    for iei, lab in ((iei_r, "real"), (iei_s, "roslan")):
        v = np.sort(iei)
        ax[1].plot(
            np.maximum(v, 1e-7), np.arange(1, v.size + 1) / v.size, label=f"{lab} ({v.size})"
        )
    grid = np.logspace(-7, 0, 200)
    ax[1].plot(grid, -np.expm1(-grid / iei_r.mean()), "k:", label="Poisson, real mean rate")
    ax[1].set(
        xscale="log",
        xlabel="interval between static-pixel events (s)",
        ylabel="cumulative fraction",
        title="Noise-event intervals (array-wide)",
    )
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    save(fig, out, "realism_events_background.png")

    fig, ax = plt.subplots(1, 2, figsize=(10, 3.4))
    kmax = int(max(rc.max(), sc.max())) + 1
    ax[0].bar(np.arange(kmax) - 0.2, np.bincount(rc, minlength=kmax), 0.4, label="real", log=True)
    ax[0].bar(np.arange(kmax) + 0.2, np.bincount(sc, minlength=kmax), 0.4, label="roslan", log=True)
    ax[0].set(
        xlabel="events per static pixel over the span", ylabel="pixels", title="Hot-pixel tail"
    )
    ax[0].legend(fontsize=7)
    tt = (edges[:-1] - t0) * 1e-9
    ax[1].step(tt, tot_r, where="post", label="real")
    ax[1].step(tt, tot_s, where="post", label="roslan (APS frames, 25 fps)")
    ax[1].set(xlabel="time (s)", ylabel="events per 40 ms", title="Moving-car region")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    save(fig, out, "realism_events_hot_cars.png")


# ----------------------------------------------------------------------------- IMU
def allan(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples ``x`` (N,) at ``fs`` Hz."""
    theta = np.cumsum(x) / fs
    n = x.size
    ms = np.unique(np.logspace(0, math.log10(n // 3), 40).astype(int))
    taus, devs = [], []
    for m in ms:
        d = theta[2 * m :] - 2 * theta[m:-m] + theta[: -2 * m]
        tau = m / fs
        taus.append(tau)
        devs.append(math.sqrt(np.mean(d * d) / (2 * tau * tau)))
    return np.array(taus), np.array(devs)


def ideal_imu(traj, t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f, g, _ = imu_measurements(traj, t_ns, np.eye(4), 9.81)
    return f, g


def kalibr_noise(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    dt = 1.0 / FS
    acc = KALIBR["accelerometer_noise_density"] * math.sqrt(FS) * rng.standard_normal((n, 3))
    acc += np.cumsum(
        KALIBR["accelerometer_random_walk"] * math.sqrt(dt) * rng.standard_normal((n, 3)), 0
    )
    gyr = KALIBR["gyroscope_noise_density"] * math.sqrt(FS) * rng.standard_normal((n, 3))
    gyr += np.cumsum(
        KALIBR["gyroscope_random_walk"] * math.sqrt(dt) * rng.standard_normal((n, 3)), 0
    )
    return acc, gyr


def band_rms(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    f, p = signal.welch(x, FS, nperseg=1024, axis=0)
    b = (f >= lo) & (f < hi)
    return np.sqrt(np.trapezoid(p[b], f[b], axis=0))


def best_lag(a: np.ndarray, b: np.ndarray, max_lag: int = 20) -> int:
    """Samples by which ``b`` lags ``a`` maximising the correlation."""
    c = [
        np.corrcoef(a[max_lag + k : a.size - max_lag + k], b[max_lag : b.size - max_lag])[0, 1]
        for k in range(-max_lag, max_lag + 1)
    ]
    return int(np.argmax(c)) - max_lag


def imu_part(gt_path: Path, imu_path: Path, out: Path, vib_yaml: Path | None) -> None:
    gt = np.loadtxt(gt_path, delimiter=",", comments="#")
    im = np.loadtxt(imu_path, delimiter=",", comments="#")
    t_gt = gt[:, 0].astype(np.int64)
    origin = int(t_gt[0])
    with tempfile.TemporaryDirectory() as tmp:
        tum = Path(tmp) / "v1_02.txt"
        q = gt[:, 4:8]  # w x y z
        rows = np.column_stack([(t_gt - origin) * 1e-9, gt[:, 1:4], q[:, 1:4], q[:, :1]])
        np.savetxt(tum, rows, fmt="%.9f")
        cfg = TrajectoryConfig.model_validate({"file": str(tum), "max_gap": 0.1})
        traj = make_trajectory(cfg)
    t_im = im[:, 0].astype(np.int64) - origin
    keep = (t_im > 0.5e9) & (t_im < min(traj.T, 1e30) * 1e9 - 0.5e9)
    t_ns = t_im[keep]
    g_real, a_real = im[keep, 1:4], im[keep, 4:7]
    bw = np.column_stack([np.interp(t_ns, t_gt - origin, gt[:, 11 + i]) for i in range(3)])
    ba = np.column_stack([np.interp(t_ns, t_gt - origin, gt[:, 14 + i]) for i in range(3)])
    g_real, a_real = g_real - bw, a_real - ba
    a_id, g_id = ideal_imu(traj, t_ns)
    n = t_ns.size
    print(f"\n## EuRoC V1_02_medium: {n} IMU samples ({n / FS:.1f} s) against the ideal IMU")
    print(
        "| axis | gyro corr | gyro residual RMS (rad/s) | gyro best lag (ms) | acc corr raw "
        "| acc corr 0.5 s mean | acc residual RMS raw (m/s^2) | 0.5 s mean (m/s^2) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    box = np.ones(100) / 100.0
    gyro_ok = True
    for i, ax_ in enumerate("xyz"):
        cg = np.corrcoef(g_real[:, i], g_id[:, i])[0, 1]
        rg = np.sqrt(np.mean((g_real[:, i] - g_id[:, i]) ** 2))
        lag = best_lag(g_id[:, i], g_real[:, i]) * 1000 / FS
        ca = np.corrcoef(a_real[:, i], a_id[:, i])[0, 1]
        sr, si = np.convolve(a_real[:, i], box, "valid"), np.convolve(a_id[:, i], box, "valid")
        cas = np.corrcoef(sr, si)[0, 1]
        ra = np.sqrt(np.mean((a_real[:, i] - a_id[:, i]) ** 2))
        ras = np.sqrt(np.mean((sr - si) ** 2))
        print(
            f"| {ax_} | {cg:.4f} | {rg:.4f} | {lag:.0f} | {ca:.3f} | {cas:.4f} "
            f"| {ra:.3f} | {ras:.3f} |"
        )
        gyro_ok &= bool(cg >= 0.98 and lag == 0)
    verdict = "PASS" if gyro_ok else "FAIL"
    print(f"CHECK gyro correlation >= 0.98 and zero lag on every axis: {verdict}")
    res_a, res_g = a_real - a_id, g_real - g_id
    # --- fit the vibration block: band RMS of the real residual per axis
    vib = {"broadband": [], "seed": 0, "fade": 0.2}
    for lo, hi in BANDS:
        ra, rg = band_rms(res_a, lo, hi), band_rms(res_g, lo, hi)
        vib["broadband"].append(
            {
                "band": [lo, hi],
                "accel_rms": [round(float(v), 4) for v in ra],
                "gyro_rms": [round(float(v), 5) for v in rg],
                "components": 16,
            }
        )
    text = yaml.safe_dump(
        {"trajectory": {"vibration": vib}}, sort_keys=False, default_flow_style=None
    )
    if vib_yaml is not None:
        vib_yaml.write_text(
            "# EuRoC V1_02_medium (AscTec Firefly): vibration fitted by benchmarks/sim_to_real.py\n"
            + text
        )
        print(f"wrote {vib_yaml}")
    vtraj = VibratingTrajectory(traj, VibrationConfig.model_validate(vib))
    a_v, g_v = ideal_imu(vtraj, t_ns)
    rng = np.random.default_rng(0)
    na, ng = kalibr_noise(n, rng)
    sim_a, sim_g = a_id + na, g_id + ng  # Kalibr noise only
    simv_a, simv_g = a_v + na, g_v + ng  # noise and fitted vibration
    f, p_real = signal.welch(res_a, FS, nperseg=1024, axis=0)
    _, p_noise = signal.welch(sim_a - a_id, FS, nperseg=1024, axis=0)
    _, p_vib = signal.welch(simv_a - a_id, FS, nperseg=1024, axis=0)
    print(
        "\n### Accelerometer residual PSD, 10-80 Hz, simulated (noise + vibration) / real, "
        "per 5 Hz band"
    )
    print("| band (Hz) | x | y | z |")
    print("|---|---|---|---|")
    worst = 1.0
    for lo in range(10, 80, 5):
        b = (f >= lo) & (f < lo + 5)
        r = p_vib[b].mean(0) / p_real[b].mean(0)
        worst = max(worst, float(np.max(np.maximum(r, 1 / r))))
        print(f"| {lo}-{lo + 5} | " + " | ".join(f"{v:.2f}" for v in r) + " |")
    print(f"worst factor over 10-80 Hz (5 Hz bands, 3 axes): {worst:.2f}")
    print(f"CHECK residual spectrum within 2x in 10-80 Hz: {'PASS' if worst <= 2 else 'FAIL'}")
    # --- figures: Allan deviations, residual spectra
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    for k, (name, real_r, sn, sv) in enumerate(
        (
            ("gyroscope (rad/s)", res_g, sim_g - g_id, simv_g - g_id),
            ("accelerometer (m/s^2)", res_a, sim_a - a_id, simv_a - a_id),
        )
    ):
        for i, c in enumerate(("tab:blue", "tab:orange", "tab:green")):
            tr, dr = allan(real_r[:, i], FS)
            ax[k].loglog(tr, dr, color=c, label=f"real - ideal {'xyz'[i]}")
            tn, dn = allan(sn[:, i], FS)
            ax[k].loglog(tn, dn, "--", color=c, alpha=0.7, label=f"Kalibr noise {'xyz'[i]}")
            tv, dv = allan(sv[:, i], FS)
            ax[k].loglog(tv, dv, ":", color=c, label=f"noise + vibration {'xyz'[i]}")
        ax[k].set(xlabel="tau (s)", ylabel="Allan deviation", title=name)
    ax[0].legend(fontsize=6, ncol=3)
    fig.tight_layout()
    save(fig, out, "realism_imu_allan.png")
    fig, ax = plt.subplots(1, 3, figsize=(11, 3.3), sharey=True)
    for i in range(3):
        ax[i].semilogy(f, p_real[:, i], label="real - ideal")
        ax[i].semilogy(f, p_noise[:, i], label="Kalibr noise")
        ax[i].semilogy(f, p_vib[:, i], label="noise + fitted vibration", alpha=0.8)
        ax[i].axvspan(10, 80, color="0.9", zorder=0)
        ax[i].set(xlabel="Hz", title=f"accelerometer {'xyz'[i]}")
    ax[0].set_ylabel("PSD ((m/s^2)^2/Hz)")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    save(fig, out, "realism_imu_spectrum.png")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--davis", type=Path, help="DAVIS346 .aedat4 (a static camera)")
    ap.add_argument("--euroc-gt", type=Path, help="EuRoC state_groundtruth_estimate0 data.csv")
    ap.add_argument("--euroc-imu", type=Path, help="EuRoC imu0 data.csv (same clock)")
    ap.add_argument("--out", type=Path, default=Path("docs/img"))
    ap.add_argument("--vibration-yaml", type=Path, default=None, help="write the fitted block here")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.davis:
        events_part(args.davis, args.out)
    if args.euroc_gt and args.euroc_imu:
        imu_part(args.euroc_gt, args.euroc_imu, args.out, args.vibration_yaml)


if __name__ == "__main__":
    main()
