"""The network of core/model.py: GATv2 fast path vs PyG, shapes, unseen garments, LBS at initialisation."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from core.body import skin_points
from core.errors import InputError
from core.model import (GATv2, GarmentModel, GATv2Weights, ModelConfig, body_distances, config_from_dict,
                        count_parameters, motion_features, neighbour_table, shaped_rest, window_index)
from core.model_data import prepare_garment
from tests.core.model_fixtures import TINY_CONFIG, perturbed_model, sequence, tube
from tests.meshes import tiny_body


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="module")
def body():
    return tiny_body()


def _garment(body, n_theta, n_rows, **kw):
    from core.garment import Garment

    v, f = tube(n_theta, n_rows, **kw)
    return prepare_garment(Garment(v, f), body, TINY_CONFIG)


def test_gatv2_fast_path_matches_pyg():
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    n = 30
    edges = np.unique(np.sort(rng.integers(0, n, size=(80, 2)), axis=1), axis=0)
    edges = edges[edges[:, 0] != edges[:, 1]]
    nbr, mask = neighbour_table(edges, n)
    for heads in (1, 2):
        layer = GATv2(5, 8, heads)
        with torch.no_grad():
            layer.conv.att.normal_()
            layer.conv.bias.normal_()
        x = torch.randn(3, n, 5)
        ei = torch.as_tensor(np.r_[edges, edges[:, ::-1]].T.copy())
        ref = torch.stack([layer.reference(x[b], ei) for b in range(3)])
        assert torch.allclose(layer(x, nbr, mask), ref, atol=1e-5)
        with torch.no_grad():  # the inference path (in-place activation)
            assert torch.allclose(layer(x, nbr, mask), ref, atol=1e-5)


def test_gatv2_weights_are_gatv2conv_parameters_and_the_model_loads_without_pyg():
    from torch_geometric.nn import GATv2Conv

    for in_features, channels, heads in ((16, 4, 2), (64, 64, 1), (7, 3, 4)):
        torch.manual_seed(0)
        ours = GATv2Weights(in_features, channels, heads).state_dict()
        after_ours = torch.rand(3)
        torch.manual_seed(0)
        pyg = GATv2Conv(in_features, channels, heads=heads).state_dict()
        # The same names, shapes and values after the same seed, and the same random numbers drawn.
        assert ours.keys() == pyg.keys() and all(torch.equal(ours[k], pyg[k]) for k in pyg)
        assert torch.equal(after_ours, torch.rand(3))
    # The command and the model import without torch_geometric (its import pulls in torch._dynamo, seconds).
    code = ("import sys, garmentcli.main, core.model, core.model_deform; garmentcli.main.all_commands(); "
            "sys.exit(any(m.startswith(('torch_geometric', 'torch._dynamo')) for m in sys.modules))")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_neighbour_table_naive():
    edges = np.array([[0, 1], [1, 2], [0, 2], [2, 3]])
    nbr, mask = neighbour_table(edges, 4)
    got = [sorted(nbr[i][mask[i]].tolist()) for i in range(4)]
    assert got == [[0, 1, 2], [0, 1, 2], [0, 1, 2, 3], [2, 3]]
    assert nbr[:, 0].tolist() == [0, 1, 2, 3]


def _run(model, body, gd, T=6, B=4, betas=None):
    rng = np.random.default_rng(1)
    poses = (rng.normal(size=(T, 24, 3)) * 0.1).astype(np.float32)
    trans = np.zeros((T, 3), np.float32)
    mf = motion_features(body, poses, trans, betas, 30.0)
    g = gd.inputs
    fr = torch.arange(T - B, T)
    win = window_index(fr, model.config.window)
    fused = model.encode(g, body_distances(body, betas))
    return model.forward_frames(fused, g, shaped_rest(g, body, betas), mf.pose[win], mf.velocity[win],
                                mf.transforms[fr]), mf, fr


def test_added_inputs_start_as_the_network_they_extend_then_see_shape_and_pose(body):
    base = perturbed_model(TINY_CONFIG, 0.05)
    added = GarmentModel(dataclasses.replace(TINY_CONFIG, shape_input=1, pose_codes=1))
    missing, unexpected = added.load_state_dict(base.state_dict(), strict=False)
    assert sorted(missing) == ["pose_codes.bias", "pose_codes.weight", "shape_code.bias", "shape_code.weight"]
    assert not unexpected
    gd = _garment(body, 12, 6)
    betas = np.full(10, 1.5, np.float32)

    def moved(b=None):
        return (_run(added, body, gd, betas=b)[0].verts - _run(base, body, gd, betas=b)[0].verts).abs().max()

    with torch.no_grad():
        assert moved(betas) == 0.0
        added.shape_code.weight.normal_()
        # The shape input is the garment's displacement by the body's shape: none for the mean shape ...
        assert moved() == 0.0
        # ... and a different garment for another body.
        assert moved(betas) > 1e-4
        added.shape_code.weight.zero_()
        added.pose_codes.weight.normal_()
        assert moved() > 1e-4  # the pose codes reach the blend shapes
    with pytest.raises(InputError, match="shape_input 0 or 1"):
        config_from_dict({"shape_input": 2})
    with pytest.raises(InputError, match="pose_codes 0 or 1"):
        config_from_dict({"pose_codes": -1})


def test_config_from_dict_refuses_unknown_keys_and_wrong_types():
    """A checkpoint's or --config's model values: a string where a number goes, a float or a bool for an integer
    (True would read as 1), a number for the pooling name: one line naming the source and the key."""
    for values, expected in (({"hidden": "wide"}, "'hidden': expected an integer, got 'wide'"),
                             ({"levels": 2.5}, "'levels': expected an integer, got 2.5"),
                             ({"shape_input": True}, "'shape_input': expected an integer, got True"),
                             ({"pooling": 3}, "'pooling': expected a string, got 3"),
                             ({"hiden": 32}, "unknown key 'hiden'")):
        with pytest.raises(InputError, match=f"ckpt.pt: .*{expected}"):
            config_from_dict(values, source="ckpt.pt")
    assert config_from_dict({"hidden": np.int64(16), "heads": 2}).hidden == 16


def test_shapes_float32_and_starts_as_lbs(body):
    torch.manual_seed(0)
    model = GarmentModel(TINY_CONFIG)
    gd = _garment(body, 12, 6)
    out, mf, fr = _run(model, body, gd)
    V = gd.inputs.n_vertices
    assert out.verts.shape == (4, V, 3) and out.weights.shape == (4, V, 24) and out.blend.shape == (4, V, 3)
    assert out.verts.dtype == torch.float32
    assert torch.allclose(out.weights.sum(-1), torch.ones(4, V), atol=1e-5)
    # Zero-initialised skinning and blend-shape heads: the untrained model is LBS with the prior weights.
    assert torch.equal(out.blend, torch.zeros_like(out.blend))
    prior = gd.inputs.prior_weights + 1e-4
    lbs = skin_points(gd.inputs.rest, prior / prior.sum(1, keepdim=True), mf.transforms[fr])
    assert torch.allclose(out.verts, lbs, atol=1e-5)


def test_runs_on_unseen_garment_and_gradients_flow(body):
    torch.manual_seed(0)
    model = GarmentModel(TINY_CONFIG)
    with torch.no_grad():  # make every head non-trivial
        for p in model.parameters():
            p.add_(0.05 * torch.randn_like(p))
    for shape in ((12, 6), (9, 7), (16, 4)):
        gd = _garment(body, *shape, radius=(0.28, 0.22))
        out, _, _ = _run(model, body, gd)
        assert torch.isfinite(out.verts).all() and out.verts.shape[1] == gd.inputs.n_vertices
    out.verts.sum().backward()
    assert all(p.grad is not None for p in model.parameters())


def test_vertex_permutation_equivariance(body):
    """Renumbering the garment's vertices renumbers the output (no vertex-order dependence)."""
    from core.garment import Garment

    model = perturbed_model(TINY_CONFIG, 0.05)
    v, f = tube(12, 6)
    perm = np.random.default_rng(3).permutation(len(v))
    inv = np.argsort(perm)
    a = prepare_garment(Garment(v, f), body, TINY_CONFIG)
    b = prepare_garment(Garment(v[perm], inv[f]), body, TINY_CONFIG)
    out_a, _, _ = _run(model, body, a)
    out_b, _, _ = _run(model, body, b)
    # The pooling hierarchy picks the same vertices (seeded by geometry), so outputs agree vertex for vertex.
    assert torch.allclose(out_a.verts[:, perm], out_b.verts, atol=1e-4)


def test_a_garment_facing_the_body_gives_the_output_of_its_twin_facing_out(body):
    """The tube with its faces turned (normals towards the body, the input the network reads): the same output as
    the tube itself (it moved the example dress's bake by 48 mm on average before `oriented_outward`)."""
    from core.garment import Garment

    model = perturbed_model(TINY_CONFIG, 0.05)
    v, f = tube(12, 6)
    a = prepare_garment(Garment(v, f), body, TINY_CONFIG)
    b = prepare_garment(Garment(v, f[:, ::-1].copy()), body, TINY_CONFIG)
    out_a, _, _ = _run(model, body, a)
    out_b, _, _ = _run(model, body, b)
    assert torch.allclose(out_a.verts, out_b.verts, atol=1e-5)


def test_config_rejects_unknown_key_and_wrong_body(body):
    with pytest.raises(InputError, match="unknown key 'width'"):
        config_from_dict({"width": 3})
    with pytest.raises(InputError, match="divisible"):
        config_from_dict({"hidden": 10, "heads": 3})
    model = GarmentModel(ModelConfig(n_joints=52, hidden=8, levels=1, n_eigenvalues=4, n_landmarks=8))
    gd = _garment(body, 12, 6)
    with pytest.raises(InputError, match="52-joint"):
        model.encode(gd.inputs, body_distances(body, None))


def test_default_config_is_small():
    n = count_parameters(GarmentModel(ModelConfig()))
    assert n * 4 < 20e6  # float32 checkpoint under 20 MB


def test_model_deformer_bakes_a_motion(body, tmp_path):
    from core.garment import Garment
    from core.model_deform import load_model_deformer
    from core.motion import Motion
    from formats.checkpoint import save_checkpoint

    torch.manual_seed(0)
    model = GarmentModel(TINY_CONFIG)
    path = save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, model.state_dict())
    d = load_model_deformer(path)
    v, f = tube(12, 6)
    poses, trans, _ = sequence(body, v, f, 7, 0, None)
    out = d.deform(Garment(v, f), body, Motion(poses=poses, trans=trans, fps=30.0))
    assert out.shape == (7, len(v), 3) and out.dtype == np.float32 and np.isfinite(out).all()
    assert d.report["method"] == "model" and d.report["precision"] == "float32"
    # The contact guard is on by default and reported; the untrained model is LBS, which it (almost) never lifts.
    assert d.report["contact_guard"]["vertices_moved_per_frame_max"] >= 0
    raw = load_model_deformer(path, contact_guard=False)
    unguarded = raw.deform(Garment(v, f), body, Motion(poses=poses, trans=trans, fps=30.0))
    assert "contact_guard" not in raw.report and np.abs(unguarded - out).max() < 1e-3
    # bfloat16 network (autocast) but float32 skinning weights and world coordinates: the untrained model (LBS)
    # gives float32's result to float32 rounding (bfloat16 coordinates would be off by millimetres).
    motion = Motion(poses=poses, trans=trans, fps=30.0)
    half = load_model_deformer(path, precision="bfloat16")
    b = half.deform(Garment(v, f), body, motion)
    assert b.dtype == np.float32 and np.abs(b - out).max() < 1e-5
    # A perturbed network in bfloat16: finite and bounded, not equal to float32.
    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=1)
    save_checkpoint(tmp_path / "p.pt", TINY_CONFIG, model.state_dict())
    a = load_model_deformer(tmp_path / "p.pt").deform(Garment(v, f), body, motion)
    b = load_model_deformer(tmp_path / "p.pt", precision="bfloat16").deform(Garment(v, f), body, motion)
    gap = np.linalg.norm(a - b, axis=-1)
    assert np.isfinite(b).all() and 0 < gap.max() < np.ptp(v, axis=0).max(), gap.max()
    with pytest.raises(InputError, match="float16"):
        load_model_deformer(tmp_path / "p.pt", precision="float16")


@pytest.mark.parametrize("guard, limit, sweeps", [(True, 1.5, 2), (True, None, 2), (False, 1.5, 2), (False, None, 1)])
def test_model_deformer_reports_progress_through_each_pass_over_the_frames(body, tmp_path, guard, limit, sweeps):
    """`on_frames` is called as the network's batches and the chunks of the contact guard and the strain limit
    (`core.pushout.guard_and_limit`: one pass over the frames, both alternating chunk by chunk) finish, each
    frame's share of the passes: the counts add up to the frames, in steps before the end (a 203k-vertex bake sat
    at 0 % for its whole run), the network's half or all of them by its last batch."""
    from core.garment import Garment
    from core.model_deform import ModelDeformer
    from core.motion import Motion

    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=2)
    v, f = tube(12, 6)
    poses, trans, _ = sequence(body, v, f, 12, 0, None)
    d = ModelDeformer(model, batch_frames=4, contact_guard=guard, strain_limit=limit)
    ticks = []
    d.on_frames = ticks.append
    d.deform(Garment(v, f), body, Motion(poses=poses, trans=trans, fps=30.0))
    assert sum(ticks) == pytest.approx(12)
    assert ticks[:3] == [pytest.approx(4 / sweeps)] * 3 and len(ticks) >= 3 + (sweeps - 1)


def test_a_body_that_starts_still_gets_no_lead_in(body):
    """A motion whose first frames stand still (a pose held, as a standing capture starts) is given no lead-in: the
    blend's transient slid a still dress 61 mm over its first eight frames; held, the cloth stands still."""
    from core.garment import Garment
    from core.model_deform import STILL_START_M_S, ModelDeformer, starts_still
    from core.motion import Motion

    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=1)
    v, f = tube(12, 6)
    poses, trans, _ = sequence(body, v, f, 9, 0, None)
    held = np.repeat(poses[4:5], 9, axis=0)
    still = Motion(poses=held, trans=np.repeat(trans[4:5], 9, axis=0), fps=30.0)
    led = ModelDeformer(model, lead_in_s=4 / 30, contact_guard=False, strain_limit=None)
    out = led.deform(Garment(v, f), body, still)
    assert led.report["starts_still"] and led.report["lead_in_frames"] == 0
    np.testing.assert_allclose(out, np.repeat(out[:1], 9, axis=0), atol=1e-5)
    led.deform(Garment(v, f), body, Motion(poses=poses, trans=trans, fps=30.0))
    assert not led.report["starts_still"] and led.report["lead_in_frames"] == 4
    # a root gliding just under and just over the threshold
    for speed, want in ((0.9 * STILL_START_M_S, True), (1.1 * STILL_START_M_S, False)):
        glide = np.repeat(trans[4:5], 3, axis=0) + np.arange(3)[:, None] * [speed / 30.0, 0.0, 0.0]
        assert starts_still(body, held[:3], glide.astype(np.float32), None, 30.0) is want
    assert starts_still(body, held[:1], trans[:1], None, 30.0)  # one frame


def test_model_lead_in_is_the_settle_blend_the_window_sees(body, tmp_path):
    """A motion without settle frames starts, in the network's window only, with the blend from the rest pose
    its training sequences start with: the same frames as baking the motion with that settle blend and
    dropping it; frames whose window no longer reaches it are unchanged; a motion with its own settle blend
    gets none; the checkpoint's "lead_in_s" sets it, in seconds."""
    from core.garment import Garment
    from core.model_deform import DEFAULT_LEAD_IN_S, LEAD_FADE_FRAMES, ModelDeformer, load_model_deformer
    from core.motion import Motion, settle
    from formats.checkpoint import save_checkpoint

    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=1)
    v, f = tube(12, 6)
    garment = Garment(v, f)
    poses, trans, _ = sequence(body, v, f, 9, 0, None)
    motion = Motion(poses=poses, trans=trans, fps=30.0)
    led = ModelDeformer(model, lead_in_s=4 / 30, contact_guard=False, strain_limit=None)
    out = led.deform(garment, body, motion)
    assert led.report["lead_in_frames"] == 4 and led.report["lead_in_fade_frames"] == LEAD_FADE_FRAMES == 3
    plain = ModelDeformer(model, lead_in_s=0, contact_guard=False, strain_limit=None)
    blended = plain.deform(garment, body, settle(motion, 4))
    assert plain.report["lead_in_frames"] == plain.report["lead_in_fade_frames"] == 0  # the motion's own blend
    still = plain.deform(garment, body, motion)
    last = TINY_CONFIG.window - 1  # the last frame whose window holds a lead-in velocity
    np.testing.assert_allclose(out[:last + 1], blended[4:][:last + 1], atol=1e-5)
    assert np.abs(out[0] - still[0]).max() > 1e-4  # the first frame's window holds the blend, not a still body
    # The blend's effect at the last frame, out of a window that starts still, fades out over the next three
    # frames (it stopped dead there: a 146 mm jump on the skirt's brisk walk), then the frames are the still
    # start's.
    residual = out[last] - still[last]
    assert np.abs(residual).max() > 1e-4
    for k, weight in enumerate((0.75, 0.5, 0.25), start=1):
        np.testing.assert_allclose(out[last + k] - still[last + k], weight * residual, atol=1e-5)
    np.testing.assert_allclose(out[last + 4:], still[last + 4:], atol=1e-5)
    np.testing.assert_allclose(out[last + 4:], blended[4 + last + 4:], atol=1e-5)
    # batches of any size fade the same frames
    batched = ModelDeformer(model, lead_in_s=4 / 30, contact_guard=False, strain_limit=None, batch_frames=2)
    np.testing.assert_allclose(batched.deform(garment, body, motion), out, atol=1e-5)
    # A body turning about the vertical: the residual turns with its root (it stayed put in the world)
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    spin = np.zeros((len(poses), 3), np.float32)
    spin[:, 2] = np.linspace(0.0, 2.0, len(poses))  # 0.25 rad a frame about world Z
    turning = poses.copy()
    turning[:, 0] = matrix_to_axis_angle(axis_angle_to_matrix(spin) @ axis_angle_to_matrix(poses[:, 0]))
    turned_motion = Motion(poses=turning, trans=trans, fps=30.0)
    out_t, still_t = led.deform(garment, body, turned_motion), plain.deform(garment, body, turned_motion)
    root = axis_angle_to_matrix(turning[:, 0])
    residual_t = out_t[last] - still_t[last]
    for k, weight in enumerate((0.75, 0.5, 0.25), start=1):
        expected = weight * residual_t @ root[last] @ root[last + k].T
        np.testing.assert_allclose(out_t[last + k] - still_t[last + k], expected, atol=1e-5)
    short = Motion(poses=poses[:last + 3], trans=trans[:last + 3], fps=30.0)  # two frames after the window's
    led.deform(garment, body, short)
    assert led.report["lead_in_fade_frames"] == 2  # the frames faded, not the fade's length
    short = Motion(poses=poses[:last + 1], trans=trans[:last + 1], fps=30.0)  # no frame after the window's
    np.testing.assert_allclose(led.deform(garment, body, short), out[:last + 1], atol=1e-5)
    assert led.report["lead_in_fade_frames"] == 0
    led.deform(garment, body, Motion(poses=poses, trans=trans, fps=60.0))
    assert led.report["lead_in_frames"] == 8  # as many seconds at twice the frame rate
    assert ModelDeformer(model).lead_in_s == DEFAULT_LEAD_IN_S
    with pytest.raises(InputError, match="lead-in"):
        ModelDeformer(model, lead_in_s=-1)
    path = save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, model.state_dict(), meta={"lead_in_s": 0.1})
    assert load_model_deformer(path).lead_in_s == 0.1
    assert load_model_deformer(path, lead_in_s=0).lead_in_s == 0
    path = save_checkpoint(tmp_path / "n.pt", TINY_CONFIG, model.state_dict())
    assert load_model_deformer(path).lead_in_s == DEFAULT_LEAD_IN_S


def test_pooled_body_velocities_match_posing_every_vertex(body):
    """motion_features pools body-vertex velocities per joint without posing the body: naive reference."""
    from core.model import motion_features

    rng = np.random.default_rng(4)
    T, fps = 6, 30.0
    poses = (rng.normal(size=(1, body.n_joints, 3)) * 0.3 + np.cumsum(rng.normal(size=(T, body.n_joints, 3)) * 0.03,
                                                                       axis=0)).astype(np.float32)
    trans = np.cumsum(rng.normal(size=(T, 3)) * 0.01, axis=0).astype(np.float32)
    betas = rng.normal(size=body.n_betas).astype(np.float32)
    mf = motion_features(body, poses, trans, betas, fps)
    verts, _, A = body.pose_with_transforms(poses, trans, betas)  # no pose correctives on this body
    w = body.weights
    expected = np.zeros((T, body.n_joints, 3))
    for t in range(1, T):
        for j in range(body.n_joints):
            v = (verts[t] - verts[t - 1]) * fps
            expected[t, j] = A[t, 0, :3, :3].T @ (w[:, j] @ v / w[:, j].sum())
    got = mf.velocity[:, : 3 * body.n_joints].numpy().reshape(T, body.n_joints, 3)
    np.testing.assert_allclose(got, expected, atol=1e-4)


@pytest.mark.parametrize("pooling", ["topk", "sag", "asap"])
def test_learned_pooling_baselines_run_train_and_report_their_levels(body, pooling, tmp_path):
    """The comparison networks: same model with PyG's TopK / SAG / ASAP pooling in the U-Net."""
    from dataclasses import replace

    from core.garment import Garment
    from core.model import config_from_dict
    from core.model_data import prepare_garment

    cfg = replace(TINY_CONFIG, pooling=pooling, levels=2)
    assert config_from_dict({"pooling": pooling, "levels": 2}).pooling == pooling
    model = perturbed_model(cfg, 0.1)  # the zero-initialised output layer would stop every gradient
    v, f = tube(12, 6)
    gd = prepare_garment(Garment(v, f), body, cfg, tmp_path)
    poses, trans, _ = sequence(body, v, f, 4, 0, None)
    from core.model import motion_features, shaped_rest, window_index

    mf = motion_features(body, poses, trans, None, 30.0)
    fused = model.encode(gd.inputs, body_distances(body, None))
    win = window_index(torch.arange(4), cfg.window)
    out = model.forward_frames(fused, gd.inputs, shaped_rest(gd.inputs, body, None), mf.pose[win],
                               mf.velocity[win], mf.transforms)
    assert out.verts.shape == (4, len(v), 3) and torch.isfinite(out.verts).all()
    out.verts.square().sum().backward()
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in model.unet.pools.parameters())
    graphs = model.unet.pooled_graphs(fused.detach(), gd.inputs)
    assert [len(k) for k, _ in graphs] == [len(v), len(v) // 2, len(v) // 4]
    for kept, edge_index in graphs:  # level-0 vertices, edges among the level's own nodes
        assert len(set(kept.tolist())) == len(kept) and int(edge_index.max()) < len(kept)
    with pytest.raises(InputError, match="pooling"):
        config_from_dict({"pooling": "random"})


def test_tensors_to_moves_every_tensor_and_keeps_the_rest(body):
    from core.model import tensors_to

    gd = _garment(body, 12, 6)
    moved = tensors_to(gd, "meta")
    assert moved.garment is gd.garment and moved.near is gd.near  # not tensors: shared
    for g in (moved, moved.inputs):
        for name, value in vars(g).items():
            for t in value if isinstance(value, list) else [value]:
                if isinstance(t, torch.Tensor):
                    assert t.device.type == "meta", name
    assert len(moved.inputs.nbr) == len(gd.inputs.nbr) and gd.inputs.rest.device.type == "cpu"


def test_temporal_encoders_run_in_the_weights_precision_under_bfloat16_autocast():
    # oneDNN has no bfloat16 LSTM on CPUs without native bfloat16 (AVX2-only AMD EPYC: "could not create a
    # primitive descriptor"): the LSTMs run outside autocast, in their weights' precision, float64 included.
    from core.model import _last_state

    torch.manual_seed(0)
    lstm, x = torch.nn.LSTM(5, 8, batch_first=True), torch.randn(3, 4, 5)
    plain = _last_state(lstm, x)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        h = _last_state(lstm, x)
    assert h.shape == (3, 8) and h.dtype == torch.float32 and torch.equal(h, plain)
    assert _last_state(lstm.double(), x).dtype == torch.float64


def test_contact_guard_with_the_network_matches_the_guard_afterwards():
    """The contact guard batch by batch where the network runs (a GPU bake's path, here forced on the CPU) gives
    the frames of the guard over the whole sequence afterwards (float32 against float64 arithmetic) and moves the
    same vertices; both differ from the network's raw output."""
    from pathlib import Path

    from core.body import default_body
    from core.model_deform import load_model_deformer
    from formats.motion import load_motion
    from formats.obj import read_garment

    root = Path(__file__).resolve().parents[2]
    garment, body = read_garment(root / "examples" / "dress.obj"), default_body()
    run = load_motion(root / "examples" / "run.npz", fps=30.0)
    motion = dataclasses.replace(run, poses=run.poses[:7], trans=run.trans[:7])
    out, reports = {}, {}
    for name, guard, on_device in (("after", True, False), ("with", True, True), ("raw", False, None)):
        d = load_model_deformer(contact_guard=guard, strain_limit=None)  # the guard alone
        d.batch_frames, d.post_on_device = 3, on_device  # batches of 3, 3 and 1 frames
        out[name] = d.deform(garment, body, motion)
        reports[name] = d.report
    after, with_net = reports["after"]["contact_guard"], reports["with"]["contact_guard"]
    assert after["device"] == with_net["device"] == "cpu" and after["vertices_moved_per_frame_mean"] > 0
    assert with_net["vertices_moved_per_frame_mean"] == after["vertices_moved_per_frame_mean"]
    assert np.abs(out["with"] - out["after"]).max() < 1e-5
    assert np.abs(out["after"] - out["raw"]).max() > 1e-3


def test_guard_and_limit_with_the_network_match_them_afterwards():
    """The contact guard and the strain limit batch by batch where the network runs (a GPU bake's path, here
    forced on the CPU) give what they give over the whole sequence afterwards (`core.pushout.guard_and_limit`,
    the guard's arithmetic in float64 there) and report the same frames and edges over; a frame's result does not
    depend on the batch it came in. Both alternate: the second guard and limit move the cloth further."""
    from pathlib import Path

    from core import pushout
    from core.body import default_body
    from core.model_deform import load_model_deformer
    from formats.motion import load_motion
    from formats.obj import read_garment

    root = Path(__file__).resolve().parents[2]
    garment, body = read_garment(root / "examples" / "dress.obj"), default_body()
    run = load_motion(root / "examples" / "run.npz", fps=30.0)
    motion = dataclasses.replace(run, poses=run.poses[40:60], trans=run.trans[40:60])

    def bake(batch, on_device, **kwargs):
        d = load_model_deformer(**kwargs)
        d.batch_frames, d.post_on_device = batch, on_device
        return d.deform(garment, body, motion), d.report

    raw, _ = bake(3, True, contact_guard=False, strain_limit=None)
    in_threes, report = bake(3, True, strain_limit=1.5)  # batches of 3 frames, the last 2
    whole, _ = bake(20, True, strain_limit=1.5)
    after, want = bake(3, False, strain_limit=1.5)
    got, want = report["strain_limit"], want["strain_limit"]
    assert got["device"] == "cpu" and got["frames_limited"] == want["frames_limited"] > 0
    assert got["edges_over_per_frame_max"] == want["edges_over_per_frame_max"] > 0
    assert report["contact_guard"]["alternations_with_strain_limit"] == pushout.GUARD_LIMIT_ALTERNATIONS == 2
    # Within rounding (the network's batches are not bit-equal), which the limit's stop at its 1 mm tolerance can
    # carry to a few vertices of a tear.
    np.testing.assert_allclose(in_threes, whole, atol=1e-3)
    np.testing.assert_allclose(in_threes, after, atol=1e-3)
    assert np.abs(in_threes - raw).max() > 1e-3
    pushout.GUARD_LIMIT_ALTERNATIONS = 1
    try:
        once, _ = bake(20, True, strain_limit=1.5)
    finally:
        pushout.GUARD_LIMIT_ALTERNATIONS = 2
    assert np.abs(once - whole).max() > 1e-3


def test_model_deformer_prepares_a_body_shape_once_and_again_after_its_weights_change():
    """A bake of several motions of one body shape encodes the garment once (`_shaped_inputs`); another shape, or
    weights changed in place since, are prepared again; at most SHAPED_CACHE shapes are kept; the frames are
    those of a fresh deformer every time."""
    from pathlib import Path

    from core.body import default_body
    from core.model_deform import SHAPED_CACHE, load_model_deformer
    from formats.motion import load_motion
    from formats.obj import read_garment

    root = Path(__file__).resolve().parents[2]
    garment, body = read_garment(root / "examples" / "dress.obj"), default_body()
    run = load_motion(root / "examples" / "run.npz", fps=30.0)
    motion = dataclasses.replace(run, poses=run.poses[:4], trans=run.trans[:4])
    d = load_model_deformer()
    calls = []
    encode = d.model.encode
    d.model.encode = lambda *a: calls.append(1) or encode(*a)
    first = d.deform(garment, body, motion)
    again = d.deform(garment, body, dataclasses.replace(motion, trans=motion.trans + 0.5))
    assert len(calls) == 1 and np.allclose(again, first + np.float32(0.5), atol=1e-5)
    for k in range(SHAPED_CACHE + 1):  # other shapes: each prepared, the oldest dropped
        d.deform(garment, body, dataclasses.replace(motion, betas=np.full(10, 0.1 * (k + 1), dtype=np.float32)))
    assert len(calls) == SHAPED_CACHE + 2 and len(d._shaped) == SHAPED_CACHE
    with torch.no_grad():
        for p in d.model.parameters():
            p.mul_(1.1)
    changed = d.deform(garment, body, motion)
    assert len(calls) == SHAPED_CACHE + 3
    fresh = load_model_deformer()
    fresh.model.load_state_dict(d.model.state_dict())
    assert np.array_equal(changed, fresh.deform(garment, body, motion))
    assert np.abs(changed - first).max() > 1e-3


def test_copies_back_from_a_gpu_trail_the_network_by_one_batch(monkeypatch):
    """`_CopiesBack` on a CUDA device (its copy and event faked here): batch k is written into the output once
    batch k+1 is queued, waiting on k's event only; `finish` writes the last; every frame lands where it belongs."""
    from core.model_deform import _CopiesBack

    waited = []

    class Event:
        def __init__(self, k):
            self.k = k

        def synchronize(self):
            waited.append(self.k)

    monkeypatch.setattr(_CopiesBack, "_start_copy", staticmethod(lambda v: (v.clone(), Event(int(v[0, 0, 0])))))
    out = np.full((7, 2, 3), -1.0, dtype=np.float32)
    copies = _CopiesBack(out, torch.device("cuda", 0))
    batches = [torch.full((n, 2, 3), float(k)) for k, n in enumerate((3, 3, 1))]
    copies.put(0, batches[0])
    assert waited == [] and (out == -1).all()
    copies.put(3, batches[1])
    assert waited == [0] and (out[:3] == 0).all() and (out[3:] == -1).all()
    copies.put(6, batches[2])
    copies.finish()
    assert waited == [0, 1, 2] and np.array_equal(out, np.concatenate([b.numpy() for b in batches]))
    assert copies.pending is None


def test_default_batch_frames_follow_the_device_and_the_garment_size():
    from core.model_deform import GPU_MAX_BATCH_FRAMES, default_batch_frames

    assert default_batch_frames("cpu", 50) == default_batch_frames("cpu", 50_000) == 2
    assert default_batch_frames("cuda", 4096) == 128 and default_batch_frames("cuda:1", 50_000) == 10
    assert default_batch_frames("cuda", 50) == GPU_MAX_BATCH_FRAMES and default_batch_frames("cuda", 10**7) == 1


def test_a_bake_does_not_build_the_training_self_collision_neighbourhood(monkeypatch):
    """The rest neighbourhood of the self-collision loss (Eq. 6) is training's alone: its pairs grow as the square
    of the vertex count (a 213k-vertex garment took over 24 GB and was killed); the model deformer and
    `prepare_garment(near=False)` leave it out, training's `prepare_garment` builds it."""
    import core.preprocess as P
    from core.body import default_body
    from core.model_data import prepare_garment
    from core.model_deform import load_model_deformer
    from core.motion import Motion
    from formats.obj import read_garment
    from tests.extremes.test_extremes import still

    calls = []
    build = P.geodesic_neighbourhood
    monkeypatch.setattr(P, "geodesic_neighbourhood", lambda *a, **k: calls.append(1) or build(*a, **k))
    body = default_body()
    garment = read_garment(Path(__file__).resolve().parents[2] / "examples" / "skirt.obj")
    d = load_model_deformer()
    out = d.deform(garment, body, Motion(poses=still(2), trans=np.zeros((2, 3), np.float32), fps=30))
    assert np.isfinite(out).all() and calls == []
    assert all(g.near is None for g in d._garments.values())
    assert prepare_garment(garment, body, d.model.config, near=False).near is None and calls == []
    assert prepare_garment(garment, body, d.model.config).near.nnz > 0 and calls == [1]


def test_the_network_is_given_the_nearest_trained_shape(body, caplog):
    """Beyond the shape coefficients a model was trained on (`trained_betas`: each one's least and largest; one
    it has no record of, 0) the network is given each within its trained range (a hair beyond, TRAINED_BETAS_SLACK,
    is within): its encoded rest pose and its shape input are those of the clipped betas, while the garment is
    fitted and posed on the body's own (the shipped model tore a jumpsuit's leg off at rest on a tall body).
    Within them nothing changes, bit for bit; beyond, the bake says so once and reports both shapes."""
    from core.garment import Garment
    from core.model import shaped_rest
    from core.model_deform import ModelDeformer
    from core.motion import Motion

    model = perturbed_model(TINY_CONFIG, scale=0.3, seed=2)
    v, f = tube(12, 6)
    garment = Garment(v, f)
    poses, trans, _ = sequence(body, v, f, 6, 0, None)
    bounds = (np.array([-0.5, 0.0, -0.2]), np.array([0.5, 0.2, 0.1]))  # a record of 3 of the body's 4
    kept = ModelDeformer(model, contact_guard=False, strain_limit=None, trained_betas=bounds)
    plain = ModelDeformer(model, contact_guard=False, strain_limit=None)

    def bake(d, betas):
        return d.deform(garment, body, Motion(poses=poses, trans=trans, fps=30.0, betas=np.float32(betas)))

    within = [0.3, 0.1, -0.2, 0.0]
    np.testing.assert_array_equal(bake(kept, within), bake(plain, within))
    assert "shape_beyond_training" not in kept.report
    # a hair beyond (a recorded bound's rounding, a shape typed to 3 digits) is within
    hair = [0.5049, -0.004, 0.1 + 1e-6, 0.009]
    np.testing.assert_array_equal(bake(kept, hair), bake(plain, hair))
    assert "shape_beyond_training" not in kept.report
    beyond, nearest = [2.0, -1.0, 0.05, 0.7], np.float32([0.51, -0.01, 0.05, 0.01])  # TRAINED_BETAS_SLACK
    np.testing.assert_array_equal(kept.network_betas(np.float32(beyond)), nearest)
    with caplog.at_level("WARNING", logger="core.model_deform"):
        out = bake(kept, beyond)
    assert np.isfinite(out).all() and not np.allclose(out, bake(plain, beyond), atol=1e-4)
    assert kept.report["shape_beyond_training"] == {"betas": beyond, "network_betas": [0.51, -0.01, 0.05, 0.01],
                                                   "coefficients": [0, 1, 3]}
    assert [r.getMessage().split(": ", 1)[1] for r in caplog.records] == [
        "the body's shape lies beyond the shapes it was trained on, betas[0] 2 (trained -0.5 to 0.5), betas[1] -1 "
        "(trained 0 to 0.2), betas[3] 0.7 (trained 0 to 0): the network is given each within its trained range, the "
        "garment fitted and posed on the body's own (its accuracy there is not measured)"]
    device = torch.device("cpu")
    shaped, seen = kept._shaped_inputs(garment, body, np.float32(beyond), device), \
        plain._shaped_inputs(garment, body, nearest, device)
    assert torch.equal(shaped.fused, seen.fused) and torch.equal(shaped.shape_view, seen.rest)
    assert torch.equal(shaped.rest, shaped_rest(shaped.g, body, np.float32(beyond)))
    assert not torch.equal(shaped.rest, seen.rest)


def test_trained_betas_are_recorded_by_training_and_default_to_the_datasets_bodies():
    """A checkpoint records each shape coefficient's least and largest over its training sequences and its --init's
    (`trained_shapes`: a coefficient a sequence lacks is 0); one that records none (the shipped model) is taken
    to have seen `garment dataset`'s default bodies (3, betas in +-2, seed 0: the mean shape among them)."""
    from core.dataset import sample_betas
    from core.model_deform import trained_betas, trained_shapes

    record = trained_shapes([np.float32([0.5, -1.0]), np.float32([-0.25, 0.0, 2.0])], None)
    assert record == {"min": [-0.25, -1.0, 0.0], "max": [0.5, 0.0, 2.0]}
    grown = trained_shapes([np.float32([1.0])], trained_betas({"trained_betas": record}))
    assert grown == {"min": [-0.25, -1.0, 0.0], "max": [1.0, 0.0, 2.0]}
    least, largest = trained_betas({})
    shapes = sample_betas(3, 10, 2.0, seed=0)
    np.testing.assert_array_equal(least, shapes.min(axis=0))
    np.testing.assert_array_equal(largest, shapes.max(axis=0))
    assert (least <= 0).all() and (largest >= 0).all() and (largest - least).max() < 4
