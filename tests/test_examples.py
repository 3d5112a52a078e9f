"""The shipped examples: every example garment bakes with every example motion, and the files are reproducible."""

from pathlib import Path

import numpy as np
import pytest

from core.bake import bake_item
from core.body import default_body
from core.deform import LBSDeformer
from core.motion import resample
from formats.motion import load_motion
from formats.obj import read_obj

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
GARMENTS = sorted(EXAMPLES.glob("*.obj"))
MOTIONS = sorted(EXAMPLES.glob("*.npz"))


def test_examples_exist():
    names = {p.stem for p in GARMENTS}
    assert {"dress", "skirt", "tshirt"} <= names and names & {"trousers", "jumpsuit"}
    assert {"walk", "run", "jump", "arms_raise", "crouch", "turn"} <= {p.stem for p in MOTIONS}


@pytest.mark.parametrize("garment_path", GARMENTS, ids=lambda p: p.stem)
def test_every_example_garment_bakes_with_every_example_motion(garment_path):
    body = default_body()
    garment = read_obj(garment_path)
    assert 2000 <= garment.n_vertices <= 8000 and garment.uvs is not None
    size = float(np.ptp(garment.vertices, axis=0).max())
    deformer = LBSDeformer()
    for motion_path in MOTIONS:
        motion = resample(load_motion(motion_path), 30.0)
        result = bake_item(garment, body, motion, deformer, with_body=True, check_penetration=False)
        pts = result.garment_points
        assert pts.shape == (motion.n_frames, garment.n_vertices, 3)
        assert np.all(np.isfinite(pts))
        # bounded: no garment vertex further from the body's vertices than the garment's own size
        far = np.linalg.norm(pts - result.body_points.mean(axis=1, keepdims=True), axis=-1).max()
        assert far < size + 1.0, (motion_path.stem, far)


@pytest.mark.parametrize("garment_path", GARMENTS, ids=lambda p: p.stem)
def test_example_garments_do_not_pass_through_themselves(garment_path):
    """Offsetting the crotch or an armpit by the ease folded the trousers, jumpsuit and t-shirt over themselves
    (282, 140 and 21 faces); the generator now reduces the ease there (`core.garmentgen._untangled_offset`)."""
    from core.geometry import self_intersecting_faces

    garment = read_obj(garment_path)
    assert not self_intersecting_faces(garment.vertices.astype(np.float64), garment.faces).any()


def test_example_motions_are_valid_amass_files():
    for p in MOTIONS:
        with np.load(p) as d:
            assert d["poses"].shape[1] in (72, 156, 165)
            assert d["trans"].shape == (d["poses"].shape[0], 3)
            assert float(d["mocap_framerate"]) > 0
            assert "betas" in d.files


def test_examples_are_reproducible_by_the_documented_generator():
    """`garment examples` regenerates what is shipped (motions exactly, garments within OBJ precision but for the
    t-shirt's vertices its help names)."""
    from core.garmentgen import generate_example_garments
    from core.motiongen import generate_example_motions

    motions = generate_example_motions(fps=60.0)
    for p in MOTIONS:
        shipped = load_motion(p)
        np.testing.assert_allclose(motions[p.stem].poses, shipped.poses, atol=1e-6)
    garments = generate_example_garments(default_body())
    assert sorted(garments) == sorted(p.stem for p in GARMENTS)
    for name, made in garments.items():
        shipped = read_obj(EXAMPLES / f"{name}.obj")
        np.testing.assert_array_equal(made.faces, shipped.faces)
        moved = np.linalg.norm(made.vertices - shipped.vertices, axis=1)
        if name == "tshirt":  # some vertices follow the CPU's float rounding (garment examples' help)
            assert (moved > 2e-6).mean() < 0.05 and moved.max() < 0.01, ((moved > 2e-6).sum(), moved.max())
        else:
            assert moved.max() < 2e-6, (name, moved.max())


def test_garments_without_shoulders_get_a_waistband_and_the_others_none():
    """The simulator pins the waistband of the skirt, trousers and strapless dress (they slide off otherwise)."""
    from core.sim import waistband_vertices

    body = default_body()
    for name, expected in {"dress": True, "skirt": True, "trousers": True, "tshirt": False, "jumpsuit": False}.items():
        garment = read_obj(EXAMPLES / f"{name}.obj")
        band = waistband_vertices(garment, body)
        assert (len(band) > 0) == expected, name
        if expected:  # the top rows only
            y = garment.vertices[:, 1]
            assert y[band].min() > np.percentile(y, 75), name


@pytest.mark.parametrize("fps", ["nan", "inf", "1e9", "1e5", "0"])
def test_examples_refuses_an_absurd_fps_in_one_line(tmp_path, fps):
    """nan, inf and huge rates crashed (ValueError, OverflowError, out of memory) or ran for minutes."""
    from click.testing import CliRunner

    from garmentcli.main import cli

    r = CliRunner().invoke(cli, ["examples", "--out", str(tmp_path / "ex"), "--fps", fps])
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), r.output
    assert "--fps" in r.output and "Traceback" not in r.output
    assert not (tmp_path / "ex").exists()
