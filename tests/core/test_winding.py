"""Faces wound alike (core.garment.consistent_winding) and garments facing away from the body
(core.skinning.oriented_outward), against a naive walk over the faces."""

import logging
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from core.garment import Garment, consistent_winding
from tests.meshes import grid

ROOT = Path(__file__).resolve().parents[2]


def naive_winding(faces):
    """Breadth-first from each piece's smallest face over edges exactly two faces share, one face at a time."""
    faces = [list(f) for f in np.asarray(faces)]
    users = {}
    for k, f in enumerate(faces):
        for i in range(3):
            users.setdefault(frozenset((f[i], f[(i + 1) % 3])), []).append(k)
    out, seen = [list(f) for f in faces], [False] * len(faces)
    for start in range(len(faces)):
        if seen[start]:
            continue
        seen[start] = True
        queue = deque([start])
        while queue:
            k = queue.popleft()
            f = out[k]
            for i in range(3):
                a, b = f[i], f[(i + 1) % 3]
                pair = users[frozenset((a, b))]
                if len(pair) != 2:
                    continue
                other = pair[0] if pair[1] == k else pair[1]
                if seen[other]:
                    continue
                seen[other] = True
                g = out[other]
                if any(g[j] == a and g[(j + 1) % 3] == b for j in range(3)):  # runs a->b too: wound against f
                    out[other] = [g[0], g[2], g[1]]
                queue.append(other)
    return np.array(out, dtype=np.int64)


def _scrambled(faces, seed, share=0.4):
    rng = np.random.default_rng(seed)
    turn = rng.random(len(faces)) < share
    out = faces.copy()
    out[turn] = out[turn][:, [0, 2, 1]]
    return out


@pytest.mark.parametrize("seed", range(4))
def test_consistent_winding_matches_a_naive_walk(seed):
    """Two grids (one with a hole), a fin of three faces on one edge, scrambled windings: the same faces as the
    naive walk (BFS trees differ, the parity does not); every shared edge then run both ways."""
    _, a = grid(6, 5)
    _, b = grid(4, 4)
    b = b[np.arange(len(b)) != 7] + a.max() + 1  # a hole
    fin = np.array([[0, 1, a.max() + b.max() + 50]])  # a third face on grid a's edge 0-1
    faces = _scrambled(np.concatenate([a, b, fin]), seed)
    got, piece = consistent_winding(faces)
    np.testing.assert_array_equal(got, naive_winding(faces))
    assert len(np.unique(piece)) >= 2
    directed = np.concatenate([got[:, [0, 1]], got[:, [1, 2]], got[:, [2, 0]]])
    _, inverse, uses = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    two = uses[inverse.ravel()] == 2  # every edge two faces share is run both ways, once each
    assert len(np.unique(directed[two], axis=0)) == two.sum() and two.sum() > len(directed) // 2


@pytest.mark.parametrize("turn", ["all", "half"])
def test_a_garment_facing_the_body_or_wound_unevenly_is_turned_back_with_a_warning(turn, caplog):
    """The example dress with every face turned (it faces the body) or those right of x = 0 turned: turned back
    to the file's own faces exactly, face UVs with them, one warning; the example garments as they are change
    nothing."""
    from core.body import default_body
    from core.skinning import oriented_outward
    from formats.obj import read_garment

    body = default_body()
    dress = read_garment(ROOT / "examples" / "dress.obj")
    assert oriented_outward(dress, body) is dress
    turned = np.ones(dress.n_faces, bool) if turn == "all" else dress.vertices[dress.faces[:, 0], 0] > 0
    faces, face_uvs = dress.faces.copy(), dress.face_uvs.copy()
    faces[turned], face_uvs[turned] = faces[turned][:, [0, 2, 1]], face_uvs[turned][:, [0, 2, 1]]
    inward = Garment(dress.vertices, faces, dress.uvs, face_uvs, name="inward")
    with caplog.at_level(logging.WARNING):
        back = oriented_outward(inward, body, "inward.obj")
    np.testing.assert_array_equal(back.faces, dress.faces)
    np.testing.assert_array_equal(back.face_uvs, dress.face_uvs)
    needle = "1 of its 1 pieces faced the body" if turn == "all" else "wound against their neighbours"
    assert f"garment mesh 'inward.obj': {int(turned.sum()):,} of its {dress.n_faces:,} faces turned" in caplog.text
    assert needle in caplog.text and "the file is left as it is" in caplog.text


def _thickened(garment, thickness=0.005):
    """`garment` (one open piece facing out) given thickness as Blender's Solidify does: an inner layer
    `thickness` behind it, wound the other way, joined to it along its rims: one closed piece."""
    from core.geometry import vertex_normals

    V = garment.n_vertices
    inner = garment.vertices - thickness * vertex_normals(garment.vertices, garment.faces)
    directed = np.stack([garment.faces, np.roll(garment.faces, -1, axis=1)], axis=2).reshape(-1, 2)
    key = np.sort(directed, axis=1)
    _, edge, uses = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    rim = directed[uses[edge.reshape(-1)] == 1]  # boundary half-edges a -> b
    a, b = rim[:, 0], rim[:, 1]
    faces = np.concatenate([garment.faces, garment.faces[:, ::-1] + V, np.stack([b, a, a + V], 1),
                            np.stack([b, a + V, b + V], 1)])
    return Garment(np.concatenate([garment.vertices, inner]).astype(np.float32), faces, name="thick")


def test_a_garment_given_thickness_reads_as_cloth_facing_out_on_both_layers(caplog):
    """The example skirt given 5 mm of thickness (a closed piece of two layers): every face of both layers turned
    away from the body on its own, with a warning naming the closed piece (read as one piece, the inner layer faced
    the body and the model pushed it out through the outer one: layers 27-35 mm apart, up to 13 cm); the layers'
    vertex normals then agree."""
    from core.body import default_body
    from core.geometry import vertex_normals
    from core.skinning import oriented_outward
    from formats.obj import read_garment

    body = default_body()
    skirt = read_garment(ROOT / "examples" / "skirt.obj")
    thick = _thickened(skirt)
    assert consistent_winding(thick.faces)[1].max() == 0  # one piece, wound alike
    with caplog.at_level(logging.WARNING):
        out = oriented_outward(thick, body, "thick.obj")
    assert "of closed pieces facing both ways (cloth given thickness? buttons?) faced the body" in caplog.text
    V = skirt.n_vertices
    np.testing.assert_array_equal(out.faces[:skirt.n_faces], skirt.faces)  # the outer layer as it was
    normals = vertex_normals(out.vertices, out.faces)
    agree = np.einsum("vc,vc->v", normals[:V], normals[V:])
    assert np.median(agree) > 0.95 and (agree > 0).mean() > 0.97
