"""formats/fbx.py against Autodesk Maya's own evaluation: FBX files Maya wrote and what Maya computed of them
(the ufbx project's test data, tests/formats/data/ufbx/README.md). Curves of every key kind give Maya's values;
meshes placed by the transforms the reader composes (pivots and offsets, inherit types) land on Maya's own OBJ
exports of them."""

import json
from pathlib import Path

import numpy as np
import pytest

from formats.fbx import (TICKS_PER_SECOND, Keys, Node, _euler, _props70, _vector, curve_keys, model_template,
                         model_transforms, placed, read_scene)

DATA = Path(__file__).parent / "data" / "ufbx"

#: Maya's values of maya_interpolation_modes' curve at 24 fps, frames 0 to 120 (ufbx's test/test_animation.h).
INTERPOLATION_MODES = [
    -8.653366, -8.653366, -8.602998, -8.464664, -8.257528, -8.00075, -7.713489, -7.414906, -7.124163, -6.86042,
    -6.642837, -6.490576, -6.388305, -6.306414, -6.242637, -6.19471, -6.160368, -6.137348, -6.123385,
    -6.116215, -6.113573, -6.113196, -5.969524, -5.825851, -5.682179, -5.538507, -5.394835, -5.251163,
    -5.107491, -4.963819, -4.820146, -4.676474, -4.532802, -4.38913, -4.245458, -4.101785, -3.958113, -4.1529,
    -4.347686, -4.542472, -4.737258, -4.932045, -5.126832, -5.321618, -5.516404, -5.71119, -5.905977, -5.767788,
    -5.315578, -4.954943, -4.83559, -4.856855, -4.960766, -5.118543, -4.976541, -4.885909, -4.865979, -4.93845,
    -5.099224, -5.270246, -5.359269, -5.349404, -5.261964, -5.118543, -5.264501, -5.33535, -5.285445, -5.058857,
    -4.69383, -4.357775, -4.124978, -3.981697, -3.904232, -3.875225, -3.875225, -3.875225, -3.875225, -3.875225,
    -3.875225, -3.875225, -2.942738, -2.942738, -2.942738, -2.942738, -2.942738, -2.942738, -2.942738, -2.942738,
    -2.942738, -1.243537, -1.243537, -1.243537, -1.243537, -1.243537, -1.243537, -1.243537] + [5.603338] * 25
#: Maya's values of maya_auto_clamp's curve at 24 fps, frames 0 to 30 (three decimals).
AUTO_CLAMP = [0.000, 0.000, 0.273, 0.515, 0.718, 0.868, 0.945, 0.920, 0.779, 0.611, 0.591, 0.747, 1.206, 2.059,
              3.191, 4.489, 5.837, 7.121, 8.228, 9.042, 9.449, 9.694, 10.128, 10.610, 10.873, 10.927, 10.854,
              10.704, 10.502, 10.264, 10.000]
#: (seconds, Maya's value) of maya_anim_interpolation's curve: cubic, linear, constant, constant-next keys.
ANIM_INTERPOLATION = [
    (0 / 30, 0.0), (1 / 30, -0.855245), (2 / 30, -1.13344), (3 / 30, -1.17802), (4 / 30, -1.10882),
    (5 / 30, -0.991537), (6 / 30, -0.875223), (7 / 30, -0.808958), (8 / 30, -0.858419), (9 / 30, -1.14293),
    (10 / 30, -2.0), (20 / 30, -4.0), (25 / 30 - 0.001, -4.0), (25 / 30, -6.0), (25 / 30 + 0.001, -8.0),
    (30 / 30, -8.0), (35 / 30 - 0.001, -8.0), (35 / 30, -10.0), (40 / 30, -12.0), (40 / 30 + 0.001, -14.0),
    (45 / 30, -14.0), (50 / 30 - 0.001, -14.0), (50 / 30, -16.0), (50 / 30 + 0.001, -14.0), (55 / 30, -14.0)]


def _translation_x(name: str) -> Keys:
    """The keys of the one Lcl Translation X curve of a file of the data folder."""
    scene = read_scene((DATA / name).read_bytes(), name)
    nodes = {n.props[0] for n in scene.objects.all("AnimationCurveNode") if str(n.props[1]).startswith("T\x00")}
    curve_ids = {child for _, child, parent, *prop in scene.links if parent in nodes and prop == ["d|X"]}
    curves = [c for c in scene.objects.all("AnimationCurve") if c.props[0] in curve_ids]
    assert len(curves) == 1
    return curve_keys(curves[0])


@pytest.mark.parametrize("name, seconds, maya, tolerance", [
    ("maya_interpolation_modes_7500_ascii.fbx", np.arange(121) / 24 + 1e-6, INTERPOLATION_MODES, 1e-4),
    ("maya_interpolation_modes_6100_ascii.fbx", np.arange(121) / 24 + 1e-6, INTERPOLATION_MODES, 1e-4),
    ("maya_auto_clamp_7700_ascii.fbx", np.arange(31) / 24 + 1e-6, AUTO_CLAMP, 1e-3),
    ("maya_anim_interpolation_7700_ascii.fbx", [s for s, _ in ANIM_INTERPOLATION], [v for _, v in ANIM_INTERPOLATION],
     1e-5),
    ("maya_anim_interpolation_6100_binary.fbx", [s for s, _ in ANIM_INTERPOLATION],
     [v for _, v in ANIM_INTERPOLATION], 1e-4)])
def test_curves_maya_wrote_give_mayas_values(name, seconds, maya, tolerance):
    """Curves of every kind of key Maya writes (user tangents, weighted and broken; auto tangents, clamped;
    linear; constant; constant-next) give Maya's own values between their keys, within the digits those were
    written to, in FBX 7 and in FBX 6 (its keys' letters and parameters, ASCII and binary); the keys joined by
    straight lines would be far off (up to 6.9 units)."""
    keys = _translation_x(name)
    t = np.asarray(seconds) * TICKS_PER_SECOND
    np.testing.assert_allclose(keys.at(t), maya, atol=tolerance)
    assert np.abs(np.interp(t, keys.ticks, keys.values) - maya).max() > 0.4


#: (frame at 24 fps, the tool's value) of curves going on outside their keys (ufbx's test/test_animation.h).
EXTRAPOLATED = {
    "maya_anim_extrapolation_7700_ascii.fbx": [  # repeated after, repeated relative before
        (1, 0.0), (12, 4.674119), (24, 10.0), (25, 0.055067), (37, 5.972713), (47, 0.0), (5820, 0.0),
        (4459471, 0.0), (4459472, 0.055067), (9514493, 5.972713), (100109698, 5.325881), (0, -0.055067),
        (-12, -5.972713), (-70, -30.213693), (-4645, -2020.0), (-100509, -43700), (-100000181, -43478340)],
    "motionbuilder_extrapolation_slope_7700_ascii.fbx": [
        (5, -2.051765), (20, 11.633479), (30, 3.016101), (61, -33.067375), (14614, -16972.513672), (-5, 7.743417),
        (-33, 43.879364), (-94, 122.604103), (-242, 313.608398), (-14301, 18457.726562)],
    "motionbuilder_extrapolation_mirror_7700_ascii.fbx": [
        (18, 10.635811), (30, 10.635811), (42, -1.749766), (52, -1.749766), (70, 10.0), (77, 9.815335),
        (355, 7.719610), (1706, -2.065491), (17357, 7.719610), (44874, 10.0), (44897, 0.0), (-24, 11.522083),
        (-52, -0.431755), (-414, -1.077311), (-2207, 0.0), (-27612, 6.519766), (-36132, 10.0), (-36155, 0.0)]}


@pytest.mark.parametrize("name", list(EXTRAPOLATED))
def test_curves_go_on_outside_their_keys_as_the_tool_that_wrote_them(name):
    """Curves Maya and MotionBuilder extrapolate (Pre-/Post-Extrapolation: repeated, repeated from where the
    last repeat ended, mirrored, along the end keys' tangents) give the tools' values before and after their
    keys, near and millions of frames away (within 1e-4 of the value, at most 1e-3)."""
    frames, values = np.array(EXTRAPOLATED[name], dtype=np.float64).T
    got = _translation_x(name).at(frames / 24 * TICKS_PER_SECOND)
    np.testing.assert_array_less(np.abs(got - values), np.minimum(1e-3, np.maximum(np.abs(values), 1) * 1e-4) + 1e-9)


#: maya_anim_layer_anim's cube at frames 0 to 24 (24 fps): translation and XYZ Euler rotation, its base layer and
#: an additive layer whose weight is animated (ufbx's test/test_animation.h, as Maya evaluates it).
LAYER_ANIM = [((0, 0, 0), (0, 0, 0))] + [((0, -y, 0), (r, 0, 0)) for y, r in (
    (0.305556, 3.75), (0.555556, 7.5), (0.75, 11.25), (0.888889, 15), (0.972222, 18.75), (1.0, 22.5),
    (0.972222, 26.25), (0.888889, 30), (0.75, 33.75), (0.555556, 37.5), (0.305556, 41.25), (0.0, 45),
    (0.333333, 41.25), (0.666667, 37.5), (1.0, 33.75), (1.333333, 30), (1.666667, 26.25), (2.0, 22.5),
    (2.333333, 18.75), (2.666667, 15), (3.0, 11.25), (3.333333, 7.5), (3.666667, 3.75), (4.0, 0))]


def _model_worlds(name: str, seconds) -> dict:
    """{Model name: (T, 4, 4) its transform in the world} of a file of the data folder at times `seconds`."""
    scene = read_scene((DATA / name).read_bytes(), name)
    world, _ = model_transforms(scene, np.asarray(seconds, dtype=np.float64) * TICKS_PER_SECOND)
    return {str(scene.models[i].props[1]).split("\x00")[0]: M for i, M in world.items()}


def test_animation_layers_combine_as_maya_combines_them():
    """A stack's animation layers combine as Maya's: an additive layer whose weight is animated adds its share of
    the translation and turns the rotation after the base's (Maya's values, 25 frames); additive layers that
    add Euler angles and scalings as numbers, and an override-passthrough layer of animated weight blending
    rotations as rotations, on joints of all six rotation orders (the transforms ufbx computes, in
    maya_anim_layers_over_acc_orders_ufbx.json, within 1e-6); the base layer alone would be far off."""
    cube = _model_worlds("maya_anim_layer_anim_7700_ascii.fbx", np.arange(25) / 24)["pCube1"]
    translation, rotation = (np.array(v, dtype=np.float64) for v in zip(*LAYER_ANIM))
    np.testing.assert_allclose(cube[:, :3, 3], translation, atol=1e-5)
    np.testing.assert_allclose(cube[:, :3, :3], _euler(rotation, "xyz"), atol=1e-6)
    reference = json.loads((DATA / "maya_anim_layers_over_acc_orders_ufbx.json").read_text())
    seconds = [float(t) for t in reference]
    worlds = _model_worlds("maya_anim_layers_over_acc_orders_7500_ascii.fbx", seconds)
    scene = read_scene((DATA / "maya_anim_layers_over_acc_orders_7500_ascii.fbx").read_bytes(), "x")
    base_only = model_transforms(scene._replace(curves=scene.curves._replace(layers=scene.curves.layers[:1])),
                                 np.asarray(seconds) * TICKS_PER_SECOND)[0]
    names = {str(scene.models[i].props[1]).split("\x00")[0]: i for i in scene.models}
    for k, by_name in enumerate(reference.values()):
        assert len(by_name) == 6
        for name, values in by_name.items():
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = np.reshape(values[:9], (3, 3)).T, values[9:]
            np.testing.assert_allclose(worlds[name][k], M, atol=1e-6)
            assert np.abs(base_only[names[name]][k] - M).max() > 0.1


def _meshes_in_the_world(name: str, frame: int) -> np.ndarray:
    """(V, 3) the vertices of every mesh of a file of the data folder at `frame`, as the reader's transforms
    place them: each Model's world transform (`model_transforms`), its geometric transform, and for a skinned
    mesh its clusters' joints (weights normalised, as Maya does)."""
    scene = read_scene((DATA / name).read_bytes(), name)
    world, _ = model_transforms(scene, np.array([frame * TICKS_PER_SECOND / scene.fps]))
    objects = {n.props[0]: n for n in scene.objects.children if n.props and isinstance(n.props[0], int)}
    children = {}
    for _, child, parent, *_ in scene.links:
        children.setdefault(parent, []).append(child)
    out = []
    for i, model in scene.models.items():
        for g in [c for c in children.get(i, []) if objects.get(c) is not None and objects[c].name == "Geometry"]:
            props = _props70(model)
            V = objects[g].child("Vertices").props[0].reshape(-1, 3) * _vector(props, "GeometricScaling", 1.0)
            V = (V @ _euler(_vector(props, "GeometricRotation", 0.0), "xyz").T
                 + _vector(props, "GeometricTranslation", 0.0))
            clusters = [objects[c] for skin in children.get(g, []) for c in children.get(skin, [])
                        if objects.get(c) is not None and objects[c].child("Indexes") is not None]
            moved, weight = np.zeros_like(V), np.zeros(len(V))
            for cluster in clusters or [None]:
                if cluster is None:  # not skinned: the Model's own transform
                    M, index, w = world[i][0], np.arange(len(V)), np.ones(len(V))
                else:  # its joint's transform now, after the mesh's in the joint's at bind time ('Transform')
                    joint = next(c for c in children[cluster.props[0]] if c in scene.models)
                    M = world[joint][0] @ cluster.child("Transform").props[0].reshape(4, 4).T
                    index, w = cluster.child("Indexes").props[0].astype(int), cluster.child("Weights").props[0]
                np.add.at(moved, index, w[:, None] * (V[index] @ M[:3, :3].T + M[:3, 3]))
                np.add.at(weight, index, w)
            out.append(moved / weight[:, None])
    return np.concatenate(out)


def _obj_vertices(name: str) -> np.ndarray:
    return np.array([line.split()[1:4] for line in (DATA / name).read_text().splitlines() if line.startswith("v ")],
                    dtype=np.float64)


@pytest.mark.parametrize("name, frame, obj", [
    ("maya_pivot_offset_7700_ascii.fbx", 8, "maya_pivot_offset_8.obj"),
    ("maya_mixed_inherit_mode_7700_ascii.fbx", 3, "maya_mixed_inherit_mode_3.obj"),
    ("maya_mixed_inherit_mode_7700_ascii.fbx", 7, "maya_mixed_inherit_mode_7.obj")])
def test_transforms_place_meshes_where_maya_exported_them(name, frame, obj):
    """Meshes Maya animated by rotation and scaling pivots and offsets (their curves cubic), and a mesh skinned
    to joints of each inherit type (the parent's scaling through its matrix, component by component, or not at
    all: Maya's segment scale compensation) under non-uniform scalings, land where Maya's own OBJ export of that
    frame has them (centimetres; the OBJ's six decimals)."""
    np.testing.assert_allclose(_meshes_in_the_world(name, frame), _obj_vertices(obj), atol=2e-5)


def _curve(times, values, flags, data, refs=None) -> Keys:
    """`curve_keys` of an AnimationCurve as a binary FBX holds it: times in seconds, one flag and four attribute
    floats per run of keys (`refs`: the runs' lengths; default one run per key)."""
    refs = [1] * len(flags) if refs is None else refs
    arrays = {"KeyTime": np.round(np.asarray(times) * TICKS_PER_SECOND).astype(np.int64),
              "KeyValueFloat": np.asarray(values, dtype=np.float32), "KeyAttrFlags": np.asarray(flags, dtype=np.int32),
              "KeyAttrDataFloat": np.asarray(data, dtype=np.float32).reshape(-1),
              "KeyAttrRefCount": np.asarray(refs, dtype=np.int32)}
    return curve_keys(Node("AnimationCurve", [1, "\x00\x01AnimCurve", ""],
                           [Node(name, [array], []) for name, array in arrays.items()]))


def test_tcb_keys_of_no_tension_continuity_or_bias_are_catmull_rom():
    """3ds Max's TCB keys of zero tension, continuity and bias (flags Cubic|TCB, the three in the key's
    attributes) run as a Catmull-Rom spline: Hermite curves whose slope at a key is the mean of its two sides'
    (a naive Hermite evaluation is the reference), one-sided at the ends."""
    rng = np.random.default_rng(3)
    times, values = np.arange(6) * 0.5, rng.normal(size=6)
    keys = _curve(times, values, [0x8 | 0x200], np.zeros((1, 4)), refs=[6])
    slope = np.gradient(values, times, edge_order=1)  # the mean of the sides' slopes inside; one side at the ends
    t = np.linspace(0, times[-1], 101)
    k = np.minimum((t // 0.5).astype(int), 4)
    u = (t - times[k]) / 0.5
    h = [2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u, -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2]
    hermite = h[0] * values[k] + h[1] * 0.5 * slope[k] + h[2] * values[k + 1] + h[3] * 0.5 * slope[k + 1]
    np.testing.assert_allclose(keys.at(t * TICKS_PER_SECOND), hermite, atol=1e-6)


def test_damaged_or_missing_key_attributes_join_keys_by_straight_lines():
    """A curve without key attributes, with runs covering fewer keys than it has, or with keys out of time
    order (a damaged file's) is read from key to key in straight lines, its keys sorted, never failing."""
    times, values = [0.0, 1.0, 2.0], [0.0, 2.0, 0.0]
    t = np.array([0.5, 1.5]) * TICKS_PER_SECOND
    cubic = _curve(times, values, [0x8 | 0x400], [[5.0, -5.0, 0.0, 0.0]], refs=[3])
    assert cubic.at(t)[0] > 1.2  # the handles' slopes of 5 bend it above the line's 1.0
    for keys in (_curve(times, values, [0x8 | 0x400], [[5.0, -5.0, 0.0, 0.0]], refs=[2]),
                 _curve([2.0, 0.0, 1.0], [0.0, 0.0, 2.0], [0x8 | 0x400], [[5.0, -5.0, 0.0, 0.0]], refs=[3])):
        np.testing.assert_allclose(keys.at(t), [1.0, 1.0])
        np.testing.assert_allclose(keys.at(np.array([-1.0, 3.0]) * TICKS_PER_SECOND), [0.0, 0.0])


def test_straight_keys_go_on_along_their_end_lines_where_told():
    """Keys without attributes (straight lines) whose curve says 'K' after and before (Post-/Pre-Extrapolation)
    go on along their last and first lines; 'C' holds the end values."""
    def curve(kind):
        ticks = (np.array([0.0, 1.0, 2.0]) * TICKS_PER_SECOND).astype(np.int64)
        out = [Node("Type", [kind], []), Node("Repetition", [-1], [])]
        return curve_keys(Node("AnimationCurve", [1, "", ""], [
            Node("KeyTime", [ticks], []), Node("KeyValueFloat", [np.array([0.0, 2.0, 3.0])], []),
            Node("Pre-Extrapolation", [], out), Node("Post-Extrapolation", [], out)]))

    t = np.array([-1.0, 3.0]) * TICKS_PER_SECOND
    np.testing.assert_allclose(curve("K").at(t), [-2.0, 4.0])
    np.testing.assert_allclose(curve("C").at(t), [0.0, 3.0])


def test_pre_rotation_and_rotation_order_apply_where_rotation_is_active():
    """A Model's pre- and post-rotation and RotationOrder apply where its RotationActive is on (its own value,
    else the file's Model template's, else on), as the FBX SDK reads them: a template of RotationActive 0 turns
    them off for the Models that do not say otherwise (their rotation then XYZ Euler angles alone)."""
    def prop(name, *values):
        return Node("P", [name, "", "", "", *values], [])

    template = Node("PropertyTemplate", ["FbxNode"], [Node("Properties70", [], [prop("RotationActive", 0)])])
    definitions = Node("Definitions", [], [Node("ObjectType", ["Model"], [template])])
    assert model_template({"Definitions": definitions}) == {"RotationActive": [0]}
    own = {"PreRotation": [0.0, 0.0, 90.0], "PostRotation": [10.0, 0.0, 0.0], "RotationOrder": [5]}
    frames = [np.zeros((1, 3)), np.array([[30.0, 40.0, 50.0]]), np.ones((1, 3))]
    active = _euler(np.array([0.0, 0.0, 90.0]), "xyz") @ _euler(frames[1], "zyx") \
        @ _euler(np.array([10.0, 0.0, 0.0]), "xyz").T
    off = model_template({"Definitions": definitions})
    for props, turn in ((own, active), ({**off, **own}, _euler(frames[1], "xyz")),
                        ({**off, **own, "RotationActive": [1]}, active)):
        np.testing.assert_allclose(placed(props, frames, None).matrix[0, :3, :3], turn[0], atol=1e-12)
