"""Tests of formats/render.py: camera framing, colourings, off-screen images, MP4, contact sheet, comparison."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import InputError
from formats import render as R
from formats.sequence import Sequence
from tests.meshes import icosphere

SMALL = dict(width=160, height=120, labels=False)


def two_spheres(n_frames=3, travel=0.0):
    """A 'garment' sphere (r 0.3) around a 'body' sphere (r 0.25), moving along -Y by `travel` per frame."""
    vb, fb = icosphere(2, radius=0.25)
    vg, fg = icosphere(2, radius=0.3)
    shift = np.array([0.0, -travel, 0.0]) * np.arange(n_frames)[:, None]
    lift = np.array([0.0, 0.0, 0.3])
    g = (vg[None] + lift + shift[:, None]).astype(np.float32)
    b = (vb[None] + lift + shift[:, None]).astype(np.float32)
    return Sequence(points=g, faces=fg, fps=30.0, body_points=b, body_faces=fb, source="spheres")


def project(points, pos, focal, fov_deg, aspect):
    """Naive pinhole projection to normalised image coordinates in [-1, 1] (Z up), per point."""
    fwd = focal - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    out = []
    for p in points:
        d = p - pos
        z = d @ fwd
        t = np.tan(np.radians(fov_deg) / 2)
        out.append(((d @ right) / (z * t * aspect), (d @ up) / (z * t)))
    return np.array(out)


@pytest.mark.parametrize("preset", ["front", "side", "back", "orbit"])
@pytest.mark.parametrize("framing", ["fixed", "follow"])
def test_camera_track_keeps_every_box_corner_inside_the_image(preset, framing):
    rng = np.random.default_rng(0)
    T = 8
    lo = rng.normal(size=(T, 3)) * 0.3 + [0, -0.5, 0] * np.arange(T)[:, None]
    hi = lo + rng.uniform(0.3, 1.8, size=(T, 3))
    opts = R.RenderOptions(width=320, height=180, framing=framing, margin=0.05)
    pos, focal = R.camera_track(lo, hi, preset, opts, fps=30.0)
    assert pos.shape == focal.shape == (T, 3)
    reach = 0.0
    for t in range(T):
        box_lo, box_hi = (lo.min(0), hi.max(0)) if framing == "fixed" else (lo[t], hi[t])
        corners = np.array([[x, y, z] for x in (box_lo[0], box_hi[0]) for y in (box_lo[1], box_hi[1])
                            for z in (box_lo[2], box_hi[2])])
        uv = project(corners, pos[t], focal[t], opts.fov_deg, 320 / 180)
        assert np.abs(uv).max() <= 0.9 + 1e-6  # inside the image, margin kept
        reach = max(reach, np.abs(uv).max())
    assert reach == pytest.approx(0.9, abs=1e-6)  # the tightest frame touches the margin: no wasted space


def test_camera_presets_look_from_the_documented_sides():
    lo, hi = np.zeros((1, 3)), np.ones((1, 3))
    opts = R.RenderOptions(framing="fixed", elevation_deg=0.0)
    front = R.camera_track(lo, hi, "front", opts)[0][0] - 0.5
    side = R.camera_track(lo, hi, "side", opts)[0][0] - 0.5
    back = R.camera_track(lo, hi, "back", opts)[0][0] - 0.5
    assert front[1] < 0 and abs(front[0]) < 1e-9  # front camera on -Y: the body faces -Y
    assert side[0] > 0 and abs(side[1]) < 1e-9
    assert back[1] > 0


def test_auto_framing_follows_a_travelling_scene():
    T = 10
    lo = np.stack([[0.0, -1.0 * t, 0.0] for t in range(T)])
    hi = lo + [0.5, 0.5, 1.7]
    follow = R.camera_track(lo, hi, "front", R.RenderOptions(framing="auto"), fps=3.0)[1]
    assert np.ptp(follow[:, 1]) > 5.0  # focal point moves with the body
    still = R.camera_track(lo[:1].repeat(T, 0), hi[:1].repeat(T, 0), "front", R.RenderOptions(framing="auto"))[1]
    assert np.ptp(still, axis=0).max() < 1e-12


def test_vertex_error_matches_a_loop():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(2, 3, 5, 3))
    ref = [[1000 * np.sqrt(sum((a[t, v, k] - b[t, v, k]) ** 2 for k in range(3))) for v in range(5)] for t in range(3)]
    np.testing.assert_allclose(R.vertex_error_mm(a, b), ref, rtol=1e-5)


def test_scene_colourings_and_their_errors(tmp_path):
    seq = two_spheres()
    gt = Sequence(points=seq.points + np.float32(0.01), faces=seq.faces, fps=30.0, source="gt")
    s = R.scene_from_sequence(seq, color="error", gt=gt)
    np.testing.assert_allclose(s.vertex_values, 10.0 * np.sqrt(3), rtol=1e-4)
    assert s.value_label == "error (mm)"
    pen = R.scene_from_sequence(seq, color="penetration", frames=[0, 2])
    assert pen.inside.shape == (2, seq.points.shape[1]) and not pen.inside.any()  # garment sphere is outside
    centre = seq.body_points.mean(axis=1, keepdims=True)
    shrunk = Sequence(points=(seq.points - centre) * np.float32(0.5) + centre, faces=seq.faces, fps=30.0, body_points=seq.body_points * 1,
                      body_faces=seq.body_faces)
    assert R.scene_from_sequence(shrunk, color="penetration", frames=[0]).inside.all()
    with pytest.raises(InputError, match="--gt"):
        R.scene_from_sequence(seq, color="error")
    bare = Sequence(points=seq.points, faces=seq.faces, fps=30.0, source="bare.npz")
    with pytest.raises(InputError, match="'bare.npz' carries no body"):
        R.scene_from_sequence(bare, color="penetration")
    wrong = Sequence(points=seq.points[:, :10], faces=seq.faces[:2], fps=30.0, source="gt")
    with pytest.raises(InputError, match="vertices"):
        R.scene_from_sequence(seq, color="error", gt=wrong)


def test_load_vertex_scalars_shapes_and_errors(tmp_path):
    p = tmp_path / "s.npz"
    np.savez(p, curvature=np.arange(4.0))
    out = R.load_vertex_scalars(p, None, 3, 4)
    assert out.shape == (3, 4) and out.dtype == np.float32 and (out[2] == np.arange(4)).all()
    np.savez(p, a=np.zeros((3, 4)), b=np.zeros(4))
    assert R.load_vertex_scalars(p, "a", 3, 4).shape == (3, 4)
    with pytest.raises(InputError, match="expected one array or FILE.npz:KEY"):
        R.load_vertex_scalars(p, None, 3, 4)
    with pytest.raises(InputError, match="expected key 'c'"):
        R.load_vertex_scalars(p, "c", 3, 4)
    with pytest.raises(InputError, match=r"shape \(5,\) or \(3, 5\)"):
        R.load_vertex_scalars(p, "a", 3, 5)


def test_options_and_size_are_checked():
    assert R.parse_size("320x240") == (320, 240)
    with pytest.raises(InputError, match="--size"):
        R.parse_size("big")
    with pytest.raises(InputError, match="--camera"):
        R.RenderOptions(cameras=("top",))
    with pytest.raises(InputError, match="--framing"):
        R.RenderOptions(framing="loose")


@pytest.fixture(scope="module")
def renderer():
    seq = two_spheres(n_frames=4, travel=0.1)
    scene = R.scene_from_sequence(seq)
    with R.Renderer(scene, R.RenderOptions(**SMALL)) as r:
        yield r


def test_render_draws_garment_and_body_in_distinct_colours(renderer):
    img = renderer.image(0, "front")
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    px = img.reshape(-1, 3).astype(int)
    reddish = (px[:, 0] > px[:, 2] + 40).mean()
    assert reddish > 0.05  # the terracotta garment covers a good part of the picture
    assert not np.array_equal(img, renderer.image(0, "side"))
    # garment off: the body is drawn grey-blue, no red left
    scene = R.Scene(renderer.scene.garment_points * 0 + 100.0, renderer.scene.garment_faces,
                    renderer.scene.body_points, renderer.scene.body_faces, fps=30.0)
    body_only = R.render_image(scene, 0, "front", R.RenderOptions(**SMALL, ground=False))
    bp = body_only.reshape(-1, 3).astype(int)
    assert (bp[:, 0] > bp[:, 2] + 40).mean() < 0.001


def test_render_is_deterministic_and_frames_differ(renderer):
    a = renderer.image(1, "front")
    assert np.array_equal(a, renderer.image(1, "front"))
    assert not np.array_equal(a, renderer.image(1, "back"))
    assert not np.array_equal(a, renderer.image(2, "front"))  # the spheres moved


def test_penetration_is_red_and_error_has_a_colour_bar():
    seq = two_spheres(n_frames=1)
    inside = Sequence(points=seq.points * np.float32(0.5) + np.float32([0, 0, 0.15]), faces=seq.faces, fps=30.0,
                      body_points=seq.body_points, body_faces=seq.body_faces)
    scene = R.scene_from_sequence(inside, color="penetration")
    img = R.render_image(scene, 0, "front", R.RenderOptions(**SMALL, show_body=False, ground=False))
    px = img.reshape(-1, 3).astype(int)
    assert ((px[:, 0] > 150) & (px[:, 1] < 80) & (px[:, 2] < 80)).mean() > 0.05
    # With the body drawn (the default) it is see-through: the red inside it still shows (opaque, none showed).
    shown = R.render_image(scene, 0, "front", R.RenderOptions(**SMALL, ground=False)).reshape(-1, 3).astype(int)
    red = lambda p: (p[:, 0] > p[:, 2] + 60).mean()  # noqa: E731
    assert red(shown) > 0.03
    gt = Sequence(points=seq.points * np.float32(1.1), faces=seq.faces, fps=30.0)
    heat = R.render_image(R.scene_from_sequence(seq, color="error", gt=gt), 0, "front",
                          R.RenderOptions(width=320, height=240, labels=False))
    plain = R.render_image(R.scene_from_sequence(seq), 0, "front", R.RenderOptions(width=320, height=240, labels=False))
    right_strip = np.abs(heat[:, 280:].astype(int) - plain[:, 280:].astype(int)).max(axis=2)
    assert (right_strip > 60).mean() > 0.05  # the colour bar sits at the right


def test_render_outputs_writes_png_mp4_and_contact_sheet(tmp_path):
    import imageio.v2 as iio

    scene = R.scene_from_sequence(two_spheres(n_frames=4, travel=0.05))
    out = R.render_outputs(scene, tmp_path, R.RenderOptions(width=96, height=64, cameras=("front", "orbit")),
                           sheet_frames=3)
    assert len(out["png"]) == 8 and (tmp_path / "frames" / "orbit" / "frame_0003.png").is_file()
    assert R.read_png(out["png"][0]).shape == (64, 96, 3)
    reader = iio.get_reader(tmp_path / "front.mp4")
    assert reader.count_frames() == 4 and abs(reader.get_meta_data()["fps"] - 30.0) < 1e-6
    reader.close()
    sheet = R.read_png(tmp_path / "contact_sheet.png")
    assert sheet.shape[0] > 2 * 64 and sheet.shape[1] > 3 * 96  # two rows (cameras) of three frames


def test_contact_sheet_layout():
    tiles = [[np.full((10, 20, 3), 50 * (r + c), np.uint8) for c in range(3)] for r in range(2)]
    sheet = R.contact_sheet(tiles, thumb_width=20, gap=2)
    assert sheet.shape == (2 * 10 + 3 * 2, 3 * 20 + 4 * 2, 3)
    assert (sheet[2 + 10 + 2 + 5, 2 + 2 * 22 + 5] == 150).all()  # row 1, column 2


def test_missing_gl_library_gives_a_one_line_error(monkeypatch):
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    monkeypatch.setattr(R, "_find_library", lambda name: None)
    with pytest.raises(R.RenderError, match="libegl1 libegl-mesa0 libgl1-mesa-dri") as exc:
        R.Renderer(R.scene_from_sequence(two_spheres(1)), R.RenderOptions(**SMALL))
    assert "\n" not in str(exc.value)


def test_compare_images_and_diff_image():
    a = np.zeros((20, 30, 3), np.uint8)
    b = a.copy()
    b[:2, :3] = 200
    b[5:, 5:] += 10  # under the threshold
    d = R.compare_images(b, a, pixel_threshold=24)
    assert d.differing_fraction == pytest.approx(6 / 600) and d.max_abs == 200
    assert R.compare_images(a[:10], a).shape_mismatch
    img = R.diff_image(b, a)
    assert img.shape == (20, 90, 3) and img[0, 60, 0] == 255 and img[10, 70, 0] == 40


def test_non_finite_coordinates_are_refused_naming_frame_and_vertex():
    seq = two_spheres(n_frames=4)
    pts = seq.points.copy()
    pts[2, 5, 1] = np.nan
    with pytest.raises(InputError, match=r"'nan.npz': expected finite coordinates, got NaN at frame 2, vertex 5$"):
        R.scene_from_sequence(Sequence(points=pts, faces=seq.faces, fps=30.0, source="nan.npz"), frames=[0, 1])
    body = seq.body_points.copy()
    body[3, 7, 0] = np.inf
    bad_body = Sequence(points=seq.points, faces=seq.faces, fps=30.0, body_points=body, body_faces=seq.body_faces,
                        source="b.npz")
    with pytest.raises(InputError, match="'b.npz': expected finite coordinates, got Inf at frame 3, body vertex 7"):
        R.scene_from_sequence(bad_body)
    gt = Sequence(points=pts, faces=seq.faces, fps=30.0, source="gt.npz")
    with pytest.raises(InputError, match="--gt 'gt.npz': expected finite coordinates"):
        R.scene_from_sequence(seq, color="error", gt=gt)


def test_a_scene_building_error_is_not_blamed_on_opengl():
    seq = two_spheres(n_frames=1)
    scene = R.Scene(seq.points * np.float32(np.nan), seq.faces, fps=30.0)  # bypasses the finite check
    with pytest.raises(Exception) as exc:
        R.Renderer(scene, R.RenderOptions(**SMALL))
    assert "OpenGL" not in str(exc.value) and "apt-get" not in str(exc.value)


def test_a_chosen_vtk_window_that_cannot_open_gives_one_line(monkeypatch):
    scene = R.scene_from_sequence(two_spheres(1))
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkXOpenGLRenderWindow")
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(R.RenderError, match="vtkXOpenGLRenderWindow: expected an X display in DISPLAY, got DISPLAY "
                                            "unset; unset VTK_DEFAULT_OPENGL_WINDOW"):
        R.Renderer(scene, R.RenderOptions(**SMALL))
    monkeypatch.setenv("DISPLAY", ":97")
    monkeypatch.setattr(R, "_x_display_opens", lambda: False)
    with pytest.raises(R.RenderError, match="got DISPLAY=:97 that does not"):
        R.check_render_window()
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")
    monkeypatch.setattr(R, "_find_library", lambda name: None if name == "OSMesa" else f"lib{name}.so")
    with pytest.raises(R.RenderError, match="vtkOSOpenGLRenderWindow: expected the OSMesa library, found no "
                                            "libOSMesa") as exc:
        R.Renderer(scene, R.RenderOptions(**SMALL))
    assert "\n" not in str(exc.value)


def test_range_and_azimuth_must_be_finite_and_ordered():
    seq = two_spheres(1)
    gt = Sequence(points=seq.points * np.float32(1.1), faces=seq.faces, fps=30.0)
    for bad, expected in (((5.0, 1.0), "LO < HI, got 5.0 1.0"), ((1.0, 1.0), "LO < HI"),
                          ((float("nan"), float("nan")), "finite LO HI, got nan nan"),
                          ((0.0, float("inf")), "finite LO HI")):
        with pytest.raises(InputError, match=f"--range: expected {expected}"):
            R.scene_from_sequence(seq, color="error", gt=gt, value_range=bad)
    for bad in (float("nan"), 360.5, -1e300):
        with pytest.raises(InputError, match=r"--azimuth: expected degrees within -360\.\.360"):
            R.RenderOptions(azimuth_deg=bad)
    assert R.RenderOptions(azimuth_deg=-360.0).azimuth_deg == -360.0


def test_follow_framing_keeps_a_fast_traveller_in_view_and_leaves_ordinary_travel_alone():
    fast = two_spheres(n_frames=5, travel=50.0)  # 50 m a frame
    lo, hi = fast.points.min(1).astype(float), fast.points.max(1).astype(float)
    opts = R.RenderOptions(**SMALL)
    pos, focal = R.camera_track(lo, hi, "front", opts, fps=30.0)
    assert not R.garment_out_of_view(fast.points, pos, focal, opts).any()
    assert np.linalg.norm(pos - focal, axis=1).max() < 10.0  # not backed off to a speck
    pos, focal = R.camera_track(lo, hi, "front", replace_framing(opts, "fixed"), fps=30.0)
    assert R.garment_out_of_view(fast.points, pos, focal, opts).all()
    walk = two_spheres(n_frames=200, travel=0.3)  # 60 m over 200 frames: the smoothed track, unclamped
    lo, hi = walk.points.min(1).astype(float), walk.points.max(1).astype(float)
    focal = R.camera_track(lo, hi, "front", opts, fps=30.0)[1]
    np.testing.assert_allclose(focal, R._smooth((lo + hi) / 2, 15))


def test_the_follow_cameras_smoothing_keeps_a_steady_traveller_where_it_is():
    """A root moving at a steady speed is its own smoothed track, to the first and last frame (the ends padded by
    repeating them dragged the camera behind a run at its start and end), however short the track."""
    for frames in (4, 12, 90):
        track = np.arange(frames, dtype=float)[:, None] * [0.27, -0.05, 0.01] + [1.0, 2.0, 0.9]
        np.testing.assert_allclose(R._smooth(track, 15), track, atol=1e-12)
    wobble = np.zeros((30, 3))
    wobble[::2, 0] = 0.02
    assert np.abs(np.diff(R._smooth(wobble, 15)[:, 0])).max() < 0.002  # a jitter of 2 cm a frame smoothed out


def test_the_error_colours_range_over_every_frame_whatever_frames_are_drawn():
    seq = two_spheres(n_frames=4)
    gt = Sequence(points=seq.points * np.linspace(1.0, 1.3, 4, dtype=np.float32)[:, None, None], faces=seq.faces,
                  fps=30.0)
    whole = R.scene_from_sequence(seq, color="error", gt=gt).value_range
    assert R.scene_from_sequence(seq, color="error", gt=gt, frames=slice(1, 2)).value_range == whole


def replace_framing(opts, framing):
    from dataclasses import replace

    return replace(opts, framing=framing)


def test_a_garment_out_of_view_warns_once(caplog):
    scene = R.scene_from_sequence(two_spheres(n_frames=5, travel=50.0))
    with caplog.at_level("WARNING", logger="formats.render"):
        with R.Renderer(scene, R.RenderOptions(**SMALL, framing="fixed", cameras=("front", "side"))) as r:
            r.camera("front")
            r.camera("side")
        with R.Renderer(scene, R.RenderOptions(**SMALL)) as r:
            r.camera("front")
    lines = [rec.getMessage() for rec in caplog.records if "out of view" in rec.getMessage()]
    assert len(lines) == 1 and "in 5 of 5 frames" in lines[0] and "--framing follow" in lines[0], lines


def test_a_garment_collapsed_to_a_point_is_refused():
    seq = two_spheres(n_frames=2)
    far = Sequence(points=np.full_like(seq.points, 1e7), faces=seq.faces, fps=30.0, source="far.npz")
    with pytest.raises(InputError, match=r"'far.npz': expected a garment of some size, got all \d+ vertices at one "
                                         r"point in every frame, 1e\+07 m from the origin"):
        R.scene_from_sequence(far)
