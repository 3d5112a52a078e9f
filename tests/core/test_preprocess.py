"""preprocess_garment: the bundle, its cache (keyed by mesh, settings and body) and the array round trip."""

import dataclasses

import numpy as np
import pytest

from core.errors import InputError
from core.garment import Garment
from core.preprocess import body_key, from_arrays, preprocess_garment, to_arrays
from formats.cache import CACHE_ENV, cache_path, default_cache_dir, read_cache, write_cache
from tests.core.preprocess_meshes import EXAMPLES, NO_EXAMPLES, example_garments
from tests.meshes import tiny_body


@pytest.fixture(scope="module")
def body():
    return tiny_body()


@pytest.fixture(scope="module")
def shell(body):
    from core.geometry import vertex_normals

    v = body.v_template + 0.02 * vertex_normals(body.v_template, body.faces)
    return Garment(vertices=v.astype(np.float32), faces=body.faces, name="shell")


def assert_same(a, b):
    aa, bb = to_arrays(a), to_arrays(b)
    assert aa.keys() == bb.keys()
    for k in aa:
        np.testing.assert_array_equal(aa[k], bb[k], err_msg=k)


def test_bundle_contents(body, shell):
    p = preprocess_garment(shell, body, levels=2, n_landmarks=16)
    V = shell.n_vertices
    assert p.features.positions.shape == (V, 3) and p.features.joint_distances.shape == (V, body.n_joints)
    assert p.hierarchy.n_levels == 2 and p.hierarchy.components == [1, 1, 1]
    assert p.descriptor.eigenvalues.shape == (16,) and len(p.descriptor.landmarks) == 16
    assert p.n_components == 1 and not p.cache_hit
    near = p.collision_near
    assert near.shape == (V, V) and (near != near.T).nnz == 0 and near.diagonal().sum() == 0


def test_cache_hit_returns_identical_arrays(body, shell, tmp_path):
    a = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    b = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    assert not a.cache_hit and b.cache_hit and a.key == b.key
    assert_same(a, b)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    assert not list(tmp_path.glob("*.partial*"))


def test_a_cache_entry_that_cannot_be_stored_is_warned_about_where_the_cache_is_optional(body, shell, tmp_path,
                                                                                         monkeypatch, caplog):
    """A full disk under the cache (ENOSPC while the entry is written): `garment preprocess`, whose work is the
    entry, stops with one line naming it; a bake or training (cache_optional) warns and goes on with the result,
    the same as computed without a cache; no partial entry is left."""
    import logging

    import formats.cache

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(formats.cache.np, "savez", disk_full)
    with pytest.raises(InputError, match=r"output '.*preprocess-.*\.npz': could not be written \(No space left"):
        preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    with caplog.at_level(logging.WARNING):
        p = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path, cache_optional=True)
    assert "No space left on device" in caplog.text and "used without being cached" in caplog.text
    assert_same(p, preprocess_garment(shell, body, n_landmarks=16))
    assert list(tmp_path.iterdir()) == []


def test_changed_mesh_settings_or_body_are_never_served_stale(body, shell, tmp_path):
    base = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    moved = shell.vertices.copy()
    moved[5] += 0.001
    g2 = dataclasses.replace(shell, vertices=moved)
    p = preprocess_garment(g2, body, n_landmarks=16, cache_dir=tmp_path)
    assert not p.cache_hit and p.key != base.key
    np.testing.assert_array_equal(p.features.positions[5], moved[5])
    for kw in ({"levels": 3}, {"n_landmarks": 17}, {"seed": 1}, {"collision_radius_m": 0.05},
               {"betas": np.array([1.0, 0, 0, 0])}):
        q = preprocess_garment(shell, body, **{"n_landmarks": 16, **kw}, cache_dir=tmp_path)
        assert not q.cache_hit, kw
    assert body_key(body, None) != body_key(body, np.array([1.0, 0, 0, 0]))
    assert preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path).cache_hit


def test_an_entry_an_earlier_computation_wrote_is_recomputed(body, shell, tmp_path, monkeypatch):
    """A package of another `PREPROCESS_REVISION` (its landmarks chosen otherwise) does not read this one's
    entries, nor this one its."""
    import core.preprocess as P

    assert not preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path).cache_hit
    assert preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path).cache_hit
    monkeypatch.setattr(P, "PREPROCESS_REVISION", P.PREPROCESS_REVISION - 1)
    assert not preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path).cache_hit


def test_a_foreign_or_broken_entry_is_recomputed(body, shell, tmp_path):
    p = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    path = cache_path(tmp_path, "preprocess", p.key)
    path.write_bytes(b"not a zip file")
    q = preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path)
    assert not q.cache_hit
    assert_same(p, q)
    # An entry at the right path written for other key fields (a hash collision, a hand copy) is a miss.
    write_cache(path, to_arrays(p), {"garment": "other"})
    assert not preprocess_garment(shell, body, n_landmarks=16, cache_dir=tmp_path).cache_hit


def test_cache_version_stamp(tmp_path, monkeypatch):
    import formats.cache as fc

    path = write_cache(tmp_path / "x.npz", {"a": np.arange(3)}, {"k": 1})
    np.testing.assert_array_equal(read_cache(path, {"k": 1})["a"], [0, 1, 2])
    assert read_cache(path, {"k": 2}) is None
    monkeypatch.setattr(fc, "CACHE_FORMAT_VERSION", fc.CACHE_FORMAT_VERSION + 1)
    assert read_cache(path, {"k": 1}) is None
    assert read_cache(tmp_path / "missing.npz", {"k": 1}) is None


def test_default_cache_dir_honours_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "garment"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / ".cache" / "garment"


def test_a_home_that_does_not_exist_is_not_made_for_the_cache(tmp_path, monkeypatch, caplog):
    """HOME=/nonexistent (a container's, a service account's): the cache went there, the home made anew as root."""
    import tempfile
    from pathlib import Path

    monkeypatch.delenv(CACHE_ENV, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "nonexistent"))
    with caplog.at_level("WARNING"):
        path = default_cache_dir()
        assert default_cache_dir() == path
    assert path.parent == Path(tempfile.gettempdir()) and path.name.startswith("garment-cache-")
    said = [r.getMessage() for r in caplog.records if "does not exist" in r.getMessage()]
    assert said == [f"home directory '{tmp_path / 'nonexistent'}' does not exist: caches in '{path}' "
                    "(set GARMENT_CACHE_DIR to keep them elsewhere)"]
    assert not (tmp_path / "nonexistent").exists()


def test_round_trip_without_collision_set(body, shell):
    p = preprocess_garment(shell, body, levels=1, n_landmarks=8, collision_radius_m=0.0)
    assert p.collision_near is None
    q = from_arrays(to_arrays(p), p.settings, p.key, p.garment_hash, p.body_key)
    assert_same(p, q)
    assert q.collision_near is None


@pytest.mark.parametrize("kw, word", [({"levels": -1}, "levels"), ({"levels": 9}, "levels"),
                                      ({"n_landmarks": 1}, "landmarks"), ({"sigma_m": 0.0}, "sigma"),
                                      ({"n_eigenvalues": 0}, "eigenvalues"),
                                      ({"collision_radius_m": float("nan")}, "collision")])
def test_bad_settings_raise_one_line_input_errors(body, shell, kw, word):
    with pytest.raises(InputError, match=word) as exc:
        preprocess_garment(shell, body, **kw)
    assert "\n" not in str(exc.value)


@pytest.mark.skipif(not EXAMPLES, reason=NO_EXAMPLES)
def test_example_garments_preprocess_on_the_default_body():
    from core.body import default_body

    body = default_body()
    for name, g in example_garments().items():
        p = preprocess_garment(g, body, collision_radius_m=0.0)
        assert p.hierarchy.components == [p.n_components] * 3, name
        assert np.isfinite(p.descriptor.eigenvalues).all() and p.descriptor.eigenvalues[0] > 0
        assert (p.features.joint_distances > 0).all()
