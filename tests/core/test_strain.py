"""The strain limit (core/strain.py) against a reference over every edge; what it leaves alone."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import core.strain as strain_mod
from core.deform import LBSDeformer, LBSOptions
from core.garment import mesh_edges
from core.strain import (STRAIN_CHECK_PASSES, STRAIN_ITERATIONS, STRAIN_PLAIN_PASSES, STRAIN_RHO, STRAIN_TOLERANCE_M,
                         limit_garment, limit_sequence, limit_strain, still_over, strain_limit)
from tests.meshes import grid


def _reference(points, rest, faces, limit, iterations):
    """limit_strain's rule frame by frame over every edge (no region): the frames with an edge longer than its
    limit by more than the tolerance take STRAIN_CHECK_PASSES Jacobi passes at a time (each edge longer than its
    limit has its ends pulled by half its excess, a vertex by the mean of its pulls, each pull weighing its excess
    over the tolerance, at most 1), Chebyshev-accelerated after STRAIN_PLAIN_PASSES, until none has one or
    `iterations` passes are made."""
    edges = mesh_edges(faces)
    a, b = edges[:, 0], edges[:, 1]
    longest = limit * np.linalg.norm(rest[b] - rest[a], axis=1)
    out = np.array(points, dtype=np.float64)

    def over(x):
        return np.linalg.norm(x[b] - x[a], axis=1) > longest + STRAIN_TOLERANCE_M

    for t in range(len(out)):
        x, prev, omega, done = out[t].copy(), None, 1.0, 0
        while over(x).any() and done < iterations:
            for _ in range(min(STRAIN_CHECK_PASSES, iterations - done)):
                i = np.linalg.norm(x[b] - x[a], axis=1) > longest
                d = x[b[i]] - x[a[i]]
                length = np.linalg.norm(d, axis=1, keepdims=True)
                pull = 0.5 * (length - longest[i, None]) / length * d
                weight = np.minimum((length[:, 0] - longest[i]) / STRAIN_TOLERANCE_M, 1.0)
                move, count = np.zeros_like(x), np.zeros(len(x))
                np.add.at(move, a[i], pull)
                np.add.at(move, b[i], -pull)
                np.add.at(count, a[i], weight)
                np.add.at(count, b[i], weight)
                y = x + move / np.maximum(count, 1)[:, None]
                done += 1
                if done > STRAIN_PLAIN_PASSES:
                    omega = 2 / (2 - STRAIN_RHO ** 2) if omega == 1.0 else 4 / (4 - STRAIN_RHO ** 2 * omega)
                    y = omega * (y - prev) + prev
                prev, x = x, y
        out[t] = x
    return out


def _stretched(rng, n_frames=3, cells=6):
    """A grid of `cells` x `cells` cells of 2 cm, its frames moved rigidly, then torn: one corner pulled 10 cm
    away, the rows beyond 6 cm pulled 3 cm further, and a little noise."""
    verts, faces = grid(cells, cells, 0.02 * cells)
    frames = []
    for t in range(n_frames):
        x = verts + rng.normal(0.0, 0.001, verts.shape)
        x[0] += [0.1, 0.05 * t, 0.0]
        x[verts[:, 1] > 0.06] += [0.0, 0.03, 0.0]
        frames.append(x @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T + rng.normal(size=3))
    return verts, faces, np.array(frames)


def _torn_corner(rng, cells=30):
    """A grid of 30 x 30 cells of 2 cm with one corner vertex pulled 8 cm away (a tear far from most edges), and
    one with a vertex in its middle pulled 5 cm out of its plane."""
    verts, faces = grid(cells, cells, 0.02 * cells)
    corner, middle = verts.copy(), verts.copy()
    corner[0] += [-0.08, 0.0, 0.0]
    middle[np.argmin(np.linalg.norm(verts - verts.mean(axis=0), axis=1))] += [0.0, 0.0, 0.05]
    return verts, faces, np.stack([corner, middle]) + rng.normal(0.0, 1e-4, (2, *verts.shape))


@pytest.mark.parametrize("case", ["stretched", "torn corner"])
def test_limit_equals_the_every_edge_reference(case):
    rng = np.random.default_rng(0)
    verts, faces, points = _stretched(rng) if case == "stretched" else _torn_corner(rng)
    for limit, iterations in ((1.5, 60), (1.2, 25)):
        got, over, passes = limit_strain(points, strain_limit(verts, faces, limit), iterations)
        want = _reference(points, verts, faces, limit, iterations)
        np.testing.assert_allclose(got, want, atol=2e-5)
        edges = mesh_edges(faces)
        length = np.linalg.norm(points[:, edges[:, 1]] - points[:, edges[:, 0]], axis=-1)
        rest = np.linalg.norm(verts[edges[:, 1]] - verts[edges[:, 0]], axis=-1)
        np.testing.assert_array_equal(over, (length > limit * rest + STRAIN_TOLERANCE_M).sum(axis=1))
        assert over.min() > 0 and 0 < passes <= iterations


def test_the_limit_passes_its_inputs_rounding_on_without_amplifying_it():
    """A pass's pulls grow from nothing as an edge crosses its limit: noise of 1e-6 m on torn grids moves the
    limited cloth by about as much (an all-or-nothing pull at the tolerance, each edge over counting one in its
    vertices' means, moved these by 3.9 and 0.5 mm; a torn dress by up to 6 mm)."""
    for seed, cells in ((1, 8), (5, 20)):
        rng = np.random.default_rng(seed)
        verts, faces, points = _stretched(rng, n_frames=6, cells=cells)
        noise = rng.normal(0.0, 1e-6, points.shape)
        sl = strain_limit(verts, faces)
        got, _, _ = limit_strain(points, sl)
        noisy, _, _ = limit_strain(points + noise, sl)
        assert np.linalg.norm(noisy - got, axis=-1).max() < 5e-5 and np.abs(got - points).max() > 0.01


def test_limit_undoes_a_tear_and_leaves_unstretched_cloth_alone():
    rng = np.random.default_rng(1)
    verts, faces, points = _stretched(rng)
    edges = mesh_edges(faces)
    rest = np.linalg.norm(verts[edges[:, 1]] - verts[edges[:, 0]], axis=-1)
    sl = strain_limit(verts, faces)
    got, _, passes = limit_strain(points, sl)
    length = np.linalg.norm(got[:, edges[:, 1]] - got[:, edges[:, 0]], axis=-1)
    assert passes < 60 and (length <= 1.5 * rest + STRAIN_TOLERANCE_M).all()
    assert np.linalg.norm(points[:, edges[:, 1]] - points[:, edges[:, 0]], axis=-1).max() / rest.max() > 4
    # Moved rigidly, squashed to half its size (folds): nothing to limit, the frames come back as they were.
    calm = np.stack([verts @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T + [0, 0, 1], verts * 0.5])
    same, over, passes = limit_strain(calm, sl)
    np.testing.assert_array_equal(same, calm.astype(np.float32))
    assert passes == 0 and not over.any()
    # A frame without an edge over the limit is left exactly as it was beside a torn one.
    mixed, over, _ = limit_strain(np.stack([points[0], calm[0]]), sl)
    np.testing.assert_array_equal(mixed[1], calm[0].astype(np.float32))
    assert over[0] > 0 and over[1] == 0


def test_limit_sequence_in_chunks_reports_what_it_did(monkeypatch):
    rng = np.random.default_rng(2)
    verts, faces, points = _stretched(rng, n_frames=5)
    points[3] = verts  # a frame at rest
    sl = strain_limit(verts, faces)
    whole, _, _ = limit_strain(points, sl)
    monkeypatch.setattr(strain_mod, "STRAIN_CHUNK_FRAMES", 2)
    chunked, report = limit_sequence(points.astype(np.float32), sl)
    np.testing.assert_allclose(chunked, whole, atol=1e-6)  # frames are limited each on its own
    assert report["limit"] == 1.5 and report["frames_limited"] == 4 and report["edges_over_per_frame_max"] > 0
    assert 0 < report["passes_max"] <= report["iterations"] and report["seconds_per_frame"] > 0


def test_a_large_garment_is_limited_in_fewer_frames_at_once():
    """`strain_chunk_frames`: 32 frames at once up to about 10k vertices, powers of two down to 8 frames beyond
    (the time and peak memory measured on 3k-203k vertices: core/strain.py)."""
    from core.strain import strain_chunk_frames

    got = [strain_chunk_frames(v) for v in (1, 50, 3240, 9999, 10001, 12816, 20001, 50976, 203328, 10**8)]
    assert got == [32, 32, 32, 32, 16, 16, 8, 8, 8, 8]


def test_limit_of_a_tensor_is_a_tensor_of_the_array_s_bits():
    """A tensor in (a GPU bake's batch; here on the CPU) gives a tensor of the frames an array gives, and the same
    counts."""
    import torch

    rng = np.random.default_rng(3)
    verts, faces, points = _stretched(rng)
    sl = strain_limit(verts, faces)
    want, over, passes = limit_strain(points, sl)
    got, t_over, t_passes = limit_strain(torch.from_numpy(points.astype(np.float32)), sl)
    assert isinstance(got, torch.Tensor) and got.dtype == torch.float32 and got.shape == points.shape
    np.testing.assert_array_equal(got.numpy(), want)
    np.testing.assert_array_equal(t_over, over)
    assert t_passes == passes > 0 and np.abs(want - points).max() > 0.01


def _dress_on(motion_frames=slice(20, 26), betas=None):
    from core.body import default_body
    from formats.motion import load_motion
    from formats.obj import read_obj

    root = Path(__file__).resolve().parents[2]
    garment, body = read_obj(root / "examples" / "dress.obj"), default_body()
    run = load_motion(root / "examples" / "run.npz")
    motion = dataclasses.replace(run, poses=run.poses[motion_frames], trans=run.trans[motion_frames],
                                 betas=run.betas if betas is None else betas)
    return garment, body, motion


def test_lbs_with_a_strain_limit_reports_it_and_is_off_by_default():
    from core.skinning import bind_garment, shaped_garment

    garment, body, motion = _dress_on()  # LBS tears the dress between the legs on these frames of the run
    plain = LBSDeformer()
    out = plain.deform(garment, body, motion)
    assert "strain_limit" not in plain.report and LBSOptions().strain_limit is None
    limited = LBSDeformer(LBSOptions(strain_limit=1.5))
    got = limited.deform(garment, body, motion)
    report = limited.report["strain_limit"]
    assert report["limit"] == 1.5 and limited.report["options"]["strain_limit"] == 1.5
    assert report["frames_limited"] > 0 and report["edges_over_per_frame_max"] > 10
    rest = shaped_garment(garment.vertices, bind_garment(garment, body, 10, 0.5), body.fit_betas(motion.betas))
    cache = {}
    want, entries = limit_garment(out, garment, rest, 1.5, cache)
    np.testing.assert_array_equal(got, want)
    assert set(entries) == {"strain_limit"} and len(cache) == 1


@pytest.mark.parametrize("beta", [5.0, -5.0])
def test_the_limit_is_against_the_garment_at_rest_on_the_motion_s_body_shape(beta):
    """On a body of betas +-5 the shape transfer lengthens (shortens) many of the dress's edges at rest by over
    half: held at the rest pose, the limited dress is the unlimited one, nothing pulled back to the authored
    lengths."""
    garment, body, motion = _dress_on(slice(0, 2), np.full(10, beta))
    motion = dataclasses.replace(motion, poses=np.zeros_like(motion.poses), trans=np.zeros_like(motion.trans))
    plain = LBSDeformer().deform(garment, body, motion)
    limited = LBSDeformer(LBSOptions(strain_limit=1.5))
    np.testing.assert_array_equal(limited.deform(garment, body, motion), plain)
    assert limited.report["strain_limit"]["frames_limited"] == 0
    edges = mesh_edges(garment.faces)
    authored = np.linalg.norm(garment.vertices[edges[:, 1]] - garment.vertices[edges[:, 0]], axis=1)
    at_rest = np.linalg.norm(plain[0, edges[:, 1]] - plain[0, edges[:, 0]], axis=1)
    assert (at_rest > 1.5 * authored + 1e-3).mean() > (0.2 if beta > 0 else 0.01)


def test_the_report_says_what_the_limit_left_over():
    """The report counted the edges over the limit before it only, so a limit whose passes ran out read as met
    (264 edges of a psd bake left 3.6 mm over): what is left, and by how much, is counted on the result, as a
    naive count over every edge does."""
    rng = np.random.default_rng(3)
    verts, faces, points = _stretched(rng, n_frames=3)
    sl = strain_limit(verts, faces)
    edges = mesh_edges(faces)
    rest = np.linalg.norm(verts[edges[:, 1]] - verts[edges[:, 0]], axis=-1)
    for iterations in (2, STRAIN_ITERATIONS):
        limited, report = limit_sequence(points.astype(np.float32), sl, iterations)
        excess = np.linalg.norm(limited[:, edges[:, 1]] - limited[:, edges[:, 0]], axis=-1) - 1.5 * rest
        left = (excess > STRAIN_TOLERANCE_M).sum(axis=1)
        assert report["frames_still_over"] == int((left > 0).sum())
        assert report["edges_still_over_per_frame_max"] == int(left.max())
        assert report["excess_left_max_mm"] == pytest.approx(max(excess.max(), 0.0) * 1e3, abs=2e-3)
    assert report["frames_still_over"] == 0 < report["frames_limited"]  # the default passes undo these tears
    short, _ = limit_sequence(points.astype(np.float32), sl, 2)
    assert still_over(short, sl)[0].max() > 0  # two passes do not
