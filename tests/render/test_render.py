"""Renderer geometry: projection with distortion (checkerboard corners vs OpenCV), metric
depth, shading and the errors it raises."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import roslan.render.gl as gl
import roslan.render.gl.context as gl_context
from camera_helpers import (
    BOARD_FILE_Z,
    board_corners,
    board_on_empty,
    board_scene,
    detect_corners,
    look_down,
    match_error,
)
from roslan.errors import RenderError
from roslan.render import REC709_LUMA
from roslan.scene.model import Lights, Material, Scene, SceneObject
from roslan.sensors.cameras import CameraModel


@pytest.fixture(scope="module")
def board() -> Scene:
    return board_scene()


@pytest.fixture(scope="module")
def board_file_scene(tmp_path_factory: pytest.TempPathFactory) -> Scene:
    return board_on_empty(tmp_path_factory.mktemp("board"))


def _render_model(
    scene: Scene, model: CameraModel, T: np.ndarray, scale: float | None = None
) -> np.ndarray:
    r = gl.get_renderer(scene)
    plan = model.render_plan(r.max_size, scale=scale)
    if not plan.identity:
        assert (plan.K[0, 0] < model.fx) == (scale is None)  # the default reduces density
    col = r.render(T, plan.K, plan.width, plan.height, depth=False).color
    assert col is not None
    if not plan.identity:
        col = cv2.remap(col, plan.map1, plan.map2, cv2.INTER_LINEAR)
    return (np.clip(col.mean(axis=2), 0, 1) ** (1 / 2.2) * 255).round().astype(np.uint8)


@pytest.mark.parametrize(
    ("model_name", "coeffs", "scale"),
    [
        ("none", (), None),
        ("plumb_bob", (-0.25, 0.08, 0.002, -0.001, -0.01), None),
        ("plumb_bob", (-0.25, 0.08, 0.002, -0.001, -0.01), 1.0),
        ("equidistant", (0.05, -0.02, 0.01, -0.003), None),
        ("equidistant", (0.05, -0.02, 0.01, -0.003), 1.0),
    ],
)
def test_projection_matches_opencv(
    board_file_scene: Scene, model_name: str, coeffs: tuple[float, ...], scale: float | None
) -> None:
    """Corners of a checkerboard-textured plane (the ``empty`` scene plus a scene-file
    board object) within 0.5 px of OpenCV's projection, at the default (reduced) render
    density of distorted lenses and at the centre's density everywhere (scale 1)."""
    model = CameraModel.create(320, 240, 210.0, 215.0, 161.3, 118.7, model_name, coeffs)
    T = look_down(0.13, -0.07, 5.0 + BOARD_FILE_Z, tilt=0.2)
    img = _render_model(board_file_scene, model, T, scale)
    found = detect_corners(img)
    assert found is not None, "checkerboard not detected"
    T_cw = np.linalg.inv(T)
    P = board_corners(BOARD_FILE_Z)
    rvec, _ = cv2.Rodrigues(T_cw[:3, :3])
    tvec = T_cw[:3, 3]
    if model_name == "equidistant":
        exp = cv2.fisheye.projectPoints(P[:, None, :], rvec, tvec, model.K, model.D)[0]
    else:
        D = model.D if model.D.size else np.zeros(5)
        exp = cv2.projectPoints(P, rvec, tvec, model.K, D)[0]
    exp = exp.reshape(-1, 2)
    assert match_error(found, exp) < 0.5
    # the lens really moved the corners (the test would catch a missing remap)
    if model_name != "none":
        pin = cv2.projectPoints(P, rvec, tvec, model.K, np.zeros(5))[0].reshape(-1, 2)
        assert np.abs(pin - exp).max() > 2.0


def test_depth_of_tilted_plane_is_analytic(board: Scene) -> None:
    r = gl.get_renderer(board)
    K = np.array([[90.0, 0, 40.2], [0, 92.0, 29.7], [0, 0, 1]])
    T = look_down(0.1, 0.2, 2.5, tilt=0.3)
    res = r.render(T, K, 80, 60, color=True, depth=True)
    res_d = r.render(T, K, 80, 60, color=False, depth=True)
    # analytic: ray through pixel (u, v) in the optical frame, hit plane z = 0 in the world
    u, v = np.meshgrid(np.arange(80.0), np.arange(60.0))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    d_world = rays @ T[:3, :3].T
    s = -T[2, 3] / d_world[..., 2]  # z-depth = s since the ray's optical z is 1
    hit = T[:3, 3] + s[..., None] * d_world
    half = np.array([(7 + 3) * 0.25, (5 + 3) * 0.25])
    inside = (np.abs(hit[..., 0]) < half[0] - 0.05) & (np.abs(hit[..., 1]) < half[1] - 0.05)
    outside = (np.abs(hit[..., 0]) > half[0] + 0.05) | (np.abs(hit[..., 1]) > half[1] + 0.05)
    assert inside.sum() > 1000
    for depth in (res.depth, res_d.depth):
        assert depth is not None
        assert depth.dtype == np.float32
        np.testing.assert_allclose(depth[inside], s[inside], rtol=1e-4)
        assert np.all(np.isinf(depth[outside]))


def test_lambert_shading_is_linear() -> None:
    v = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], np.float32)
    obj = SceneObject(
        "p",
        v,
        np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
        np.zeros((4, 2), np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.int32),
        Material(color=(0.5, 0.25, 1.0)),
    )
    angle = 0.6
    sun = (np.sin(angle), 0.0, -np.cos(angle))
    scene = Scene("shade", (obj,), Lights(sun_direction=sun, sun_intensity=0.5, ambient=0.2))
    res = gl.get_renderer(scene).render(
        look_down(0, 0, 2.0),
        np.array([[40.0, 0, 15.5], [0, 40.0, 11.5], [0, 0, 1]]),
        32,
        24,
    )
    assert res.color is not None
    expected = np.array([0.5, 0.25, 1.0]) * (0.2 + 0.5 * np.cos(angle))
    np.testing.assert_allclose(res.color[12, 16], expected, atol=2e-3)


def test_too_large_resolution(board: Scene) -> None:
    r = gl.get_renderer(board)
    with pytest.raises(RenderError, match=str(r.max_size)):
        r.render(np.eye(4), np.eye(3), r.max_size + 1, 10)


def test_missing_egl_names_debian_packages(monkeypatch: pytest.MonkeyPatch) -> None:
    import moderngl

    def fail(**_: object) -> None:
        raise Exception("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(gl_context, "_context", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(RenderError) as err:
        gl.create_context()
    for pkg in ("libegl1", "libegl-mesa0", "libgl1-mesa-dri", "libEGL.so.1"):
        assert pkg in str(err.value)


def _square_scene() -> Scene:
    """A white unlit square (radiance exactly 1) rotated 20 deg on black background."""
    a = np.deg2rad(20.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    xy = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], np.float64) @ R.T
    v = np.c_[xy, np.zeros(4)].astype(np.float32)
    obj = SceneObject(
        "sq",
        v,
        np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
        np.zeros((4, 2), np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.int32),
        Material(color=(1.0, 1.0, 1.0)),
    )
    return Scene("sq", (obj,), Lights(sun_direction=(0, 0, -1), sun_intensity=0.0, ambient=1.0))


@pytest.mark.parametrize("samples", [1, 4])
def test_edges_are_antialiased_and_luminance_matches(samples: int) -> None:
    r = gl.get_renderer(_square_scene())
    K = np.array([[30.0, 0, 31.5], [0, 30.0, 23.5], [0, 0, 1]])
    T = look_down(0.0, 0.0, 4.0)
    res = r.render(T, K, 64, 48, depth=False, samples=samples)
    lum = r.render(T, K, 64, 48, color=False, depth=False, luminance=True, samples=samples)
    assert res.depth is None
    assert lum.color is None
    assert lum.depth is None
    assert res.color is not None
    assert lum.luminance is not None
    c = res.color
    np.testing.assert_allclose(lum.luminance, c @ np.array(REC709_LUMA, np.float32), atol=1e-3)
    g = c.mean(axis=2)
    # ~ perimeter 8 m * 30 px/4 m = 60 px of edge: most edge pixels are blended
    partial = int(((g > 0.05) & (g < 0.95)).sum())
    assert partial > 40, partial
    assert np.all(g[20:28, 28:36] > 0.999)  # interior untouched
    assert np.all(g[:3, :] < 1e-3)
    assert np.all(g[-3:, :] < 1e-3)


def test_culling_keeps_every_visible_triangle() -> None:
    # 400 small quads over 60 m x 60 m: many culling clusters
    rng = np.random.default_rng(3)
    objs = []
    for i, (x, y) in enumerate(rng.uniform(-30, 30, size=(400, 2))):
        v = np.array([[x, y, 0], [x + 0.3, y, 0], [x + 0.3, y + 0.3, 0.2], [x, y + 0.3, 0.2]])
        objs.append(
            SceneObject(
                f"q{i}",
                v.astype(np.float32),
                np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
                np.zeros((4, 2), np.float32),
                np.array([[0, 1, 2], [0, 2, 3]], np.int32),
            )
        )
    scene = Scene("quads", tuple(objs), Lights())
    r = gl.get_renderer(scene)
    assert r.n_clusters > 50
    K = np.array([[50.0, 0, 40.0], [0, 50.0, 30.0], [0, 0, 1]])
    tri = np.stack([o.vertices[o.faces] for o in objs]).reshape(-1, 3, 3).astype(np.float64)
    centres = np.stack([o.vertices.mean(axis=0) for o in objs]).astype(np.float64)
    for k in range(5):
        T = look_down(*rng.uniform(-20, 20, size=2), 6.0 + 4 * k, tilt=0.3 * k)
        P = gl.projection_from_K(K, 80, 60, r.near, 200.0) @ np.linalg.inv(T)
        clip = np.c_[tri.reshape(-1, 3), np.ones(tri.shape[0] * 3)] @ P.T
        w = clip[:, 3:4]
        inside = np.all((np.abs(clip[:, :3]) < w) & (w > 0), axis=1).reshape(-1, 3).any(axis=1)
        seen = inside.reshape(len(objs), 2).any(axis=1)  # per quad
        # index position -> quad: the renderer reorders faces; read its index buffer
        idx = np.frombuffer(r.buffers.ibo.read(), np.uint32)
        eye = T[:3, 3]
        drawn_by: list[np.ndarray] = []
        # (front to back whether back-face culling is on or off)
        for order_eye, bfc in ((None, True), (eye, True), (eye, False)):
            r.cull_back_faces = bfc
            first, count, _, _ = r.visible_ranges(P, order_eye)
            r.cull_back_faces = True
            drawn = np.zeros(len(objs), bool)
            nearest = []  # per run: distance of its nearest quad centre
            for f, n in zip(first.tolist(), count.tolist(), strict=True):
                q = idx[f : f + n] // 4  # 4 vertices per quad, uploaded in order
                drawn[q] = True
                nearest.append(np.linalg.norm(centres[q] - eye, axis=1).min())
            assert seen.sum() > 0
            assert np.all(drawn[seen]), "a visible triangle was culled"
            assert drawn.sum() < drawn.size  # and culling did cull
            drawn_by.append(drawn)
            if order_eye is not None:  # front to back: runs by nearest distance (the
                # renderer sorts by box distance: a quad's centre is <= 0.25 m further)
                near = np.asarray(nearest)
                assert np.all(np.diff(near) > -0.3)
                assert near[0] <= near.min() + 0.3
        assert np.array_equal(drawn_by[0], drawn_by[1])  # same set, other order
        assert np.array_equal(drawn_by[1], drawn_by[2])


def test_bad_msaa_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROSLAN_MSAA_SAMPLES", "many")
    with pytest.raises(RenderError, match="ROSLAN_MSAA_SAMPLES"):
        gl.default_samples()
    monkeypatch.setenv("ROSLAN_MSAA_SAMPLES", "4")
    assert gl.default_samples() == 4
    assert gl.default_samples(2) == 2
    monkeypatch.delenv("ROSLAN_MSAA_SAMPLES")
    assert gl.default_samples() == gl.DEFAULT_SAMPLES == 1  # on every GL implementation


def test_edge_filter_leaves_textures_on_planes_alone(board: Scene) -> None:
    # Inside the board (one plane) 1-sample + edge filter must equal 4x MSAA: the filter
    # acts on silhouettes and creases only, never on the (high-contrast) texture.
    r = gl.get_renderer(board)
    K = np.array([[60.0, 0, 39.5], [0, 60.0, 29.5], [0, 0, 1]])
    T = look_down(0.1, 0.05, 2.0, tilt=0.15)
    one = r.render(T, K, 80, 60, depth=False, samples=1).color
    four = r.render(T, K, 80, 60, depth=False, samples=4).color
    assert one is not None
    assert four is not None
    g = four.mean(axis=2)
    assert g.max() - g.min() > 0.3  # the checkerboard is in view
    np.testing.assert_allclose(one, four, atol=2e-3)


@pytest.mark.parametrize("samples", [1, 4])
def test_interleaved_resolutions_do_not_leak_between_frames(board: Scene, samples: int) -> None:
    """A camera frame rendered after another resolution (e.g. the event camera's) equals the
    same frame rendered on a fresh sequence: no state of one target leaks into another."""
    r = gl.get_renderer(board)
    K = np.array([[90.0, 0, 40.0], [0, 90.0, 30.0], [0, 0, 1]])
    K_small = np.array([[40.0, 0, 16.0], [0, 40.0, 12.0], [0, 0, 1]])
    T1 = look_down(0.1, 0.2, 2.5, tilt=0.3)
    T2 = look_down(-0.3, 0.1, 2.0, tilt=0.1)
    ref = r.render(T2, K, 80, 60, samples=samples)
    r.render(T1, K, 80, 60, samples=samples)
    r.render(T1, K_small, 32, 24, color=False, luminance=True, depth=True, samples=samples)
    r.render(T1, K_small, 32, 24, color=False, depth=True)
    again = r.render(T2, K, 80, 60, samples=samples)
    assert ref.color is not None
    assert again.color is not None
    assert ref.depth is not None
    assert again.depth is not None
    np.testing.assert_array_equal(again.color, ref.color)
    np.testing.assert_array_equal(again.depth, ref.depth)


@pytest.mark.parametrize("lum", [False, True])
def test_fast_paths_give_the_same_pixels(board_file_scene: Scene, lum: bool) -> None:
    """imageLoad point loads, the RGB32F filter target and split flushes are speed-ups
    only: the image equals texelFetch + RGBA32F + one flush bit for bit, and the edge
    filter did act on this view (the board's rim and the horizon)."""
    r = gl.get_renderer(board_file_scene)
    K = np.array([[30.0, 0, 39.5], [0, 30.0, 29.5], [0, 0, 1]])
    T = look_down(0.2, 0.1, 1.5, tilt=1.0)
    out = "luminance" if lum else "color"
    flushes = []
    flush = r._flush
    if flush is not None:
        r._flush = lambda: (flushes.append(1), flush())[1]

    def render(image: bool, rgb: bool, chunks: int) -> tuple[np.ndarray, np.ndarray]:
        saved = (r._image, r._rgb_target, r.flush_chunks)
        r._image, r._rgb_target, r.flush_chunks = image, rgb, chunks
        try:
            res = r.render(T, K, 80, 60, color=not lum, luminance=lum, depth=True, samples=1)
            t = r._targets[(80, 60, 1, lum, True, rgb)]
            raw = np.frombuffer(t.out_color.read(), np.float32).reshape(60, 80, -1)[..., 0]
        finally:
            r._image, r._rgb_target, r.flush_chunks = saved
        img = getattr(res, out)
        assert img is not None
        return img, raw

    ref, raw = render(False, False, 1)
    first = ref if lum else ref[..., 0]
    assert np.count_nonzero(first != raw) > 20  # edge pixels were resampled
    assert r._image == (int(r.ctx.version_code) >= 420)
    try:
        for image, rgb, chunks in [
            (True, True, 1),
            (True, True, 4),
            (False, True, 3),
            (True, False, 2),
        ]:
            img, _ = render(image, rgb, chunks)
            np.testing.assert_array_equal(img, ref)
    finally:
        r._flush = flush
    assert flush is None or len(flushes) >= 3  # the split draws were flushed


def test_render_into_a_callers_buffer(board: Scene) -> None:
    r = gl.get_renderer(board)
    K = np.array([[60.0, 0, 39.5], [0, 60.0, 29.5], [0, 0, 1]])
    T = look_down(0.1, 0.05, 2.0, tilt=0.15)
    fresh = r.render(T, K, 80, 60, depth=True)
    buf = np.full((60, 80, 3), np.nan, np.float32)
    res = r.render(T, K, 80, 60, depth=True, out=buf)
    assert res.color is buf
    assert fresh.color is not None
    np.testing.assert_array_equal(buf, fresh.color)
    lum = np.full((60, 80), np.nan, np.float32)
    res = r.render(T, K, 80, 60, color=False, luminance=True, depth=False, out=lum)
    assert res.luminance is lum
    assert np.isfinite(lum).all()
    assert lum.max() > 0.1
    for bad in (np.empty((60, 80), np.float32), np.empty((60, 80, 3)), buf[:, ::-1]):
        with pytest.raises(RenderError, match=r"render\(out=\).*\(60, 80, 3\)"):
            r.render(T, K, 80, 60, depth=False, out=bad)


def _solids_scene() -> Scene:
    """Separate closed solids (no touching faces), a ground slab, an open inside-out box
    and a closed room: a back-face culling test bed."""
    from roslan.scene import mesh as m

    rng = np.random.default_rng(3)
    checker = np.kron((np.indices((8, 8)).sum(axis=0) % 2) * 200 + 30, np.ones((8, 8)))
    tex = np.repeat(checker[..., None], 3, axis=2).astype(np.uint8)
    ground = m.box((80.0, 80.0, 0.2), (0.0, 0.0, -0.1))
    objs = [m.place("ground", ground, Material(texture=tex, texture_scale=0.5))]
    shapes = [
        m.box((1.5, 1.0, 2.0)),
        m.sphere(0.8),
        m.cylinder(0.5, 2.5, 16),
        m.ring(0.4, 1.0, 0.3),
    ]
    for i in range(16):
        pose = m.pose_matrix(
            (*rng.uniform(-25, 25, size=2), rng.uniform(1.5, 6.0)), rng.uniform(-3, 3, size=3)
        )
        mat = Material(color=tuple(rng.uniform(0.2, 1.0, size=3)), texture=tex)
        objs.append(m.place(f"s{i}", shapes[i % 4], mat, pose))
    inv = m.box((2.0, 2.0, 2.0))
    inv = m.LocalMesh(inv.vertices, -inv.normals, inv.uvs, inv.faces[:, ::-1].copy())
    objs.append(
        m.place("inside_out", inv, Material(color=(0.9, 0.2, 0.2)), m.pose_matrix((8, 8, 3)))
    )
    objs.append(
        m.place(
            "room", m.box((4.0, 4.0, 3.0)), Material(texture=tex), m.pose_matrix((-8, -8, 1.52))
        )
    )
    return Scene("solids", tuple(objs), Lights(sun_direction=(0.3, 0.2, -1.0)))


def test_back_face_culling_changes_no_pixel() -> None:
    # Closed solids seen from outside hide their back faces, so culling them must give
    # the same image, luminance and depth, bit for bit; an inside-out object stays
    # two-sided; from inside the room (a closed box), its walls must still show.
    scene = _solids_scene()
    r = gl.Renderer(scene)
    try:
        assert r.closed_solids == {o.name for o in scene.objects} - {"inside_out"}
        rng = np.random.default_rng(7)
        K = np.array([[120.0, 0, 79.5], [0, 110.0, 59.5], [0, 0, 1]])
        poses = [
            look_down(x, y, z, tilt)
            for x, y, z, tilt in rng.uniform([-20, -20, 2, 0.3], [20, 20, 12, 1.2], size=(10, 4))
        ]
        room = look_down(-8.0, -8.0, 1.5, 1.4)  # inside the room, looking at a wall
        # just outside the room, the near plane inside its wall: the cut shows the inside
        near_wall = look_down(-8.0, -10.0 - r.near * 0.5, 1.5, 1.5707963)
        counts = []
        for T in [*poses, room, near_wall]:
            out = {}
            for cull in (True, False):  # (culled first: a stale target would show)
                r.cull_back_faces = cull
                res = r.render(T, K, 160, 120, depth=True, luminance=True)
                lum = r.render(T, K, 160, 120, color=False, depth=False, luminance=True)
                dep = r.render(T, K, 160, 120, color=False, depth=True)
                out[cull] = (res.color, res.depth, lum.luminance, dep.depth)
                clip = gl.projection_from_K(K, 160, 120, r.near, 500.0) @ np.linalg.inv(T)
                counts.append(int(r.visible_ranges(clip, T[:3, 3])[3].sum()))
            for a, b in zip(out[False], out[True], strict=True):
                assert a is not None
                assert b is not None
                np.testing.assert_array_equal(a, b)
        assert np.isfinite(out[True][1]).all()  # the room's walls, not the sky (inf)
        assert max(counts) > 0  # culling was on for some views
    finally:
        r.release()


def test_back_face_culling_on_builtin_scene_only_settles_ties() -> None:
    # The warehouse's parts touch (boxes on shelves, beams on beams): where a back face
    # lies in the plane of another part's front face the depth test used to pick either;
    # and a pixel centre exactly on a silhouette edge (llvmpipe snaps to 1/256 px) may
    # belong to the back face. Only such ties may change: few pixels, nearly all with
    # the depth within a few steps of the 24-bit depth buffer.
    from roslan.scene import load_scene

    scene = load_scene("warehouse")
    r = gl.get_renderer(scene)
    K = np.array([[160.0, 0, 159.5], [0, 160.0, 119.5], [0, 0, 1]])
    goal = np.asarray(scene.goal_position)
    try:
        for dx, dy, z, tilt in ((-6, 1, 3, 0.9), (4, -8, 6, 1.1), (10, 12, 1.5, 1.5)):
            T = look_down(goal[0] + dx, goal[1] + dy, z, tilt)
            r.cull_back_faces = False
            a = r.render(T, K, 320, 240, depth=True)
            r.cull_back_faces = True
            b = r.render(T, K, 320, 240, depth=True)
            assert a.depth is not None
            assert b.depth is not None
            diff = a.depth != b.depth
            assert diff.mean() < 0.005
            if diff.any():
                z0 = a.depth[diff]
                steps = np.abs(b.depth[diff] - z0) / (z0**2 / (r.near * 2**24))
                assert np.mean(steps <= 8) >= 0.95
    finally:
        r.cull_back_faces = True


@pytest.mark.parametrize("samples", [1, 4])
def test_sky_where_nothing_is_hit(samples: int) -> None:
    # The scene's sky radiance fills every pixel without a surface (colour, luminance), the
    # depth there stays inf, and silhouettes blend the square's white with the sky's blue
    # (not with black)
    sq = _square_scene()
    sky = (0.1, 0.3, 0.6)
    scene = Scene("sky", sq.objects, Lights(sun_intensity=0.0, ambient=1.0, sky=sky))
    r = gl.Renderer(scene)
    try:
        K = np.array([[30.0, 0, 31.5], [0, 30.0, 23.5], [0, 0, 1]])
        T = look_down(0.0, 0.0, 4.0)
        res = r.render(T, K, 64, 48, depth=True, luminance=True, samples=samples)
        lum = r.render(T, K, 64, 48, color=False, depth=True, luminance=True, samples=samples)
        assert res.color is not None
        assert res.depth is not None
        assert lum.luminance is not None
        assert lum.depth is not None
        out = np.isinf(res.depth)
        assert out.sum() > 1000
        tol = 1e-6 if samples == 1 else 1e-3  # (MSAA colour targets are half floats)
        np.testing.assert_allclose(res.color[:3, :], np.broadcast_to(sky, (3, 64, 3)), atol=tol)
        np.testing.assert_allclose(lum.luminance[:3, :], float(np.dot(sky, REC709_LUMA)), atol=tol)
        np.testing.assert_array_equal(np.isinf(lum.depth), out)
        assert np.all(res.color[20:28, 28:36] > 0.999)  # the square itself is unchanged
        # edge pixels: between sky and white in every channel
        edge = (res.color[..., 2] > sky[2] + 0.02) & (res.color[..., 2] < 0.98)
        assert edge.sum() > 20
        assert np.all(res.color[edge] >= np.array(sky) - tol)
    finally:
        r.release()


@pytest.mark.parametrize("depth", [False, True])
def test_edge_filter_border_rows_and_colour_only_renders(board: Scene, depth: bool) -> None:
    """The edge filter sees 1/z whether or not depth is read back (colour-only renders of
    RGB cameras included), and the image border of a plane is not mistaken for a crease:
    1 sample + filter equals 4x MSAA on every pixel, borders included."""
    r = gl.get_renderer(board)
    K = np.array([[60.0, 0, 39.5], [0, 60.0, 29.5], [0, 0, 1]])
    T = look_down(0.1, 0.05, 2.0, tilt=0.15)
    one = r.render(T, K, 80, 60, depth=depth, samples=1).color
    four = r.render(T, K, 80, 60, depth=False, samples=4).color
    assert one is not None
    assert four is not None
    np.testing.assert_allclose(one[[0, -1]], four[[0, -1]], atol=2e-3)
    np.testing.assert_allclose(one[:, [0, -1]], four[:, [0, -1]], atol=2e-3)
    # and a crease (the board's edge against the ground) is still filtered in both modes
    T_edge = look_down(0.9, 0.05, 1.5, tilt=0.3)
    a = r.render(T_edge, K, 80, 60, depth=False, samples=1).color
    b = r.render(T_edge, K, 80, 60, depth=True, samples=1).color
    np.testing.assert_array_equal(a, b)
