"""Binding a garment to a body: skinning weights and shape offsets transferred from the body surface.

Each garment vertex takes the skinning weights (and shape blend shapes) of the
body's rest surface where it is nearest: the barycentric blend at the closest
point of every face within a margin of the nearest distance (`surface_blend`),
so a vertex equally near two body parts (a skirt between the legs) takes both,
and nearly the same garment binds nearly the same; weights can then be smoothed
over the garment's edge graph so loose parts do not tear between neighbouring
joints.
"""

from __future__ import annotations

import hashlib
import logging
import re
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from core.body import Body
from core.errors import InputError
from core.garment import UNIT_GUESSES, Garment, mesh_edges
from core.geodesic import edge_lengths
from core.geometry import ClosestPoints, TriangleMesh, face_normals
from core.graph import adjacency

log = logging.getLogger(__name__)

#: A garment whose median distance to the rest body exceeds MAX_MEDIAN_BODY_DISTANCE_M and whose closest
#: 5 % lie further than MAX_NEAR_BODY_DISTANCE_M from it does not rest on that body (a ball gown's skirt may
#: stand far from the legs, but its bodice lies on the body; the examples' closest 5 %: 0.8-1.5 cm).
MAX_MEDIAN_BODY_DISTANCE_M = 0.25
MAX_NEAR_BODY_DISTANCE_M = 0.05
#: A garment vertex this far inside the rest body counts as inside (the bake's penetration depth).
REST_INSIDE_DEPTH_M = 0.002
#: More of a garment's vertices than this inside the rest body: warned (the example garments: none).
REST_INSIDE_WARN_SHARE = 0.02
#: A garment this much inside the rest body, that one of `FRAME_FIXES` puts on it (at most
#: REST_INSIDE_WARN_SHARE inside), is refused with that fix: it is in another frame (the example garments
#: turned by one of them: 6-27 % inside).
REST_INSIDE_FRAME_SHARE = 0.05
#: A fix puts a garment on the body when its median distance to the rest surface is at most this (the example
#: garments: 1.6-5 cm; the wrong fixes of the examples turned or lifted: 17 cm or more) and at most
#: REST_INSIDE_WARN_SHARE of it is inside.
FRAME_FIX_MEDIAN_M = 0.10
#: A fix whose median distance on an even sample of the garment (`SHIFT_SAMPLE` vertices) is over FRAME_FIX_SCREEN
#: times FRAME_FIX_MEDIAN_M is not tried on the whole garment (most of the 47 fixes put it far from the body).
FRAME_FIX_SCREEN = 1.5
#: A garment that rests near the body (not far, at most REST_INSIDE_FRAME_SHARE inside) but with a median distance
#: over FRAME_FIX_SUSPECT_MEDIAN_M (the example garments: 1.6-5 cm) is tried with `FRAME_FIXES` too, and refused
#: when one puts it on the body with its median distance and that of its closest 5 % both FRAME_FIX_GAIN times
#: smaller or more: a skirt or dress authored on a body standing at y = 0 hangs about the chest, arms and head
#: (the example skirt and dress: 3.1 and 4.9 times; the examples, generated garments and loose tube dresses with
#: any fix: 1.3 times at most).
FRAME_FIX_SUSPECT_MEDIAN_M = 0.06
FRAME_FIX_GAIN = 2.0
#: A fix also puts a garment on the body, far from it or more than REST_INSIDE_FRAME_SHARE inside, when it makes
#: its `_fit_score` this many times smaller, its median distance at most FRAME_FIX_MEDIAN_M, however much of it is
#: then still inside: a garment authored on another body (SMPL's, a mannequin's) in another frame, which no frame
#: puts on this body without some of it inside (real garments: trousers and t-shirts authored on bodies standing
#: on the floor, 3.4-12 times; a Z-up outfit authored on SMPL, 2.8 times; the fix's text says how much is inside).
#: So must a turn upside down (the file's up turned down) that fits: a tube around the hips 6 % inside fitted
#: upside down, 1.06 times better; the example t-shirt, trousers and jumpsuit written upside down fit turned back
#: 3.5-4.5 times better; the dress and skirt only 1.1-1.3 times (those are warned of as partly inside).
FRAME_FIX_SCORE_GAIN = 2.0
#: A garment far from the body that spans more than this (metres) is said to be in other units (`core.garment`
#: refuses one over 10 units, naming the units that fit; a Maya export of 5.95 units fitted none).
GARMENT_MAX_SPAN_M = 3.0
#: Two such fixes whose scores are within this factor leave the choice open: neither is named (a t-shirt of
#: GarmentTransfer's, turned about X either way: 1.2).
FRAME_FIX_TIE = 1.25
#: Of the fixes that put a garment on the body, the earliest (one change before two) whose `_fit_score` is within
#: this factor of the best is told: a skirt turned -90 degrees about X fits upside down too (its score 7 % worse:
#: it was told the first fix that fitted, `--turn z-up`, leaving it upside down); a symmetric skirt lifted by
#: the floor fits as well turned round (0.2 %).
FRAME_FIX_PREFER = 1.02
#: After such a fix the garment is climbed (`_shift_climb`) at most this far on each axis (metres: x, y, z).
FRAME_FIX_CLIMB_M = np.array([0.1, 0.35, 0.1])
#: A garment whose top lies more than ABOVE_HEAD_M above the rest body's head with none of it more than
#: FLOOR_SLACK_M below y = 0, that the drop to the body's soles puts on the body (at most REST_INSIDE_WARN_SHARE
#: inside, its top then no more than ABOVE_HEAD_M above the head), was authored on a body standing at y = 0,
#: however loose: a flared skirt lifted by the default body's soles reaches 15 cm above its head (a dress 46 cm),
#: and its hem, 10-30 cm from the legs, hangs about the chest no further from it than when worn (medians 0.7-1.4
#: times as far). A hat or a hood on the head is not moved into the chest.
ABOVE_HEAD_M = 0.10
FLOOR_SLACK_M = 0.01
#: A garment more than SHIFT_DEEP_SHARE of which lies more than SHIFT_DEEP_M inside the rest body (the example and
#: generated garments, however loose: none) and that no fix above explains is tried moved up and down by
#: SHIFT_RANGE_M (then sideways, forwards and back: SHIFT_SIDE_RANGE_M): authored on a body whose origin stands
#: elsewhere, such as SMPL's rest body (SNUG's five garments, authored on it, fit the embedded body best 0.24-0.27 m
#: higher). It is refused naming the move when the move makes its `_shift_score` SHIFT_GAIN times smaller or more
#: and leaves no more than 1.25 times as much of it that deep, plus 1 % (SNUG's: 1.65-5.6 times; the examples moved
#: by 0.15-0.30 m: 2.1-5.3 times, but for the loose dress, 1.1-1.4: warned as inside, as before; the example
#: t-shirt, trousers and dress generated on 12 other body shapes: none refused, the move at the search's end not
#: named: benchmarks/garment_placement.py).
#: The range starts above the height differences of body shapes and ends below the floor's drop (`FRAME_FIXES`).
SHIFT_DEEP_M = 0.01
SHIFT_DEEP_SHARE = 0.01
SHIFT_RANGE_M = (0.12, 0.45)
SHIFT_GAIN = 1.5
#: Then sideways and forwards or back by SHIFT_SIDE_RANGE_M (an object exported away from the origin), where a move
#: along that axis makes the score SHIFT_AXIS_GAIN times smaller (the examples and SNUG's garments: no such move).
SHIFT_SIDE_RANGE_M = (0.06, 0.45)
SHIFT_AXIS_GAIN = 1.2
#: An up move of SMPL_UP_M with at most SMPL_ASIDE_M aside or forwards (SNUG's t-shirt and long-sleeve top: 1-2 cm)
#: is said to be SMPL's, on the embedded body, and named where it makes the score SHIFT_AXIS_GAIN times smaller (not
#: SHIFT_GAIN): SMPL's garments are the commonest real ones, and tight trousers authored on SMPL's thinner legs stay
#: inside this body wherever they are put (ISP's trousers moved up 0.25 m: 1.25 times smaller, 9 % still inside).
SMPL_UP_M = (0.20, 0.30)
#: Unless a move further up fits better (the example t-shirt moved 0.6 m down fits 0.21 m up better than where it
#: is, and far better 0.6 m up).
SMPL_BEYOND_M = (0.35, 0.45, 0.55, 0.65)
SMPL_ASIDE_M = 0.03
#: At most this many steps of `_shift_climb` (26 moves each) after the axes' search.
SHIFT_CLIMB_STEPS = 40
#: At most this many of a garment's vertices (evenly through the file) are moved in that search (about 6 ms a move).
SHIFT_SAMPLE = 2000
#: The searched moves' nearest and furthest reach on each axis (x, y, z; metres).
_SHIFT_NEAREST = np.array([SHIFT_SIDE_RANGE_M[0], SHIFT_RANGE_M[0], SHIFT_SIDE_RANGE_M[0]])
_SHIFT_FURTHEST = np.array([SHIFT_SIDE_RANGE_M[1], SHIFT_RANGE_M[1], SHIFT_SIDE_RANGE_M[1]])


#: `surface_blend`'s margin: a face whose closest point is within BLEND_SHARE of the nearest distance (at least
#: BLEND_MIN_M, at most BLEND_MAX_M; metres) further than the nearest counts, weighted from 1 (as near) down to 0 (at
#: the margin). With the nearest point alone, a vertex of the example skirt between the legs, float rounding of
#: 3e-8 m (a centimetre export) swapped the hips' weights and moved its LBS bake by up to 14 mm.
#: The cap keeps the search near the body: a 125k-vertex skirt's blend took 8.1 s with 2 cm, 4.3 with 1.
BLEND_SHARE = 0.25
BLEND_MIN_M = 0.002
BLEND_MAX_M = 0.01


@dataclass(frozen=True, eq=False)
class GarmentBinding:
    """How a garment follows a body.

    weights: (V, J) float32, rows sum to 1.
    shapedirs: (V, 3, S) float32, metres per unit beta (garment moves with the body's shape).
    body_distance: (V,) float32, metres from each vertex to the rest body surface.
    """

    weights: np.ndarray
    shapedirs: np.ndarray
    body_distance: np.ndarray


def bind_garment(garment: Garment, body: Body, smooth_iterations: int = 0, smooth_strength: float = 0.5,
                 source: str | None = None, placed: Placement | None = None) -> GarmentBinding:
    """Transfer skinning weights and shape blend shapes from the nearest body face.

    smooth_iterations: passes of neighbour averaging of the weights over the
    garment graph (x <- (1-s) x + s mean(neighbours)); 0 keeps the raw transfer.
    Raises InputError when the garment is not near the body's rest surface.
    placed: what was done to the file `source` to make `garment` (see `unpose_command`): the fixes named follow
    it [default: nothing, on the body's file (`Body.path`)].
    """
    mesh = TriangleMesh(body.v_template, body.faces)
    hit, signed = mesh.signed_closest(garment.vertices)
    check_rest_fit(garment, body, mesh, signed, source or garment.name, placed)
    blend = surface_blend(mesh, garment.vertices, hit)
    weights = transfer_weights(blend, body, garment.faces, smooth_iterations, smooth_strength)
    shapedirs = transfer_shapedirs(blend, body).astype(np.float32)
    return GarmentBinding(weights=weights, shapedirs=shapedirs, body_distance=hit.distance.astype(np.float32))


def _axis_turn(axis: int, degrees: float) -> np.ndarray:
    """(3, 3) the rotation by `degrees` about axis `axis` (0: X, 1: Y, 2: Z), right-handed (a quarter or half turn
    exact)."""
    angle = np.radians(degrees)
    c, s = (float(f(angle)) for f in (np.cos, np.sin))
    if float(degrees) % 90.0 == 0.0:
        c, s = round(c), round(s)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    rotation = np.eye(3)
    rotation[[i, i, j, j], [i, j, i, j]] = (c, -s, s, c)
    return rotation


#: The turns `garment unpose --turn` makes, by name, each a quarter or half turn about an axis (right-handed, on the
#: file's vertices); z-up and backwards are x-90 and y+180, under the names their files come with.
TURNS = {"z-up": _axis_turn(0, -90), "x+90": _axis_turn(0, 90), "backwards": _axis_turn(1, 180),
         "x+180": _axis_turn(0, 180), "y+90": _axis_turn(1, 90), "y-90": _axis_turn(1, -90),
         "z+90": _axis_turn(2, 90), "z-90": _axis_turn(2, -90), "z+180": _axis_turn(2, 180)}
_TURN_WORDS = {"z-up": "rotated -90 degrees about X (Z-up to Y-up)", "x+90": "rotated +90 degrees about X",
               "backwards": "turned 180 degrees about Y (it faces backwards)"}


def _turn_words(turn: str) -> str:
    """How the fix `turn` (a name in `TURNS`) is told: "rotated +90 degrees about Y"."""
    return _TURN_WORDS.get(turn) or f"rotated {turn[1:]} degrees about {turn[0].upper()}"


#: A turn by any angle about an axis, as `garment unpose --turn` takes it besides `TURNS`' names: "y-15" (-15
#: degrees about Y, right-handed).
TURN_PATTERN = r"[xyz][+-](\d+(\.\d*)?|\.\d+)"


def turn_matrix(turn: str) -> np.ndarray:
    """(3, 3) the rotation of a turn: a name in `TURNS`, or an axis and degrees (`TURN_PATTERN`: "y-15")."""
    if turn in TURNS:
        return TURNS[turn]
    if not re.fullmatch(TURN_PATTERN, turn):
        raise ValueError(f"expected one of {', '.join(TURNS)} or an axis and degrees (y-15), got {turn!r}")
    return _axis_turn("xyz".index(turn[0]), float(turn[1:]))


def _turns_rotation(turns: tuple[str, ...]) -> np.ndarray:
    """(3, 3) the turns named (`turn_matrix`), one after the other."""
    rotation = np.eye(3)
    for turn in turns:
        rotation = turn_matrix(turn) @ rotation
    return rotation


def _rotation_key(rotation) -> bytes:
    return np.asarray(rotation, dtype=np.float64).round().astype(np.int8).tobytes()


def _fewest_turns() -> dict[bytes, tuple[str, ...]]:
    """The 24 axis-aligned turns (the cube's rotations; `_rotation_key`), each as its fewest `TURNS`, one turn
    before two (every one is at most two), in `TURNS`' order; none as ()."""
    found = {_rotation_key(np.eye(3)): ()}
    for turns in [(t,) for t in TURNS] + [(a, b) for a in TURNS for b in TURNS]:
        found.setdefault(_rotation_key(_turns_rotation(turns)), turns)
    return found


_FEWEST_TURNS = _fewest_turns()


_DROP = "moved down by {drop:.2f} m (authored on a body standing at y = 0)"
#: The turns a garment file can come in, tried in this order: one before two, the three common ones (Blender's and
#: Maya's Z-up, Z-down, facing backwards) before the others (Unreal's Z-up facing +Y or +X, Y-up facing +X, ...):
#: (the fix as told, its `TURNS`), each of `_FEWEST_TURNS` but none.
_TURNS = tuple((", then ".join(_turn_words(t) for t in turns), turns)
               for turns in sorted(filter(None, _FEWEST_TURNS.values()),
                                   key=lambda turns: (len(turns), not set(turns) <= set(_TURN_WORDS))))
#: Frame mix-ups a garment file can come with, tried in this order (one change before two, so that a symmetric
#: skirt lifted by the floor is told to move down, not to turn and move down): (the fix, as told to the user;
#: the turns applied to the file's vertices, names in `TURNS`; whether the body it was authored on stood on the
#: floor, soles at y = 0, so the fix lowers it to this body's soles).
FRAME_FIXES = (tuple((what, turns, False) for what, turns in _TURNS if len(turns) == 1)
               + ((_DROP, (), True),)
               + tuple((what, turns, False) for what, turns in _TURNS if len(turns) == 2)
               + tuple((f"{what}, then {_DROP}", turns, True) for what, turns in _TURNS))
#: The fixes `_best_place` tries with each scale mix-up (a unit and a frame mix-up at once; each fix costs a
#: search of heights): the common turns' (`_TURN_WORDS`).
_COMMON_FIXES = tuple(f for f in FRAME_FIXES if set(f[1]) <= set(_TURN_WORDS))

#: A garment scaled to metres by the wrong unit (written in inches, scaled by 0.01 as centimetres: a doll's dress
#: 0.39 times its size) is scaled back by the two units' ratio (`_scale_fix`). The units mixed up are those
#: `core.garment.unit_hint` names together for one file (20-98 units: centimetres or inches; 200-250: centimetres
#: or millimetres): (scale back, "inches read as centimetres").
_MIXED = {("inches", "centimetres"), ("centimetres", "inches"), ("centimetres", "millimetres"),
          ("millimetres", "centimetres")}
UNIT_MIXUPS = tuple((written / read, f"{w} read as {r}") for w, written in UNIT_GUESSES for r, read in UNIT_GUESSES
                    if (w, r) in _MIXED)
#: Scaled back, at its best place, a garment's fit score over its span must be SCALE_GAIN times smaller than its own
#: at its best place (`_scale_fix`) where it is enlarged (real garments authored on SMPL, scaled by 0.39: 1.6-3),
#: SCALE_SHRINK_GAIN times where it is shrunk (a loose garment fits closer shrunk: the loose tubes of
#: benchmarks/garment_placement.py with 12 cm of ease, shrunk by 0.39, up to 2.07; real garments of SMPL's scaled
#: by 2.54: 1.4-5.1, 5 of 9 over 2.2; the examples: 2.4), SCALE_TENFOLD_GAIN times for a tenfold scale (the
#: examples scaled by 0.1 or 10: 3.1-11; a Maya export 4.3 units across, in none of these units, scaled by 0.1: 1.6).
SCALE_GAIN = 1.5
SCALE_SHRINK_GAIN = 2.2
SCALE_TENFOLD_GAIN = 2.5
#: The scale search moves at most this many of a garment's vertices, evenly through them, up and down in steps of
#: SCALE_HEIGHT_STEP_M (metres).
SCALE_SAMPLE = 500
SCALE_HEIGHT_STEP_M = 0.10


@dataclass(frozen=True)
class Placement:
    """What `garment unpose` does to a garment file's vertices, in this order: scaled by `scale` about the origin,
    turned by each of `turns` (names in `TURNS`) in turn, moved by `move` (metres, the body's frame); then the
    pose and shape its `pose` options (" --pose tpose", " --pose apose --betas 1,2") name are taken off, for the
    body its `body` option names (" --body smpl.npz"; "" for the embedded one)."""

    scale: float = 1.0
    turns: tuple[str, ...] = ()
    move: tuple[float, float, float] = (0.0, 0.0, 0.0)
    pose: str = " --pose tpose"
    body: str = ""

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) the turns, one after the other."""
        return _turns_rotation(self.turns)

    def apply(self, vertices: np.ndarray) -> np.ndarray:
        """(V, 3) float64: `vertices` scaled, turned and moved (the pose is not taken off)."""
        return np.asarray(vertices, dtype=np.float64) * self.scale @ self.rotation.T + np.asarray(self.move)

    def then(self, fix: Placement) -> Placement:
        """This placement followed by `fix` (scaled, turned and moved, as found on this one's result), as one.
        A fix found on a garment unposed from another pose is made before the pose is taken off: a unit or frame
        mix-up is the file's (the command's result is checked again)."""
        rotation = fix.rotation @ self.rotation
        key = _rotation_key(rotation)
        if np.allclose(rotation, np.frombuffer(key, dtype=np.int8).reshape(3, 3), atol=1e-9):
            turns = _FEWEST_TURNS[key]  # an axis-aligned turn, as few as make it; a turn and its undoing: none
        else:  # by another angle (a yaw): as given, one after the other
            turns = self.turns + fix.turns
        move = fix.scale * fix.rotation @ np.asarray(self.move, dtype=np.float64) + np.asarray(fix.move)
        if np.any(self.move):  # a move found (in 1 cm steps) undoing the one given leaves that step at most: none
            move = np.where((np.abs(move) <= MOVE_SEARCH_STEP_M + 1e-9) & (np.asarray(fix.move) != 0), 0.0, move)
        return Placement(self.scale * fix.scale, turns, tuple(float(m) for m in np.round(move, 2)), self.pose,
                         self.body)

    def options(self) -> str:
        """The `garment unpose` options that make it, but the pose's: " --scale 2.54 --turn z-up --move 0,-0.2,0"
        ("" for none)."""
        return "".join(((f" --scale {self.scale:.6g}" if abs(self.scale - 1.0) > 1e-9 else ""),
                        "".join(f" --turn {turn}" for turn in self.turns),
                        (f" --move {_move_option(np.array(self.move))}" if np.any(np.round(self.move, 2)) else "")))


#: The finest step (metres) of the search for a move that places a garment (`_shift_fix`).
MOVE_SEARCH_STEP_M = 0.01


def unpose_command(name: str, fix: Placement, placed: Placement | None = None) -> str:
    """The `garment unpose` command that places the garment file `name` so: `fix` after `placed` (what the command
    that found the fix had done to the file already: its options), as one command (`Placement.then`)."""
    whole = fix if placed is None else placed.then(fix)
    if whole.pose == " --pose tpose" and not whole.options():
        return f"bake the file as it is (`garment bake {name} ...`), without `garment unpose`"
    return f"`garment unpose {name}{whole.pose}{whole.options()}{whole.body}`"


def surface_blend(mesh: TriangleMesh, points: np.ndarray, hit: ClosestPoints | None = None,
                  normals: np.ndarray | None = None, reach: float = 0.0) -> sp.csr_matrix:
    """(N, V) float64 sparse, rows summing to 1: where each of `points` (N, 3) takes values of the mesh's V vertices.

    Every face whose closest point lies within the margin (`BLEND_SHARE` of the nearest distance, clipped to
    [`BLEND_MIN_M`, `BLEND_MAX_M`]) of the nearest contributes its closest point's barycentric coordinates,
    weighted by 1 - (its distance - the nearest) / margin: the rows are continuous in the points and the mesh
    (a point equally near two parts takes both halves; the nearest point alone jumps from one to the other).
    hit: `mesh.closest(points)`, where the caller has it (nothing else: the result is cached by the points and the
    mesh, `_LAST_BLEND`; each call gets a copy of it).
    normals: the points' own outward directions (N, 3), or None: a point takes only the faces facing its way
    (normals at a positive angle's cosine) wherever one lies within `reach` (metres) beyond its nearest face, the
    nearest of those standing for the nearest (the underside of a sleeve on an arm hanging by the torso faces the
    arm's side, not the torso's, though the torso is nearer: `core.unpose`)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    parts = (mesh.verts + 0.0, np.sort(mesh.faces, axis=1), points + 0.0,
             np.zeros(0) if normals is None else np.asarray(normals, dtype=np.float64) + 0.0)  # + 0.0: -0.0 as 0.0
    key = hashlib.blake2b(b"".join([np.ascontiguousarray(a).tobytes() for a in parts] + [repr(
        ([a.shape for a in parts], BLEND_SHARE, BLEND_MIN_M, BLEND_MAX_M, reach)).encode()])).digest()
    if _LAST_BLEND[0] == key:  # a model's or psd's bake blends the same points twice: weights, then contact anchors
        return _LAST_BLEND[1].copy()
    if not len(points) or not len(mesh.faces):
        return sp.csr_matrix((len(points), len(mesh.verts)))
    hit = mesh.closest(points) if hit is None else hit
    nearest, facing = hit.distance, np.zeros(len(points), dtype=bool)
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        fn = face_normals(mesh.verts, mesh.faces)

        def its_way(fi, pi):  # faces `fi` facing the way of points `pi`'s normals
            return np.einsum("pc,pc->p", fn[fi], normals[pi]) > 0.0

        # a point whose nearest face faces its way has it for the nearest facing one; the others look further
        best = np.where(its_way(hit.face_index, slice(None)), hit.distance, np.inf)
        away = np.flatnonzero(~np.isfinite(best))
        for pi, fi, _, dist in mesh.faces_within(points[away], hit.distance[away] + reach):
            ok = its_way(fi, away[pi])
            np.minimum.at(best, away[pi[ok]], dist[ok])
        facing = np.isfinite(best)
        nearest = np.where(facing, best, hit.distance)
    margin = np.clip(BLEND_SHARE * nearest, BLEND_MIN_M, BLEND_MAX_M)
    rows, cols, values = [], [], []
    for pi, fi, bary, dist in mesh.faces_within(points, nearest + margin):
        if facing.any():  # a point of a facing face: the faces facing away from it left out
            keep = ~facing[pi] | its_way(fi, pi)
            pi, fi, bary, dist = pi[keep], fi[keep], bary[keep], dist[keep]
        w = np.clip(1.0 - (dist - nearest[pi]) / margin[pi], 0.0, 1.0)
        rows.append(np.repeat(pi.astype(np.int32), 3))
        cols.append(mesh.faces[fi].reshape(-1).astype(np.int32))
        values.append((w[:, None] * bary).reshape(-1))
    blend = sp.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(len(points), len(mesh.verts)))  # a vertex met through several faces: summed
    blend.data /= np.repeat(np.asarray(blend.sum(axis=1)).reshape(-1), np.diff(blend.indptr))  # rows sum to 1
    _LAST_BLEND[:] = [key, blend]
    return blend.copy()


#: `surface_blend`'s last (key: a hash of its mesh, points and margins; result).
_LAST_BLEND: list = [None, None]


def transfer_weights(blend: sp.csr_matrix, body: Body, faces: np.ndarray, smooth_iterations: int = 0,
                     smooth_strength: float = 0.5) -> np.ndarray:
    """(V, J) float32 skinning weights, rows summing to 1: the body's weights at each point's `surface_blend` of
    the body's surface, then `smooth_iterations` passes of `smooth_over_graph` over the garment's `faces`."""
    weights = np.asarray(blend @ body.weights.astype(np.float64)).astype(np.float32)
    if smooth_iterations > 0:
        weights = smooth_over_graph(weights, faces, smooth_iterations, smooth_strength)
    return weights / np.maximum(weights.sum(axis=1, keepdims=True), 1e-12)


#: The joints whose weights `spread_leg_weights` spreads (SMPL's names; SMPL+H's and SMPL-X's, the first 22 of
#: theirs, are the same: `core.body.default_joint_names`).
LEG_JOINTS = ("left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_foot",
              "right_foot")
#: How far (metres, over the garment's surface) LBS spreads the weights of cloth skinned to the legs by default
#: (`spread_leg_weights`). Skinned to the nearest body part, the cloth between the legs of a skirt or dress goes
#: with one thigh or the other and tears between them at strides (an edge over twice its rest length and 2 cm
#: longer): with 10 passes of smoothing alone, the example skirt in 56 of the example walk's 91 frames and 56 of
#: the run's 76, the dress in 72 and 76, the jumpsuit in 19 of the run's. Spread over 0.1 m: the skirt and the
#: jumpsuit in none, the dress in 8 and 41; on the held-out brisk walk's first 15 frames the skirt's and dress's
#: error against the simulator 47.2 -> 44.5 and 47.3 -> 44.3 mm; the share of vertices inside the body at most
#: 0.03 points above before on those motions; the t-shirt, skinned to the torso and arms, as before. Over 17
#: motions (the six examples and eleven of `core.motiongen`'s: kicks, sitting, crouches, bends) torn frames of
#: 2,177 per garment: skirt 850 -> 254, dress 1,065 -> 447, jumpsuit 357 -> 53; vertices inside on average skirt
#: 0.67 -> 0.69 %, dress 1.10 -> 1.23, jumpsuit 1.30 -> 1.32, t-shirt 2.71 -> 2.78, trousers 0.80 -> 0.70, most
#: where sitting folds the cloth over the thighs (the dress sitting down 2.6 -> 3.3 %).
#: Wider spreads tear less and come closer to the simulator (0.15 m: the dress torn in 0 and 7 frames, 42.6 mm;
#: 0.2 m: none, 41.4 mm) but the cloth in front of a raised thigh follows both legs and the knee shows through
#: the dress on the run (vertices inside 0.55 % -> 0.87 % at 0.15 m, 1.90 % at 0.2 m).
LEG_SPREAD_M = 0.1
#: Most passes `spread_leg_weights` makes (a garment of edges under 2.2 mm spreads over less than LEG_SPREAD_M; the
#: example dress made of 51,000 vertices, edges of 4.6 mm, takes about 950 passes in 2 s, once per garment).
LEG_SPREAD_MAX_PASSES = 1000


def spread_passes_over(edge_m: float, spread_m: float, most: int, strength: float = 0.5) -> int:
    """Passes of `graph_smoothing` (`strength`) that spread values over about `spread_m` metres of a mesh of
    edges `edge_m` long: a pass spreads a value's variance by about strength x edge^2 (a random walk's),
    so (spread / edge)^2 / strength of them, rounded (none where the edges are longer than twice the spread);
    at most `most`, none on a degenerate mesh."""
    if not edge_m > 0:
        return 0
    return int(min(np.round((spread_m / edge_m) ** 2 / strength), most))


def spread_leg_weights(weights: np.ndarray, garment: Garment, body: Body,
                       spread_m: float = LEG_SPREAD_M) -> tuple[np.ndarray, int]:
    """(weights (V, J) float32, rows summing to 1; the passes made): each vertex's weights blended with the same
    weights smoothed over about `spread_m` of the garment's surface (`spread_passes_over`), by the share of its
    weight on the legs (`LEG_JOINTS`), so cloth between the legs follows both and sleeves still follow the arms;
    the blend changes continuously with the weights. Unchanged on a body without those joint names."""
    legs = [j for j, name in enumerate(body.joint_names) if name in LEG_JOINTS]
    share = weights[:, legs].astype(np.float64).sum(axis=1, keepdims=True) if legs else None
    edges = mesh_edges(garment.faces)
    if share is None or not share.any() or not len(edges):
        return weights, 0
    passes = spread_passes_over(float(np.median(edge_lengths(garment.vertices, edges))), spread_m,
                                LEG_SPREAD_MAX_PASSES)
    if not passes:
        return weights, 0
    used = np.flatnonzero(weights.any(axis=0))  # a joint of no weight has none after smoothing either
    wide = np.zeros(weights.shape, dtype=np.float64)
    wide[:, used] = smooth_over_graph(weights[:, used].astype(np.float64), garment.faces, passes)
    wide /= np.maximum(wide.sum(axis=1, keepdims=True), 1e-12)
    out = share * wide + (1.0 - share) * weights
    return (out / np.maximum(out.sum(axis=1, keepdims=True), 1e-12)).astype(np.float32), passes


def transfer_shapedirs(blend: sp.csr_matrix, body: Body) -> np.ndarray:
    """(V, 3, S) float64 shape blend shapes, metres per unit beta: the body's at each point's `surface_blend`
    (as in `transfer_weights`)."""
    shapedirs = body.shapedirs.reshape(len(body.shapedirs), -1).astype(np.float64)
    return np.asarray(blend @ shapedirs).reshape(blend.shape[0], *body.shapedirs.shape[1:])


def check_rest_fit(garment: Garment, body: Body, mesh: TriangleMesh, signed: np.ndarray, name: str,
                   placed: Placement | None = None) -> None:
    """Refuse a garment that is not on the body's rest surface, warn about one partly inside it.

    mesh: the body's rest surface; signed: (V,) signed distances of the garment's vertices to it (metres,
    negative inside). Raises InputError, naming the fix when one of `FRAME_FIXES` puts the garment on the body,
    when the garment is far from the body (median distance over MAX_MEDIAN_BODY_DISTANCE_M, its closest 5 %
    over MAX_NEAR_BODY_DISTANCE_M) or more than REST_INSIDE_FRAME_SHARE of its vertices are inside and a fix
    explains it, or when a fix puts it FRAME_FIX_GAIN times closer to the body (`FRAME_FIX_SUSPECT_MEDIAN_M`),
    or when it reaches above the body's head standing on y = 0 and the drop to the soles puts it on the body
    (`ABOVE_HEAD_M`: a loose skirt authored on a body standing on the floor); logs a warning above
    REST_INSIDE_WARN_SHARE otherwise. A garment written in other units than it was read in (`UNIT_MIXUPS`) is
    refused naming the scale that puts it on the body. placed: see `bind_garment`.
    """
    if placed is None:  # the commands named put the garment on this body
        placed = Placement(body="" if body.path is None else f" --body {body.path}")
    body_piece = _body_piece(garment, body, signed)
    if body_piece:
        raise InputError(f"garment mesh '{name}': expected the garment alone, got {body_piece}: the avatar exported "
                         f"with the garment? export the garment without it")
    prop = _prop_piece(garment, body, signed)
    if prop:
        from formats.obj import USD_SUFFIXES

        usd = " (or name the garment's mesh 'garment': it is read alone)" if str(name).lower().endswith(
            USD_SUFFIXES) else ""
        raise InputError(f"garment mesh '{name}': expected the garment alone, got {prop}: a ground plane or a prop "
                         f"exported with the garment? export the garment without it{usd}")
    median, near = (float(d) for d in np.percentile(np.abs(signed), [50, 5]))
    inside = float(np.mean(signed < -REST_INSIDE_DEPTH_M))
    far = _rests_nowhere(median, near)
    fix = maybe = None
    if far or inside > REST_INSIDE_FRAME_SHARE or median > FRAME_FIX_SUSPECT_MEDIAN_M:
        fix, maybe = _scale_fix(garment.vertices, body, mesh, name, near, inside, placed, median)
        if not fix:  # no unit mix-up: a frame mix-up? (a garment near the body must be put far closer by it)
            closer = None if far or inside > REST_INSIDE_FRAME_SHARE else (median, near)
            fix = _frame_fix(garment.vertices, body, mesh, closer_than=closer, name=name, placed=placed)
    lift = None if fix else _lifted_by_floor(garment, body, mesh, name, placed)
    expected = "expected a garment authored on the body's rest pose (Y-up, T-pose, metres"
    if not (far or fix or lift) and inside > A_POSE_CHECK_SHARE:
        key = (_content_key(garment.vertices, garment.faces, body.v_template, body.faces), body.name, name, placed)
        if key not in _SEARCHED:  # a second binding of the same garment (lbs after the model) searches no more
            unposed = _unposed_angle(garment, body, mesh, signed, median)
            _SEARCHED[key] = (unposed, (None, None) if unposed is not None or inside <= REST_INSIDE_WARN_SHARE
                              else _shift_fix(garment.vertices, body, mesh, name, placed))
            while len(_SEARCHED) > 8:
                _SEARCHED.pop(next(iter(_SEARCHED)))
        unposed = _SEARCHED[key][0]
        if unposed is not None:  # its sleeves or arms lowered: baked so, every frame's arms were as far off
            from core.unpose import A_POSE_ARM_DEGREES

            angle = "" if unposed == A_POSE_ARM_DEGREES else f" --arm-angle {unposed:g}"
            raise InputError(f"garment mesh '{name}': {expected}), got {inside:.1%} of its vertices more than "
                             f"{REST_INSIDE_DEPTH_M * 1e3:.0f} mm inside the body; it fits when unposed from an A-pose "
                             f"(arms lowered {unposed:g} degrees): `garment unpose {name} --pose apose{angle}"
                             f"{placed.options()}{placed.body}`")  # after the scale, turns and move given
    if not (far or fix or lift) and inside <= REST_INSIDE_WARN_SHARE:
        if maybe:  # 2.5 times too large, or loose: told, not refused
            log.warning("garment mesh '%s': it stands off the body (%.2f m from it, median; its closest 5 %% %.0f cm "
                        "or more); %s: in other units? (a loose garment fits closer shrunk too)", name, median,
                        near * 100, maybe)
        return
    if lift and not far and inside <= REST_INSIDE_FRAME_SHARE:
        above = float(garment.vertices[:, 1].max() - body.v_template[:, 1].max())
        raise InputError(f"garment mesh '{name}': {expected}, resting on it), got its top {above:.2f} m above the "
                         f"body's head and none of it below y = 0 (the floor); {lift}")
    fix = fix or lift
    if fix:  # an A-pose besides? (an avatar's A-pose on the floor)
        fix = _then_a_pose(garment, body, mesh, fix, name, placed) or fix
    hint = f"; {fix}" if fix else f"; {maybe}: in other units?" if maybe else ""
    span = float(np.ptp(garment.vertices[np.unique(garment.faces)], axis=0).max())
    if far and not fix and span > GARMENT_MAX_SPAN_M:  # under the unit check's 10 units, over any garment
        hint = (f"; it spans {span:.2f} m, more than a garment does (under {GARMENT_MAX_SPAN_M:g} m): in other "
                f"units? scale it to metres (S metres per unit): `garment unpose {name}{placed.pose} --scale S"
                f"{placed.body}`")
    if far or (fix and inside <= REST_INSIDE_FRAME_SHARE):
        raise InputError(f"garment mesh '{name}': {expected}, resting on it), got a median distance of {median:.2f} m "
                         f"and its closest 5 % {near:.2f} m or more from the body{hint}")
    if fix:
        raise InputError(f"garment mesh '{name}': {expected}, outside it), got {inside:.0%} of its vertices more "
                         f"than {REST_INSIDE_DEPTH_M * 1e3:.0f} mm inside the body{hint}")
    _, (shift, nearer) = _SEARCHED[key]  # searched above (over A_POSE_CHECK_SHARE inside): no A-pose
    if shift:
        raise InputError(f"garment mesh '{name}': {expected}, outside it), got {inside:.0%} of its vertices more "
                         f"than {REST_INSIDE_DEPTH_M * 1e3:.0f} mm inside the body; {shift}")
    cause = ("authored on another body shape? pass that body with --body; in another pose? `garment unpose`"
             + (f"; {nearer}" if nearer else ""))
    log.warning("garment mesh '%s': %.1f %% of its vertices lie more than %.0f mm inside the body's rest surface "
                "(%s); expect them inside the body (--push-out moves them out)", name, inside * 100,
                REST_INSIDE_DEPTH_M * 1e3, cause)


def fit_in_units(read, body: Body, units: list[tuple[str, float]], name: str) -> str | None:
    """For a garment file `name` refused as too large for metres (`core.garment.UnitsError`), which of its `units`
    ([(unit, scale)]) puts it on `body`, as "in centimetres (scaled by 0.01) it rests on the body: `garment unpose
    ...`" or, where a frame mix-up comes with the units (3ds Max: centimetres, Z-up), "in centimetres (scaled by
    0.01) it fits when rotated ...: `garment unpose ... --scale 0.01 --turn z-up`": of those that rest on it
    (`check_rest_fit`) or name a fix, the one whose `_fit_score` is least once placed so (the trousers in
    centimetres turned 30 degrees rest on the body in inches, 2.54 times too large, 0.32 m from it: 382 mm against
    26 once turned back in centimetres); a fix naming another scale or the same score: the one that rests; None
    where none does (it was told "centimetres or inches?", then refused again once scaled). read: scale -> the
    file's Garment. A candidate's warnings (welded seams, partly inside) are not the file's: the caller silences
    them (`garmentcli.common.read_garment_on`)."""
    mesh = TriangleMesh(body.v_template, body.faces)
    found = []  # (score placed, names another scale, the text)
    for unit, scale in units:
        placed = Placement(scale=scale, body="" if body.path is None else f" --body {body.path}")
        said = f"in {unit} (scaled by {scale:g})"
        garment = None
        try:
            garment = read(scale)
            check_rest_fit(garment, body, mesh, mesh.signed_closest(garment.vertices)[1], name, placed)
        except InputError as refused:
            text = str(refused)
            told = re.search(r"it fits (better )?when", text)  # a frame, unit or pose fix; a move's
            if garment is not None and told:
                fix = text[told.start():]
                found.append((_placed_score(mesh, garment.vertices, fix, name, scale), "scaled by" in fix,
                              f"{said} {fix}"))
            continue
        found.append((_placed_score(mesh, garment.vertices, "", name, scale), False,
                      f"{said} it rests on the body: {unpose_command(name, Placement(), placed)}"))
    return min(found, key=lambda f: (round(f[0] * 1e4), f[1]))[2] if found else None  # (to 0.1 mm: the same
    # placement reached by another unit's fix rounds otherwise)


def _placed_score(mesh: TriangleMesh, vertices: np.ndarray, fix: str, name: str, scale: float) -> float:
    """`_fit_score` of a garment's `vertices` (read at `scale`) once placed as the `garment unpose` command that
    `fix` ends with names for the file `name` (its scale, turns and move: a pose's unposing is not made), or as they
    are without one."""
    named = _named_placement(fix, name)
    if named is not None:
        vertices = replace(named, scale=named.scale / scale).apply(vertices)
    return _fit_score(mesh.signed_distance(np.asarray(vertices, dtype=np.float64), exact=False))


def _named_placement(fix: str, name: str) -> Placement | None:
    """The `Placement` (scale, turns, move and pose, not the body) of the `garment unpose` command for the file
    `name` that the text `fix` ends with (`unpose_command`), or None without one."""
    command = re.search(r"`garment unpose (.*)`$", fix)
    if not command or not command[1].startswith(name):
        return None
    options = command[1][len(name):]
    scale, move = re.search(r" --scale (\S+)", options), re.search(r" --move (\S+)", options)
    pose = re.match(r"( --pose \S+( --arm-angle \S+)?)", options)
    return Placement(float(scale[1]) if scale else 1.0, tuple(re.findall(r" --turn (\S+)", options)),
                     tuple(float(m) for m in move[1].split(",")) if move else (0.0, 0.0, 0.0),
                     pose[1] if pose else " --pose tpose")


def _then_a_pose(garment: Garment, body: Body, mesh: TriangleMesh, fix: str, name: str,
                 placed: Placement) -> str | None:
    """`fix` ("it fits when moved down by 0.90 m ...: `garment unpose ...`") with the A-pose the garment is in
    besides, where the garment placed so is more than A_POSE_CHECK_SHARE inside the body and unposing it from an
    A-pose puts it on it (`_unposed_angle`): "it fits when moved down by 0.90 m ..., then unposed from an A-pose
    (arms lowered 45 degrees): `garment unpose ... --pose apose --scale 0.001 --move 0,-0.9,0`" (Marvelous
    Designer's avatars stand A-posed on the floor, in millimetres: the drop was named, then, once made, the
    A-pose); else None. placed: what was done to the file to make `garment` (the command names the file's whole)."""
    whole = _named_placement(fix, name)
    if whole is None or whole.pose != " --pose tpose":
        return None
    file = (garment.vertices.astype(np.float64) - np.asarray(placed.move)) @ placed.rotation / placed.scale
    fixed = replace(garment, vertices=whole.apply(file).astype(np.float32))
    signed = mesh.signed_distance(fixed.vertices, exact=False)
    if np.mean(signed < -REST_INSIDE_DEPTH_M) <= A_POSE_CHECK_SHARE:
        return None
    angle = _unposed_angle(fixed, body, mesh, signed, float(np.median(np.abs(signed))))
    if angle is None:
        return None
    from core.unpose import A_POSE_ARM_DEGREES

    start = fix.index(": `garment unpose")
    what = re.sub(r" \(\d+% of it then still inside the body: [^)]*\)", "", fix[:start])
    option = "" if angle == A_POSE_ARM_DEGREES else f" --arm-angle {angle:g}"
    command = fix[start:].replace(f"`garment unpose {name} --pose tpose", f"`garment unpose {name} --pose apose{option}",
                                  1)
    return f"{what}, then unposed from an A-pose (arms lowered {angle:g} degrees){command}"


#: A piece of the garment file (connected component) with at least half the body's vertices, this share of them
#: within BODY_PIECE_SKIN_M of the rest body's surface, is the body itself (an avatar exported with the garment).
BODY_PIECE_SHARE = 0.95
BODY_PIECE_SKIN_M = 0.001
#: A piece spanning this share of the rest body's extent on every axis (head to soles, fingertip to fingertip, back
#: to front), its median distance from the body's skin at most BODY_PIECE_NEAR_M, is an avatar too: one remeshed
#: or pushed off the skin (the example skirt with the body 3 mm off its skin baked as a garment of 15,364
#: vertices, the skirt 76 mm off with the model). One of another shape lies further (betas[0] = 1: 17 mm, warned
#: of as a garment partly inside); a suit closed around the whole body 2 cm off it (the simulator tests' shell)
#: is cloth.
BODY_PIECE_SPAN = 0.9
BODY_PIECE_NEAR_M = 0.01


def _body_piece(garment: Garment, body: Body, signed: np.ndarray) -> str:
    """"" or, for a piece of a garment of several that is the body itself (`BODY_PIECE_SHARE`), what it is:
    "piece 2 of 2 (6,890 vertices, 100 % of them on the body's skin)". A skin-tight garment covers less than half
    the body; a garment of one piece on the skin (a second skin, as tests use) is left alone."""
    n, labels = garment.pieces
    if n < 2:
        return ""
    sizes = np.bincount(labels, minlength=n)
    for k in np.flatnonzero(sizes >= 0.5 * body.n_vertices):
        on_skin = float(np.mean(np.abs(signed[labels == k]) < BODY_PIECE_SKIN_M))
        if on_skin >= BODY_PIECE_SHARE:
            return f"piece {k + 1} of {n} ({sizes[k]:,} vertices, {on_skin:.0%} of them on the body's skin)"
    extent = np.ptp(body.v_template, axis=0)
    for k in np.flatnonzero(sizes >= 4):
        piece = labels == k
        near = float(np.median(np.abs(signed[piece])))
        if (np.ptp(garment.vertices[piece], axis=0) >= BODY_PIECE_SPAN * extent).all() and near <= BODY_PIECE_NEAR_M:
            return (f"piece {k + 1} of {n} ({sizes[k]:,} vertices spanning the body from head to soles and "
                    f"fingertip to fingertip, {near * 1e3:.0f} mm from its skin (median))")
    return ""


def _rests_nowhere(median: float, near: float) -> bool:
    """Whether points whose median distance from the rest body is `median` and whose closest 5 % lie `near`
    (metres) or more from it rest on it nowhere: the median over MAX_MEDIAN_BODY_DISTANCE_M, the closest 5 % over
    MAX_NEAR_BODY_DISTANCE_M."""
    return bool(median > MAX_MEDIAN_BODY_DISTANCE_M and near > MAX_NEAR_BODY_DISTANCE_M)


#: A piece no thicker than this (metres, up and down) whose top lies no more than this above the rest body's soles
#: and that reaches under both feet (the body's vertices within GROUND_FEET_M of its soles) is the ground, however
#: finely divided (a 2 m plane of 100 x 100 vertices has over 5 % of them by the feet); a dress's train lying on the
#: floor behind the feet, a sandal's sole under one foot, are cloth (audit 30).
GROUND_FLAT_M = 0.005
GROUND_FEET_M = 0.05
#: A piece resting on the body nowhere that comes within this (metres) of the rest of the garment is cloth of it (a
#: train lying on the floor behind the dress's hem, a cape's panel by the shoulders), not a prop.
PROP_APART_M = 0.05


def _prop_piece(garment: Garment, body: Body, signed: np.ndarray) -> str:
    """"" or, for a piece of a garment of several that rests on the body nowhere (`_rests_nowhere`) while the rest
    of the garment does, or lies flat at its soles (`GROUND_FLAT_M`), what it is: "piece 2 of 2 (4 vertices, 0.62
    m from the body (median), its closest 5 % 0.45 m or more)": not cloth worn but a ground plane or a prop
    exported with it (a USD stage's 1 m ground quad under the feet baked with the skirt as cloth, skinned to the
    feet). A garment resting nowhere as a whole is left to the unit and frame checks; a ball gown's skirt, however
    far from the legs, is one piece with its bodice, as is a train on the floor with its dress; a piece within
    PROP_APART_M of the rest is cloth too."""
    n, labels = garment.pieces
    if n < 2:
        return ""
    distance = np.abs(signed)
    soles = float(body.v_template[:, 1].min())
    order = np.argsort(labels, kind="stable")
    sizes = np.bincount(labels, minlength=n)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    points = garment.vertices[order]
    top, bottom = np.maximum.reduceat(points[:, 1], starts), np.minimum.reduceat(points[:, 1], starts)
    feet = body.v_template[body.v_template[:, 1] <= soles + GROUND_FEET_M][:, [0, 2]]
    under = np.ones(n, dtype=bool)  # the piece reaches under both feet, on both axes along the ground
    for axis, column in ((0, 0), (1, 2)):
        under &= (np.minimum.reduceat(points[:, column], starts) <= feet[:, axis].min()) & (
            np.maximum.reduceat(points[:, column], starts) >= feet[:, axis].max())
    ground = (top - bottom <= GROUND_FLAT_M) & (top <= soles + GROUND_FLAT_M) & under
    # (pieces of 3 vertices or more, a face's: a vertex no face uses is no piece; only those reaching beyond
    # MAX_MEDIAN_BODY_DISTANCE_M can rest nowhere: an unwelded file of 100,000 pieces is not looked at one by one)
    for k in np.flatnonzero((sizes >= 3) & (ground | (np.maximum.reduceat(distance[order], starts)
                                                       > MAX_MEDIAN_BODY_DISTANCE_M))):
        members = order[starts[k]:starts[k] + sizes[k]]
        if ground[k]:
            return f"piece {k + 1} of {n} ({len(members):,} vertices, flat at the body's soles)"
        median, near = np.percentile(distance[members], [50, 5])
        if not _rests_nowhere(median, near):
            continue
        if _rests_nowhere(*np.percentile(np.delete(distance, members), [50, 5])):
            return ""  # the rest too: the whole garment is off the body (a unit or frame mix-up)
        from scipy.spatial import cKDTree

        rest = np.delete(garment.vertices, members, axis=0)
        if cKDTree(rest).query(garment.vertices[members], distance_upper_bound=PROP_APART_M)[0].min() <= PROP_APART_M:
            continue  # by the rest of the garment: cloth hanging from it (a train on the floor by the hem)
        return (f"piece {k + 1} of {n} ({len(members):,} vertices, resting on the body nowhere: {median:.2f} m from "
                f"it (median), its closest 5 % {near:.2f} m or more)")
    return ""


#: The outcomes of the unpose and move searches of the last garments bound, by content (`_content_key`), the body's
#: name (which the move's text speaks of) and the garment's: (fits unposed, `_shift_fix`'s (refusal, hint)).
_SEARCHED: dict = {}


def _content_key(*arrays: np.ndarray) -> str:
    import hashlib

    h = hashlib.sha1()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


#: A garment more than this share inside the rest body is tried unposed from A-poses (`_unposed_angle`; the example
#: garments: none inside; the example jumpsuit skinned into the 45-degree A-pose: 1.2 %, the t-shirt at 30: 2.3 %).
A_POSE_CHECK_SHARE = 0.005
#: The arm angles (degrees lowered from the T-pose) a garment is tried unposed from: avatars' A-poses; the others
#: only where the first leaves at most A_POSE_TRY_SHARE of what was inside (the t-shirt at 30 degrees unposed from
#: 45: 2.3 -> 1.4 %; garments moved off the body: as much or more; each try about 1.5-5 s on the t-shirt).
A_POSE_CHECK_DEGREES = (45.0, 30.0, 60.0)
A_POSE_TRY_SHARE = 0.75
#: Only a garment whose vertices inside the rest body lie by its upper arms is tried: their nearest body vertices'
#: weights on the collars, shoulders and elbows (SMPL's joints 13, 14, 16-19) at least A_POSE_ARM_WEIGHT on average
#: (the example t-shirt and jumpsuit skinned into A-poses of 30-75 degrees: 0.36-1.0, their cloth inside at the
#: shoulders; the examples moved 0.1-0.27 m: 0.23 at most, the dress 0.44; a suit around the whole body, inside at
#: the hands, feet and head: 0, whose three unposes took 266 s at 50,000 vertices).
A_POSE_ARM_JOINTS = (13, 14, 16, 17, 18, 19)
A_POSE_ARM_WEIGHT = 0.3


def _unposed_angle(garment: Garment, body: Body, mesh: TriangleMesh, signed: np.ndarray,
                   median: float) -> float | None:
    """The arm angle of `A_POSE_CHECK_DEGREES` from whose A-pose unposing the garment (`core.unpose`) puts it on
    the rest body best, or None where none does: at most REST_INSIDE_WARN_SHARE and under half of what was inside
    left inside, its median distance not 5 mm further out (`median`, metres, as it is; `signed`: its vertices'
    signed distances to the rest body `mesh`, metres). (The example t-shirt skinned into an A-pose: 4.3 % inside,
    0 % unposed; shrunk by 5 % instead: 2.3 %, 10.4 % unposed; a garment in the T-pose unposed from an A-pose takes
    its sleeves above the arms: further out.) Not tried where the cloth inside is not by the arms
    (`A_POSE_ARM_WEIGHT`); not told where a move of a few centimetres (`_near_move`) leaves as little inside (the
    example dress moved 3 cm up, 0.6 % inside: unposed from 30 degrees it fitted, 33 mm from where it belongs)."""
    from scipy.spatial import cKDTree

    from core.unpose import a_pose, unpose_garment

    inside = float(np.mean(signed < -REST_INSIDE_DEPTH_M))
    if body.layout is None or not inside:
        return None
    _, nearest = cKDTree(body.v_template).query(garment.vertices[signed < -REST_INSIDE_DEPTH_M])
    arms = [j for j in A_POSE_ARM_JOINTS if j < body.n_joints]
    if float(np.asarray(body.weights)[nearest][:, arms].sum(axis=1).mean()) < A_POSE_ARM_WEIGHT:
        return None  # not by the arms: no sleeves lowered (the cloth of a garment moved or shrunk)
    found = []
    for degrees in A_POSE_CHECK_DEGREES:
        try:
            rest, _ = unpose_garment(garment, body, a_pose(body, degrees))
        except InputError:
            continue
        signed = mesh.signed_distance(rest.vertices, exact=False)
        left, out = float(np.mean(signed < -REST_INSIDE_DEPTH_M)), float(np.median(np.abs(signed)))
        if left <= min(REST_INSIDE_WARN_SHARE, inside / 2) and out <= median + 0.005:
            found.append((_fit_score(signed), degrees, left))
        elif degrees == A_POSE_CHECK_DEGREES[0] and left > A_POSE_TRY_SHARE * inside:
            break  # no A-pose's cloth: the first try brings none of it out
    if not found:
        return None
    score, degrees, left = min(found)
    _, near = _near_move(mesh, _shift_sample(garment.vertices.astype(np.float64)))
    if round(near[2] * 200) <= round(left * 200) and near[0] <= SHIFT_AXIS_GAIN * score:
        return None  # a move of a few centimetres brings as much out: a garment moved (the example dress 3 cm up)
    return degrees


#: How far (metres, along each axis) `_near_move` moves a garment: a slip of a tool, not another body's origin.
NEAR_MOVE_M = 0.03


def _near_move(mesh: TriangleMesh, v: np.ndarray,
               reach: float | None = None) -> tuple[np.ndarray, tuple[float, float, float]]:
    """The move of points `v` (N, 3) by at most `reach` (metres; default NEAR_MOVE_M) along each axis (up, then
    sideways, then forwards; whole centimetres) that leaves the least share inside the body's rest surface `mesh`
    (to 0.5 %), then the least `_shift_score`, twice over (a move up first taken for one forwards is undone in the second
    round): (move, `_shift_score` there)."""
    reach = NEAR_MOVE_M if reach is None else reach
    move = np.zeros(3)
    for axis in 2 * (1, 0, 2):
        tried = []
        for d in np.round(np.arange(-reach, reach + 1e-9, MOVE_SEARCH_STEP_M), 2):
            m = move.copy()
            m[axis] = d
            score = _shift_score(mesh, v + m)
            tried.append(((round(score[2] * 200), score[0]), m, score))
        _, move, best = min(tried, key=lambda t: t[0])
    return move, best


def _frame_fix(vertices: np.ndarray, body: Body, mesh: TriangleMesh,
               closer_than: tuple[float, float] | None = None, name: str = "GARMENT",
               placed: Placement | None = None) -> str | None:
    """The one of `FRAME_FIXES` that puts the garment on the body best (median distance at most
    FRAME_FIX_MEDIAN_M, at most REST_INSIDE_WARN_SHARE of it inside, or, without `closer_than`, its `_fit_score`
    FRAME_FIX_SCORE_GAIN times smaller), as "it fits when ..." (`_fix_text`), or None.
    closer_than: (median, closest 5 %) distances of the garment as it is (metres): the fix must also make both
    FRAME_FIX_GAIN times smaller or more."""
    v = np.asarray(vertices, dtype=np.float64)
    soles = -float(body.v_template[:, 1].min())  # how far the body's soles are below its origin
    as_is = mesh.signed_distance(v, exact=False) if closer_than is None else None
    base = None if as_is is None else _fit_score(as_is)
    sample = _shift_sample(v)
    scored = []  # (score, what, turns, drop, moved vertices, share inside) of the fixes putting it near the body,
    # partly inside
    fitting = []  # (score, what, turns, drop, share inside) of those that fit
    nearest = np.inf  # the least `_fit_score` of a fix putting it within FRAME_FIX_MEDIAN_M (median)
    for what, turns, on_floor in FRAME_FIXES:
        if on_floor and soles <= 0.0:
            continue  # a body standing on y = 0 itself: no floor to take off
        rotation, drop = _turns_rotation(turns), soles if on_floor else 0.0
        if np.median(np.abs(mesh.signed_distance(sample @ rotation.T - [0.0, drop, 0.0], exact=False))) > \
                FRAME_FIX_SCREEN * FRAME_FIX_MEDIAN_M:
            continue  # far from the body (most turns): the whole garment is not looked at
        moved = v @ rotation.T - [0.0, drop, 0.0]
        signed = mesh.signed_distance(moved, exact=False)
        median, near = np.percentile(np.abs(signed), [50, 5])
        inside = float(np.mean(signed < -REST_INSIDE_DEPTH_M))
        fits = median <= FRAME_FIX_MEDIAN_M and inside <= REST_INSIDE_WARN_SHARE
        if median <= FRAME_FIX_MEDIAN_M:
            nearest = min(nearest, _fit_score(signed))
        if closer_than is not None:
            fits = fits and median * FRAME_FIX_GAIN <= closer_than[0] and near * FRAME_FIX_GAIN <= closer_than[1]
        elif fits and rotation[1, 1] < 0.0 and _fit_score(signed) * FRAME_FIX_SCORE_GAIN > base:
            fits = False  # upside down, but hardly better: a tube fits either way up (see FRAME_FIX_SCORE_GAIN)
        elif not fits and median <= FRAME_FIX_MEDIAN_M:
            scored.append((_fit_score(signed), what.format(drop=drop), turns, drop, moved, inside))
        if fits:
            fitting.append((_fit_score(signed), what.format(drop=drop), turns, drop, inside))
    # One that fits but sits FRAME_FIX_SCORE_GAIN times worse than another that leaves some of it inside is by
    # chance (trousers slimmed for another body, on the floor: upside down and turned sideways fitted, 9.7 cm from
    # the body, median, 5.6 times worse than the drop, which leaves 3.8 % inside)
    fitting = [f for f in fitting if f[0] <= FRAME_FIX_SCORE_GAIN * nearest]
    if fitting:  # the best of those that fit, an earlier (fewer changes) where about as good
        best = min(f[0] for f in fitting)
        score, what, turns, drop, inside = next(f for f in fitting if f[0] <= FRAME_FIX_PREFER * best)
        if closer_than is None and not drop:  # a turn that a move of a few centimetres matches: no turn
            _, near = _near_move(mesh, sample, SHIFT_SIDE_RANGE_M[0] - MOVE_SEARCH_STEP_M)
            if round(near[2] * 200) <= round(inside * 200) and near[0] <= FRAME_FIX_TIE * score:
                return None  # (the dress moved 4 cm back, 17 % inside, was told to face backwards: audit 30)
        return _fix_text(what, turns, np.array([0.0, -drop, 0.0]), inside, name, placed)
    # Turned about the up axis as well: as it is, or after the two turns or drops that fit best, partly inside
    # (written Z-up from a scene whose avatar stood turned: z-up fitted, 22 % inside, blamed on the body's shape)
    scored.sort(key=lambda t: t[0])
    tried = [] if as_is is None else ([("", (), 0.0, v, float(np.mean(as_is < -REST_INSIDE_DEPTH_M)))]
                                      + [entry[1:] for entry in scored[:2]])
    for what, turns, drop, moved, inside in tried:
        yaw = _yaw_fix(moved, mesh, inside)
        if yaw:
            degrees, left = yaw
            words = f"rotated {degrees:+d} degrees about Y (the up axis)"
            return _fix_text(f"{what}, then {words}" if what else words, turns + (f"y{degrees:+d}",),
                             np.array([0.0, -drop, 0.0]), left, name, placed)
    # None fits outright (in order): the one that fits best, FRAME_FIX_SCORE_GAIN times better than as it is, unless
    # another fits nearly as well (within FRAME_FIX_TIE): then neither is told. Authored on another body, it may sit
    # higher or lower on this one (a mannequin's shirt, dropped to this body's soles, reached the chin; a Z-up
    # outfit of SMPL's, turned, sat 0.25 m low): climbed from there (`_shift_climb`), the move is told too.
    if (not scored or base is None or scored[0][0] * FRAME_FIX_SCORE_GAIN > base
            or (len(scored) > 1 and scored[1][0] <= FRAME_FIX_TIE * scored[0][0])):
        return None
    _, what, turns, drop, moved, _ = scored[0]
    sample = _shift_sample(moved)
    start = _shift_score(mesh, sample)
    ups = np.round(np.arange(-FRAME_FIX_CLIMB_M[1], FRAME_FIX_CLIMB_M[1] + 1e-9, 0.02), 2)
    up = min(ups, key=lambda dy: _shift_score(mesh, sample + [0.0, dy, 0.0])[0])  # first up or down, 2 cm steps
    shift, best = _shift_climb(mesh, sample, np.array([0.0, up, 0.0]),
                               _shift_score(mesh, sample + [0.0, up, 0.0]), reach=FRAME_FIX_CLIMB_M)
    if best[0] * SHIFT_AXIS_GAIN > start[0]:
        shift = np.zeros(3)  # no better than the fix alone
    if shift.any():
        what += f", then moved {_move_words(shift)}"
    inside = float(np.mean(mesh.signed_distance(moved + shift, exact=False) < -REST_INSIDE_DEPTH_M))
    return _fix_text(what, turns, shift - [0.0, drop, 0.0], inside, name, placed)


#: A garment that no fix of `FRAME_FIXES` puts on the body, over REST_INSIDE_FRAME_SHARE inside, is tried turned about
#: the up axis (as it is, and after the two fixes that put it nearest, partly inside: Z-up and turned, lifted and
#: turned) by every YAW_STEP_DEG (on `SHIFT_SAMPLE` of its vertices), then by whole degrees about the best:
#: refused naming the turn where it fits turned so (at most REST_INSIDE_WARN_SHARE and a third of what was inside
#: left inside, its median distance at most FRAME_FIX_MEDIAN_M): exported from a scene whose avatar stood turned
#: (the example t-shirt turned 15 degrees: 9.6 % inside, baked 44 mm off with LBS, warned of as another body shape).
#: Only where the turn is sharp: its score YAW_SHARPNESS times smaller than 10 degrees either side (the example
#: t-shirt, jumpsuit and trousers: 1.37, 1.14, 1.07; the loose dress and skirt, whose turn their distance to the
#: body hardly tells, 1.001-1.002: their best turns lay 8-23 degrees from the right one).
YAW_STEP_DEG = 5
YAW_SHARPNESS = 1.03


def _yaw_fix(v: np.ndarray, mesh: TriangleMesh, inside: float) -> tuple[int, float] | None:
    """(degrees, the share then inside) of the turn about the up axis (`YAW_STEP_DEG`; `--turn y-15`) that puts
    points `v` (V, 3), a share `inside` of them inside the body's rest surface `mesh`, on it, else None."""
    sample = _shift_sample(v)

    def score(degrees: float) -> float:
        return _fit_score(mesh.signed_distance(sample @ _axis_turn(1, degrees).T, exact=False))

    best = min((d for d in range(-180 + YAW_STEP_DEG, 181, YAW_STEP_DEG) if d % 90), key=score)
    best = min(range(best - YAW_STEP_DEG + 1, best + YAW_STEP_DEG), key=score)
    if best % 90 == 0 or min(score(best - 10), score(best + 10)) < YAW_SHARPNESS * score(best):
        return None  # no yaw (the axis-aligned turns were tried), or one the fit hardly tells
    signed = mesh.signed_distance(v @ _axis_turn(1, best).T, exact=False)
    left = float(np.mean(signed < -REST_INSIDE_DEPTH_M))
    if np.median(np.abs(signed)) > FRAME_FIX_MEDIAN_M or left > min(REST_INSIDE_WARN_SHARE, inside / 3):
        return None
    return best, left


def _scale_fix(vertices: np.ndarray, body: Body, mesh: TriangleMesh, name: str, near: float, inside: float,
               placed: Placement | None = None, median: float = 0.0) -> tuple[str | None, str | None]:
    """(fix, maybe): "it fits when scaled by 2.54 (inches read as centimetres?)[, then <a frame fix>][, then moved
    ...]" (naming `garment unpose`) for a garment that one of `UNIT_MIXUPS` (about the origin; the nearest to 1
    first) puts on the body far better than it is, else None; maybe: for the first scale that fits SCALE_GAIN
    times better but not as much better as its own gain asks (a shrink, a tenfold scale), "it fits 1.7 times
    better for its size when scaled by ...", else None. Far better: at its best place (`_best_place`, not at the
    end of its heights), its `_fit_score` over its span (a small garment sits near the body anywhere: the example
    trousers scaled by 0.39 fit 2.7 times better 0.55 m down than 0.3 m aside, where they belong) SCALE_GAIN
    times smaller (SCALE_SHRINK_GAIN shrunk, SCALE_TENFOLD_GAIN for a tenfold scale) than the garment's own at its
    best place, its median distance then at most FRAME_FIX_MEDIAN_M. Only scales that leave it spanning
    `GARMENT_SPAN_M` are tried; smaller ones only where its closest 5 % lie over MAX_NEAR_BODY_DISTANCE_M from the
    body (`near`, metres: a garment too large rests on it nowhere, a loose one does, and fits closer shrunk) or its
    median distance over MAX_MEDIAN_BODY_DISTANCE_M (`median`: trousers 2.54 times too large and turned cross the
    legs, 0.32 m from the body, median; none of the loose tubes of `benchmarks/garment_placement.py` lies so),
    larger ones only where over REST_INSIDE_WARN_SHARE of it is inside (`inside`: a garment too small)."""
    from core.garment import GARMENT_SPAN_M

    v = _shift_sample(np.asarray(vertices, dtype=np.float64), SCALE_SAMPLE)
    span = float(np.ptp(v, axis=0).max())
    tried = sorted(((ratio, mixup) for ratio, mixup in UNIT_MIXUPS
                    if GARMENT_SPAN_M[0] <= span * ratio <= GARMENT_SPAN_M[1]
                    and (near > MAX_NEAR_BODY_DISTANCE_M or median > MAX_MEDIAN_BODY_DISTANCE_M if ratio < 1.0
                         else inside > REST_INSIDE_WARN_SHARE)),
                   key=lambda t: abs(np.log(t[0])))
    own = _best_place(mesh, v, body)[0] / span if tried else 0.0
    maybe = None
    for ratio, mixup in tried:
        score, what, turns, drop, dy = _best_place(mesh, ratio * v, body)
        gain = SCALE_TENFOLD_GAIN if abs(np.log10(ratio)) > 0.5 else SCALE_GAIN if ratio > 1.0 else SCALE_SHRINK_GAIN
        if score / (ratio * span) * SCALE_GAIN > own or abs(dy) >= SHIFT_RANGE_M[1] - 0.005:
            continue
        move = np.array([0.0, dy - drop, 0.0])
        moved = ratio * np.asarray(vertices, dtype=np.float64) @ _turns_rotation(turns).T + move
        signed = mesh.signed_distance(moved, exact=False)
        if np.median(np.abs(signed)) > FRAME_FIX_MEDIAN_M:
            continue
        told = ", then ".join(w for w in (f"scaled by {ratio:.4g} ({mixup}?)", what) if w)
        if dy:
            told += f", then moved {_move_words(np.array([0.0, dy, 0.0]))}"
        text = _fix_text(told, turns, move, float(np.mean(signed < -REST_INSIDE_DEPTH_M)), name, placed,
                         scale=ratio)
        if score / (ratio * span) * gain <= own:
            return text, None
        maybe = maybe or text.replace("it fits when", f"it fits {own * ratio * span / score:.1f} times better for "
                                                      f"its size when", 1)
    return None, maybe


def _best_place(mesh: TriangleMesh, v: np.ndarray, body: Body) -> tuple[float, str, tuple[str, ...], float, float]:
    """Where points `v` (N, 3) sit best on the body's rest surface `mesh`: as they are or with one of `_COMMON_FIXES`
    (the first within FRAME_FIX_TIE of the best: a symmetric skirt is not turned), then moved up or down by up
    to SHIFT_RANGE_M's end (SCALE_HEIGHT_STEP_M steps, then whole centimetres about the best: the least share
    inside, then the least score; none unless that makes the score SHIFT_AXIS_GAIN times smaller): (`_fit_score`
    there, the fix as told ("" for none), its turns, its drop to the body's soles and the height then, metres:
    the whole move up is height - drop)."""
    soles = -float(body.v_template[:, 1].min())
    heights = np.arange(-SHIFT_RANGE_M[1], SHIFT_RANGE_M[1] + 1e-9, SCALE_HEIGHT_STEP_M)

    def at(points: np.ndarray, dy: float) -> tuple[float, float]:
        signed = mesh.signed_distance(points + [0.0, dy, 0.0], exact=False)
        return _fit_score(signed), float(np.mean(signed < -REST_INSIDE_DEPTH_M))

    found = []  # (score, what, turns, drop, height)
    for what, turns, on_floor in (("", (), False), *_COMMON_FIXES):
        if on_floor and soles <= 0.0:
            continue
        drop = soles if on_floor else 0.0
        turned = v @ _turns_rotation(turns).T - [0.0, drop, 0.0]
        found.append(min((at(turned, dy)[0], what.format(drop=drop), turns, drop, dy) for dy in heights))
    best = min(t[0] for t in found)
    _, what, turns, drop, dy = next(t for t in found if t[0] <= FRAME_FIX_TIE * best)
    turned = v @ _turns_rotation(turns).T - [0.0, drop, 0.0]
    near = np.round(dy + np.arange(-SCALE_HEIGHT_STEP_M, SCALE_HEIGHT_STEP_M + 1e-9, 0.01), 2)
    near = near[np.abs(near) <= SHIFT_RANGE_M[1] + 1e-9]
    (score, _), dy = min(((at(turned, h), h) for h in near), key=lambda t: (round(t[0][1] * 200), t[0][0]))
    unmoved = at(turned, 0.0)[0]
    if score * SHIFT_AXIS_GAIN > unmoved:  # no move unless it helps (a garment where it belongs stays there)
        return unmoved, what, turns, drop, 0.0
    return score, what, turns, drop, float(dy)


def _fix_text(what: str, turns: tuple[str, ...], move: np.ndarray, inside: float, name: str,
              placed: Placement | None = None, scale: float = 1.0) -> str:
    """ "it fits when <what>", naming the `garment unpose` that makes the fix (`scale`, then `turns`: names in
    `TURNS`, then `move`, metres; after `placed`: `unpose_command`), and how much of the garment the fix still
    leaves inside the body (share `inside`) where that is over REST_INSIDE_WARN_SHARE."""
    fix = Placement(scale, turns, tuple(float(m) for m in np.round(move, 2)))
    still = (f" ({inside:.0%} of it then still inside the body: authored on another body shape too? pass it with "
             f"--body)" if inside > REST_INSIDE_WARN_SHARE else "")
    return f"it fits when {what}{still}: {unpose_command(name, fix, placed)}"


def _fit_score(signed: np.ndarray) -> float:
    """How badly points with these signed distances to the body's rest surface (metres, negative inside) sit on it:
    their mean distance plus 5 times their mean depth inside, metres."""
    return float(np.abs(signed).mean() + 5.0 * np.clip(-signed, 0.0, None).mean())


def _shift_score(mesh: TriangleMesh, points: np.ndarray) -> tuple[float, float, float]:
    """How badly `points` (N, 3) sit on the body's rest surface `mesh`: (their mean distance to it plus 5 times
    their mean depth inside it, in metres; the share of them more than SHIFT_DEEP_M inside; the share more than
    REST_INSIDE_DEPTH_M inside)."""
    signed = mesh.signed_distance(points, exact=False)
    return (_fit_score(signed), float(np.mean(signed < -SHIFT_DEEP_M)), float(np.mean(signed < -REST_INSIDE_DEPTH_M)))


def _shift_fix(vertices: np.ndarray, body: Body, mesh: TriangleMesh, name: str,
               placed: Placement | None = None) -> tuple[str | None, str | None]:
    """(refusal, hint): "it fits better when moved up by ..." (naming `garment unpose` for the file `name`) for a
    garment that moving straight up or down (`SHIFT_RANGE_M`), then sideways and forwards or back
    (`SHIFT_SIDE_RANGE_M`), puts on the body (see SHIFT_DEEP_SHARE), else None; hint: for a nearer move that makes
    the score SHIFT_GAIN times smaller and halves the share deep inside, "it fits better moved ...", for the
    warning of a garment partly inside (NeuralClothSim's SMPL t-shirt: 3 cm up and 4 cm forwards, 17 % deep inside
    to 1.7 %), else None. Along each axis in turn, twice over (a move sideways first taken for
    one up or down is undone in the second round): 2 cm steps for the least `_shift_score`, then whole
    centimetres within 3 cm of it (the move as it is told) for the least share inside (to 0.5 %; a tight collar
    1.5 cm too low is inside), then the least score; that axis is left unmoved unless the move makes the score
    SHIFT_AXIS_GAIN times smaller than unmoved."""
    v = _shift_sample(np.asarray(vertices, dtype=np.float64))
    score, deep, _ = _shift_score(mesh, v)
    if deep <= SHIFT_DEEP_SHARE:
        return None, None
    move = np.zeros(3)
    for axis, (low, high) in 2 * ((1, SHIFT_RANGE_M), (0, SHIFT_SIDE_RANGE_M), (2, SHIFT_SIDE_RANGE_M)):
        def tried(steps: np.ndarray) -> list[tuple[float, float, float, float]]:
            steps = steps[(np.abs(steps) >= low - 1e-9) & (np.abs(steps) <= high + 1e-9)]
            out = []
            for d in steps:
                m = move.copy()
                m[axis] = d
                out.append((*_shift_score(mesh, v + m), float(d)))
            return out

        still = move.copy()
        still[axis] = 0.0
        here = _shift_score(mesh, v + still)[0]  # this axis left alone
        coarse = np.arange(low, high + 1e-9, 0.02)
        d = min(tried(np.concatenate([-coarse[::-1], coarse])))[3]
        found = min(tried(np.round(d + np.arange(-0.03, 0.03 + 1e-9, MOVE_SEARCH_STEP_M), 2)),
                    key=lambda t: (round(t[2] * 200), t[0]))
        move[axis] = found[3] if found[0] * SHIFT_AXIS_GAIN <= here else 0.0
    best = _shift_score(mesh, v + move)
    if best[1] > SHIFT_DEEP_SHARE:  # the axes' move leaves it inside: moved several ways at once?
        move, best = _shift_climb(mesh, v, move, best)
    smpl = body.name == "default" and _smpl_like(move) and not any(
        _shift_score(mesh, v + [move[0], up, move[2]])[0] < best[0] for up in SMPL_BEYOND_M)
    words = _move_words(move)
    command = unpose_command(name, Placement(move=tuple(float(m) for m in move)), placed)
    if move.any() and not _shift_reaches(move) and best[0] * SHIFT_GAIN <= score and best[1] <= deep / 2:
        return None, f"it fits better moved {words}: {command}"  # a nearer move: a hint, not a refusal
    if (not _shift_reaches(move) or _at_edge(move) or best[0] * (SHIFT_AXIS_GAIN if smpl else SHIFT_GAIN) > score
            or best[1] > 1.25 * deep + 0.01):
        return None, None
    smpl = "; garments authored on SMPL's rest body sit 0.24-0.27 m low on this one" if smpl else ""
    return (f"it fits better when moved {words} (authored on a body whose origin stands elsewhere{smpl}): pass the "
            f"body it was authored on with --body, or move it: {command}"), None


def _shift_sample(v: np.ndarray, n: int = SHIFT_SAMPLE) -> np.ndarray:
    """At most `n` of the points `v`, evenly through them: those a move search moves."""
    if len(v) <= n:
        return v
    return v[np.linspace(0, len(v) - 1, n).round().astype(np.int64)]


def _move_words(move: np.ndarray) -> str:
    """`move` (metres, body frame) in words: "up by 0.25 m and 0.01 m forwards"."""
    return " and ".join(w for w in (
        f"{'up' if move[1] > 0 else 'down'} by {abs(move[1]):.2f} m" if move[1] else "",
        f"{abs(move[0]):.2f} m to the body's {'left' if move[0] > 0 else 'right'}" if move[0] else "",
        f"{abs(move[2]):.2f} m {'forwards' if move[2] > 0 else 'back'}" if move[2] else "") if w)


def _move_option(move: np.ndarray) -> str:
    """`move` as `garment unpose --move` takes it: "0,0.25,0.01"."""
    return ",".join(f"{m + 0.0:.2f}".rstrip("0").rstrip(".") for m in np.round(move, 2))


def _smpl_like(move: np.ndarray) -> bool:
    """Whether `move` is SMPL's rest body's offset on the embedded one: up by SMPL_UP_M, at most SMPL_ASIDE_M aside
    or forwards."""
    return bool(SMPL_UP_M[0] - 1e-9 <= move[1] <= SMPL_UP_M[1] + 1e-9
                and np.abs(move[[0, 2]]).max() <= SMPL_ASIDE_M + 1e-9)


def _at_edge(move: np.ndarray) -> bool:
    """Whether `move` reaches the end of the searched range along some axis: the best move may lie beyond it (a
    skirt authored on a body 0.66 m tall: told 0.45 m up, it then sat on the head)."""
    return bool(np.any(np.abs(move) >= _SHIFT_FURTHEST - 0.005))


def _shift_reaches(move: np.ndarray) -> bool:
    """Whether `move` goes as far as a move is searched along some axis (SHIFT_RANGE_M up or down,
    SHIFT_SIDE_RANGE_M sideways, forwards or back): nearer moves are left to body shapes."""
    return bool(np.any(np.abs(move) >= _SHIFT_NEAREST - 1e-9))


def _shift_climb(mesh: TriangleMesh, v: np.ndarray, move: np.ndarray, start: tuple,
                 reach=None) -> tuple[np.ndarray, tuple]:
    """A garment moved several ways at once, for which no single axis, or only one, helped (the example t-shirt
    moved 0.2 m aside, 0.1 m down and 0.1 m forwards): from `move`, steps of 4, 2, then 1 cm along every
    combination of the three axes (26 neighbours) while one makes the `_shift_score` of `v` smaller, within the
    searched reach and SHIFT_CLIMB_STEPS steps. Taken where it makes the score SHIFT_AXIS_GAIN times smaller than
    `move` (so the axes' own choice stands for a garment moved along one of them), then the whole centimetre
    around it with the least share inside (to 0.5 %), then the least score, as the axes' search ends.
    start: `_shift_score` at `move`; reach: (3,) metres on each axis (default the searched ranges' ends). (move,
    `_shift_score` there)."""
    if reach is None:
        reach = _SHIFT_FURTHEST
    dirs = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], dtype=np.float64) - 1.0

    def around(m: np.ndarray, step: float) -> list[tuple[tuple, np.ndarray]]:
        tries = [np.round(m + step * d, 2) for d in dirs]
        return [(_shift_score(mesh, v + t), t) for t in tries if np.all(np.abs(t) <= reach + 1e-9)]

    best, climbed, steps = start, move, 0
    for step in (0.04, 0.02, 0.01):
        while steps < SHIFT_CLIMB_STEPS:
            steps += 1
            found = min(around(climbed, step), key=lambda t: t[0][0], default=None)
            if found is None or found[0][0] >= best[0]:
                break
            best, climbed = found
    if best[0] * SHIFT_AXIS_GAIN > start[0]:
        return move, start
    return min([(best, climbed), *around(climbed, 0.01)], key=lambda t: (round(t[0][2] * 200), t[0][0]))[::-1]


def _lifted_by_floor(garment: Garment, body: Body, mesh: TriangleMesh, name: str = "GARMENT",
                    placed: Placement | None = None) -> str | None:
    """The drop fix of `FRAME_FIXES` ("it fits when moved down by ...") for a garment authored on a body standing
    at y = 0 (see ABOVE_HEAD_M), else None: dropped, at most REST_INSIDE_WARN_SHARE of it inside, or its
    `_fit_score` FRAME_FIX_SCORE_GAIN times smaller (a garment authored on another body standing on the floor)."""
    y = garment.vertices[:, 1].astype(np.float64)
    head = float(body.v_template[:, 1].max())
    soles = -float(body.v_template[:, 1].min())
    if (soles <= 0.0 or y.max() <= head + ABOVE_HEAD_M or y.min() < -FLOOR_SLACK_M
            or y.max() - soles > head + ABOVE_HEAD_M):
        return None
    dropped = garment.vertices.astype(np.float64) - [0.0, soles, 0.0]
    signed = mesh.signed_distance(dropped, exact=False)
    inside = float(np.mean(signed < -REST_INSIDE_DEPTH_M))
    if (inside > REST_INSIDE_WARN_SHARE and _fit_score(signed) * FRAME_FIX_SCORE_GAIN
            > _fit_score(mesh.signed_distance(garment.vertices.astype(np.float64), exact=False))):
        return None
    return _fix_text(_DROP.format(drop=soles), (), np.array([0.0, -soles, 0.0]), inside, name, placed)


#: A closed piece whose faces face the body over this share of its area or more, wound alike, is cloth of two
#: layers (`oriented_outward`).
LAYERED_SHARE = 0.25


def wound_outward(vertices: np.ndarray, faces: np.ndarray, body: TriangleMesh) -> tuple[np.ndarray, tuple]:
    """`faces` wound alike across shared edges (`core.garment.consistent_winding`) and each connected piece turned
    to face away from the `body` surface (the faces' area, signed by whether their normal points away from the
    closest body point, sums positive): (those faces, (faces wound against their neighbours, the pieces turned,
    the count of pieces, (F,) faces of closed layered pieces, (F,) faces turned))."""
    from core.garment import consistent_winding

    wound, piece = consistent_winding(faces)
    rewound = int(np.count_nonzero((wound != faces).any(axis=1)))
    tri = np.asarray(vertices, dtype=np.float64)[wound]
    centroid = tri.mean(axis=1)
    area = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    away = centroid - body.closest(centroid, exact=False).closest
    vote = np.sign(np.einsum("ij,ij->i", area, away)) * np.linalg.norm(area, axis=1)
    # A closed piece (no edge of one face) whose faces face the body over a quarter of its area or more however it
    # is wound is cloth given thickness (two layers joined at the rims): each of its faces is turned away from the
    # body on its own, so both layers read as cloth facing out (its inner layer, read facing the body, was pushed
    # out through the outer one). A closed shell about the body faces one way and turns as a piece.
    sealed = closed_pieces(wound, piece)
    facing = np.bincount(piece, weights=np.maximum(vote, 0.0))
    against = np.bincount(piece, weights=np.maximum(-vote, 0.0))
    layered = sealed[np.minimum(facing, against)[sealed] >= LAYERED_SHARE * (facing + against)[sealed]]
    inward = np.setdiff1d(np.flatnonzero(np.bincount(piece, weights=vote) < 0), layered)
    closed = np.isin(piece, layered)
    turned = np.where(closed, vote < 0, np.isin(piece, inward))
    wound[turned] = wound[turned][:, [0, 2, 1]]
    return wound, (rewound, inward, int(piece.max()) + 1 if len(piece) else 0, closed, turned)


def oriented_outward(garment: Garment, body: Body, source: str | None = None) -> Garment:
    """`garment` with its faces wound alike across shared edges (`core.garment.consistent_winding`) and each
    connected piece facing away from the rest body (the faces' area, signed by whether their normal points away
    from the closest body point, sums positive), as the example garments all do; `garment` itself where nothing
    changes, else warned about. The model reads the rest normals: a dress written facing the body baked 48 mm
    (mean) from itself written facing out. face_uvs follow their faces; the file's own mesh (`source`) is kept."""
    faces, (rewound, inward, n_pieces, closed, turned) = wound_outward(
        garment.vertices, garment.faces, TriangleMesh(body.v_template, body.faces))
    changed = (faces != garment.faces).any(axis=1)
    if not changed.any():
        return garment
    log.warning("garment mesh '%s': %s of its %s faces turned for the model's normals (%s): the file is left as "
                "it is", source or garment.name, f"{int(changed.sum()):,}", f"{len(faces):,}",
                "; ".join(what for what, n in (
                    (f"{rewound:,} wound against their neighbours", rewound),
                    (f"{len(inward)} of its {n_pieces} pieces faced the body", len(inward)),
                    (f"{int((closed & turned).sum()):,} of closed pieces facing both ways (cloth given "
                     f"thickness? buttons?) faced the body",
                     int((closed & turned).sum()))) if n))
    face_uvs = garment.face_uvs
    if face_uvs is not None:  # a changed face had its last two corners swapped once (twice is no change)
        face_uvs = face_uvs.copy()
        face_uvs[changed] = face_uvs[changed][:, [0, 2, 1]]
    return replace(garment, faces=faces, face_uvs=face_uvs)


def closed_pieces(faces: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """The labels of the pieces (`piece` (F,) per face) none of whose edges belongs to one face only."""
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    _, edge, uses = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    open_piece = np.zeros(int(piece.max(initial=-1)) + 1, dtype=bool)
    open_piece[np.repeat(piece, 3)[uses[edge.reshape(-1)] == 1]] = True
    return np.flatnonzero(~open_piece)


def shaped_garment(vertices: np.ndarray, binding: GarmentBinding, betas: np.ndarray) -> np.ndarray:
    """The garment's rest vertices (V, 3) moved with the body's shape: betas (S,) as `Body.fit_betas` gives them."""
    return vertices + np.einsum("vcs,s->vc", binding.shapedirs, betas)


def graph_smoothing(faces: np.ndarray, n_vertices: int, strength: float = 0.5) -> sp.csr_matrix:
    """One pass of `smooth_over_graph` as a sparse (V, V) float64 operator: x <- P @ x. A vertex without edges
    keeps its value (its row is the identity's)."""
    adj = adjacency(mesh_edges(faces), n_vertices)
    deg = np.asarray(adj.sum(axis=1)).ravel()
    has = deg > 0
    keep = np.where(has, 1.0 - strength, 1.0)
    return (sp.diags(keep) + sp.diags(np.where(has, strength / np.maximum(deg, 1), 0.0)) @ adj).tocsr()


def smooth_over_graph(values: np.ndarray, faces: np.ndarray, iterations: int, strength: float = 0.5) -> np.ndarray:
    """Uniform-Laplacian smoothing of per-vertex values over the mesh edge graph.

    values: (V, C); faces: (F, 3). Each pass: x <- (1 - strength) x + strength * mean of neighbours.
    Isolated vertices keep their values. Returns (V, C) of the input dtype.
    """
    op = graph_smoothing(faces, values.shape[0], strength)
    x = values.astype(np.float64)
    for _ in range(iterations):
        x = op @ x
    return x.astype(values.dtype)
