"""Colour constants shared by the renderer and the camera sensors."""

from __future__ import annotations

__all__ = ["REC709_LUMA"]

REC709_LUMA = (0.2126, 0.7152, 0.0722)
"""Rec. 709 luminance weights of linear RGB: ``Y = 0.2126 R + 0.7152 G + 0.0722 B``."""
