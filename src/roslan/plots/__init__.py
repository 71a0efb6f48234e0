"""Figures of a run (``roslan plot ...``, ``roslan preview``, the overview); the command
line lives in :mod:`roslan.cli.plot`.

Names are imported on first use (PEP 562), so importing one light module of the
package does not load the heavy ones.
"""

from __future__ import annotations

from roslan.lazy import lazy_getattr

_WHERE = {
    "AXIS_COLORS": "style",
    "BACKGROUND_RGB": "raster",
    "COLOR_BY": "lidar",
    "DEFAULT_KS": "tau_family",
    "DPI": "style",
    "EVENT_NEG_RGB": "style",
    "EVENT_POS_RGB": "style",
    "EVENT_WINDOW_NS": "overview",
    "GAP_COLORS": "style",
    "ImuTruth": "imu",
    "MEASURED_ALPHA": "style",
    "PreviewInfo": "preview",
    "RunMedia": "media",
    "TrajectorySamples": "trajectory",
    "bev_image": "raster",
    "choose_scan": "lidar",
    "colormap_lut": "style",
    "event_frame": "raster",
    "event_rate": "events",
    "figure": "style",
    "fit_into": "raster",
    "imu_truth": "imu",
    "label": "raster",
    "load_samples": "trajectory",
    "make_preview": "preview",
    "placeholder": "raster",
    "plot_events": "events",
    "plot_imu": "imu",
    "plot_lidar": "lidar",
    "plot_tau_family": "tau_family",
    "plot_trajectory": "trajectory",
    "render_events": "media",
    "save_figure": "style",
    "scan_values": "lidar",
    "style": "style",
    "write_overview": "overview",
}

__all__ = sorted(_WHERE)

__getattr__ = lazy_getattr(__name__, _WHERE)
