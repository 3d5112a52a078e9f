"""The reference simulator on tiny scenes: the real Newton VBD solver, no mock.

Invariants, not snapshots: a cloth at rest on a static collider stays still; a
dropped cloth falls as g t^2 / 2 before contact; a collider moving into the cloth
pushes it without letting it through (beyond the contact distance); no NaN; the
retry path re-runs frames with more substeps and gives up naming the frame.
Warp compiles its kernels once (about a minute on CPU) into the shared cache.
"""

import dataclasses
import json
import logging
import os
from pathlib import Path

os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import numpy as np
import pytest

from core.errors import InputError
from core.garment import Garment
from core.motion import Motion, select_frames
from core.sim import (
    ClothSim,
    Material,
    SimDeformer,
    SimOptions,
    SimulationError,
    edge_strain,
    load_material,
)
from tests.meshes import grid, icosphere, tiny_body

G = 9.81
FPS = 30.0


def box(half=(0.3, 0.3, 0.1), center=(0.0, 0.0, 0.0)):
    """Closed outward box mesh: verts (8, 3), faces (12, 3)."""
    h = np.asarray(half)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64) * h + center
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], dtype=np.int64)
    return v, f


def cloth(z, n=9, size=0.3):
    """A (n+1) x (n+1) grid cloth of side `size` centred over the origin at height z."""
    v, f = grid(n, n, size)
    v = v - [size / 2, size / 2, 0.0]
    v[:, 2] = z
    return v, f


def box_top_sim(z_offset=0.0, material=Material()):
    bv, bf = box()
    cv, cf = cloth(0.1 + material.contact_distance_m + z_offset)
    sim = ClothSim(cv, cf, bv, bf, material, iterations=10, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]))
    return sim, cv, bv


def test_cloth_at_rest_on_a_static_body_stays_still():
    sim, cv, bv = box_top_sim()
    for _ in range(10):
        x = sim.advance(bv, bv, 1 / FPS, 10)
    assert np.all(np.isfinite(x))
    assert np.abs(x - cv).max() < 1e-3  # under a millimetre after a third of a second
    _, v = sim.get_state()
    assert np.abs(v).max() < 0.02


def test_dropped_cloth_falls_with_gravity_then_stops_on_the_body():
    m = Material()
    sim, cv, bv = box_top_sim(z_offset=0.3)
    z0 = cv[:, 2].mean()
    zs = []
    for _ in range(6):  # 0.2 s: falls 0.196 m of the 0.3 m gap, no contact yet
        zs.append(sim.advance(bv, bv, 1 / FPS, 10)[:, 2].mean())
    t = np.arange(1, 7) / FPS
    free = z0 - 0.5 * G * t**2
    # Implicit (backward) Euler falls slightly faster than the exact parabola: g dt t / 2 more.
    np.testing.assert_allclose(zs, free, atol=0.5 * G * (1 / FPS / 10) * t.max() + 1e-4)
    for _ in range(24):
        x = sim.advance(bv, bv, 1 / FPS, 10)
    assert np.all(np.isfinite(x))
    assert x[:, 2].min() > 0.1 + m.contact_distance_m - 2e-3  # resting on the top face, not through it
    assert x[:, 2].max() < 0.1 + m.contact_distance_m + 0.01


def test_moving_collider_pushes_cloth_without_penetration():
    """The box rises 0.2 m in 0.3 s under the cloth; points and velocities updated every substep."""
    m = Material()
    sim, cv, bv = box_top_sim()
    lift = np.array([0.0, 0.0, 0.02])
    for k in range(10):
        x = sim.advance(bv + k * lift, bv + (k + 1) * lift, 1 / FPS, 10)
        top = 0.1 + (k + 1) * 0.02
        assert np.all(np.isfinite(x))
        assert x[:, 2].min() > top + m.contact_distance_m - 3e-3, k  # no penetration beyond the contact distance
    strain = np.abs(edge_strain(x, *_edges_and_rest(cv)))
    assert strain.mean() < 0.02


def _edges_and_rest(v):
    from core.garment import mesh_edges

    _, f = cloth(0.0)
    e = mesh_edges(f)
    return e, np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)


def _shell_scene():
    body = tiny_body()
    from core.geometry import vertex_normals

    v, f = icosphere(2)
    v = v * np.array([0.25, 0.8, 0.15]) * 1.0
    v = v + 0.02 * vertex_normals(v, f)
    garment = Garment(v.astype(np.float32), f, name="shell")
    poses = np.zeros((3, 24, 3), np.float32)
    poses[:, 0] = [np.pi / 2, 0, 0]  # Y-up body into the Z-up world
    motion = Motion(poses=poses, trans=np.zeros((3, 3), np.float32), fps=FPS, name="still", n_settle=1)
    return body, garment, motion


#: The golden simulations of `SIMULATOR_VERSION`, one per CPU kind they were made on
#: (test_simulator_behaviour_matches_its_declared_version): sim_shell_walk.npz (an AVX2 AMD EPYC; no kind recorded)
#: and sim_shell_walk_<kind>.npz.
GOLDEN_DIR = Path(__file__).resolve().parents[1] / "regression" / "golden"
#: Largest vertex difference from the golden of this CPU's kind (metres): repeated runs agree exactly; a 0.1
#: change of friction moves vertices by up to 9 cm, a 10x bending stiffness by 0.5-1.5 mm.
GOLDEN_SIM_TOLERANCE_M = 1e-4
#: Against a golden of another CPU kind (the simulator's kernels are compiled for the CPU they run on, and their
#: rounding grows through the contacts): mean and largest vertex distance (metres). A Zen 4 EPYC (AVX-512) against
#: the AVX2 EPYC's golden: mean 0.04 mm, largest 1.0 mm; friction 0.3 -> 0.2 moves them by 16 mm and 93 mm, twice
#: the stretch damping by 0.23 mm and 1.8 mm; a 10x bending stiffness (0.08 mm, 0.5 mm) passes unseen.
OTHER_CPU_TOLERANCE_M = (1.5e-4, 3e-3)


def _cpu_kind() -> str:
    """This CPU's kind, the key of its golden: vendor, family and model as /proc/cpuinfo gives them (else the
    machine's architecture)."""
    import platform

    info: dict = {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            info.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    parts = [info.get(k) for k in ("vendor_id", "cpu family", "model")]
    return "-".join(p.replace(" ", "") for p in parts if p) or platform.machine()


def _golden_sim(material=Material()):
    """The shell carried 15 cm sideways over 5 frames while the hips swing, with self-contact on."""
    body, garment, _ = _shell_scene()
    T = 5
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 0] = [np.pi / 2, 0, 0]
    poses[:, 1, 0], poses[:, 2, 0] = np.linspace(0, 0.6, T), -np.linspace(0, 0.6, T)
    trans = np.zeros((T, 3), np.float32)
    trans[:, 0] = np.linspace(0, 0.15, T)
    motion = Motion(poses=poses, trans=trans, fps=FPS, name="golden", n_settle=1)
    return SimDeformer(material, SimOptions(settle_s=0.1, self_contact=True)).deform(garment, body, motion)


def test_simulator_behaviour_matches_its_declared_version():
    """Stored simulations are keyed on SIMULATOR_VERSION: a change that moves the cloth must bump it. Compared
    exactly (GOLDEN_SIM_TOLERANCE_M) with the golden of this CPU's kind where there is one (an AMD EPYC of family
    25 model 1 lies 0.34 mm from the AVX2 EPYC's golden on average, up to 5.5 mm: beyond the tolerance between
    other kinds, so it has its own), else within OTHER_CPU_TOLERANCE_M of the nearest golden (a
    new kind need not lie between kinds that lie apart)."""
    from core.sim import SIMULATOR_VERSION

    out = _golden_sim()
    kind = _cpu_kind()
    own = GOLDEN_DIR / f"sim_shell_walk_{kind}.npz"
    if os.environ.get("GARMENT_UPDATE_GOLDENS", "") not in ("", "0"):
        np.savez_compressed(own, points=out, simulator_version=SIMULATOR_VERSION, cpu_kind=kind)
    remake = "GARMENT_UPDATE_GOLDENS=1 python -m pytest tests/core/test_sim.py -k declared_version"
    goldens = sorted(GOLDEN_DIR.glob("sim_shell_walk*.npz"))
    assert goldens, f"no golden simulation in {GOLDEN_DIR}: make one ({remake})"
    for path in goldens:  # each made with the simulator the code declares
        with np.load(path) as g:
            version, made_on = int(g["simulator_version"]), str(g["cpu_kind"]) if "cpu_kind" in g else "unknown"
        assert version == SIMULATOR_VERSION, (
            f"{path.name} was made with SIMULATOR_VERSION {version}, the code declares {SIMULATOR_VERSION}: remake "
            f"it on its CPU kind ({made_on}; {remake}) or delete it")
    change = (f"if the simulator's behaviour changed on purpose, bump core.sim.SIMULATOR_VERSION and remake the "
              f"golden ({remake})")
    if own.is_file():  # this CPU's kind: exactly; others' rounding may have grown beyond their tolerance here
        with np.load(own) as g:
            dist = np.linalg.norm(out - g["points"], axis=-1)
        assert dist.max() <= GOLDEN_SIM_TOLERANCE_M, (
            f"the simulated cloth moved by up to {dist.max() * 1e3:.2f} mm from {own.name}, made on this CPU's "
            f"kind: {change}")
    else:  # another kind's rounding: near one of the kinds (they lie up to 5.5 mm apart from each other)
        mean, most = OTHER_CPU_TOLERANCE_M
        apart = {}
        for path in goldens:
            with np.load(path) as g:
                dist = np.linalg.norm(out - g["points"], axis=-1)
            apart[path.name] = (float(dist.mean()), float(dist.max()))
        assert any(m <= mean and x <= most for m, x in apart.values()), (
            "the simulated cloth moved beyond the tolerance between CPU kinds from every golden ("
            + "; ".join(f"{name}: {m * 1e3:.3f} mm on average, up to {x * 1e3:.2f} mm" for name, (m, x) in apart.items())
            + f"; this CPU's kind is {kind}): {change}")
    # The tolerances are far below what a material change does.
    moved = np.linalg.norm(_golden_sim(dataclasses.replace(Material(), friction=0.2)) - out, axis=-1)
    assert moved.max() > 10 * OTHER_CPU_TOLERANCE_M[1] and moved.mean() > 10 * OTHER_CPU_TOLERANCE_M[0]


def test_sim_deformer_on_a_tiny_body_reports_checks():
    body, garment, motion = _shell_scene()
    d = SimDeformer(options=SimOptions(settle_s=0.1))
    out = d.deform(garment, body, motion)
    assert out.shape == (3, garment.n_vertices, 3) and out.dtype == np.float32
    assert np.all(np.isfinite(out))
    c = d.report["checks"]
    assert c["penetration_percent_max"] < 1.0 and c["edge_strain_mean"] < 0.05 and not c["nan"]
    assert d.report["retries"] == []
    # The Y-up garment is carried into the Z-up world: its long axis is now along Z.
    ext = np.ptp(out[-1], axis=0)
    assert ext[2] > 2 * ext[1]


def test_failing_frames_are_retried_with_more_substeps_then_kept_or_refused():
    body, garment, motion = _shell_scene()
    # retry_mean_strain 0: every frame "fails" the soft check, is retried twice, the best try is kept.
    d = SimDeformer(options=SimOptions(settle_s=0.0, max_retries=1, retry_mean_strain=0.0, substeps=4))
    out = d.deform(garment, body, motion)
    assert np.all(np.isfinite(out))
    assert [r["frame"] for r in d.report["retries"]] == [0, 1, 2]
    assert all(r["tries"] == 2 and r["kept_substeps"] in (4, 8) for r in d.report["retries"])
    # fail_mean_strain 0: no try can pass; the error names the frame.
    d = SimDeformer(options=SimOptions(settle_s=0.0, max_retries=1, retry_mean_strain=0.0, fail_mean_strain=0.0,
                                       substeps=4))
    with pytest.raises(SimulationError, match=r"frame 0 of motion 'still' failed after 2 tries \(up to 8 substeps\)"):
        d.deform(garment, body, motion)
    # A frame whose try passes the retries' checks but fails the final ones was tried once, at its substeps (it
    # said "after 3 tries (up to 4 substeps)")
    d = SimDeformer(options=SimOptions(settle_s=0.0, max_retries=2, fail_mean_strain=-1.0, substeps=4))
    with pytest.raises(SimulationError, match=r"frame 0 of motion 'still' failed after 1 try \(4 substeps\): "):
        d.deform(garment, body, motion)


def test_material_json_round_trip_and_unknown_key(tmp_path):
    p = tmp_path / "silk.json"
    p.write_text(json.dumps({"density_kg_m2": 0.08, "friction": 0.2}))
    m = load_material(p)
    assert m.density_kg_m2 == 0.08 and m.friction == 0.2 and m.bending_stiffness_n_m == Material().bending_stiffness_n_m
    p.write_text(json.dumps({"density": 0.08}))
    with pytest.raises(InputError, match=r"material file '.*silk.json': unknown key 'density'") as e:
        load_material(p)
    assert "\n" not in str(e.value)
    p.write_text(json.dumps({"friction": "high"}))
    with pytest.raises(InputError, match="expected a number for 'friction'"):
        load_material(p)
    p.write_text(json.dumps({"friction": -1}))
    with pytest.raises(InputError, match="friction"):
        load_material(p)
    p.write_text("{not json")
    with pytest.raises(InputError, match="expected a JSON object"):
        load_material(p)


def test_edge_strain_matches_naive_loop():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(10, 3))
    e = np.array([[0, 1], [2, 5], [3, 9]])
    rest = np.array([1.0, 2.0, 0.5])
    naive = [(np.linalg.norm(v[a] - v[b]) - r) / r for (a, b), r in zip(e, rest)]
    np.testing.assert_allclose(edge_strain(v, e, rest), naive)


def test_the_off_body_check_counts_from_the_garments_own_rest_distance():
    """The shell rests 2 cm off the tiny body (the median): with fail_off_body_m at 1 cm it is still on the body
    (it stays near its 2 cm); measured from the body itself it would have failed at frame 0."""
    body, garment, motion = _shell_scene()
    d = SimDeformer(options=SimOptions(settle_s=0.0, max_retries=0, fail_off_body_m=0.01))
    out = d.deform(garment, body, motion)
    assert np.isfinite(out).all()
    from core.geometry import TriangleMesh

    posed, _ = body.pose(motion.poses[-1:], motion.trans[-1:])
    median = np.median(np.abs(TriangleMesh(posed[0], body.faces).signed_distance(out[-1])))
    assert 0.01 < median < 0.03


def test_a_garment_that_falls_off_the_body_stops_the_bake():
    """A loose open tube around the tiny body's middle has nothing to hang on: it falls, and the
    off-body check says so (a falling garment neither penetrates nor stretches)."""
    body, _, motion = _shell_scene()
    theta = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rows = [np.stack([0.35 * np.cos(theta), np.full(24, y), 0.35 * np.sin(theta)], 1) for y in (-0.1, 0.0, 0.1)]
    i = np.arange(24)
    j = (i + 1) % 24
    faces = np.concatenate([np.stack([r * 24 + i, r * 24 + j, (r + 1) * 24 + i], 1) for r in (0, 1)]
                           + [np.stack([r * 24 + j, (r + 1) * 24 + j, (r + 1) * 24 + i], 1) for r in (0, 1)])
    tube = Garment(np.concatenate(rows).astype(np.float32), faces, name="tube")
    d = SimDeformer(options=SimOptions(settle_s=0.5, max_retries=0))
    with pytest.raises(SimulationError, match="median distance to the body"):
        d.deform(tube, body, motion)


def test_pinned_particles_follow_their_targets_while_the_rest_falls():
    """Zero-mass pinned particles sit exactly on the targets given to advance (moved linearly); the others fall."""
    bv, bf = box()
    cv, cf = cloth(1.0)  # far above the box: no contact
    pinned = np.flatnonzero(np.isclose(cv[:, 1], cv[:, 1].min()))  # one edge row
    sim = ClothSim(cv, cf, bv, bf, iterations=10, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]), pinned=pinned)
    step = np.array([0.01, 0.0, 0.0])
    targets = cv[pinned]
    for k in range(6):
        x = sim.advance(bv, bv, 1 / FPS, 10, targets + k * step, targets + (k + 1) * step)
        np.testing.assert_allclose(x[pinned], targets + (k + 1) * step, atol=1e-6)
    far = np.isclose(cv[:, 1], cv[:, 1].max())
    assert x[far, 2].mean() < 1.0 - 0.05  # the free edge swings down under gravity
    assert np.all(np.isfinite(x))


def _torso_tube(body, y_top, y_bottom, gap=0.01, n_theta=48, n_rows=12):
    """A tube around the tiny body's ellipsoid torso, `gap` metres off its surface, from y_top down to y_bottom."""
    from tests.core.model_fixtures import tube

    v, f = tube(n_theta, n_rows, radius=(1.0, 1.0), y=(y_bottom, y_top))  # unit circles, then the ellipsoid's
    scale = np.sqrt(np.clip(1 - (v[:, 1] / 0.8) ** 2, 0.05, None))
    v[:, 0] *= 0.25 * scale + gap
    v[:, 2] *= 0.15 * scale + gap
    return Garment(v.astype(np.float32), f, name="tube")


def test_waistband_is_the_top_opening_of_a_garment_hanging_from_the_waist():
    from core.sim import waistband_vertices

    body = tiny_body()
    skirt = _torso_tube(body, 0.1, -0.3)  # top below the chest: pinned
    band = waistband_vertices(skirt, body, band_m=0.02)
    top = np.flatnonzero(np.isclose(skirt.vertices[:, 1], 0.1))
    assert set(top) <= set(band)
    assert skirt.vertices[band, 1].min() > 0.1 - 0.02 - 1e-6  # only the band below the edge
    assert len(band) < skirt.n_vertices // 2
    # A wider band takes more rows.
    assert len(waistband_vertices(skirt, body, band_m=0.1)) > len(band)
    # A top opening above the chest (a neckline) is not a waistband; nor is a loose opening, nor a flat sheet.
    assert len(waistband_vertices(_torso_tube(body, 0.5, 0.0), body)) == 0
    assert len(waistband_vertices(_torso_tube(body, 0.1, -0.3, gap=0.08), body)) == 0
    v, f = grid(6, 6, 0.3)
    assert len(waistband_vertices(Garment((v + [0, 0, 0.2]).astype(np.float32), f), body)) == 0


def test_sim_options_reject_an_unknown_pin_or_floor_mode():
    from core.sim import FLOOR_MODES, PIN_MODES
    from garmentcli.common import FLOOR_CHOICES, PIN_CHOICES

    # the CLI's copies (it starts without importing the simulator)
    assert PIN_CHOICES == PIN_MODES and FLOOR_CHOICES == FLOOR_MODES
    with pytest.raises(InputError, match="pin"):
        SimOptions(pin="waist")
    with pytest.raises(InputError, match="sim option floor: expected one of auto, none, got 'off'"):
        SimOptions(floor="off")


@pytest.mark.parametrize("mb", [-1.0, float("nan")])
def test_sim_options_reject_a_negative_or_non_finite_contact_buffer_cap(mb):
    with pytest.raises(InputError, match=r"contact_buffer_mb: expected a number >= 0, got"):
        SimOptions(contact_buffer_mb=mb)


@pytest.mark.parametrize("jitter", [-1e-6, float("nan"), float("inf")])
def test_sim_rejects_a_negative_or_non_finite_start_jitter(jitter):
    with pytest.raises(InputError, match="expected jitter_m >= 0"):
        SimDeformer(jitter_m=jitter)


def test_scene_skips_leave_the_simulation_unchanged_and_are_reported():
    from core.scene import parse_no_skip
    from tests.core.model_fixtures import tube

    body = tiny_body()
    v, f = tube(16, 6, radius=(0.27, 0.17), y=(-0.1, 0.1))  # 2 cm off the body's middle: it rests there
    garment = Garment(v.astype(np.float32), f, name="tube")
    _, _, motion = _shell_scene()
    options = SimOptions(settle_s=0.05, pin="none")
    d = SimDeformer(options=options)
    skipped = d.deform(garment, body, motion)
    faces = d.scene["body-faces"]
    assert faces["skipped_work"] and 0 < faces["kept_faces"] <= 0.5 * faces["body_faces"] == 0.5 * len(body.faces)
    assert d.scene["self-contact"] == {"skipped_work": False, "overridden": False, "reason": "self-contact not requested"}
    d.skips = parse_no_skip(["all"])
    full = d.deform(garment, body, motion)
    assert d.scene["body-faces"]["overridden"] and not d.scene["body-faces"]["skipped_work"]
    assert np.abs(skipped - full).max() < 1e-4
    # A longer tube, its cloth free to swing 48 cm from where it rests: the collider would keep over half the body,
    # and stays whole; one 5 cm off the body everywhere rests nowhere: whole too
    for radius, y, reason in (((0.27, 0.17), (-0.35, 0.05), "keeps over 50% of the body's faces"),
                              ((0.3, 0.3), (-0.35, 0.05), "no part of the garment rests within 3 cm")):
        v, f = tube(16, 6, radius=radius, y=y)
        d = SimDeformer(options=options)
        d.deform(Garment(v.astype(np.float32), f, name="tube"), body, select_frames(motion, 0, 2))
        assert not d.scene["body-faces"]["skipped_work"] and reason in d.scene["body-faces"]["reason"]
    # Self-contact asked for: the tube's sides are 34-54 cm apart and never meet, so contact is switched off.
    d = SimDeformer(options=dataclasses.replace(options, self_contact=True))
    d.deform(garment, body, motion)
    assert d.scene["self-contact"]["skipped_work"] and d.scene["self-contact"]["pairs"] == 0


def test_self_contact_ignores_cloth_that_crosses_itself_as_authored():
    """Two sheets modelled crossing each other (as trouser legs at a crotch): with self-contact, the contacts
    they start in would pull them apart; pairs closer than `self_contact_rest_exclusion_m` at rest are ignored."""
    from dataclasses import replace

    from core.garment import mesh_edges

    bv, bf = box()
    a, fa = cloth(0.5)
    b, fb = cloth(0.0)
    tilt = np.radians(20.0)
    b = b @ np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]]).T + [0, 0, 0.5]
    cv, cf = np.concatenate([a, b]), np.concatenate([fa, fb + len(a)])
    edges = mesh_edges(cf)
    rest = np.linalg.norm(cv[edges[:, 0]] - cv[edges[:, 1]], axis=1)
    strain = {}
    for exclusion in (0.0, Material().self_contact_rest_exclusion_m):
        sim = ClothSim(cv, cf, bv, bf, replace(Material(), self_contact_rest_exclusion_m=exclusion), self_contact=True,
                       iterations=10, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]))
        for _ in range(5):  # falling freely above the box: only the contacts can strain the sheets
            x = sim.advance(bv, bv, 1 / FPS, 10)
        assert np.isfinite(x).all()
        strain[exclusion] = np.abs(np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) / rest - 1).max()
    assert strain[0.0] > 1e-4 and strain[Material().self_contact_rest_exclusion_m] < 1e-5, strain


def test_self_contact_detection_distance_follows_the_cloth_speed():
    """Two sheets 4 mm apart (in self-contact range) thrown down together at 3 m/s, far above the collider.

    Nothing touches: they should fall ballistically. Newton keeps self-contact penetration-free by capping
    every vertex's move between two detections at 0.85 x half the detection distance: with the 3 mm
    contact distance as the gap that is 2.55 mm per substep, and the sheets fall half the way;
    with the gap `self_contact_gap` sizes for their speed, they fall freely."""
    from core.sim import cloth_speed_limit, self_contact_gap

    bv, bf = box()
    a, fa = cloth(1.0, n=6)
    b, fb = cloth(1.004, n=6)
    cv, cf = np.concatenate([a, b]), np.concatenate([fa, fb + len(a)])
    v0, dt, substeps = 3.0, 1 / FPS, 20
    expected = v0 * dt + 0.5 * G * dt**2
    fastest = v0 + G * dt
    drop = {}
    for gap in (None, self_contact_gap(Material(), fastest, dt / substeps)):
        sim = ClothSim(cv, cf, bv, bf, self_contact=True, iterations=10, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]),
                       self_contact_gap_m=gap)
        sim.set_state(cv, np.tile([0.0, 0.0, -v0], (len(cv), 1)))
        drop[gap] = float(np.mean(cv[:, 2] - sim.advance(bv, bv, dt, substeps)[:, 2]))
    held, free = drop.values()
    limit = cloth_speed_limit(Material(), Material().self_contact_distance_m, dt / substeps)
    assert abs(held - limit * dt) < 0.02 * limit * dt, (drop, limit)
    assert abs(free - expected) < 0.02 * expected, (drop, expected)


def test_self_contact_filters_match_a_naive_search():
    """Vertex-triangle and edge-edge pairs within the radius along the surface (all-pairs Dijkstra on the
    same graph, corner by corner); a second sheet close above is another stretch of cloth: never filtered."""
    from scipy.sparse.csgraph import dijkstra

    from core.garment import mesh_edges
    from core.geodesic import geodesic_graph
    from core.sim import self_contact_filters

    a, fa = cloth(0.0, n=7, size=0.14)
    b, fb = cloth(0.01, n=7, size=0.14)
    v, f = np.concatenate([a, b]), np.concatenate([fa, fb + len(a)])
    e = mesh_edges(f)
    radius = 0.045
    vt, ee = self_contact_filters(v, f, e, radius)
    d = dijkstra(geodesic_graph(v, f), directed=True)
    near = d <= radius
    want_vt = {i: {t for t in range(len(f)) if near[i, f[t]].any()} for i in range(len(v))}
    want_ee = {i: {j for j in range(len(e)) if near[np.ix_(e[i], e[j])].any()} for i in range(len(e))}
    assert {i: set(x) for i, x in vt.items()} == want_vt
    assert {i: set(x) for i, x in ee.items()} == want_ee
    # Filtered: some pairs, none across the sheets (which lie 1 cm apart, inside any detection distance).
    assert 0 < sum(map(len, vt.values())) < len(v) * len(f)
    assert all((np.asarray(x) < len(fa)).all() == (i < len(a)) for i, x in vt.items() if x)


def test_self_contact_checks_no_pair_along_one_sheet_but_keeps_those_between_sheets():
    """With a 2 cm detection gap on a 1.5 cm grid, Newton's ring filter alone leaves each vertex paired
    with triangles of its own sheet; the surface filter leaves none, while two sheets 1 cm apart stay paired."""
    from core.sim import self_contact_filter_radius

    bv, bf = box()
    single, fs = cloth(1.0, n=12, size=0.18)
    a, fa = cloth(1.0, n=12, size=0.18)
    b, fb = cloth(1.01, n=12, size=0.18)
    pairs = {}
    for name, (cv, cf) in {"one sheet": (single, fs),
                           "two sheets": (np.concatenate([a, b]), np.concatenate([fa, fb + len(a)]))}.items():
        sim = ClothSim(cv, cf, bv, bf, self_contact=True, iterations=2, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]),
                       self_contact_gap_m=0.02)
        sim.advance(bv, bv, 1 / FPS, 1)
        pairs[name] = tuple(sim.contact_pairs().values())
        assert sim.contact_filter["surface_radius_m"] == pytest.approx(self_contact_filter_radius(cv, cf, 0.023))
    assert pairs["one sheet"] == (0, 0), pairs
    assert min(pairs["two sheets"]) > len(a), pairs


def test_self_contact_surface_filter_is_reported_and_no_skip_turns_it_off(monkeypatch):
    import core.scene
    from core.scene import parse_no_skip

    body, garment, motion = _shell_scene()
    # The shell's parts never meet: say they do, so the analysis keeps self-contact on.
    monkeypatch.setattr(core.scene, "distant_parts_meet", lambda *a: {"meet": True, "frame": 0, "pairs": 1})
    d = SimDeformer(options=SimOptions(settle_s=0.05, self_contact=True))
    d.deform(garment, body, motion)
    kept = d.scene["self-contact"]["filtered_along_surface"]
    assert kept["surface_radius_m"] > Material().self_contact_distance_m and kept["vertex_triangle_pairs"] > 0
    assert d.report["self_contact"]["filtered_along_surface"] == kept
    assert d.report["self_contact"]["buffers"]["start"] == {"pairs_per_vertex": 32, "pairs_per_edge": 64}
    assert d.report["self_contact"]["buffers"]["pairs_dropped_at"] == []
    d.skips = parse_no_skip(["self-contact"])
    d.deform(garment, body, motion)
    assert d.scene["self-contact"]["filtered_along_surface"] is None and d.scene["self-contact"]["overridden"]


def _stacked_sheets(gap_m=0.005, n=20, size=0.18, **kwargs):
    """Two 9 mm grids `gap_m` apart under a 2 cm detection gap: each vertex finds about 40 triangles of the
    other sheet, more than Newton's 32 pairs a vertex (and its edges more than 64 edges)."""
    bv, bf = box()
    a, fa = cloth(1.0, n=n, size=size)
    b, fb = cloth(1.0 + gap_m, n=n, size=size)
    sim = ClothSim(np.concatenate([a, b]), np.concatenate([fa, fb + len(a)]), bv, bf, self_contact=True,
                   iterations=2, bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]), self_contact_gap_m=0.02, **kwargs)
    return sim, bv


def test_self_contact_buffers_grow_until_no_pair_is_dropped():
    from core.sim import CONTACT_BUFFERS, ContactBuffers

    sim, bv = _stacked_sheets()
    assert sim.contact_buffers == CONTACT_BUFFERS
    steps = ContactBuffers(sim)
    before = sim.get_state()[0]
    points = steps.advance("frame 0", bv, bv, 1 / FPS, 1)
    found = sim.contact_overflow()  # the last detection, with the grown buffers
    assert not found["vertex_triangle"] and not found["edge_edge"]
    assert CONTACT_BUFFERS[0] < found["vertex_triangle_max"] <= sim.contact_buffers[0]
    assert CONTACT_BUFFERS[1] < found["edge_edge_max"] <= sim.contact_buffers[1]
    rep = steps.report()
    assert rep["grown"] and rep["grown"][0]["at"] == "frame 0" and rep["pairs_dropped_at"] == []
    assert rep["end"] == {"pairs_per_vertex": sim.contact_buffers[0], "pairs_per_edge": sim.contact_buffers[1]}
    # The step was re-run from its start with the new buffers: one step of the cloth, not two.
    rerun, _ = _stacked_sheets(contact_buffers=sim.contact_buffers)
    np.testing.assert_allclose(points, rerun.advance(bv, bv, 1 / FPS, 1), atol=1e-6)
    assert np.abs(points - before).max() < 0.01


def test_self_contact_buffers_stop_at_their_memory_cap_and_report_the_dropped_pairs(caplog):
    from core.sim import CONTACT_BUFFERS, ContactBuffers

    sim, bv = _stacked_sheets()
    steps = ContactBuffers(sim, sim.contact_buffer_bytes(CONTACT_BUFFERS) / 2**20)
    with caplog.at_level("WARNING", logger="core.sim"):
        for t in range(2):
            assert np.isfinite(steps.advance(f"frame {t}", bv, bv, 1 / FPS, 1)).all()
    assert sim.contact_buffers == CONTACT_BUFFERS
    assert steps.report()["pairs_dropped_at"] == ["frame 0", "frame 1"] and steps.report()["grown"] == []
    assert len(caplog.records) == 1 and "from frame 0 on" in caplog.records[0].getMessage()


def test_self_contact_filter_radius_is_the_detection_distance_capped_on_fine_meshes():
    from core.sim import SELF_CONTACT_FILTER_MAX_VERTICES, self_contact_filter_radius

    v, f = cloth(0.0, n=10, size=0.2)  # 2 cm edges
    assert self_contact_filter_radius(v, f, 0.023) == 0.023
    v, f = cloth(0.0, n=200, size=0.2)  # 1 mm edges: a disc of the cap holds the capped number of vertices
    r = self_contact_filter_radius(v, f, 0.023)
    assert r < 0.023 and np.pi * r**2 / (0.2**2 / 201**2) == pytest.approx(SELF_CONTACT_FILTER_MAX_VERTICES)


def test_self_contact_gap_allows_the_speed_with_margin_within_bounds():
    from core.sim import MAX_SELF_CONTACT_GAP_M, SELF_CONTACT_SPEED_MARGIN, cloth_speed_limit, self_contact_gap

    m, dt = Material(), 1 / 600
    gap = self_contact_gap(m, 2.0, dt)
    assert np.isclose(cloth_speed_limit(m, gap, dt), SELF_CONTACT_SPEED_MARGIN * 2.0)
    assert self_contact_gap(m, 0.0, dt) == m.self_contact_distance_m  # a still scene: the contact distance
    assert self_contact_gap(m, 1e4, dt) == MAX_SELF_CONTACT_GAP_M  # a teleport: bounded


def test_frame_checks_count_tunnelled_vertices_apart_from_pressed_ones():
    """Cloth pressed 3 mm into the body counts as penetrating (2 mm) but not as tunnelled (retry depth 5 mm)."""
    from core.garment import mesh_edges
    from core.sim import frame_checks

    bv, bf = box(half=(0.5, 0.5, 0.5))
    depths = np.array([-0.01, 0.003, 0.003, 0.008])  # metres inside the top face (negative: above it)
    points = np.stack([np.zeros(4), np.linspace(-0.2, 0.2, 4), 0.5 - depths], axis=1)
    faces = np.array([[0, 1, 2], [1, 2, 3]])
    edges = mesh_edges(faces)
    rest = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    c = frame_checks(points, bv, bf, edges, rest)
    assert c["penetration_share"] == 0.75 and c["tunnelled_share"] == 0.25
    assert c["finite"] and c["mean_strain"] == 0.0
    c = frame_checks(points, bv, bf, edges, rest, tunnel_depth=0.0025)
    assert c["tunnelled_share"] == 0.75


def test_self_contact_does_not_hold_back_a_garment_riding_a_walking_body():
    """A body travelling at 1.5 m/s (a walk) carries its garment; self-contact must not change that.

    Newton caps every vertex's move per substep when self-contact is on (0.77 m/s with the contact distance
    as the detection gap); the simulator runs in a frame that follows the root's translation, so the cap
    bounds motion relative to the body, and sizes the gap for that motion. The shell never touches itself:
    with self-contact forced on, it must move as without. (No ground: the shell reaches below the body's lowest
    point, and a body sliding over the ground drags the cloth it pinches there.)"""
    from core.scene import parse_no_skip

    body, garment, _ = _shell_scene()
    n = 8
    poses = np.zeros((n, 24, 3), np.float32)
    poses[:, 0] = [np.pi / 2, 0, 0]
    trans = np.zeros((n, 3), np.float32)
    trans[:, 0] = 1.5 * np.arange(n) / FPS
    motion = Motion(poses=poses, trans=trans, fps=FPS, name="travel", n_settle=1)
    out = {}
    for contact in (False, True):
        d = SimDeformer(options=SimOptions(settle_s=0.1, self_contact=contact, floor="none"))
        d.skips = parse_no_skip(["all"])
        out[contact] = d.deform(garment, body, motion)
        assert not d.report["retries"]
    # The frame's velocity jumps by 1.5 m/s as the body sets off: the detection distance allows that, with margin.
    assert d.report["self_contact"]["cloth_speed_limit_m_s"] >= 1.5 * 1.5 - 1e-6
    travelled = (out[False][-1] - out[False][0]).mean(axis=0)[0]
    assert abs(travelled - trans[-1, 0]) < 0.05, travelled  # it keeps up (sloshing as the body sets off)
    assert np.abs(out[True] - out[False]).max() < 2e-3


def test_native_stderr_filter_drops_only_the_named_line_and_passes_the_rest(capfd):
    """C code writes to file descriptor 2 directly: the filter must catch it there, keep other lines, and
    restore the descriptor even when the call fails."""
    from core.sim import filter_native_stderr

    def noisy():
        os.write(2, b"Warp CUDA warning: no driver here\nsomething else went wrong\n")
        return 7

    assert filter_native_stderr(noisy, b"no driver here") == 7
    err = capfd.readouterr().err
    assert "something else went wrong" in err and "no driver here" not in err

    def failing():
        os.write(2, b"last words\n")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        filter_native_stderr(failing, b"no driver here")
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "last words\nafter\n"


def test_starting_the_simulator_prints_no_cuda_driver_warning_on_a_cpu_machine():
    """warp's native init says it found no NVIDIA driver on every CPU-only run; the simulator just runs on
    the CPU (its report says so), so the line is noise in every bake, tradeoff and dataset log."""
    import subprocess
    import sys

    code = "from core.sim import _warp; wp = _warp(); print(wp.is_cuda_available())"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         cwd=Path(__file__).resolve().parents[2])
    assert run.returncode == 0, run.stderr
    assert "NVIDIA CUDA driver" not in run.stderr


def test_non_manifold_edges_are_counted_and_said_once(caplog):
    """A grid with three flaps sewn on along one of its edges each: three edges shared by three faces. One warning
    of ours with the count, none of Newton's per-edge ones."""
    import warnings

    from core.sim import non_manifold_edge_count

    bv, bf = box()
    v, f = cloth(1.0, n=6, size=0.1)
    flaps = [f[k][[0, 2]] for k in (0, 10, 20)]  # each quad's diagonal: already shared by its two triangles
    extra_v = np.array([(v[a] + v[b]) / 2 + [0, 0, 0.01] for a, b in flaps])
    extra_f = np.array([[a, b, len(v) + i] for i, (a, b) in enumerate(flaps)])
    faces = np.concatenate([f, extra_f])
    assert non_manifold_edge_count(f) == 0 and non_manifold_edge_count(faces) == 3
    with caplog.at_level(logging.WARNING), warnings.catch_warnings(record=True) as raised:
        warnings.simplefilter("always")
        sim = ClothSim(np.concatenate([v, extra_v]), faces, bv, bf, iterations=2,
                       bounds=np.array([[-1, -1, -1], [1, 1, 2.0]]))
    assert sim.non_manifold_edges == 3
    assert caplog.text.count("3 garment edges are shared by more than two faces") == 1
    assert not [w for w in raised if "non-manifold" in str(w.message)]


def _cut_above(garment: Garment, y_min: float, name: str) -> Garment:
    """The faces of `garment` whose corners all lie above rest height `y_min` (metres, the body's Y-up)."""
    kept = garment.faces[(garment.vertices[garment.faces][:, :, 1] > y_min).all(axis=1)]
    used = np.unique(kept)
    return Garment(garment.vertices[used], np.searchsorted(used, kept), name=name)


def test_a_garment_down_to_the_soles_rests_on_the_ground(caplog):
    """The shell wraps the tiny body 2 cm out, so it reaches 2 cm below its soles. With the floor (the default)
    it stands on the ground, the plane through the body's lowest point: its lowest vertex, authored below it, is
    lifted onto it at the start and nothing sinks more than the cloth's pinch under the body; with `floor none`
    it hangs through (and is warned about). The shell's upper half never comes near the ground: skipped."""
    from core.scene import parse_no_skip

    body, garment, motion = _shell_scene()
    d = SimDeformer(options=SimOptions(settle_s=0.1, max_retries=0))
    with caplog.at_level(logging.WARNING):
        out = d.deform(garment, body, motion)
    ground = float(body.v_template[:, 1].min())  # the Y-up body turned Z-up, standing still at the origin
    assert d.report["floor"]["ground_z_m"] == pytest.approx(ground, abs=1e-6)
    assert d.report["floor"]["lifted_onto_it_at_start"] == int(np.sum(garment.vertices[:, 1] < ground + 0.004))
    assert d.scene["floor"]["skipped_work"] is False
    assert d.scene["floor"]["garment_lowest_above_ground_m"] < 0
    # Below the ground: only the vertex pinched between it and the body's lowest point (on the vertical axis),
    # pressed in by the body from above, less than a centimetre.
    sunk = out[..., 2] < ground - 0.001
    assert np.all(np.linalg.norm(out[..., :2], axis=-1)[sunk] < 0.01) and sunk.sum(axis=1).max() <= 1
    assert out[..., 2].min() > ground - 0.01
    assert "floor" not in caplog.text
    assert d.report["hem_above_soles_m"] == pytest.approx(garment.vertices[:, 1].min() - body.v_template[:, 1].min())
    caplog.clear()
    d = SimDeformer(options=SimOptions(settle_s=0.1, max_retries=0, floor="none"))
    with caplog.at_level(logging.WARNING):
        out = d.deform(garment, body, motion)
    assert "2.0 cm below the body's soles at rest, and the floor is off" in caplog.text
    assert d.report["floor"] is None and d.scene["floor"]["reason"] == "floor none"
    assert out[..., 2].min() < ground - 0.03 and (out[..., 2] < ground - 0.001).sum(axis=1).min() >= 3
    caplog.clear()
    top = _cut_above(garment, 0.0, "top")
    with caplog.at_level(logging.WARNING):
        d = SimDeformer(options=SimOptions(settle_s=0.0, max_retries=0))
        d.deform(top, body, motion)
    assert d.scene["floor"]["skipped_work"] is True and d.report["floor"] is None
    assert d.scene["floor"]["garment_lowest_above_ground_m"] > 0.7
    assert "floor" not in caplog.text
    d.skips = parse_no_skip(["floor"])  # the ground anyway
    d.deform(top, body, motion)
    assert d.scene["floor"]["overridden"] and not d.scene["floor"]["skipped_work"]
    assert d.report["floor"] == {"ground_z_m": pytest.approx(ground, abs=1e-6), "lowest_z_m": pytest.approx(ground, abs=1e-6),
                                 "lifted_onto_it_at_start": 0}


def test_a_ground_the_cloth_does_not_touch_changes_nothing():
    """The shell cut 2.5 cm above the soles (its lowest vertices 2.9 cm above them) comes within reach of the
    ground (10 cm), so the ground is simulated, but the cloth never touches it: the same cloth as without."""
    body, garment, motion = _shell_scene()
    ground = float(body.v_template[:, 1].min())
    skirt = _cut_above(garment, ground + 0.025, "long")
    runs = {}
    for floor in ("auto", "none"):
        d = SimDeformer(options=SimOptions(settle_s=0.1, max_retries=0, floor=floor))
        runs[floor] = d.deform(skirt, body, motion)
        assert (d.report["floor"] is not None) == (floor == "auto")
    assert np.abs(runs["auto"] - runs["none"]).max() < 1e-5


def test_cloth_dropped_on_the_ground_lands_on_it_and_friction_carries_it_with_the_ground():
    """ClothSim's ground plane: a cloth dropped 3 cm onto it stops at the contact distance above it; a ground
    moving at 1 m/s (as in the simulator's moving frame) drags it along by friction, a still one does not."""
    m = Material()
    bv, bf = box(half=(0.05, 0.05, 0.05), center=(0.0, 0.0, 3.0))  # the body, far above
    cv, cf = cloth(0.03, n=6, size=0.2)
    bounds = np.array([[-1, -1, -1], [1, 1, 4.0]])
    moved = {}
    for speed in (0.0, 1.0):
        sim = ClothSim(cv, cf, bv, bf, m, iterations=10, bounds=bounds, floor_z=np.zeros(2))
        x = cv
        for _ in range(15):  # 0.5 s: falls 3 cm in 0.08 s, then lies on the ground
            x = sim.advance(bv, bv, 1 / FPS, 10, floor=(0.0, 0.0, np.zeros(3)))
        assert np.abs(x[:, 2] - m.contact_distance_m).max() < 1.5e-3
        start = x.copy()
        for _ in range(6):
            x = sim.advance(bv, bv, 1 / FPS, 10, floor=(0.0, 0.0, np.array([speed, 0.0, 0.0])))
        moved[speed] = float(np.mean(x[:, 0] - start[:, 0]))
        assert np.all(x[:, 2] > 0.0)
    assert abs(moved[0.0]) < 1e-3
    # Kinetic friction (0.3 g) brings the cloth up to the ground's speed within 0.34 s: over 0.2 s it moves
    # 0.3 * 9.81 * 0.2^2 / 2 = 5.9 cm.
    assert 0.03 < moved[1.0] < 0.2


def _with_patch(garment: Garment, centre, half=0.02, n=4) -> Garment:
    """`garment` and a flat square patch (a pocket) of side 2 `half` in the XY plane at `centre`, not joined to it."""
    v, f = grid(n, n, 2 * half)
    v = v - [half, half, 0.0] + np.asarray(centre)
    return Garment(np.concatenate([garment.vertices, v]).astype(np.float32),
                   np.concatenate([garment.faces, f + garment.n_vertices]), name="patched")


def test_small_pieces_are_the_detached_ones_under_two_percent_of_the_area():
    from core.sim import small_pieces

    big_v, big_f = grid(10, 10, 1.0)  # 1 m^2
    cloth_ = Garment(big_v.astype(np.float32), big_f, name="sheet")
    assert small_pieces(cloth_)[1].size == 0
    patched = _with_patch(_with_patch(cloth_, (0.5, 0.5, 0.1), half=0.05), (0.5, 0.5, 0.2), half=0.2)
    labels, small = small_pieces(patched)
    assert labels.max() == 2  # three pieces
    n = cloth_.n_vertices
    np.testing.assert_array_equal(small, np.arange(n, n + 25))  # the 10 cm patch (1 %), not the 40 cm one (14 %)
    assert small_pieces(patched, share=0.2)[1].size == 50


def test_a_small_detached_piece_follows_the_body_or_falls_and_stops_the_bake(caplog):
    """A 4 cm pocket modelled apart, 5 mm off the shell's chest: with pin auto it is pinned whole (said once, and
    reported) and rides with the body; with pin none nothing holds it, it falls, and the bake stops naming the
    piece (the garment's median distance alone never moves)."""
    body, garment, motion = _shell_scene()
    front = 0.15 * np.sqrt(1 - (0.3 / 0.8) ** 2) + 0.02 + 0.005
    patched = _with_patch(garment, (0.0, 0.3, front))
    patch = np.arange(garment.n_vertices, patched.n_vertices)
    with caplog.at_level(logging.WARNING):
        d = SimDeformer(options=SimOptions(settle_s=1.0, max_retries=0))
        out = d.deform(patched, body, motion)
    assert caplog.text.count("1 piece of the garment (25 vertices) is not joined to the rest of the cloth") == 1
    assert d.report["pieces"] == {"count": 2, "small_pinned_vertices": 25}
    assert d.report["pinned_vertices"] == 25  # the shell has no waistband
    # Pinned, it stays where skinning puts it: on the chest, 2.5 cm off the body.
    assert np.abs(out[:, patch, 2].mean(axis=1) - out[0, patch, 2].mean()).max() < 0.01
    with pytest.raises(SimulationError, match=r"piece 2 of 2 \(25 vertices, not joined to the rest\) fell or slid "
                                              r"off the body"):
        # (No ground: the shell reaches below the soles, so the ground is simulated, and the pocket would land on it.)
        SimDeformer(options=SimOptions(settle_s=1.0, max_retries=0, pin="none", floor="none")).deform(patched, body,
                                                                                                    motion)
    # With the ground it lands by the feet, near the body: it is more than 1 m from where skinning puts it.
    with pytest.raises(SimulationError, match=r"piece 2 of 2 \(25 vertices, not joined to the rest\) fell or slid "
                                              r"down the body: its median distance from where skinning puts it is "
                                              r"1\d\d cm \(over 50 cm\); --pin auto holds waistbands and small pieces"):
        SimDeformer(options=SimOptions(settle_s=1.0, max_retries=0, pin="none")).deform(patched, body, motion)
    # The pocket alone, one piece that nothing holds (no waistband, no shoulders): it falls, and the error says why
    # and what to do (it said only that the garment fell or slid down the body)
    alone = Garment(patched.vertices[patch], patched.faces[patched.faces.min(axis=1) >= garment.n_vertices]
                    - garment.n_vertices, name="pocket")
    with pytest.raises(SimulationError, match=r"the garment fell or slid down the body: .*; nothing held it: no "
                                              r"waistband to pin, and it hangs from no shoulders .*--method model "
                                              r"or lbs"):
        SimDeformer(options=SimOptions(settle_s=1.0, max_retries=0)).deform(alone, body, motion)


def test_a_failure_after_a_jump_of_the_body_names_it_and_the_split():
    """A 10 m teleport or a 180-degree flip of the root stops the simulator a few frames later with one line that
    said nothing of the jump: it names the frame and the speed, and --frames (`_cut_before`); a human motion's
    fastest vertex (a throw, 20 m/s) is not called one."""
    from core.sim import _cut_before

    rng = np.random.default_rng(0)
    body = np.cumsum(rng.normal(scale=0.002, size=(14, 50, 3)), axis=0)  # about 0.1-0.3 m/s at 30 fps
    body[7:] += [10.0, 0.0, 0.0]  # frame 7 (output frame 5 after 2 lead frames) 10 m away
    assert _cut_before(body, 2, 7, 30.0) == ("; the body moved 10.00 m in one frame at frame 5 (300 m/s: a teleport "
                                             "or a cut in the capture?): bake the parts before and after it apart "
                                             "with --frames")
    assert _cut_before(body, 2, 2, 30.0) == ""  # the jump comes after the failing frame
    assert _cut_before(body, 2, 9, 30.0).startswith("; the body moved 10.00 m")  # CUT_LOOKBACK frames before it
    assert _cut_before(body, 2, 10, 30.0) == ""  # more
    throw = body.copy()
    throw[5:] += [0.6, 0.0, 0.0]  # 18 m/s: a hand in a throw
    assert _cut_before(throw, 2, 4, 30.0) == ""
