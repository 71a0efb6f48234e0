"""Plots, overview and preview video on a tiny synthetic OUTDIR written in the documented
formats (no simulation): each command yields a non-blank image/video of the right size;
missing inputs name the sensor the plot needs."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from roslan.trajectory import TauTrajectory, Trajectory, TrajectoryConfig

W, H = 64, 48  # event camera / camera resolution of the synthetic run
IMU_RATE = 200.0
LIDAR_RATE = 5.0


def _traj() -> Trajectory:
    cfg = TrajectoryConfig.model_validate(
        {"initial": {"position": [-3.0, 1.0, 2.0], "rpy": [0.05, 0.1, 0.3], "descent_rate": 2.0}}
    )
    return TauTrajectory(cfg, warn=False)


def _ground_truth_events(duration: float) -> tuple[np.ndarray, ...]:
    """A bright 12 px square sliding right: ON events on its leading edge, OFF on its
    trailing edge, every 5 ms. Returns t (s), x, y, p (+1/-1)."""
    t = np.arange(0.0, duration, 0.005)
    left = np.rint(4 + (W - 20) * t / duration).astype(np.int64)
    rows = np.arange(18, 30)
    tt, rr = np.meshgrid(t, rows, indexing="ij")
    lead = np.broadcast_to((left + 12)[:, None], tt.shape)
    trail = np.broadcast_to(left[:, None], tt.shape)
    ts = np.concatenate([tt.ravel(), tt.ravel()])
    xs = np.concatenate([lead.ravel(), trail.ravel()])
    ys = np.concatenate([rr.ravel(), rr.ravel()])
    ps = np.concatenate([np.ones(tt.size, np.int8), -np.ones(tt.size, np.int8)])
    order = np.argsort(ts, kind="stable")
    return ts[order], xs[order], ys[order], ps[order]


def _scan(k: int) -> dict[str, np.ndarray]:
    """A VLP-16-like scan 1.5 m above flat ground with a wall 6 m ahead (sensor frame)."""
    elev = np.deg2rad(np.arange(-15.0, 16.0, 2.0))
    az = np.deg2rad(np.arange(0.0, 360.0, 1.0) + k)
    ee, aa = np.meshgrid(elev, az, indexing="ij")
    d = np.stack([np.cos(ee) * np.cos(aa), np.cos(ee) * np.sin(aa), np.sin(ee)], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r_ground = np.where(d[..., 2] < 0, -1.5 / d[..., 2], np.inf)
        r_wall = np.where(d[..., 0] > 0, 6.0 / d[..., 0], np.inf)
    r = np.minimum(r_ground, r_wall)
    r[r > 30.0] = np.nan  # no return beyond the maximum range
    p = d * r[..., None]
    ring = np.broadcast_to(np.arange(elev.size, dtype=np.uint16)[:, None], ee.shape)
    return {
        "x": p[..., 0].ravel().astype(np.float32),
        "y": p[..., 1].ravel().astype(np.float32),
        "z": p[..., 2].ravel().astype(np.float32),
        "intensity": (100.0 / (1.0 + r)).ravel().astype(np.float32),
        "ring": ring.ravel().copy(),
        "time": np.broadcast_to((aa - aa[:, :1]) / (2 * math.pi) / LIDAR_RATE, ee.shape)
        .ravel()
        .astype(np.float32),
    }


def write_synthetic_outdir(
    out: Path,
    *,
    camera: bool = True,
    events: str | None = "both",
    lidar: bool = True,
    imu: bool = True,
) -> Path:
    """A tiny OUTDIR in the documented layout. ``events``: 'txt', 'h5', 'both' or None."""
    import cv2

    out.mkdir(parents=True, exist_ok=True)
    traj = _traj()
    cfg = traj.config
    # trajectory.csv / summary.json / groundtruth.txt
    tt, gaps, rates, accels = traj.gaps_at(traj.table_times())
    header = "t,x,y,z,roll,pitch,yaw,vx,vy,vz,vroll,vpitch,vyaw,ax,ay,az,aroll,apitch,ayaw"
    np.savetxt(
        out / "trajectory.csv",
        np.column_stack([tt, gaps, rates, accels]),
        fmt="%.9f",
        delimiter=",",
        header=header,
        comments="",
    )
    (out / "summary.json").write_text(json.dumps(traj.summary()))
    tg = np.arange(0.0, traj.duration, 0.02)
    st = traj.state(tg)
    np.savetxt(
        out / "groundtruth.txt", np.column_stack([tg, st.position, st.quat_xyzw]), fmt="%.9f"
    )
    sensors: list[dict[str, object]] = []
    rng = np.random.default_rng(0)
    if imu:
        pose = {"position": [0.05, -0.02, 0.01], "rpy": [0.0, 0.0, math.pi / 2]}
        sensors.append(
            {
                "type": "imu",
                "name": "imu",
                "rate": IMU_RATE,
                "topic": "/imu",
                "pose": pose,
                "gravity": 9.81,
            }
        )
        ti = np.arange(0.0, traj.duration, 1.0 / IMU_RATE)
        s = traj.state(ti)
        # independent truth: IMU rotated 90 deg about z, lever arm ignored in the noise
        R_bs = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        r = np.array(pose["position"])
        lever = np.cross(s.alpha_body, r) + np.cross(s.omega_body, np.cross(s.omega_body, r))
        a_s = s.acceleration + np.einsum("nij,nj->ni", s.R_world_body, lever)
        R_ws = s.R_world_body @ R_bs
        f = np.einsum("nji,nj->ni", R_ws, a_s + np.array([0.0, 0.0, 9.81]))
        w = s.omega_body @ R_bs
        acc = f + 0.05 * rng.standard_normal(f.shape)
        gyro = w + 0.01 * rng.standard_normal(w.shape)
        np.savetxt(
            out / "imu.txt",
            np.column_stack([ti, acc, gyro]),
            fmt="%.9f",
            header="t ax ay az gx gy gz",
            comments="# ",
        )
    if camera:
        sensors.append(
            {
                "type": "event_camera",
                "name": "dvs",
                "rate": 20.0,
                "topic": "/dvs",
                "width": W,
                "height": H,
            }
        )
        (out / "images").mkdir()
        lines = []
        yy, xx = np.mgrid[0:H, 0:W]
        for i, t in enumerate(np.arange(0.0, traj.duration, 0.1)):
            left = round(4 + (W - 20) * t / traj.duration)
            img = (40 + 2 * xx + yy).astype(np.uint8)
            img[18:30, left : left + 12] = 230
            name = f"images/{i:08d}.png"
            cv2.imwrite(str(out / name), img)
            lines.append(f"{t:.9f} {name}")
        (out / "images.txt").write_text("\n".join(lines) + "\n")
    if events is not None:
        t, x, y, p = _ground_truth_events(traj.duration)
        if events in ("txt", "both"):
            np.savetxt(
                out / "events.txt",
                np.column_stack([t, x, y, (p > 0).astype(int)]),
                fmt=["%.9f", "%d", "%d", "%d"],
            )
        if events in ("h5", "both"):
            import h5py

            with h5py.File(out / "events.h5", "w") as h5:
                g = h5.create_group("events")
                g["t"] = np.rint(t * 1e9).astype(np.int64) // 1000  # DSEC: microseconds
                g["x"] = x.astype(np.uint16)
                g["y"] = y.astype(np.uint16)
                g["p"] = p.astype(np.int8)
    if lidar:
        sensors.append(
            {"type": "lidar", "name": "velodyne", "rate": LIDAR_RATE, "topic": "/velodyne"}
        )
        folder = out / "lidar" / "velodyne"
        folder.mkdir(parents=True)
        for k in range(3):
            np.savez(folder / f"{k:06d}.npz", **_scan(k))
    run = {"config": {"trajectory": cfg.model_dump(mode="json"), "sensors": sensors, "seed": 0}}
    (out / "run.json").write_text(json.dumps(run))
    return out


# ---------------------------------------------------------------- fixtures and helpers
import imageio.v3 as iio  # noqa: E402
import pytest  # noqa: E402

from roslan.cli import main  # noqa: E402
from roslan.errors import PlotError  # noqa: E402
from roslan.plots.style import AXIS_COLORS, DPI, EVENT_NEG_RGB, EVENT_POS_RGB  # noqa: E402
from roslan.rundir.events import open_events  # noqa: E402


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_synthetic_outdir(tmp_path_factory.mktemp("plots") / "run")


@pytest.fixture(scope="module")
def bare_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run with the trajectory files only (no sensors)."""
    return write_synthetic_outdir(
        tmp_path_factory.mktemp("plots") / "bare",
        camera=False,
        events=None,
        lidar=False,
        imu=False,
    )


def _png(path: Path) -> np.ndarray:
    img = iio.imread(path)
    return np.asarray(img)[..., :3]


def _hex(c: str) -> np.ndarray:
    return np.array([int(c[i : i + 2], 16) for i in (1, 3, 5)])


def _near(img: np.ndarray, rgb: np.ndarray | tuple[int, int, int], tol: int = 40) -> int:
    """Pixels within ``tol`` of ``rgb`` (per channel)."""
    return int(np.all(np.abs(img.astype(int) - np.asarray(rgb)) <= tol, axis=-1).sum())


def _assert_figure(img: np.ndarray, min_w: int, min_h: int, min_ink: float = 0.03) -> None:
    h, w = img.shape[:2]
    assert w >= min_w
    assert h >= min_h
    non_white = np.any(img < 235, axis=-1).mean()
    assert non_white > min_ink, f"figure almost blank ({non_white:.3f} non-white)"
    assert img.std() > 20 * min_ink / 0.03


# ---------------------------------------------------------------- plot commands
def test_plot_trajectory_draws_path_triads_and_gaps(run_dir: Path, tmp_path: Path) -> None:
    from roslan.plots.trajectory import plot_trajectory

    out = plot_trajectory(run_dir, tmp_path / "traj.png")
    img = _png(out)
    # 12.5 x 6.2 in at DPI
    assert img.shape[1] == round(12.5 * DPI)
    assert img.shape[0] == round(6.2 * DPI)
    _assert_figure(img, 1500, 800)
    for c in AXIS_COLORS:  # triads and gap curves in the x/y/z colours
        assert _near(img, _hex(c), 30) > 200


def test_plot_trajectory_from_csv_only(run_dir: Path, tmp_path: Path) -> None:
    """Without run.json the table alone is drawn (no closed form)."""
    import shutil

    from roslan.plots.trajectory import load_samples, plot_trajectory

    d = tmp_path / "run"
    d.mkdir()
    for f in ("trajectory.csv", "summary.json"):
        shutil.copy(run_dir / f, d / f)
    s = load_samples(d)
    assert not s.closed_form
    summary = json.loads((run_dir / "summary.json").read_text())
    assert s.touchdown == pytest.approx(summary["touchdown_time"])
    _assert_figure(_png(plot_trajectory(d)), 1500, 800)
    assert (d / "plots" / "trajectory.png").is_file()


def test_tau_of_gaps_matches_theory(run_dir: Path) -> None:
    """tau_z from the drawn samples follows tau0 + k t; tau_x = kappa_x tau_z."""
    from roslan.plots.trajectory import load_samples, tau_of

    s = load_samples(run_dir)
    d = s.dense
    m = d.t < 0.9 * s.touchdown
    tau_z = tau_of(d.gaps[m, 2], d.rates[m, 2])
    assert s.k is not None
    assert s.tau0 is not None
    np.testing.assert_allclose(tau_z, s.tau0 + s.k * d.t[m], atol=1e-9)
    tau_x = tau_of(d.gaps[m, 0], d.rates[m, 0])
    np.testing.assert_allclose(tau_x, _traj().config.kappa.x * tau_z, rtol=1e-9)


@pytest.mark.parametrize("color_by", ["ring", "height"])
def test_plot_lidar(run_dir: Path, tmp_path: Path, color_by: str) -> None:
    from roslan.plots.lidar import plot_lidar

    img = _png(plot_lidar(run_dir, tmp_path / "l.png", color_by=color_by))
    _assert_figure(img, 1500, 700)
    # the turbo-coloured points are saturated colours, absent from a grey figure
    sat = img.max(axis=-1).astype(int) - img.min(axis=-1)
    assert (sat > 120).sum() > 1000


def test_plot_lidar_scan_choice_and_errors(run_dir: Path, tmp_path: Path) -> None:
    from roslan.plots.lidar import choose_scan, plot_lidar

    seq, i = choose_scan(run_dir, "x")
    assert (seq.name, i, len(seq)) == ("velodyne", 1, 3)
    # stamps: index / rate of the config (no timestamps.txt, no stamp in the files)
    np.testing.assert_array_equal(seq.t_ns, np.arange(3) * round(1e9 / LIDAR_RATE))
    assert choose_scan(run_dir, "x", index=-1)[1] == 2
    with pytest.raises(PlotError, match="has 3 scans"):
        plot_lidar(run_dir, tmp_path / "l.png", scan=7)
    with pytest.raises(PlotError, match=r"no LiDAR named 'ouster'.*velodyne"):
        plot_lidar(run_dir, tmp_path / "l.png", sensor="ouster")


def test_plot_lidar_title_gives_the_scan_index_as_given(
    run_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """--scan 1 draws the file 000001.npz and its title says scan 1 (0-based, as --help
    says); -1 is the last."""
    import roslan.plots.lidar as lidar_plot

    drawn: list[Any] = []
    save = lidar_plot.save_figure
    monkeypatch.setattr(
        lidar_plot, "save_figure", lambda fig, out, **kw: drawn.append(fig) or save(fig, out, **kw)
    )
    for scan, shown in ((1, 1), (0, 0), (-1, 2)):
        lidar_plot.plot_lidar(run_dir, tmp_path / "l.png", scan=scan)
        title = drawn[-1]._suptitle.get_text()
        assert f"scan {shown} of 0..2 ({shown:06d}.npz)" in title, title
    with pytest.raises(SystemExit):
        main(["plot", "lidar", "--help"])
    assert "0-based" in " ".join(capsys.readouterr().out.split())


def test_lidar_reader_uses_timestamps_and_drops_nan(tmp_path: Path) -> None:
    from roslan.rundir.readers import find_lidar

    folder = tmp_path / "lidar" / "vlp"
    folder.mkdir(parents=True)
    scan = _scan(0)
    n_ok = int(np.isfinite(scan["x"]).sum())
    for k in range(2):
        np.savez(folder / f"{k:06d}.npz", stamp=np.int64(123 + k), **scan)
    (folder / "timestamps.txt").write_text(
        "# t file\n0.250000000 vlp/000000.npz\n0.350000000 vlp/000001.npz\n"
    )
    (seq,) = find_lidar(tmp_path, "x")
    np.testing.assert_array_equal(seq.t_ns, [250_000_000, 350_000_000])
    sc = seq.read(0)
    assert sc.xyz.shape == (n_ok, 3)
    assert np.all(np.isfinite(sc.xyz))
    assert sc.ring is not None
    assert sc.ring.shape == (n_ok,)


def test_plot_imu_truth_is_the_closed_form(run_dir: Path, tmp_path: Path) -> None:
    from roslan.plots.imu import imu_truth, plot_imu
    from roslan.rundir.readers import load_imu

    data = load_imu(run_dir, "x")
    truth = imu_truth(run_dir, data)
    # independent: the fixture's noise is N(0, 0.05) / N(0, 0.01); the truth must sit
    # in the middle of the measurements with that spread
    res_a, res_g = data.acc - truth.acc, data.gyro - truth.gyro
    assert np.all(np.abs(res_a.mean(axis=0)) < 0.02)
    np.testing.assert_allclose(res_a.std(axis=0), 0.05, rtol=0.2)
    np.testing.assert_allclose(res_g.std(axis=0), 0.01, rtol=0.2)
    assert "closed form" in truth.source
    _assert_figure(_png(plot_imu(run_dir, tmp_path / "imu.png")), 1500, 800)


def test_plot_imu_draws_the_thin_truth_over_the_wider_measurement(
    run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the noise is thinner than a line (a_z, w_y of a flapping landing), the
    measurement still shows: on every panel the truth is the thinner line, drawn on top."""
    import roslan.plots.imu as imu_plot

    drawn: list[Any] = []
    save = imu_plot.save_figure
    monkeypatch.setattr(
        imu_plot, "save_figure", lambda fig, out: drawn.append(fig) or save(fig, out)
    )
    imu_plot.plot_imu(run_dir, tmp_path / "imu.png")
    (fig,) = drawn
    assert len(fig.axes) == 6
    for ax in fig.axes:
        by = {str(ln.get_label()).split(" (")[0]: ln for ln in ax.get_lines()}
        measured, truth = by["measured"], by["noise-free truth"]
        assert truth.get_linewidth() < measured.get_linewidth()
        assert truth.get_zorder() > measured.get_zorder()
        assert truth.get_color() == "k"


def test_imu_truth_from_groundtruth_fallback(run_dir: Path) -> None:
    """Differentiated TUM poses agree with the closed form at base_link."""
    from roslan.plots.imu import _truth_from_poses
    from roslan.rundir.readers import load_groundtruth

    gt = load_groundtruth(run_dir)
    assert gt is not None
    traj = _traj()
    tq = np.linspace(0.2, 0.8 * traj.T, 50)
    f, w = _truth_from_poses(*gt, tq)
    st = traj.state(tq)
    f_ref = np.einsum("nji,nj->ni", st.R_world_body, st.acceleration + np.array([0.0, 0.0, 9.81]))
    np.testing.assert_allclose(f, f_ref, atol=0.05 * np.abs(f_ref).max())
    np.testing.assert_allclose(w, st.omega_body, atol=0.02 * np.abs(st.omega_body).max())


# ---------------------------------------------------------------- events and rasters
def test_event_windows_agree_between_txt_and_h5(run_dir: Path, tmp_path: Path) -> None:
    import shutil

    d = tmp_path / "txt"
    d.mkdir()
    shutil.copy(run_dir / "events.txt", d / "events.txt")
    t, x, y, p = _ground_truth_events(_traj().duration)
    t_ns = np.rint(t * 1e9).astype(np.int64)
    with open_events(run_dir, "x") as h5, open_events(d, "x") as txt:
        assert h5.path.suffix == ".h5"
        assert txt.path.suffix == ".txt"
        for a, b in ((0, 20_000_000), (500_000_000, 530_000_000), (1_000_000_000, 1_010_000_000)):
            sel = (t_ns >= a) & (t_ns < b)
            for src in (h5, txt):
                ex, ey, ep = src.window(a, b)
                np.testing.assert_array_equal(
                    np.sort(ex * 1000 + ey), np.sort(x[sel] * 1000 + y[sel])
                )
                assert int((ep > 0).sum()) == int((p[sel] > 0).sum())
        # going back in time restarts the text walk
        ex, _, _ = txt.window(0, 20_000_000)
        assert ex.size == int(((t_ns >= 0) & (t_ns < 20_000_000)).sum())


@pytest.mark.parametrize("kind", ["events.h5", "events.txt"])
def test_plot_events_spreads_frames_and_rate_over_the_run(
    run_dir: Path, tmp_path: Path, kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """events.h5 holds microseconds (DSEC): the time range, the frames and the rate plot
    must cover the whole run, as from events.txt (seconds)."""
    import shutil

    import roslan.plots.events as ev

    d = tmp_path / "run"
    d.mkdir()
    shutil.copy(run_dir / kind, d / kind)
    t, _, _, _ = _ground_truth_events(_traj().duration)
    with open_events(d, "x") as src:
        assert src.path.name == kind
        assert src.time_range_ns() == (0, round(t[-1] * 1e9))
    spans: list[tuple[int, int]] = []
    real_rate = ev.event_rate

    def rate(src: object, t0: int, t1: int, bin_ns: int) -> object:
        spans.append((t0, t1))
        return real_rate(src, t0, t1, bin_ns)  # type: ignore[arg-type]

    monkeypatch.setattr(ev, "event_rate", rate)
    ev.plot_events(d, tmp_path / "plots", frames=4)
    assert spans == [(0, round(t[-1] * 1e9) + 1)]
    # the square slides right over the run: each frame's ON edge lies further right
    cols = []
    for i in range(4):
        img = iio.imread(tmp_path / "plots" / f"event_frame_{i:02d}.png")[:, :, :3]
        on = np.argwhere(np.all(img == EVENT_POS_RGB, axis=-1))
        assert on.size, i
        cols.append(on[:, 1].mean())
    assert np.all(np.diff(cols) > 5), cols
    assert cols[-1] - cols[0] > 0.5 * (W - 20), cols


def test_event_frame_colours_net_polarity() -> None:
    from roslan.plots.raster import event_frame

    x = np.array([1, 1, 1, 3, 5, 5])
    y = np.array([0, 0, 0, 2, 4, 4])
    p = np.array([1, 1, -1, -1, 1, -1], np.int8)
    img = event_frame(x, y, p, 8, 6, np.zeros((6, 8, 3), np.uint8))
    assert tuple(img[0, 1]) == EVENT_POS_RGB
    assert tuple(img[2, 3]) == EVENT_NEG_RGB
    assert tuple(img[4, 5]) == tuple(img[5, 7])  # cancelled: background


def test_bev_puts_forward_up_and_left_left() -> None:
    from roslan.plots.raster import BACKGROUND_RGB, bev_image

    xyz = np.array([[8.0, 0.0, 0.0], [0.0, 8.0, 1.0]])
    img = bev_image(xyz, xyz[:, 2], 101, 10.0, rings=None)
    lit = np.argwhere(np.any(img != BACKGROUND_RGB, axis=-1) & (img.min(axis=-1) < 200))
    rows, cols = lit[:, 0], lit[:, 1]
    # forward point at row ~ 50 - 40, same column; left point at column ~ 50 - 40
    assert np.any((np.abs(rows - 10) <= 1) & (np.abs(cols - 50) <= 1))
    assert np.any((np.abs(rows - 50) <= 1) & (np.abs(cols - 10) <= 1))


# ---------------------------------------------------------------- overview and preview
def test_overview_with_all_sensors(run_dir: Path, tmp_path: Path) -> None:
    from roslan.plots.overview import write_overview

    out = write_overview(run_dir, tmp_path / "overview.png")
    img = _png(out)
    _assert_figure(img, 1400, 1000)
    assert _near(img, EVENT_POS_RGB, 25) > 20
    assert _near(img, EVENT_NEG_RGB, 25) > 20


def test_overview_warm_up_changes_no_pixel(run_dir: Path, tmp_path: Path) -> None:
    """``roslan simulate`` warms matplotlib up on a thread while it streams: the overview
    drawn after that is the same file as one drawn in a fresh interpreter."""
    import subprocess
    import sys
    import threading

    from roslan.plots.overview import warm_up, write_overview

    fresh = tmp_path / "fresh.png"
    code = (
        "import sys; from pathlib import Path; from roslan.plots.overview import write_overview;"
        " write_overview(Path(sys.argv[1]), Path(sys.argv[2]), title='t')"
    )
    subprocess.run([sys.executable, "-c", code, str(run_dir), str(fresh)], check=True)
    th = threading.Thread(target=warm_up)
    th.start()
    th.join()
    warm = write_overview(run_dir, tmp_path / "warm.png", title="t")
    assert warm.read_bytes() == fresh.read_bytes()


def test_overview_copes_with_missing_sensors(bare_dir: Path) -> None:
    from roslan.plots.overview import write_overview

    out = write_overview(bare_dir)
    assert out == bare_dir / "overview.png"
    img = _png(out)
    _assert_figure(img, 1400, 600)  # one row: the trajectory and its gaps
    # no event pixels without an event camera
    assert _near(img, EVENT_POS_RGB, 10) == 0


def _overview(outdir: Path) -> tuple[list[str], list[str]]:
    """Panel titles of the overview figure and the legend texts of its trajectory panel."""
    from roslan.plots.media import RunMedia
    from roslan.plots.overview import overview_figure
    from roslan.plots.style import style

    media = RunMedia.open(outdir, "test")
    try:
        with style():
            fig = overview_figure(outdir, media, "test")
    finally:
        media.close()
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]  # colorbars have none
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    return titles, legend


def test_overview_draws_only_what_the_run_has(
    run_dir: Path, bare_dir: Path, tmp_path: Path
) -> None:
    import shutil

    # event camera (APS frames at the root), LiDAR, IMU: the media, no IMU panel
    titles, legend = _overview(run_dir)
    assert [t.split(" ")[0] for t in titles] == ["Trajectory", "Event", "Events,", "LiDAR"]
    assert titles[1].startswith("Event camera 'dvs' APS frame, t = ")
    assert any("(frames shown)" in t for t in legend)
    # the same run while roslan simulate draws it: no run.json yet, names from calib/
    d = tmp_path / "nojson"
    shutil.copytree(run_dir, d)
    (d / "run.json").unlink()
    (d / "calib").mkdir(exist_ok=True)
    (d / "calib" / "extrinsics.yaml").write_text("sensors:\n  dvs: {type: event_camera}\n")
    assert _overview(d)[0][1].startswith("Event camera 'dvs' APS frame")
    # IMU only: accelerometer, gyroscope, gaps; no "frames shown" dot
    imu = write_synthetic_outdir(tmp_path / "imu", camera=False, events=None, lidar=False)
    titles, legend = _overview(imu)
    assert [t.split(" ")[0] for t in titles] == ["Trajectory", "IMU", "IMU", "Position"]
    assert not any("shown" in t for t in legend)
    # nothing but the trajectory: two panels, no placeholder
    titles, legend = _overview(bare_dir)
    assert [t.split(" ")[0] for t in titles] == ["Trajectory", "Position"]
    assert not any("shown" in t for t in legend)


@pytest.mark.parametrize("speed", [1.0, 2.5])
def test_preview_mp4_frames_and_panels(run_dir: Path, tmp_path: Path, speed: float) -> None:
    from roslan.plots.preview import make_preview

    fps = 10.0
    info = make_preview(run_dir, tmp_path / "p.mp4", fps=fps, speed=speed, panel_width=320)
    duration = _traj().duration
    assert info.frames == math.floor(duration * fps / speed + 1e-9) + 1
    frames = iio.imread(info.path, index=None)
    assert frames.shape == (info.frames, info.size[1], info.size[0], 3)
    assert info.size[0] % 16 == 0
    assert info.size[1] % 16 == 0
    assert not list(tmp_path.glob(".*part*"))
    mid = frames[len(frames) // 2].astype(int)
    assert mid.std() > 25
    # the event panel (top right) shows ON (blue) and OFF (red) events
    h0 = 32
    ev = mid[h0 : h0 + (info.size[1] - h0) // 2, info.size[0] // 2 :]
    assert _near(ev, EVENT_POS_RGB, 60) > 20
    assert _near(ev, EVENT_NEG_RGB, 60) > 20
    # frames change over time (the clock, the dot, the events move)
    assert np.abs(frames[0].astype(int) - frames[-1]).mean() > 1.0


def test_preview_gif_via_cli(run_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "p.mp4"
    assert main(["preview", str(run_dir), "-o", str(out), "--gif", "--fps", "5", "-q"]) == 0
    gif = out.with_suffix(".gif")
    frames = iio.imread(gif, index=None)
    assert frames.shape[0] == math.floor(_traj().duration * 5 + 1e-9) + 1
    assert frames.shape[2] == 480
    assert frames[len(frames) // 2].std() > 20


def test_preview_progress_without_a_terminal_is_one_line_a_count(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without a TTY (capsys, a log, a pipe), ``roslan preview`` prints each frame count
    on its own line: no carriage returns running the counts together."""
    out = tmp_path / "p.mp4"
    assert main(["preview", str(run_dir), "-o", str(out), "--fps", "40"]) == 0
    err = capsys.readouterr().err
    n = math.floor(_traj().duration * 40 + 1e-9) + 1
    counts = [ln for ln in err.splitlines() if ln.startswith("frame ")]
    expected = [f"frame {k + 1}/{n}" for k in range(n) if k % 30 == 0 or k == n - 1]
    assert counts == expected
    assert len(expected) > 1
    assert "\r" not in err


def test_preview_without_sensors_shows_placeholders(bare_dir: Path, tmp_path: Path) -> None:
    from roslan.plots.preview import make_preview

    info = make_preview(bare_dir, tmp_path / "bare.mp4", fps=4, panel_width=160)
    frames = iio.imread(info.path, index=None)
    assert frames.shape[0] == info.frames > 1
    assert frames[-1].std() > 10  # the trajectory inset and the labels


# ---------------------------------------------------------------- CLI and missing inputs
@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["plot", "lidar"], "has no LiDAR scans.*add a sensor of type lidar"),
        (["plot", "imu"], "has no IMU samples.*add a sensor of type imu"),
    ],
)
def test_missing_inputs_name_the_sensor(
    bare_dir: Path, argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    import re

    assert main([*argv, str(bare_dir)]) == 2
    err = capsys.readouterr().err
    assert re.search(f"roslan {argv[0]} {argv[1]}: .*{needle}", err), err


def test_missing_trajectory_and_events_errors(tmp_path: Path) -> None:
    from roslan.plots.trajectory import plot_trajectory

    with pytest.raises(PlotError, match=r"no trajectory\.csv"):
        plot_trajectory(tmp_path)
    with pytest.raises(PlotError, match="add a sensor of type event_camera"):
        open_events(tmp_path, "roslan plot events")
    with pytest.raises(PlotError, match="is not a directory"):
        plot_trajectory(tmp_path / "nope")
    assert main(["preview", str(tmp_path)]) == 2


def test_cli_plot_commands_write_pngs(run_dir: Path, tmp_path: Path) -> None:
    for fig in ("trajectory", "lidar", "imu", "overview"):
        out = tmp_path / f"{fig}.png"
        assert main(["plot", fig, str(run_dir), "-o", str(out)]) == 0
        assert out.stat().st_size > 20_000


def test_bad_trajectory_csv_is_a_clear_error(tmp_path: Path) -> None:
    from roslan.plots.trajectory import plot_trajectory

    (tmp_path / "trajectory.csv").write_text("t,x\n0.0,1.0\n")
    with pytest.raises(PlotError, match=r"trajectory.csv: 2 columns"):
        plot_trajectory(tmp_path)


def test_plot_shutter_window_and_events(tmp_path: Path) -> None:
    """A frame camera (rolling shutter, per-frame exposures) beside the run's events: the
    event panel holds exactly the events of the frame's shutter window, computed here from
    events.txt, and the window is centred on the stamp."""
    import cv2

    from roslan.plots.shutter import plot_shutter, shutter_panels

    out = write_synthetic_outdir(tmp_path / "run", events="txt")
    (out / "cam" / "images").mkdir(parents=True)
    stamps = np.arange(0.1, 1.0, 0.1)
    exposures = 0.002 + 0.001 * np.arange(stamps.size)
    lines = []
    for i, t in enumerate(stamps):
        cv2.imwrite(str(out / "cam" / "images" / f"{i:08d}.png"), np.full((24, 32), 90, np.uint8))
        lines.append(f"{t:.9f} images/{i:08d}.png")
    (out / "cam" / "images.txt").write_text("\n".join(lines) + "\n")
    np.savetxt(out / "cam" / "exposures.txt", np.column_stack([stamps, exposures]), fmt="%.9f")
    run = json.loads((out / "run.json").read_text())
    run["config"]["sensors"].append(
        {"type": "camera", "name": "cam", "rate": 10.0, "topic": "/cam", "readout_time": 0.03}
    )
    (out / "run.json").write_text(json.dumps(run))
    p = shutter_panels(out, time=0.52)
    assert p.stamp_ns == 500_000_000
    assert p.exposure == pytest.approx(exposures[4])
    span = 0.03 * 23 / 24 + exposures[4]
    assert p.window[0] == pytest.approx(0.5e9 - span * 5e8, abs=1)
    assert p.window[1] == pytest.approx(0.5e9 + span * 5e8, abs=1)
    t = np.loadtxt(out / "events.txt", usecols=0)
    t_ns = np.rint(t * 1e9)
    expected = int(((t_ns >= p.window[0]) & (t_ns < p.window[1])).sum())
    assert expected > 0
    assert p.count == expected
    assert p.image.shape[:2] == (24, 32)
    png = plot_shutter(out)  # default frame: the largest pitch rate
    _assert_figure(_png(png), 600, 200)
    assert main(["plot", "shutter", str(out), "-o", str(tmp_path / "s.png")]) == 0
    with pytest.raises(PlotError, match="no frame-camera images"):
        shutter_panels(write_synthetic_outdir(tmp_path / "nocam", events="txt"))
    # a frame camera without an event camera: the events are what is missing
    with pytest.raises(PlotError, match=r"no events \(add a `type: event_camera` sensor\)"):
        shutter_panels(write_synthetic_outdir(tmp_path / "noevents", events=None))
