"""Event Camera Dataset layout of a run, read by third-party readers (pandas, OpenCV, h5py)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from pipeline_helpers import SHORT_TRAJECTORY
from roslan.config.sim import SimConfig
from roslan.pipeline import run_simulation

pd = pytest.importorskip("pandas")
cv2 = pytest.importorskip("cv2")


def _config(event_camera: bool) -> SimConfig:
    sensors: list[dict[str, object]] = [
        {"type": "camera", "name": "front", "rate": 10, "topic": "/front",
         "resolution": [64, 48], "fx": 40.0, "pose": {"rpy": [0.0, 0.6, 0.0]}},
        {"type": "stereo_camera", "name": "pair", "rate": 5, "topic": "/pair",
         "resolution": [40, 30], "fx": 25.0, "baseline": 0.1, "pose": {"rpy": [0.0, 0.6, 0.0]}},
        {"type": "imu", "name": "imu", "rate": 200, "topic": "/imu"},
        {"type": "sonar", "name": "sonar", "rate": 20, "topic": "/sonar"},
    ]  # fmt: skip
    if event_camera:
        sensors.insert(
            1,
            {"type": "event_camera", "name": "dvs", "rate": 10, "topic": "/dvs",
             "resolution": [48, 36], "pose": {"rpy": [0.0, 0.6, 0.0]}},
        )  # fmt: skip
    return SimConfig.model_validate(
        {"trajectory": {**SHORT_TRAJECTORY, "hold": 0.0}, "scene": "empty", "sensors": sensors,
         "output": {"ground_truth_rate": 50.0, "formats": ["ros1"]}, "seed": 1}
    )  # fmt: skip


@pytest.fixture(scope="module", params=[True, False], ids=["event_camera", "cameras_only"])
def run(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("roslan.render.gl")
    out = tmp_path_factory.mktemp("ecd") / "out"
    run_simulation(_config(request.param), out, quiet=True, overview=False)
    return out


def _size(path: Path) -> tuple[int, int]:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None, path
    return int(img.shape[1]), int(img.shape[0])


def _check_camera_folder(folder: Path, size: tuple[int, int]) -> None:
    """images.txt (time + path) lists frames of the size calib.txt describes."""
    calib = pd.read_csv(folder / "calib.txt", sep=" ", header=None)
    assert calib.shape == (1, 9)
    assert all(dt.kind == "f" for dt in calib.dtypes)
    fx, fy, cx, cy = calib.iloc[0, :4]
    listing = pd.read_csv(folder / "images.txt", sep=" ", header=None)
    assert listing.shape[1] == 2
    assert listing[0].dtype.kind == "f"
    assert np.all(np.diff(listing[0].to_numpy()) > 0)
    for rel in listing[1]:
        assert rel.startswith("images/")
        assert _size(folder / rel) == size
    # the principal point of a centred lens is the image centre: calib.txt describes them
    assert (cx, cy) == ((size[0] - 1) / 2, (size[1] - 1) / 2)
    assert fx > 0
    assert fy > 0


def test_every_root_text_file_loads_numeric_with_pandas(run: Path) -> None:
    texts = sorted(run.glob("*.txt"))
    names = {p.name for p in texts}
    assert {"imu.txt", "groundtruth.txt", "calib.txt", "images.txt"} <= names
    for path in texts:
        first = path.read_text().splitlines()[0]
        assert not first.startswith("#"), path
        table = pd.read_csv(path, sep=" ", header=None)
        assert len(table) > 0, path
        kinds = [dt.kind for dt in table.dtypes]
        if path.name == "images.txt":
            assert len(kinds) == 2, path  # time + path
            assert kinds[0] == "f", (path, kinds)
        else:
            assert all(k in "fi" for k in kinds), (path, kinds)
    gt = pd.read_csv(run / "groundtruth.txt", sep=" ", header=None).to_numpy()
    assert gt.shape[1] == 8
    np.testing.assert_allclose(np.linalg.norm(gt[:, 4:], axis=1), 1.0, atol=1e-8)
    assert pd.read_csv(run / "imu.txt", sep=" ", header=None).shape[1] == 7
    readme = (run / "README.md").read_text()
    for name in names:
        assert f"`{name}`" in readme, name


def test_root_holds_one_sensor_and_every_other_camera_its_own_folder(run: Path) -> None:
    has_dvs = (run / "events.txt").is_file()
    if has_dvs:
        _check_camera_folder(run, (48, 36))  # root = the event camera (APS frames)
        ev = pd.read_csv(run / "events.txt", sep=" ", header=None, nrows=200_000)
        assert [dt.kind for dt in ev.dtypes] == ["f", "i", "i", "i"]
        assert ev[1].max() < 48
        assert ev[2].max() < 36
        _check_camera_folder(run / "front", (64, 48))
        assert not (run / "dvs").exists()
    else:
        _check_camera_folder(run, (64, 48))  # root = the first camera
        assert not (run / "front").exists()
    _check_camera_folder(run / "pair_left", (40, 30))
    _check_camera_folder(run / "pair_right", (40, 30))
    assert not list(run.glob("images_*.txt"))


@pytest.mark.parametrize("with_run_json", [True, False])
def test_overview_inputs_follow_the_root_sensor(
    run: Path, tmp_path: Path, with_run_json: bool
) -> None:
    """The overview and preview show the frame camera in the camera panel and the event
    camera's APS frames under the events, with run.json and without it (the overview is
    drawn before run.json is written)."""
    from roslan.plots.media import RunMedia

    folder = tmp_path / "copy"
    shutil.copytree(run, folder, ignore=shutil.ignore_patterns("landing*"))
    if not with_run_json:
        (folder / "run.json").unlink()
    media = RunMedia.open(folder, "test")
    try:
        assert media.camera is not None
        assert media.aps is not None
        has_dvs = (run / "events.txt").is_file()
        cam_size = _size(media.camera.paths[0])
        aps_size = _size(media.aps.paths[0])
        assert cam_size == (64, 48)
        assert aps_size == ((48, 36) if has_dvs else (64, 48))
    finally:
        media.close()
