"""formats/body.py: SMPL-format .npz and chumpy .pkl files, built in code, and every bad input."""

from __future__ import annotations

import logging
import pickle
import sys
import types
from contextlib import contextmanager

import numpy as np
import pytest
import scipy.sparse
import torch

from core.body import SMPL_PARENTS, default_body
from core.errors import InputError
from formats.body import load_body

V = 30


def smpl_arrays(n_joints: int = 24, n_betas: int = 10, seed: int = 0) -> dict:
    """A tiny random SMPL-format model as the official files lay it out."""
    rng = np.random.default_rng(seed)
    J = n_joints
    parents = list(SMPL_PARENTS) + [int(rng.integers(0, j)) for j in range(24, J)]
    kintree = np.array([parents, list(range(J))], dtype=np.int64)
    kintree[0, 0] = 2**32 - 1  # how the official files store the root's parent
    weights = rng.random((V, J)) ** 4
    weights /= weights.sum(1, keepdims=True)
    Jr = rng.random((J, V)) * (rng.random((J, V)) < 0.2)
    Jr[:, 0] += 1e-3
    Jr /= Jr.sum(1, keepdims=True)
    return {
        "v_template": rng.normal(size=(V, 3)) * 0.3,
        "shapedirs": rng.normal(size=(V, 3, n_betas)) * 0.01,
        "posedirs": rng.normal(size=(V, 3, 9 * (J - 1))) * 0.01,
        "J_regressor": Jr,
        "weights": weights,
        "kintree_table": kintree,
        "f": rng.integers(0, V, size=(40, 3)).astype(np.uint32),
        "gender": "neutral",
    }


class _Ch:
    """Stand-in for chumpy.ch.Ch while dumping: its pickled state is {'x': array, ...}."""

    def __init__(self, x):
        self.x = x
        self._dirty_vars = set()


@contextmanager
def _fake_chumpy():
    """Register modules 'chumpy' and 'chumpy.ch' (holding `_Ch` as `Ch`) only while dumping."""
    _Ch.__module__, _Ch.__qualname__, _Ch.__name__ = "chumpy.ch", "Ch", "Ch"
    pkg, mod = types.ModuleType("chumpy"), types.ModuleType("chumpy.ch")
    mod.Ch = _Ch
    pkg.ch = mod
    saved = {k: sys.modules.get(k) for k in ("chumpy", "chumpy.ch")}
    sys.modules.update({"chumpy": pkg, "chumpy.ch": mod})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v


def write_pkl(path, arrays: dict) -> None:
    """Write like the official SMPL pickles: chumpy arrays, a scipy.sparse J_regressor, protocol 2."""
    data = dict(arrays)
    with _fake_chumpy():
        for key in ("v_template", "shapedirs", "posedirs"):
            data[key] = _Ch(arrays[key])
        data["J_regressor"] = scipy.sparse.csc_matrix(arrays["J_regressor"])
        with open(path, "wb") as fh:
            pickle.dump(data, fh, protocol=2)
    assert "chumpy" not in sys.modules


def write_npz(path, arrays: dict) -> None:
    np.savez(path, **{k: v for k, v in arrays.items() if k != "gender"})


def assert_body_matches(body, arrays):
    np.testing.assert_allclose(body.v_template, arrays["v_template"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(body.shapedirs, arrays["shapedirs"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(body.posedirs, arrays["posedirs"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(body.J_regressor, arrays["J_regressor"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(body.weights, arrays["weights"], rtol=1e-6, atol=1e-7)
    assert body.parents.tolist() == [-1] + arrays["kintree_table"][0, 1:].tolist()
    np.testing.assert_array_equal(body.faces, arrays["f"].astype(np.int64))
    for a in (body.v_template, body.shapedirs, body.J_regressor, body.weights):
        assert a.dtype == np.float32


def test_npz_round_trip(tmp_path):
    arrays = smpl_arrays()
    write_npz(tmp_path / "m.npz", arrays)
    body = load_body(tmp_path / "m.npz")
    assert_body_matches(body, arrays)
    assert body.name == "m" and body.layout == "smpl" and body.n_betas == 10


def test_chumpy_pkl_loads_without_chumpy_and_matches_npz(tmp_path):
    arrays = smpl_arrays(seed=1)
    write_pkl(tmp_path / "basicModel.pkl", arrays)
    write_npz(tmp_path / "basicModel.npz", arrays)
    from_pkl = load_body(tmp_path / "basicModel.pkl")
    from_npz = load_body(tmp_path / "basicModel.npz")
    assert "chumpy" not in sys.modules
    assert_body_matches(from_pkl, arrays)
    # Same model either way: pose both.
    pose = np.random.default_rng(2).normal(scale=0.4, size=(3, 24, 3))
    betas = np.linspace(-1, 1, 10)
    v1, j1 = from_pkl.pose(pose, betas=betas)
    v2, j2 = from_npz.pose(pose, betas=betas)
    np.testing.assert_allclose(v1, v2, atol=1e-6)
    np.testing.assert_allclose(j1, j2, atol=1e-6)


@pytest.mark.parametrize("n_joints,layout", [(52, "smplh"), (55, "smplx")])
def test_hand_families_load(tmp_path, n_joints, layout):
    arrays = smpl_arrays(n_joints=n_joints, n_betas=16)
    write_pkl(tmp_path / "h.pkl", arrays)
    body = load_body(tmp_path / "h.pkl")
    assert body.layout == layout and body.n_joints == n_joints and body.n_betas == 16
    assert_body_matches(body, arrays)


def test_a_body_converted_naively_or_misnamed_is_read_or_named_for_what_it_is(tmp_path):
    """An official pickle's dict given to np.savez (its scipy.sparse J_regressor a pickled object: it was called
    no .npz archive), a flattened shapedirs (reported with an axis the file lacks), and a body .npz named .pkl (an
    UnpicklingError): one line naming the key, the file's own shape; the misnamed one reads."""
    import scipy.sparse

    arrays = smpl_arrays()
    np.savez(tmp_path / "converted.npz", **{**arrays, "J_regressor": np.array(scipy.sparse.csc_matrix(
        arrays["J_regressor"]), dtype=object)})
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "converted.npz")
    _one_line(e, "converted.npz", "expected 'J_regressor' as a numeric array, got a pickled object", ".toarray()")
    np.savez(tmp_path / "flat.npz", **{**arrays, "shapedirs": arrays["shapedirs"].reshape(V * 3, 10)})
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "flat.npz")
    _one_line(e, "flat.npz", f"expected shapedirs of shape (V={V}, 3, S), got ({V * 3}, 10)")
    write_npz(tmp_path / "body.npz", arrays)
    (tmp_path / "body.pkl").write_bytes((tmp_path / "body.npz").read_bytes())
    assert_body_matches(load_body(tmp_path / "body.pkl"), arrays)


@pytest.mark.parametrize("n_dirs, n_shape", [(400, 300), (20, 10)])
def test_smplx_expression_dirs_are_dropped(tmp_path, caplog, n_dirs, n_shape):
    """SMPL-X 1.1's 300 shape + 100 expression directions, SMPL-X 1.0's 10 + 10 (a motion's betas 11-16 moved the
    face as shape); an SMPL body of 20 betas keeps them all."""
    arrays = smpl_arrays(n_joints=55, n_betas=n_dirs)
    write_npz(tmp_path / "SMPLX_NEUTRAL.npz", arrays)
    with caplog.at_level(logging.INFO, logger="formats.body"):
        body = load_body(tmp_path / "SMPLX_NEUTRAL.npz")
    assert body.n_betas == n_shape
    np.testing.assert_allclose(body.shapedirs, arrays["shapedirs"][:, :, :n_shape], rtol=1e-6)
    assert any(f"first {n_shape}" in r.getMessage() for r in caplog.records)
    write_npz(tmp_path / "smpl20.npz", smpl_arrays(n_betas=20))
    assert load_body(tmp_path / "smpl20.npz").n_betas == 20


def test_default_body_file_reads_as_smpl_format():
    from importlib import resources

    with resources.as_file(resources.files("core.assets").joinpath("default_body.npz")) as path:
        body = load_body(path)
    ref = default_body()
    np.testing.assert_array_equal(body.v_template, ref.v_template)
    np.testing.assert_array_equal(body.J_regressor, ref.J_regressor)
    np.testing.assert_array_equal(body.weights, ref.weights)
    assert body.parents.tolist() == ref.parents.tolist()


def _one_line(exc_info, *needles):
    msg = str(exc_info.value)
    assert "\n" not in msg
    for n in needles:
        assert n in msg, msg


def test_missing_file(tmp_path):
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "nope.pkl")
    _one_line(e, "nope.pkl", "not found")


def test_unknown_suffix(tmp_path):
    (tmp_path / "body.obj").write_text("v 0 0 0\n")
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "body.obj")
    _one_line(e, "body.obj", ".npz or .pkl", "'.obj'")


@pytest.mark.parametrize("suffix", [".npz", ".pkl"])
def test_corrupt_file(tmp_path, suffix):
    p = tmp_path / f"bad{suffix}"
    p.write_bytes(b"\x80\x02not really a body" * 3)
    with pytest.raises(InputError) as e:
        load_body(p)
    _one_line(e, f"bad{suffix}", "cannot read")


def _corrupt_deflate(tmp_path):
    np.savez_compressed(tmp_path / "c.npz", **smpl_arrays())
    b = bytearray((tmp_path / "c.npz").read_bytes())
    start = 30 + int.from_bytes(b[26:28], "little") + int.from_bytes(b[28:30], "little")  # the first member's data
    for i in range(start + 5, start + 40):
        b[i] ^= 0x5A
    return bytes(b)


def _npy(tmp_path):
    np.save(tmp_path / "v.npy", smpl_arrays()["v_template"])
    return (tmp_path / "v.npy").read_bytes()


@pytest.mark.parametrize("make, needle", [
    (_corrupt_deflate, "Error -3 while decompressing data"),  # zlib.error went past the reader: a traceback
    (_npy, "it is a single .npy array"),  # np.load returned an array: TypeError (no context manager), a traceback
    (lambda tmp_path: b"PK\x07\x08" + bytes(60), "it is a damaged or incomplete zip archive"),  # a spanned zip's start
])
def test_a_damaged_npz_or_an_npy_is_one_line(tmp_path, make, needle):
    (tmp_path / "bad.npz").write_bytes(make(tmp_path))
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "bad.npz")
    _one_line(e, "bad.npz", "cannot read it as a numpy .npz archive", needle)


def test_truncated_pickle(tmp_path):
    write_pkl(tmp_path / "m.pkl", smpl_arrays())
    data = (tmp_path / "m.pkl").read_bytes()
    (tmp_path / "t.pkl").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "t.pkl")
    _one_line(e, "t.pkl", "cannot read")


@pytest.mark.parametrize("suffix", [".npz", ".pkl"])
def test_missing_keys_are_named(tmp_path, suffix):
    arrays = smpl_arrays()
    del arrays["weights"], arrays["kintree_table"]
    p = tmp_path / f"m{suffix}"
    (write_npz if suffix == ".npz" else write_pkl)(p, arrays)
    with pytest.raises(InputError) as e:
        load_body(p)
    _one_line(e, f"m{suffix}", "missing keys", "weights", "kintree_table")


def test_a_motion_given_as_the_body_is_named_for_what_it_is(tmp_path):
    """An AMASS motion as --body listed six missing keys."""
    p = tmp_path / "walk.npz"
    np.savez(p, poses=np.zeros((2, 72)), trans=np.zeros((2, 3)), mocap_framerate=np.array(30.0))
    with pytest.raises(InputError) as e:
        load_body(p)
    _one_line(e, "walk.npz", "expected an SMPL-format body", "got a motion file (it has 'poses')", "--body")


@pytest.mark.parametrize("key,bad,needle", [
    ("weights", np.ones((V, 23)) / 23, "weights"),
    ("J_regressor", np.ones((24, V + 1)), "J_regressor"),
    ("v_template", np.zeros((V, 2)), "v_template"),
    ("posedirs", np.ones((V, 3, 10)), "posedirs"),
    ("f", np.full((4, 3), V + 5), "face indices"),
    ("kintree_table", np.zeros((2, 16), dtype=np.int64), "16"),
])
def test_wrong_shapes(tmp_path, key, bad, needle):
    arrays = smpl_arrays()
    arrays[key] = bad
    write_npz(tmp_path / "m.npz", arrays)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "m.npz")
    _one_line(e, "m.npz", needle)


def test_weights_whose_rows_do_not_sum_to_one_are_refused(tmp_path):
    """Rows summing to 0.5 (the posed body shrinks to half) or with the hand joints' columns zeroed and not
    renormalised: one line naming the file, how many vertices and the worst sum. float32 rounding passes."""
    arrays = smpl_arrays()
    arrays["weights"] = arrays["weights"] * 0.5
    write_npz(tmp_path / "half.npz", arrays)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "half.npz")
    _one_line(e, "half.npz", "expected skinning weights whose rows sum to 1", f"at {V} of {V} vertices",
              "the worst sums to 0.5")
    arrays = smpl_arrays()
    w = arrays["weights"].copy()
    w[:, 20:] = 0.0
    worst = int(np.argmin(w.sum(1)))
    arrays["weights"] = w
    write_pkl(tmp_path / "hands.pkl", arrays)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "hands.pkl")
    _one_line(e, "hands.pkl", f"at vertex {worst}")
    arrays = smpl_arrays()
    arrays["weights"] = arrays["weights"].astype(np.float32) * np.float32(1 + 1e-6)
    write_npz(tmp_path / "rounded.npz", arrays)
    load_body(tmp_path / "rounded.npz")


def test_a_joint_regressor_whose_rows_do_not_sum_to_one_is_refused(tmp_path):
    """A regressor of zeros (every joint at the origin) or halves (joints at half their places) posed the body and
    the garment about the wrong joints alike, silently: one line naming the file, how many joints and the worst."""
    for name, scale in (("zero.npz", 0.0), ("half.npz", 0.5)):
        arrays = smpl_arrays()
        arrays["J_regressor"] = arrays["J_regressor"] * scale
        write_npz(tmp_path / name, arrays)
        with pytest.raises(InputError) as e:
            load_body(tmp_path / name)
        _one_line(e, name, "expected J_regressor rows that sum to 1", "got 24 of 24 that do not",
                  f"sums to {scale:g}")


def test_weights_quantised_by_another_tool_are_scaled_to_sum_to_one_with_a_warning(tmp_path, caplog):
    """Weights rounded to 8 bits (as glTF stores them; rows off by up to a few per cent, under
    WEIGHT_SUM_RESCALE): the body loads, every row summing to 1, with one warning naming the file, how many rows
    and the worst; rows exact to float32 are left as they are."""
    from core.body import WEIGHT_SUM_RESCALE

    arrays = smpl_arrays()
    w = np.round(np.asarray(arrays["weights"], dtype=np.float64) * 255) / 255
    off = np.abs(w.sum(1) - 1)
    assert 1e-3 < off.max() <= WEIGHT_SUM_RESCALE
    arrays["weights"] = w
    write_npz(tmp_path / "gltf.npz", arrays)
    with caplog.at_level(logging.WARNING):
        body = load_body(tmp_path / "gltf.npz")
    np.testing.assert_allclose(body.weights.sum(1), 1.0, atol=1e-6)
    exact = off <= 1e-3
    np.testing.assert_array_equal(body.weights[exact], w[exact].astype(np.float32))
    assert "gltf.npz" in caplog.text and f"{int((~exact).sum()):,} of {V:,} vertices sum to 1 only within" in \
        caplog.text and "scaled to sum to 1" in caplog.text


@pytest.mark.parametrize("scale,unit", [(100.0, "is it in centimetres? scale it by 0.01"),
                                        (1000.0, "is it in millimetres? scale it by 0.001")])
def test_body_in_centimetres_or_millimetres_is_refused(tmp_path, scale, unit):
    """The default body (1.70 m) written in centimetres or millimetres: one line naming the file and the unit,
    not a garment 'far from the body' later."""
    ref = default_body()
    v = (ref.v_template * scale).astype(np.float32)
    np.savez(tmp_path / "cm.npz", v_template=v, shapedirs=ref.shapedirs * scale, J_regressor=ref.J_regressor,
             weights=ref.weights, kintree_table=np.array([ref.parents, np.arange(24)]), f=ref.faces)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "cm.npz")
    extent = float(np.max(v.max(axis=0) - v.min(axis=0)))
    _one_line(e, "cm.npz", "expected metres (a body stands 0.5-2.5 m tall)", f"spanning {extent:.1f} units; {unit}")


def test_pickle_that_is_not_a_dict(tmp_path):
    with open(tmp_path / "l.pkl", "wb") as fh:
        pickle.dump([1, 2, 3], fh, protocol=2)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "l.pkl")
    _one_line(e, "l.pkl", "dict", "list")


class _Evil:
    def __reduce__(self):
        return (print, ("pwned",))


def test_pickle_with_foreign_globals_is_refused(tmp_path, capsys):
    arrays = smpl_arrays()
    arrays["extra"] = _Evil()
    with open(tmp_path / "e.pkl", "wb") as fh:
        pickle.dump(arrays, fh, protocol=2)
    with pytest.raises(InputError) as e:
        load_body(tmp_path / "e.pkl")
    _one_line(e, "e.pkl", "builtins.print", "refused")
    assert "pwned" not in capsys.readouterr().out


def test_lbs_on_loaded_body_is_finite(tmp_path):
    arrays = smpl_arrays()
    write_pkl(tmp_path / "m.pkl", arrays)
    body = load_body(tmp_path / "m.pkl")
    v, j = body.pose(np.zeros((2, 24, 3)), trans=np.ones((2, 3)))
    assert np.isfinite(v).all()
    # Zero pose and betas: the template, translated.
    np.testing.assert_allclose(v[0], arrays["v_template"] + 1.0, atol=1e-5)
    assert torch.is_tensor(body.torch()[0])
