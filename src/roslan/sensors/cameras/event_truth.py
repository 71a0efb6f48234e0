"""An event camera's ground truth as dataset files, beside its bag topics.

``optic_flow: true`` -> DSEC's optical-flow layout (Gehrig et al., "DSEC: A Stereo Event
Camera Dataset for Driving Scenarios", RA-L 2021; dsec.ifi.uzh.ch, "Optical Flow"):

* ``flow/forward/NNNNNN.png``: one 16-bit, 3-channel PNG per flow map (index ``NNNNNN``
  from 0), channels in RGB order: ``R = flow_x * 128 + 2**15``,
  ``G = flow_y * 128 + 2**15``, ``B = valid`` (1 or 0). Decode as DSEC's loaders do:
  ``flow = (png[..., :2] - 2**15) / 128``, ``valid = png[..., 2] == 1``. ``flow`` is the
  true displacement of each pixel's scene point from ``from_timestamp_us`` to
  ``to_timestamp_us`` (``flow_interval`` later), in the distorted pixel coordinates of
  ``events.h5``; occluded, leaving, out-of-range and (by default) sky pixels invalid
  (:mod:`roslan.sensors.cameras.flow_truth`). The bag's ``<topic>/optic_flow`` is
  something else: the instantaneous motion field at its stamp, px/s.
* ``flow/forward_timestamps.txt``: DSEC's comma-separated listing, a header line
  ``# from_timestamp_us, to_timestamp_us`` then one line per PNG, absolute microseconds
  (the clock of ``events.h5``'s ``events/t + t_offset`` and of the bag stamps). Maps
  start at the ground-truth instants after the first event whose interval ends by the
  end of the run (the last ground-truth sample).

``depthmap: true`` -> ``depth.h5`` in MVSEC's layout (Zhu et al., "The Multivehicle Stereo
Event Camera Dataset", RA-L 2018; its ``*_data.hdf5`` files):

* ``davis/left/depth_image_raw`` (N, H, W) float32 metres along the optical axis (z), NaN
  where nothing is hit, exactly the bag's ``<topic>/depthmap`` images;
* ``davis/left/depth_image_raw_ts`` (N,) float64 absolute seconds (bag stamps);
* ``davis/left/depth_image_raw_t_ns`` (N,) int64 exact nanoseconds since the trajectory
  start (roslan's addition; MVSEC readers ignore it).

Both are written by the camera's background writer thread, in order, one sample at a time
(memory bounded by one image; the flow maps' open intervals:
:class:`~roslan.sensors.cameras.flow_truth.FlowTruth`).
"""

from __future__ import annotations

from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from roslan.io.images import write_png

__all__ = ["DepthH5Writer", "FlowPngWriter", "decode_dsec_flow", "encode_dsec_flow"]

DSEC_FLOW_SCALE = 128.0
DSEC_FLOW_OFFSET = 2**15
DSEC_TIMESTAMPS_HEADER = "# from_timestamp_us, to_timestamp_us"


def encode_dsec_flow(disp: NDArray[np.floating]) -> NDArray[np.uint16]:
    """(H, W, 2) displacement, px (NaN/inf invalid) -> (H, W, 3) uint16 DSEC PNG pixels."""
    d = np.asarray(disp, dtype=np.float64)
    code = np.rint(d * DSEC_FLOW_SCALE) + DSEC_FLOW_OFFSET
    valid = np.all(np.isfinite(code) & (code >= 0) & (code <= 65535), axis=-1)
    out = np.zeros((*d.shape[:2], 3), dtype=np.uint16)
    out[..., :2] = np.where(valid[..., None], code, DSEC_FLOW_OFFSET).astype(np.uint16)
    out[..., 2] = valid
    return out


def decode_dsec_flow(png: NDArray[np.uint16]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """DSEC's decoding of (H, W, 3) RGB uint16 pixels: displacement (H, W, 2) px, valid."""
    raw = np.asarray(png).astype(np.float64)
    return (raw[..., :2] - DSEC_FLOW_OFFSET) / DSEC_FLOW_SCALE, png[..., 2] == 1


class FlowPngWriter:
    """``<folder>flow/forward/NNNNNN.png`` and ``forward_timestamps.txt`` (module docstring).

    Args:
        flow_dir: the camera's ``flow`` folder inside OUTDIR.
        start_time_ns: absolute stamp of trajectory time 0.
    """

    def __init__(self, flow_dir: Path, start_time_ns: int) -> None:
        self.dir = flow_dir / "forward"
        self.dir.mkdir(parents=True, exist_ok=True)
        self._fh: IO[str] = (flow_dir / "forward_timestamps.txt").open(
            "w", encoding="utf-8", newline="\n"
        )
        self._fh.write(DSEC_TIMESTAMPS_HEADER + "\n")
        self.start_time_ns = int(start_time_ns)
        self.count = 0

    def write(self, t0_ns: int, t1_ns: int, disp: NDArray[np.floating]) -> None:
        """The map from trajectory time ``t0_ns`` to ``t1_ns``: displacement ``disp``
        (H, W, 2) px, NaN where invalid."""
        write_png(self.dir / f"{self.count:06d}.png", encode_dsec_flow(disp))
        a = (self.start_time_ns + int(t0_ns)) // 1000
        b = (self.start_time_ns + int(t1_ns)) // 1000
        self._fh.write(f"{a}, {b}\n")
        self.count += 1

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()


class DepthH5Writer:
    """``<folder>depth.h5`` in MVSEC's layout (module docstring), appended per sample.

    Args:
        path: the file to create.
        width, height: image size.
        start_time_ns: absolute stamp of trajectory time 0.
    """

    GROUP = "davis/left"

    def __init__(self, path: Path, width: int, height: int, start_time_ns: int) -> None:
        import h5py

        self.path = path
        self.start_time_ns = int(start_time_ns)
        self._f = h5py.File(path, "w", libver="earliest", track_order=False)
        g = self._f.create_group(self.GROUP)
        opts: dict[str, Any] = {"track_times": False}
        self._img = g.create_dataset(
            "depth_image_raw",
            shape=(0, height, width),
            maxshape=(None, height, width),
            dtype=np.float32,
            chunks=(1, height, width),
            compression="gzip",
            compression_opts=1,
            shuffle=True,
            **opts,
        )
        self._ts = g.create_dataset(
            "depth_image_raw_ts",
            shape=(0,),
            maxshape=(None,),
            dtype=np.float64,
            chunks=(1024,),
            **opts,
        )
        self._tns = g.create_dataset(
            "depth_image_raw_t_ns",
            shape=(0,),
            maxshape=(None,),
            dtype=np.int64,
            chunks=(1024,),
            **opts,
        )
        self._img.attrs["unit"] = "m along the optical axis; NaN: no surface"
        self._ts.attrs["unit"] = "s, absolute (bag stamps)"
        self._tns.attrs["unit"] = "ns since the trajectory start (exact)"
        self.count = 0

    def write(self, t_ns: int, depth: NDArray[np.float32]) -> None:
        n = self.count
        for ds in (self._img, self._ts, self._tns):
            ds.resize(n + 1, axis=0)
        self._img[n] = depth
        self._ts[n] = (self.start_time_ns + int(t_ns)) * 1e-9
        self._tns[n] = int(t_ns)
        self.count += 1

    def close(self) -> None:
        if self._f.id.valid:
            self._f.attrs["count"] = self.count
            self._f.close()
