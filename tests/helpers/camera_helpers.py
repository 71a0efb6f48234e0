"""Shared helpers of the renderer / camera tests: checkerboard scenes (built with numpy, or
the ``empty`` scene plus a board object from a scene file)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from roslan.scene.model import Lights, Material, Scene, SceneObject

SQUARE = 0.5  # m
INNER = (7, 5)  # inner corners (cols, rows)


def board_texture(px: int = 32) -> np.ndarray:
    """(H, W, 3) uint8 board: (INNER+1) squares plus a one-square white border."""
    nx, ny = INNER[0] + 1, INNER[1] + 1
    sq = (np.add.outer(np.arange(ny), np.arange(nx)) % 2 == 0).astype(np.uint8) * 255
    img = np.kron(sq, np.ones((px, px), np.uint8))
    img = np.pad(img, px, constant_values=255)
    return np.repeat(img[..., None], 3, axis=2)


def board_scene(z: float = 0.0) -> Scene:
    """Board in the plane ``z`` (normal +z), centred at the origin; texture v = 0 at y_min."""
    nx, ny = INNER[0] + 3, INNER[1] + 3  # squares incl. border
    w, h = nx * SQUARE, ny * SQUARE
    v = np.array(
        [[-w / 2, -h / 2, z], [w / 2, -h / 2, z], [w / 2, h / 2, z], [-w / 2, h / 2, z]], np.float32
    )
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    n = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mat = Material(color=(1.0, 1.0, 1.0), texture=board_texture())
    obj = SceneObject("board", v, n, uv, f, mat)
    return Scene(
        "board", (obj,), Lights(sun_direction=(0.0, 0.0, -1.0), sun_intensity=0.6, ambient=0.3)
    )


BOARD_FILE_Z = 0.01  # the scene-file board lies 1 cm above the empty scene's ground


def board_on_empty(folder: Path) -> Scene:
    """The built-in ``empty`` scene plus the board as a scene-file object: a textured
    ``plane`` primitive (``board.yaml`` + ``board.png`` written to ``folder``) loaded by
    the scene loader, centred at the origin ``BOARD_FILE_Z`` above the ground."""
    from PIL import Image

    from roslan.scene import load_scene

    nx, ny = INNER[0] + 3, INNER[1] + 3  # squares incl. border
    w, h = nx * SQUARE, ny * SQUARE
    img = board_texture()
    # Primitive UVs are metres from the plane's corner, times one texture_scale (1 / w):
    # v spans [0, h / w]. Pad white rows on top (v = 1 is the image's top row) so that
    # the board fills exactly that part of a square image.
    img = np.pad(img, ((img.shape[1] - img.shape[0], 0), (0, 0), (0, 0)), constant_values=255)
    Image.fromarray(img).save(folder / "board.png")
    (folder / "board.yaml").write_text(
        "name: board\n"
        "objects:\n"
        "  - name: board\n"
        f"    primitive: {{type: plane, size: [{w}, {h}]}}\n"
        f"    pose: {{position: [0.0, 0.0, {BOARD_FILE_Z}], rpy: [0, 0, 0]}}\n"
        f"    material: {{color: [1, 1, 1], texture: board.png, texture_scale: {1.0 / w}}}\n"
    )
    board = load_scene(folder / "board.yaml")
    empty = load_scene("empty")
    return replace(empty, name="empty+board", objects=empty.objects + board.objects)


def board_corners(z: float = 0.0) -> np.ndarray:
    """(N, 3) world positions of the inner corners."""
    xs = (np.arange(INNER[0]) - (INNER[0] - 1) / 2) * SQUARE
    ys = (np.arange(INNER[1]) - (INNER[1] - 1) / 2) * SQUARE
    X, Y = np.meshgrid(xs, ys)
    return np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)


def look_down(x: float, y: float, height: float, tilt: float = 0.0) -> np.ndarray:
    """T_world_optical of a camera at (x, y, height) looking down, tilted about its x axis."""
    c, s = np.cos(tilt), np.sin(tilt)
    R = np.diag([1.0, -1.0, -1.0]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = (x, y, height)
    return T


def detect_corners(gray: np.ndarray) -> np.ndarray | None:
    import cv2

    ok, c = cv2.findChessboardCorners(gray, INNER)
    if not ok:
        return None
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    return cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), crit).reshape(-1, 2)


def match_error(found: np.ndarray, expected: np.ndarray) -> float:
    """Largest distance from each expected point to its nearest detection (px)."""
    d = np.linalg.norm(found[None, :, :] - expected[:, None, :], axis=2)
    return float(d.min(axis=1).max())
