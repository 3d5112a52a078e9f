"""Regression renders: fixed scenes drawn off-screen and compared with golden PNGs kept in the repository.

Each example garment (examples/*.obj) is baked with `lbs` (deterministic) on
frame FRAME of examples/walk.npz on the default body and drawn at 320x240 from
the front (the dress from the side too), without text. A render matches its
golden when at most PIXEL_BUDGET of its pixels differ by more than
PIXEL_THRESHOLD (0-255, any channel) and the mean difference stays under
MEAN_BUDGET: enough slack for software rasterisers (Mesa llvmpipe versions,
CPU vector widths) to disagree along silhouettes and in shading, far too little
for a moved garment, a new colour or another camera (see the perturbation tests).

On a mismatch the test writes golden | actual | difference side by side into
$GARMENT_RENDER_DIFF_DIR (default: <tmp>/garment-render-diffs/) and names the file.

Update the goldens on purpose (after a change that should alter the pictures):

    GARMENT_UPDATE_GOLDENS=1 python -m pytest tests/regression -p no:cacheprovider

then look at tests/regression/golden/*.png before committing them.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from formats import render as R

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = Path(os.environ.get("GARMENT_REGRESSION_EXAMPLES", ROOT / "examples"))  # override: trying other inputs
GOLDEN = Path(__file__).resolve().parent / "golden"
MOTION = EXAMPLES / "walk.npz"
FRAME = 30
SIZE = (320, 240)
PIXEL_THRESHOLD = 24
PIXEL_BUDGET = 0.0025
MEAN_BUDGET = 1.0
UPDATE = os.environ.get("GARMENT_UPDATE_GOLDENS", "") not in ("", "0")

GARMENTS = sorted(p.stem for p in EXAMPLES.glob("*.obj"))
#: (golden name, garment, camera)
CASES = [(f"{g}_front", g, "front") for g in GARMENTS] + ([("dress_side", "dress", "side")] if "dress" in GARMENTS
                                                           else [])
OPTIONS = R.RenderOptions(width=SIZE[0], height=SIZE[1], labels=False, framing="fixed")


@pytest.fixture(scope="module")
def posed():
    """The default body and frame FRAME of the walk: (body, motion of one frame, body points (1, Vb, 3))."""
    from core.body import default_body
    from core.motion import poses_for_body, select_frames
    from formats.motion import load_motion

    if not MOTION.is_file() or not GARMENTS:
        pytest.fail(f"regression renders need the examples: {MOTION} and examples/*.obj "
                    "(make them with `garment examples --out examples --overwrite`)")
    body = default_body()
    motion = select_frames(load_motion(MOTION), FRAME, FRAME + 1)
    body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
    return body, motion, body_points.astype(np.float32)


_SCENES: dict[str, R.Scene] = {}


def scene_for(garment_name: str, posed) -> R.Scene:
    """The example garment baked with lbs on the fixed frame, with the body (cached per garment)."""
    if garment_name not in _SCENES:
        from core.deform import LBSDeformer
        from formats.obj import read_obj

        body, motion, body_points = posed
        garment = read_obj(EXAMPLES / f"{garment_name}.obj")
        points = LBSDeformer().deform(garment, body, motion)
        _SCENES[garment_name] = R.Scene(points.astype(np.float32), garment.faces, body_points, body.faces,
                                        fps=30.0, frame_numbers=np.array([FRAME]))
    return _SCENES[garment_name]


def check_against_golden(name: str, image: np.ndarray) -> None:
    """Assert `image` matches golden/<name>.png (or write it when updating); on failure write a diff image."""
    path = GOLDEN / f"{name}.png"
    if UPDATE:
        R.write_png(path, image)
        return
    if not path.is_file():
        pytest.fail(f"no golden {path}: create it with GARMENT_UPDATE_GOLDENS=1 python -m pytest tests/regression")
    expected = R.read_png(path)
    diff = R.compare_images(image, expected, PIXEL_THRESHOLD)
    if diff.shape_mismatch or diff.differing_fraction > PIXEL_BUDGET or diff.mean_abs > MEAN_BUDGET:
        out_dir = Path(os.environ.get("GARMENT_RENDER_DIFF_DIR", Path(tempfile.gettempdir()) / "garment-render-diffs"))
        diff_path = R.write_png(out_dir / f"{name}_diff.png", R.diff_image(image, expected))
        R.write_png(out_dir / f"{name}_actual.png", image)
        pytest.fail(f"render '{name}' differs from {path}: {diff.differing_fraction:.2%} of pixels off by more "
                    f"than {PIXEL_THRESHOLD} (budget {PIXEL_BUDGET:.2%}), mean {diff.mean_abs:.2f} (budget "
                    f"{MEAN_BUDGET}); golden | actual | difference written to {diff_path}. If the change is "
                    "intended: GARMENT_UPDATE_GOLDENS=1 python -m pytest tests/regression")


@pytest.mark.parametrize("name, garment, camera", CASES, ids=[c[0] for c in CASES])
def test_render_matches_golden(name, garment, camera, posed):
    image = R.render_image(scene_for(garment, posed), 0, camera, OPTIONS)
    assert image.shape == (SIZE[1], SIZE[0], 3)
    check_against_golden(name, image)


@pytest.mark.skipif(UPDATE, reason="updating goldens")
@pytest.mark.parametrize("perturbation", ["garment moved 1 cm", "garment colour", "camera turned 5 deg"])
def test_a_changed_render_fails_the_comparison(perturbation, posed, tmp_path, monkeypatch):
    """The same check must fail when the scene changes a little: the tolerance is not too loose."""
    monkeypatch.setenv("GARMENT_RENDER_DIFF_DIR", str(tmp_path))
    name, garment, camera = CASES[0]
    scene, options = scene_for(garment, posed), OPTIONS
    if perturbation == "garment moved 1 cm":
        scene = replace(scene, garment_points=scene.garment_points + np.float32([0.01, 0.0, 0.0]))
    elif perturbation == "garment colour":
        options = replace(options, garment_color=(0.60, 0.30, 0.60))
    else:
        options = replace(options, azimuth_deg=5.0)
    image = R.render_image(scene, 0, camera, options)
    with pytest.raises(pytest.fail.Exception, match="differs from") as exc:
        check_against_golden(name, image)
    assert str(tmp_path / f"{name}_diff.png") in str(exc.value)
    assert R.read_png(tmp_path / f"{name}_diff.png").shape == (SIZE[1], 3 * SIZE[0], 3)
