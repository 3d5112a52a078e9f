"""Reference cloth simulation (`bake --method sim`): Newton's VBD cloth solver with the body as a moving collider.

Follows Newton's split: a Model (the garment's rest geometry, masses and material,
plus one static triangle-mesh collision shape for the body), a State (particle
positions and velocities) and a step function (`SolverVBD.step`). The body's
collision mesh is re-posed every substep: its points are interpolated linearly
between the posed bodies of consecutive frames and its per-vertex velocities are
the finite difference over the frame, then its BVH is refitted. Gravity acts
along world -Z (the motion's Z-up world, metres, seconds). Where the garment comes near it
(`core.scene`), the ground is a second mesh shape: a horizontal plane through the lowest point the body
reaches in the run.

A run has three phases: (1) the garment, shaped like the body (`core.skinning`
shape blend shapes), hangs on the static rest body (T-pose, frame 0's root
orientation and translation) for `SimOptions.settle_s` seconds; (2) when the motion
has no `--settle` blend frames, an internal blend of `SimOptions.blend_frames`
frames carries the body from the rest pose into frame 0 (not output); (3) every
output frame is simulated and checked (NaN/Inf, share of garment vertices more than
2 mm inside the body, edge strain). A frame that fails the checks is re-run from
the previous frame's state with twice the substeps (up to `max_retries` times); a
frame that still fails hard raises `SimulationError` naming the frame.

With self-contact, Newton stores the cloth-cloth pairs each detection finds in buffers of a fixed number of
pairs per vertex and per edge, and drops any beyond them; a step whose detections overflowed is re-run from
its start with larger buffers (`ContactBuffers`), so no pair in reach is left out below a memory cap.

Warp compiles its kernels on first use (about a minute on a CPU) into
`WARP_CACHE_PATH` (default here: warp/ in the garment cache, `formats.cache.default_cache_dir`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import sys
import tempfile
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import torch

from core.body import Body, skin_points
from core.deform import Deformer
from core.errors import InputError
from core.garment import Garment, boundary_loops, edge_face_counts, mesh_edges
from core.geodesic import geodesic_graph, geodesic_neighbourhood
from core.geometry import TriangleMesh, face_cross, outward_faces
from core.motion import CUT_SPEED_M_S, Motion, blend_in, poses_for_body
from core.provenance import package_version
from core.scene import SceneAnalysis, analyse_collisions, lbs_preview
from core.skinning import bind_garment, shaped_garment

log = logging.getLogger(__name__)

GRAVITY_M_S2 = 9.81
#: The simulator's behaviour, declared: stored simulations (`garment tradeoff --reuse-sim`) are keyed on it, not
#: on this file's bytes, so a refactor keeps them. Bump it with any change that moves the simulated cloth (this
#: module, the pins' binding in core.skinning, material or solver defaults); tests/core/test_sim.py checks a
#: golden simulation made with this version (GARMENT_UPDATE_GOLDENS=1 remakes it after a bump).
SIMULATOR_VERSION = 4  # 2: self-contact candidates filtered along the surface (`self_contact_filters`); 3: no
# self-contact pair dropped for want of buffer room (`ContactBuffers`); 4: a ground plane where the garment
# comes near it (`SimOptions.floor`), small detached pieces pinned (`small_pieces`)
#: Depth below the body surface at which a garment vertex counts as penetrating (as in core.bake).
PENETRATION_DEPTH_M = 0.002


#: Values of `SimOptions.pin`.
PIN_MODES = ("auto", "none")
#: Values of `SimOptions.floor`.
FLOOR_MODES = ("auto", "none")
#: With `pin` "auto", a piece of the garment not joined to its largest (a pocket, a label, a button modelled
#: apart) with less than this share of its area follows the body by skinning, pinned whole: nothing holds it on
#: the cloth (the example t-shirt with an 8 cm pocket 5 mm off its chest: the pocket fell 4.6 m in 5 frames).
SMALL_PIECE_AREA_SHARE = 0.02
#: A waistband's edge must lie on average within this distance of the rest body (metres).
WAISTBAND_MAX_GAP_M = 0.03
#: A loop encircles the body's vertical axis when no angular gap between its vertices exceeds this.
WAISTBAND_MAX_ANGLE_GAP_RAD = np.pi / 2


#: Newton's Divide-and-Truncate relaxation (its default): between two self-contact detections every cloth
#: vertex moves at most DAT_RELAXATION / 2 x the detection distance (margin + gap), whether or not it is near
#: anything: what keeps self-contact penetration-free also caps the cloth's speed.
DAT_RELAXATION = 0.85
#: The self-contact detection distance lets cloth move this many times its fastest LBS speed in the scene.
SELF_CONTACT_SPEED_MARGIN = 1.5
#: Largest self-contact detection gap (metres): the cost grows steeply with it (the example skirt, 10 substeps:
#: 1 cm 1.7 s/frame, 2 cm 3.7 s/frame, 5 cm over 30 s/frame). At 10 substeps and 30 fps it lets cloth move at
#: 2.9 m/s relative to the body; faster cloth is held back (reported as `cloth_speed_limit_m_s`).
MAX_SELF_CONTACT_GAP_M = 0.02


def self_contact_gap(material: "Material", speed_m_s: float, dt_s: float) -> float:
    """Self-contact detection gap (metres beyond `material.self_contact_distance_m`) that lets cloth move at
    SELF_CONTACT_SPEED_MARGIN x `speed_m_s` in steps of `dt_s` seconds, between self_contact_distance_m and
    MAX_SELF_CONTACT_GAP_M.

    With the gap equal to the contact distance (3 mm), Newton holds every vertex to 2.55 mm per substep:
    0.77 m/s at 10 substeps and 30 fps, where a walk moves the legs' cloth at 1-3 m/s.
    """
    margin = material.self_contact_distance_m
    need = SELF_CONTACT_SPEED_MARGIN * speed_m_s * dt_s / (0.5 * DAT_RELAXATION) - margin
    return float(min(max(need, margin), MAX_SELF_CONTACT_GAP_M))


#: Most vertices (at the mesh's mean density) in the surface disc of `self_contact_filter_radius`.
SELF_CONTACT_FILTER_MAX_VERTICES = 128

#: Self-contact pairs Newton stores per cloth vertex (vertex-triangle) and per edge (edge-edge) at the start
#: (Newton's defaults). Newton drops the pairs a detection finds beyond them, silently and in the order its BVH
#: meets them (not the nearest last): on the example trousers (2.3 cm detection distance, the legs' panels
#: close at the crotch) 85 vertices found up to 98 and 130 edges up to 163 from the first frame, so the
#: simulator doubles them when a detection overflows and re-runs the frame (`ContactBuffers`), up to
#: `SimOptions.contact_buffer_mb`.
CONTACT_BUFFERS = (32, 64)


def self_contact_filters(rest_vertices: np.ndarray, tri_indices: np.ndarray, edge_ends: np.ndarray,
                         radius_m: float) -> tuple[dict[int, list[int]], dict[int, list[int]]]:
    """Self-contact pairs that are one stretch of cloth: within `radius_m` of each other along the rest surface.

    rest_vertices (V, 3) metres (the garment as authored); tri_indices (F, 3); edge_ends (E, 2) vertex indices
    of the solver's edges. Returns (vertex -> triangles, edge -> edges) for Newton's external contact
    filtering maps: triangle t is filtered for vertex v when a corner of t lies within `radius_m` of v
    (surface geodesic, `core.geodesic`); edges e and f when an end of e lies within it of an end of f.

    Newton's own filter works in mesh rings (2: the triangles around a vertex's neighbours), a distance
    that shrinks with the mesh's edge length, while the detection distance (`self_contact_gap`) grows
    with the motion's speed: with a 2.3 cm detection distance on the example trousers (15 mm edges), 86 %
    of the vertices carried 13 pairs each with their own stretch of cloth, 17-30 mm away along it, that
    only a fold that deep could bring into contact; checking them every iteration made self-contact 7x
    slower than none (70 s per frame at 20 substeps, against 25 s with this filter, 2026-12-03).
    """
    V = len(rest_vertices)
    near = geodesic_neighbourhood(rest_vertices, geodesic_graph(rest_vertices, tri_indices), radius_m,
                                  distances=False).astype(np.float32)
    near = (near + sp.identity(V, dtype=np.float32, format="csr")).tocsr()

    def incidence(cells: np.ndarray) -> sp.csr_matrix:  # (V, cells) with a 1 where a vertex is a corner or end
        n, k = cells.shape
        return sp.csr_matrix((np.ones(n * k, np.float32), (cells.reshape(-1), np.repeat(np.arange(n), k))),
                             shape=(V, n))

    def rows(m: sp.csr_matrix) -> dict[int, list[int]]:
        m = m.tocsr()
        return {i: m.indices[m.indptr[i]:m.indptr[i + 1]].tolist() for i in range(m.shape[0])}

    tris = incidence(np.asarray(tri_indices, dtype=np.int64))
    ends = incidence(np.asarray(edge_ends, dtype=np.int64))
    return rows(near @ tris), rows(ends.T @ (near @ ends))


def self_contact_filter_radius(rest_vertices: np.ndarray, tri_indices: np.ndarray, detection_m: float) -> float:
    """Surface radius of `self_contact_filters` for a detection distance of `detection_m` metres: that distance,
    capped where a disc of it would hold more than SELF_CONTACT_FILTER_MAX_VERTICES vertices at the mesh's
    mean density (on a fine mesh the filter grows with the square of the radius; pairs beyond the cap are
    checked as before).

    A larger radius (the detection distance plus the median edge) made the example trousers' self-contact
    another 2x faster, but let folds up to that deep pass through themselves: the skirt on walk_brisk had
    twice the self-intersecting faces (0.81 % against 0.40 % before the filter; 0.36 % with this radius).
    """
    v = np.asarray(rest_vertices, dtype=np.float64)
    area = 0.5 * float(np.linalg.norm(face_cross(v, tri_indices), axis=-1).sum())
    cap = np.sqrt(SELF_CONTACT_FILTER_MAX_VERTICES * area / max(len(v), 1) / np.pi)
    return float(min(detection_m, cap))


def cloth_speed_limit(material: "Material", gap_m: float, dt_s: float) -> float:
    """The fastest a cloth vertex can move (m/s) with self-contact detection distance margin + `gap_m`."""
    return 0.5 * DAT_RELAXATION * (material.self_contact_distance_m + gap_m) / dt_s


class SimulationError(FloatingPointError):
    """The simulator could not produce an acceptable frame, even with more substeps."""


@dataclass(frozen=True)
class Material:
    """Cloth material for Newton's VBD solver; defaults are a light woven fabric (cotton shirting, ~0.2 mm).

    density_kg_m2: areal density (light cotton 0.1-0.2 kg/m^2; HOOD uses 0.20).
    shear_stiffness_n_m: membrane Lame mu (VBD `tri_ke`), N/m; resists shear and stretch.
    stretch_stiffness_n_m: membrane Lame lambda (VBD `tri_ka`), N/m; resists area change.
      (HOOD's StVK: mu 23600, lambda 44400; woven fabric is far stiffer in stretch than in bending.)
    bending_stiffness_n_m: dihedral-angle bending stiffness (VBD `edge_ke`), N*m per radian
      (HOOD 3.96e-5; larger values keep folds rounder).
    stretch_damping_s: stiffness-proportional membrane damping (VBD `tri_kd`), seconds.
    bending_damping_s: stiffness-proportional bending damping (VBD `edge_kd`), seconds.
    friction: Coulomb friction coefficient between cloth and body (HOOD 0.5).
    contact_stiffness_n_m: body contact penalty stiffness, N/m.
    contact_damping: body contact damping (VBD soft contact `kd`, dimensionless ratio).
    contact_distance_m: cloth half-thickness: the distance the solver keeps between
      garment vertices and the body surface (particle radius).
    contact_gap_m: extra detection distance beyond contact_distance_m, so fast body
      motion within a substep does not skip contacts.
    self_contact_distance_m: cloth-cloth separation kept when self-contact is on.
    self_contact_rest_exclusion_m: cloth-cloth pairs closer than this in the garment as authored never
      collide. Garments are often modelled with parts touching or crossing (the legs of trousers at the
      crotch, a sleeve at the armpit): with self-contact on, such pairs start in contact and their forces
      tear the cloth apart within frames (the example trousers blew up at frame 8 of a walk without it).
    """

    density_kg_m2: float = 0.2
    shear_stiffness_n_m: float = 1.0e4
    stretch_stiffness_n_m: float = 1.0e4
    bending_stiffness_n_m: float = 1.0e-4
    stretch_damping_s: float = 1.0e-6
    bending_damping_s: float = 1.0e-6
    friction: float = 0.3
    contact_stiffness_n_m: float = 1.0e4
    contact_damping: float = 1.0e-3
    contact_distance_m: float = 0.004
    contact_gap_m: float = 0.02
    self_contact_distance_m: float = 0.003
    self_contact_rest_exclusion_m: float = 0.01

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v) or v < 0:
                raise InputError(f"material {f.name}: expected a finite non-negative number, got {v!r}")
        if self.density_kg_m2 <= 0:
            raise InputError(f"material density_kg_m2: expected a positive number, got {self.density_kg_m2}")


def load_material(path: str | os.PathLike) -> Material:
    """Read a Material from a JSON object of field -> number; missing fields keep their defaults.

    Raises InputError (one line naming the file and the key) for unknown keys, non-numbers or bad JSON.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(f"material file '{path}': file not found") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"material file '{path}': expected a JSON object, could not parse it ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"material file '{path}': expected a JSON object of field -> number, got {type(data).__name__}")
    known = {f.name for f in dataclasses.fields(Material)}
    for key, value in data.items():
        if key not in known:
            raise InputError(f"material file '{path}': unknown key '{key}' (known: {', '.join(sorted(known))})")
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise InputError(f"material file '{path}': expected a number for '{key}', got {value!r}")
    try:
        return Material(**{k: float(v) for k, v in data.items()})
    except InputError as exc:
        raise InputError(f"material file '{path}': {exc}") from None


#: SimOptions fields that only decide whether a run stops with SimulationError: a run that completes gives
#: the same cloth whatever their values, so a dataset resumed with other values of them keeps its sequences.
STOP_CHECK_OPTIONS = frozenset({"fail_penetration_share", "fail_mean_strain", "fail_off_body_m", "fail_off_place_m"})


@dataclass(frozen=True)
class SimOptions:
    """Solver settings of the `sim` method.

    substeps: solver steps per output frame (dt = 1 / (fps * substeps)).
    iterations: VBD iterations per substep.
    self_contact: cloth-cloth contact (about 3-10x slower; README "Reference physics").
    settle_s: seconds the garment hangs on the static rest body before the motion.
    blend_frames: frames blending rest pose -> frame 0 when the motion has no settle frames (not output).
    max_retries: re-runs of a failing frame, each with twice the substeps of the previous try.
    retry_depth_m: depth inside the body from which a vertex counts as tunnelled for the retry and
      fail checks: deeper than the cloth's contact distance (4 mm) and the give of the soft contact.
      Cloth pressed against the body by a moving limb, or pinched between two, sits 2-3 mm inside
      it in every frame and at every substep count (the example trousers with self-contact: 1-2 %
      of vertices 2.0-2.2 mm deep on a walk); counted at 2 mm, every frame of such a scene was
      re-run twice and the `substeps` setting meant nothing. The 2 mm share is still reported.
    retry_penetration_share: a frame with more vertices than this share tunnelled is retried.
    retry_mean_strain: a frame whose mean |edge strain| exceeds this is retried.
    fail_penetration_share / fail_mean_strain: after the retries, a frame worse than these
      (or with NaN/Inf) raises SimulationError; one between the retry and fail levels is kept
      (the best try) and recorded in the report. These catch explosions: a single edge pinched
      between two body parts (an arm against the torso) can stretch far without the cloth failing,
      so the largest edge strain is reported, not used to stop.
    fail_off_body_m: a frame where the median garment-to-body distance of a piece of the garment (a connected
      component) exceeds the piece's own at rest by more than this (it fell or slid off the body) raises
      SimulationError: no retry can fix the garment's fit. (Measured from the rest distance: a hoop skirt may
      stand 25 cm from the legs at rest.)
    fail_off_place_m: a frame where the median distance of a piece from where skinning (LBS) puts it exceeds
      this raises SimulationError as well: a piece that fell to the ground by the feet, or trousers that slid
      down to the ankles, stay near the body (the simulated dataset's example garments: a median of 14 cm at
      most, a dress in a high jump; 5 cm at most on the trousers).
    pin: "auto" pins the garment's waistband (see `waistband_vertices`) to the body, as the
      elastic of a real skirt, pair of trousers or strapless dress holds it, and every small piece not joined
      to the rest of the cloth (`small_pieces`: a pocket, a label modelled apart), which nothing holds on;
      "none" pins nothing.
    pin_band_m: width of the pinned band below the waistband's edge, metres along the surface.
    floor: "auto" simulates the ground, a plane at the lowest point the body reaches in the run, where the
      garment comes near it (`core.scene`'s `floor` skip); "none" never does (a motion whose lowest body point
      is not on the ground: feet dangling from a seat for the whole clip).
    contact_buffer_mb: most memory (MiB) the self-contact pair buffers may grow to (`ContactBuffers`: a step
      whose detection found more pairs at a vertex or edge than they hold is re-run with larger ones); at the
      cap the pairs beyond are left out, logged and reported. 0 keeps Newton's fixed CONTACT_BUFFERS.
    """

    substeps: int = 10
    iterations: int = 10
    self_contact: bool = False
    settle_s: float = 0.5
    blend_frames: int = 10
    max_retries: int = 2
    retry_depth_m: float = 0.005
    retry_penetration_share: float = 0.01
    retry_mean_strain: float = 0.05
    fail_penetration_share: float = 0.10
    fail_mean_strain: float = 0.25
    fail_off_body_m: float = 0.25
    fail_off_place_m: float = 0.5
    pin: str = "auto"
    pin_band_m: float = 0.02
    floor: str = "auto"
    contact_buffer_mb: float = 512.0

    def __post_init__(self):
        if self.retry_depth_m < 0:
            raise InputError(f"sim options: expected retry_depth_m >= 0, got {self.retry_depth_m}")
        if self.substeps < 1 or self.iterations < 1:
            raise InputError(f"sim options: expected substeps >= 1 and iterations >= 1, got {self.substeps}, "
                             f"{self.iterations}")
        if self.max_retries < 0 or self.blend_frames < 0 or self.settle_s < 0:
            raise InputError("sim options: expected non-negative max_retries, blend_frames and settle_s")
        if not (np.isfinite(self.contact_buffer_mb) and self.contact_buffer_mb >= 0):
            raise InputError(f"sim option contact_buffer_mb: expected a number >= 0, got {self.contact_buffer_mb}")
        if self.pin not in PIN_MODES:
            raise InputError(f"sim option pin: expected one of {', '.join(PIN_MODES)}, got {self.pin!r}")
        if self.floor not in FLOOR_MODES:
            raise InputError(f"sim option floor: expected one of {', '.join(FLOOR_MODES)}, got {self.floor!r}")


def edge_strain(points: np.ndarray, edges: np.ndarray, rest_length: np.ndarray) -> np.ndarray:
    """Relative edge length change (|e| - |e0|) / |e0|.

    points: (V, 3) metres; edges: (E, 2) int; rest_length: (E,) metres (> 0). Returns (E,) float64.
    """
    length = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    return (length - rest_length) / rest_length


def frame_checks(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray, edges: np.ndarray,
                 rest_length: np.ndarray, depth: float = PENETRATION_DEPTH_M,
                 tunnel_depth: float = SimOptions.retry_depth_m, pieces: np.ndarray | None = None) -> dict:
    """Stability statistics of one frame.

    points: (V, 3) garment, body_points: (Vb, 3) posed body, metres, same world; body_faces: (Fb, 3);
    pieces: (V,) the piece (connected component, 0..N-1) of each vertex (None: one piece).
    Returns finite (bool), penetration_share (fraction of vertices more than `depth` inside),
    tunnelled_share (more than `tunnel_depth` inside), mean_strain and max_strain (of |edge strain|),
    median_body_distance_m (signed; a garment that slides or falls off the body shows here, where
    neither penetration nor strain would flag it) and piece_median_body_distance_m, the same per piece (a
    pocket that falls off does not move the garment's median).
    """
    n_pieces = 1 if pieces is None else int(pieces.max(initial=0)) + 1
    if not np.all(np.isfinite(points)):
        return {"finite": False, "penetration_share": 1.0, "tunnelled_share": 1.0, "mean_strain": float("inf"),
                "max_strain": float("inf"), "median_body_distance_m": float("inf"),
                "piece_median_body_distance_m": [float("inf")] * n_pieces}
    sd = TriangleMesh(body_points, body_faces).signed_distance(points, exact=False)
    strain = np.abs(edge_strain(points.astype(np.float64), edges, rest_length))
    return {"finite": True, "penetration_share": float(np.mean(sd < -depth)),
            "tunnelled_share": float(np.mean(sd < -tunnel_depth)),
            "mean_strain": float(strain.mean()), "max_strain": float(strain.max()),
            "median_body_distance_m": float(np.median(sd)),
            "piece_median_body_distance_m": piece_medians(sd, pieces, n_pieces)}


def piece_medians(values: np.ndarray, pieces: np.ndarray | None, n_pieces: int) -> list[float]:
    """The median of (V,) `values` over each piece's vertices (`pieces` (V,) labels 0..n_pieces-1; None: one)."""
    if pieces is None or n_pieces == 1:
        return [float(np.median(values))]
    from scipy import ndimage

    return [float(m) for m in ndimage.median(values, labels=pieces, index=np.arange(n_pieces))]


def small_pieces(garment: Garment, share: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The garment's pieces (connected components) and the vertices of the small detached ones.

    Returns (labels (V,) int64 0..N-1, the sorted vertices (P,) of every piece but the largest by area whose area
    is under `share` (default SMALL_PIECE_AREA_SHARE) of the garment's): a pocket, a label or a button
    modelled apart from the cloth it sits on.
    """
    share = SMALL_PIECE_AREA_SHARE if share is None else share
    n, labels = garment.pieces
    if n == 1:
        return labels, np.zeros(0, dtype=np.int64)
    area = 0.5 * np.linalg.norm(face_cross(np.asarray(garment.vertices, np.float64), garment.faces), axis=-1)
    piece_area = np.bincount(labels[garment.faces[:, 0]], weights=area, minlength=n)
    small = piece_area < share * piece_area.sum()
    small[np.argmax(piece_area)] = False
    return labels, np.flatnonzero(small[labels]).astype(np.int64)


def waistband_vertices(garment: Garment, body: Body, band_m: float = 0.02) -> np.ndarray:
    """Vertices of the garment's waistband: the band that holds a skirt, trousers or a strapless top up.

    A garment without shoulders hangs from a snug opening around the torso; cloth alone (friction on
    a waist no narrower than the hips) lets it slide off, so the simulator pins this band to the
    skinned body. Rule, in the body's rest frame (Y-up): take the garment's highest boundary loop that
    encircles the vertical axis through the pelvis joint (no angular gap between its vertices wider
    than 90 degrees); it is a waistband when its mean height is below the midpoint of the spine3
    (chest) and neck joints (a neckline is above) and its vertices lie on average within 3 cm of the
    body. The band is that loop plus every vertex within `band_m` metres of it along the mesh edges.

    garment: in the body's rest frame; body: SMPL-format with at least 13 joints (spine3 = 9, neck = 12).
    Returns sorted vertex indices (P,) int64, empty when the garment has no waistband (a t-shirt,
    a jumpsuit: they hang from the shoulders).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    verts = np.asarray(garment.vertices, dtype=np.float64)
    if body.n_joints < 13:
        return np.zeros(0, dtype=np.int64)
    body_verts, joints = body.shaped(None)
    pelvis = joints[0]
    ceiling = 0.5 * (joints[9, 1] + joints[12, 1])
    encircling = []
    for loop in boundary_loops(garment.faces, garment.n_vertices):
        p = verts[loop]
        angle = np.sort(np.arctan2(p[:, 0] - pelvis[0], p[:, 2] - pelvis[2]))
        gaps = np.diff(np.concatenate([angle, angle[:1] + 2 * np.pi]))
        if len(loop) >= 3 and gaps.max() <= WAISTBAND_MAX_ANGLE_GAP_RAD:
            encircling.append(loop)
    if not encircling:
        return np.zeros(0, dtype=np.int64)
    top = max(encircling, key=lambda loop: verts[loop, 1].mean())
    if verts[top, 1].mean() >= ceiling:
        return np.zeros(0, dtype=np.int64)
    gap = np.abs(TriangleMesh(body_verts, outward_faces(body_verts, body.faces)).signed_distance(verts[top]))
    if gap.mean() > WAISTBAND_MAX_GAP_M:
        return np.zeros(0, dtype=np.int64)
    edges = mesh_edges(garment.faces)
    length = np.linalg.norm(verts[edges[:, 0]] - verts[edges[:, 1]], axis=1)
    n = garment.n_vertices
    graph = coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    dist = dijkstra(graph, directed=False, indices=top, min_only=True, limit=band_m + 1e-9)
    return np.flatnonzero(dist <= band_m).astype(np.int64)


#: What warp's native library writes to stderr at init on a machine without an NVIDIA driver (every CPU-only
#: run; the simulator then runs on the CPU, which its report records): dropped, anything else passes.
NO_CUDA_DRIVER_NOTICE = b"Could not find or load the NVIDIA CUDA driver"


def filter_native_stderr(fn, drop: bytes):
    """Call fn() with file descriptor 2 captured (C code writes there, not to sys.stderr); then write back
    every captured line that does not contain `drop`. Returns fn's result."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as capture:
            os.dup2(capture.fileno(), 2)
            try:
                return fn()
            finally:
                os.dup2(saved, 2)
                capture.seek(0)
                kept = b"".join(line for line in capture.read().splitlines(keepends=True) if drop not in line)
                if kept:
                    os.write(2, kept)
    finally:
        os.close(saved)


def require_simulator(what: str) -> None:
    """InputError naming `what` (the command or option) where the reference simulator's packages (the `sim`
    extra: newton, warp-lang) are not installed: a traceback of `import warp` otherwise, after the inputs were
    read."""
    try:
        import newton  # noqa: F401
        import warp  # noqa: F401
    except ImportError as exc:
        raise InputError(f"{what} needs the reference simulator, whose packages are not installed ({exc.name or exc} "
                         f"is missing): pip install 'garment[sim]'") from None


def _warp():
    from formats.cache import default_cache_dir

    os.environ.setdefault("WARP_CACHE_PATH", str(default_cache_dir() / "warp"))
    import warp as wp

    # warp 1.19 logs every kernel module load at INFO; users should see warnings only.
    wp.config.log_level = wp.LOG_WARNING
    filter_native_stderr(wp.init, NO_CUDA_DRIVER_NOTICE)
    return wp


#: With `SimOptions.floor` "none", a garment whose lowest point at rest is less than this above the body's soles
#: is warned about (the example trousers and jumpsuit end 11.3 cm above them, the dress 45 cm).
FLOOR_WARN_M = 0.05
#: Half the side of the ground's square (metres), around the root in the simulation's moving frame.
FLOOR_HALF_M = 10.0


def non_manifold_edge_count(faces: np.ndarray) -> int:
    """How many edges of the triangle mesh `faces` (F, 3) are shared by more than two faces."""
    return int(np.sum(edge_face_counts(faces)[1] > 2))


class ClothSim:
    """One garment (cloth) and one triangle-mesh collider whose points move, on Newton's VBD solver.

    rest_vertices: (V, 3) cloth rest shape, metres; faces: (F, 3) int; start_vertices: (V, 3)
    initial positions (default: the rest shape); collider_vertices: (Vb, 3) initial collider
    points; collider_faces: (Fb, 3) int, outward-oriented; bounds: (2, 3) world box that
    contains the collider during the whole run (its collision AABB); pinned: (P,) int indices of
    particles that do not move under the solver but follow targets given to `advance` (a waistband);
    self_contact_gap_m: self-contact detection distance beyond the material's self_contact_distance_m
    (None: that distance again; see `self_contact_gap`); floor_z: (N,) metres, the heights the ground plane
    (horizontal, `floor_half_m` either side of the origin, upward-facing) takes during the run, [0] at the start
    (None: no ground); it moves with `advance`'s `floor`.
    """

    def __init__(self, rest_vertices: np.ndarray, faces: np.ndarray, collider_vertices: np.ndarray,
                 collider_faces: np.ndarray, material: Material = Material(), self_contact: bool = False,
                 iterations: int = 10, start_vertices: np.ndarray | None = None, bounds: np.ndarray | None = None,
                 pinned: np.ndarray | None = None, device: str | None = None,
                 self_contact_gap_m: float | None = None, contact_filter: bool = True,
                 contact_buffers: tuple[int, int] = CONTACT_BUFFERS, floor_z: np.ndarray | None = None,
                 floor_half_m: float = FLOOR_HALF_M):
        wp = _warp()
        import newton

        self.wp = wp
        self.material = material
        device = device or ("cuda:0" if wp.is_cuda_available() else "cpu")
        self.device = device
        m = material
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, -GRAVITY_M_S2))  # Z-up world
        cfg = newton.ModelBuilder.ShapeConfig(ke=m.contact_stiffness_n_m, kd=m.contact_damping, mu=m.friction)
        cv = np.asarray(collider_vertices, dtype=np.float32)
        self.collider = newton.Mesh(cv, np.asarray(collider_faces, dtype=np.int32).reshape(-1), compute_inertia=False)
        self.shape = builder.add_shape_mesh(-1, mesh=self.collider, cfg=cfg)
        #: The ground: a mesh shape of its own (one open quad; the body's watertight mesh keeps its inside test).
        self.floor = self.floor_shape = None
        if floor_z is not None:
            h, z = float(floor_half_m), float(floor_z[0])
            quad = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]], dtype=np.float32)
            self.floor = newton.Mesh(quad, np.array([0, 1, 2, 0, 2, 3], dtype=np.int32), compute_inertia=False)
            self.floor_shape = builder.add_shape_mesh(-1, mesh=self.floor, cfg=cfg)
        rest = np.asarray(rest_vertices, dtype=np.float32)
        #: Edges shared by more than two faces (a pocket sewn on along one edge): Newton bends the cloth across
        #: the first two faces of each only, and warns once per edge; said here once.
        self.non_manifold_edges = non_manifold_edge_count(faces)
        if self.non_manifold_edges:
            log.warning("sim: %d garment edges are shared by more than two faces (non-manifold): the cloth bends "
                        "across the first two faces of each only", self.non_manifold_edges)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Detected non-manifold edge")
            builder.add_cloth_mesh(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0,
                                   vel=wp.vec3(0.0, 0.0, 0.0), vertices=[wp.vec3(*p) for p in rest],
                                   indices=np.asarray(faces, dtype=np.int32).reshape(-1), density=m.density_kg_m2,
                                   tri_ke=m.shear_stiffness_n_m, tri_ka=m.stretch_stiffness_n_m,
                                   tri_kd=m.stretch_damping_s, edge_ke=m.bending_stiffness_n_m,
                                   edge_kd=m.bending_damping_s, particle_radius=m.contact_distance_m)
        self.pinned = np.zeros(0, dtype=np.int64) if pinned is None else np.asarray(pinned, dtype=np.int64)
        for i in self.pinned:  # zero mass: VBD leaves the particle where the state puts it
            builder.particle_mass[int(i)] = 0.0
        builder.color(include_bending=True)
        self.model = builder.finalize(device=device)
        self.model.soft_contact_ke = m.contact_stiffness_n_m
        self.model.soft_contact_kd = m.contact_damping
        self.model.soft_contact_mu = m.friction
        kwargs = {}
        #: With self-contact: the surface radius of `self_contact_filters` and the pairs it filters.
        self.contact_filter = None
        if self_contact:
            gap = m.self_contact_distance_m if self_contact_gap_m is None else self_contact_gap_m
            kwargs = dict(particle_enable_self_contact=True, particle_self_contact_margin=m.self_contact_distance_m,
                          particle_self_contact_gap=gap, dat_conservative_bound_relaxation=DAT_RELAXATION,
                          particle_rest_shape_contact_exclusion_radius=m.self_contact_rest_exclusion_m)
            if contact_filter:  # pairs one stretch of cloth apart along its surface are no contact candidates
                tri = self.model.tri_indices.numpy()
                ends = self.model.edge_indices.numpy()[:, 2:4]
                radius = self_contact_filter_radius(rest, tri, m.self_contact_distance_m + gap)
                vt, ee = self_contact_filters(rest.astype(np.float64), tri, ends, radius)
                self.contact_filter = {"surface_radius_m": radius,
                                       "vertex_triangle_pairs": sum(map(len, vt.values())),
                                       "edge_edge_pairs": sum(map(len, ee.values()))}
                kwargs.update(particle_external_vertex_contact_filtering_map=vt,
                              particle_external_edge_contact_filtering_map=ee)
        self._solver_kwargs = dict(iterations=iterations, **kwargs)
        #: Self-contact pairs stored per vertex (vertex-triangle) and per edge (edge-edge); see CONTACT_BUFFERS.
        self.contact_buffers = tuple(int(b) for b in contact_buffers)
        self.n_particles = rest.shape[0]
        self._build_solver()
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        self.control = self.model.control()
        if start_vertices is not None:
            self.state_0.particle_q.assign(np.asarray(start_vertices, dtype=np.float32))
        if bounds is None:
            bounds = np.stack([cv.min(0), cv.max(0)])
        self.set_collider_bounds(bounds)
        if self.floor is not None:
            self.set_collider_bounds(np.array([[-h, -h, np.min(floor_z)], [h, h, np.max(floor_z)]]),
                                     shape=self.floor_shape)

    def _build_solver(self) -> None:
        """(Re)make the collision pipeline and the VBD solver over the model (the states are the model's: kept)."""
        import newton

        self.pipeline = newton.CollisionPipeline(self.model, soft_contact_gap=self.material.contact_gap_m)
        vt, ee = self.contact_buffers
        self.solver = newton.solvers.SolverVBD(self.model, collision_pipeline=self.pipeline,
                                               particle_vertex_contact_buffer_size=vt,
                                               particle_edge_contact_buffer_size=ee, **self._solver_kwargs)

    def contact_overflow(self) -> dict | None:
        """Whether a self-contact detection since the last call found more pairs than the buffers hold (those are
        dropped), with the largest pair counts of the last detection; resets the overflow flags. None: no
        self-contact."""
        if not self.solver.particle_enable_self_contact:
            return None
        from newton._src.geometry.kernels import (
            EDGE_COLLISION_BUFFER_OVERFLOW_INDEX,
            VERTEX_COLLISION_BUFFER_OVERFLOW_INDEX,
        )

        flags_array = self.pipeline._soft_self_contact_detector.resize_flags  # newton 1.8: sticky until reset
        flags = flags_array.numpy().copy()  # on a CPU, a view of the array zeroed below
        flags_array.zero_()
        info = self.solver.trimesh_collision_info
        return {"vertex_triangle": bool(flags[int(VERTEX_COLLISION_BUFFER_OVERFLOW_INDEX)]),
                "edge_edge": bool(flags[int(EDGE_COLLISION_BUFFER_OVERFLOW_INDEX)]),
                "vertex_triangle_max": int(info.vertex_colliding_triangles_count.numpy().max(initial=0)),
                "edge_edge_max": int(info.edge_colliding_edges_count.numpy().max(initial=0))}

    def contact_buffer_bytes(self, buffers: tuple[int, int]) -> int:
        """Bytes of the self-contact pair buffers at `buffers` pairs per vertex and per edge (two int32 a pair)."""
        return 8 * (self.n_particles * buffers[0] + self.model.edge_count * buffers[1])

    def grow_contact_buffers(self, overflow: dict, max_bytes: float) -> bool:
        """Double each buffer `overflow` (from `contact_overflow`) says overflowed, or more up to the last
        detection's largest count, and remake the solver; the cloth's state is kept. False (nothing changed)
        when that would take more than `max_bytes`."""
        grown = []
        for kind, size in zip(("vertex_triangle", "edge_edge"), self.contact_buffers):
            if overflow[kind]:
                size = max(2 * size, int(2 ** np.ceil(np.log2(max(overflow[f"{kind}_max"], 1)))))
            grown.append(size)
        grown = tuple(grown)
        if grown == self.contact_buffers or self.contact_buffer_bytes(grown) > max_bytes:
            return False
        self.contact_buffers = grown
        self._build_solver()
        return True

    def contact_pairs(self) -> dict | None:
        """Cloth-cloth pairs of the last self-contact detection: {"vertex_triangle": n, "edge_edge": m} (None: off)."""
        if not self.solver.particle_enable_self_contact:
            return None
        info = self.solver.trimesh_collision_info
        return {"vertex_triangle": int(info.vertex_colliding_triangles_count.numpy().sum()),
                "edge_edge": int(info.edge_colliding_edges_count.numpy().sum())}

    def set_collider_bounds(self, bounds: np.ndarray, pad_m: float = 0.1, shape: int | None = None) -> None:
        """Set the collision AABB of the collider (or of `shape`, the ground) to `bounds` (2, 3) metres (plus
        `pad_m`): it must contain the moving mesh."""
        b = np.asarray(bounds, dtype=np.float32)
        shape = self.shape if shape is None else shape
        lo = self.model.shape_collision_aabb_lower.numpy()
        hi = self.model.shape_collision_aabb_upper.numpy()
        lo[shape], hi[shape] = b[0] - pad_m, b[1] + pad_m
        self.model.shape_collision_aabb_lower.assign(lo)
        self.model.shape_collision_aabb_upper.assign(hi)

    def set_collider(self, points: np.ndarray, velocities: np.ndarray, mesh=None) -> None:
        """Move the collider (or `mesh`, the ground): points (Vb, 3) metres, velocities (Vb, 3) m/s; refits its BVH."""
        wm = (self.collider if mesh is None else mesh).mesh
        wm.points.assign(np.asarray(points, dtype=np.float32))
        wm.velocities.assign(np.asarray(velocities, dtype=np.float32))
        wm.refit()

    def set_floor(self, height_m: float, velocity: np.ndarray) -> None:
        """Move the ground plane to height `height_m` (metres), moving at `velocity` (3,) m/s (friction drags the
        cloth lying on it along)."""
        quad = self.floor.vertices.copy()
        quad[:, 2] = height_m
        self.set_collider(quad, np.broadcast_to(np.asarray(velocity, dtype=np.float32), quad.shape), mesh=self.floor)

    def get_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(positions (V, 3), velocities (V, 3)) float32 copies."""
        return self.state_0.particle_q.numpy().copy(), self.state_0.particle_qd.numpy().copy()

    def set_state(self, positions: np.ndarray, velocities: np.ndarray) -> None:
        self.state_0.particle_q.assign(np.asarray(positions, dtype=np.float32))
        self.state_0.particle_qd.assign(np.asarray(velocities, dtype=np.float32))

    def advance(self, body_from: np.ndarray, body_to: np.ndarray, duration_s: float, substeps: int,
                pins_from: np.ndarray | None = None, pins_to: np.ndarray | None = None,
                floor: tuple[float, float, np.ndarray] | None = None) -> np.ndarray:
        """Step `duration_s` seconds in `substeps` steps while the collider moves linearly body_from -> body_to.

        body_from, body_to: (Vb, 3) metres; pins_from, pins_to: (P, 3) metres, where the pinned
        particles are at the start and the end (moved linearly too); floor: (height at the start, at the end,
        velocity (3,) m/s) of the ground plane, which moves linearly too (None: it stays). Returns the cloth
        positions (V, 3) float32 at the end.
        """
        dt = duration_s / substeps
        a = np.asarray(body_from, dtype=np.float32)
        b = np.asarray(body_to, dtype=np.float32)
        vel = (b - a) / duration_s
        pinning = len(self.pinned) > 0 and pins_from is not None
        if pinning:
            pa = np.asarray(pins_from, dtype=np.float32)
            pb = np.asarray(pins_to, dtype=np.float32)
        for k in range(substeps):
            # The collider sits where the body is at the end of the substep, moving at the frame's velocity.
            s = (k + 1) / substeps
            self.set_collider(a + s * (b - a), vel)
            if floor is not None and self.floor is not None:
                self.set_floor(floor[0] + s * (floor[1] - floor[0]), floor[2])
            if pinning:
                q, qd = self.get_state()
                q[self.pinned] = pa + s * (pb - pa)
                qd[self.pinned] = (pb - pa) / duration_s
                self.set_state(q, qd)
            self.state_0.clear_forces()
            self.solver.step(self.state_0, self.state_1, self.control, None, dt)
            self.state_0, self.state_1 = self.state_1, self.state_0
        return self.state_0.particle_q.numpy().copy()



def _buffer_sizes(buffers: tuple[int, int]) -> dict:
    """A (vertex-triangle, edge-edge) buffer pair as the report writes it."""
    return {"pairs_per_vertex": buffers[0], "pairs_per_edge": buffers[1]}


class ContactBuffers:
    """Advances a ClothSim so that no self-contact pair is dropped for want of buffer room: a step whose
    detections overflowed Newton's buffers is re-run from its start state with larger ones
    (`ClothSim.grow_contact_buffers`), and where they cannot grow any more the step is kept, its dropped pairs
    logged once and reported."""

    def __init__(self, sim: ClothSim, max_mb: float = SimOptions.contact_buffer_mb):
        self.sim, self.max_bytes = sim, max_mb * 2**20
        self.start = sim.contact_buffers
        self.grown: list[dict] = []
        self.dropped: list[str] = []

    def advance(self, label: str, *args) -> np.ndarray:
        """`ClothSim.advance(*args)`, whole; `label` names the step in the report ("frame 3")."""
        saved = self.sim.get_state()
        while True:
            points = self.sim.advance(*args)
            over = self.sim.contact_overflow()
            if over is None or not (over["vertex_triangle"] or over["edge_edge"]):
                return points
            if not self.sim.grow_contact_buffers(over, self.max_bytes):
                if not self.dropped:
                    log.warning("sim: self-contact found more pairs at a cloth vertex or edge than buffers of %s "
                                "pairs leave room for (contact_buffer_mb %g), from %s on; those pairs are left out",
                                self.sim.contact_buffers, self.max_bytes / 2**20, label)
                self.dropped.append(label)
                return points
            self.grown.append({"at": label, **_buffer_sizes(self.sim.contact_buffers)})
            log.info("sim: self-contact buffers grown to %s pairs at %s; re-running it",
                     self.sim.contact_buffers, label)
            self.sim.set_state(*saved)

    def report(self) -> dict:
        return {"start": _buffer_sizes(self.start), "end": _buffer_sizes(self.sim.contact_buffers),
                "grown": self.grown, "pairs_dropped_at": self.dropped}


class SimDeformer(Deformer):
    """Reference physics: the garment as VBD cloth on the posed body (moving collider), gravity along -Z."""

    name = "sim"

    def __init__(self, material: Material = Material(), options: SimOptions = SimOptions(), jitter_m: float = 0.0):
        """jitter_m: standard deviation (metres) of a seeded random displacement of the garment's starting
        positions, 0 for none: the same scene started a hair apart (`garment tradeoff --spread`), to measure
        how far two equally valid simulations of a chaotic cloth drift apart."""
        super().__init__()
        if not (np.isfinite(jitter_m) and jitter_m >= 0):
            raise InputError(f"sim: expected jitter_m >= 0, got {jitter_m}")
        self.material = material
        self.options = options
        self.jitter_m = float(jitter_m)
        self._bindings: dict = {}

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        """Bind the garment to the body (shape blend shapes, distance check), find what is pinned (the waistband,
        small detached pieces) and the garment's pieces; imports warp early."""
        key = (garment.content_hash(), id(body))
        if key not in self._bindings:
            pieces, small = small_pieces(garment)
            pinned = np.zeros(0, dtype=np.int64)
            if self.options.pin == "auto":
                pinned = np.union1d(waistband_vertices(garment, body, self.options.pin_band_m), small)
                if len(small):
                    n_small = len(np.unique(pieces[small]))
                    log.warning("sim: %d piece%s of the garment (%d vertices) %s not joined to the rest of the cloth "
                                "and too small to hang on %s own (a pocket, a label): %s the body by skinning",
                                n_small, "s" if n_small > 1 else "", len(small), "are" if n_small > 1 else "is",
                                "their" if n_small > 1 else "its", "they follow" if n_small > 1 else "it follows")
            self._bindings[key] = (bind_garment(garment, body, source=source), pinned, pieces, small)
        _warp()

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        o, m = self.options, self.material
        t_start = time.perf_counter()
        self.prepare(garment, body)
        binding, pinned, pieces, small = self._bindings[(garment.content_hash(), id(body))]
        betas = body.fit_betas(motion.betas)
        poses = poses_for_body(motion, body.n_joints)
        T = motion.n_frames
        frame_dt = 1.0 / motion.fps
        # Rest body in the world: every joint at rest except the root, which takes frame 0's orientation.
        rest_pose = np.zeros((1, body.n_joints, 3), dtype=np.float32)
        rest_pose[0, 0] = poses[0, 0]
        pre = []  # internal blend frames (rest -> frame 0), not output
        if motion.n_settle == 0 and o.blend_frames > 0:
            pre = blend_in(poses[0], o.blend_frames)[1:]  # [0] is the rest pose itself
        all_poses = np.concatenate([rest_pose, *([pre] if len(pre) else []), poses])
        all_trans = np.concatenate([motion.trans[:1], np.repeat(motion.trans[:1], len(pre), axis=0), motion.trans])
        body_pts, _, transforms = body.pose_with_transforms(all_poses, all_trans, betas)
        faces_b = outward_faces(body_pts[0], body.faces)  # Newton expects outward normals
        A = body.skinning_transforms(rest_pose, motion.trans[:1], betas)[0, 0]
        shaped = shaped_garment(garment.vertices, binding, betas)
        # fail_off_body_m counts from each piece's median distance at rest.
        n_pieces = int(pieces.max(initial=0)) + 1
        rest_medians = piece_medians(binding.body_distance, pieces, n_pieces)
        # Where skinning puts each vertex, a frame at a time (the check of fail_off_place_m).
        shaped_t, weights_t = torch.from_numpy(shaped.astype(np.float32)), torch.from_numpy(binding.weights)
        transforms_t = torch.from_numpy(np.asarray(transforms, dtype=np.float32))
        # The waistband follows the body by skinning: (frames, P, 3) targets of the pinned particles.
        pins = skin_points(torch.from_numpy(shaped[pinned].astype(np.float32)),
                           torch.from_numpy(binding.weights[pinned]),
                           torch.from_numpy(np.asarray(transforms, dtype=np.float32))).numpy()
        # The simulation runs in a frame that follows the root's translation (`all_trans`): the same physics
        # (Galilean; the frame's velocity changes are applied to the cloth at frame boundaries), but
        # self-contact's speed cap (`self_contact_gap`) then bounds the cloth's motion relative to the body,
        # not the walk's own speed, and coordinates stay small.
        origin = all_trans.astype(np.float64)
        local_body = body_pts - origin[:, None]
        start = shaped @ A[:3, :3].T + A[:3, 3] - origin[0]
        if self.jitter_m > 0:
            start = start + np.random.default_rng(0).normal(0.0, self.jitter_m, start.shape)
        template = garment.vertices @ A[:3, :3].T + A[:3, 3] - origin[0]  # rest lengths: the garment as authored
        pins = pins - origin[:, None].astype(np.float32)
        bounds = np.stack([local_body.reshape(-1, 3).min(0), local_body.reshape(-1, 3).max(0)])
        edges = mesh_edges(garment.faces)
        rest_length = np.linalg.norm(garment.vertices[edges[:, 0]] - garment.vertices[edges[:, 1]], axis=1)
        keep = rest_length > 1e-9
        edges, rest_length = edges[keep], rest_length[keep].astype(np.float64)

        hem_m = float(garment.vertices[:, 1].min() - body.v_template[:, 1].min())
        if o.floor == "none" and hem_m < FLOOR_WARN_M:
            log.warning("sim: the garment reaches %.1f cm %s the body's soles at rest, and the floor is off "
                        "(floor none): cloth that would rest on the ground hangs through it", abs(hem_m) * 100,
                        "above" if hem_m >= 0 else "below")
        # Scene analysis: the collider keeps the body faces within reach of the garment; self-contact only
        # where distant parts of the garment can meet; the ground only where the garment comes near it.
        scene = SceneAnalysis(self.skips)
        offset = 1 + len(pre)  # the first output frame among the simulated ones
        kept, self_contact, floor_world = analyse_collisions(scene, garment, body_pts, faces_b, shaped, binding.weights,
                                                          np.asarray(transforms), o.self_contact,
                                                          floor=o.floor == "auto", motion_from=offset)
        collider_v, collider_f = np.arange(body.n_vertices), faces_b
        if kept is not None:
            collider_v = np.unique(faces_b[kept])
            collider_f = np.searchsorted(collider_v, faces_b[kept])
        collider = local_body[:, collider_v]
        # Self-contact: a detection distance wide enough for the garment's fastest motion relative to the moving
        # frame: its LBS motion relative to the root, plus the largest change of the frame's velocity.
        frame_velocity = np.diff(origin, axis=0, prepend=origin[:1]) * motion.fps  # (frames, 3) m/s
        speed = 0.0
        if self_contact:
            speed = (_relative_lbs_speed(shaped, binding.weights, transforms, origin, motion.fps)
                     + float(np.linalg.norm(np.diff(frame_velocity, axis=0), axis=1).max(initial=0.0)))
        gap = self_contact_gap(m, speed, frame_dt / o.substeps)
        # The ground, static in the world (but lowered under a lead-in body that reaches below it), moves against
        # the frame: (height, its height one frame on, velocity).
        floor_z = None if floor_world is None else floor_world - origin[:, 2]
        lifted = 0
        if floor_z is not None:  # cloth authored below the ground starts on it (the body never is below it)
            low = start[:, 2] < floor_z[0] + m.contact_distance_m
            lifted = int(low.sum())
            start[low, 2] = floor_z[0] + m.contact_distance_m

        def ground(i: int, j: int):
            if floor_z is None:
                return None
            velocity = -frame_velocity[j]
            velocity[2] = (floor_z[j] - floor_z[i]) * motion.fps
            return floor_z[i], floor_z[j], velocity

        sim = ClothSim(template, garment.faces, collider[0], collider_f, m, self_contact, o.iterations,
                       start_vertices=start, bounds=bounds, pinned=pinned,
                       self_contact_gap_m=gap, contact_filter=scene.enabled("self-contact"), floor_z=floor_z)
        if self_contact:  # None: --no-skip self-contact checks every pair in reach
            scene.report["self-contact"]["filtered_along_surface"] = sim.contact_filter
        t_built = time.perf_counter()
        buffers = ContactBuffers(sim, o.contact_buffer_mb)
        # Phase 1: settle on the static rest body.
        n_settle_steps = int(round(o.settle_s * motion.fps))
        for i in range(n_settle_steps):
            buffers.advance(f"settle {i}", collider[0], collider[0], frame_dt, o.substeps, pins[0], pins[0],
                            ground(0, 0))
        # Phase 2: internal blend into frame 0.
        for i in range(len(pre)):
            buffers.advance(f"blend {i}", collider[i], collider[i + 1], frame_dt, o.substeps, pins[i], pins[i + 1],
                            ground(i, i + 1))
        t_pre = time.perf_counter()
        # Phase 3: the output frames, checked and retried.
        out = np.empty((T, garment.n_vertices, 3), dtype=np.float32)
        stats, retries = [], []
        for t in range(T):
            prev = collider[offset + t - 1]
            cur = body_pts[offset + t]
            q, qd = sim.get_state()
            sim.set_state(q, qd - (frame_velocity[offset + t] - frame_velocity[offset + t - 1]))
            saved = sim.get_state()
            best = None
            substeps = o.substeps
            for attempt in range(o.max_retries + 1):
                if attempt:
                    sim.set_state(*saved)
                    substeps *= 2
                points = buffers.advance(f"frame {t}", prev, collider[offset + t], frame_dt, substeps,
                                         pins[offset + t - 1], pins[offset + t], ground(offset + t - 1, offset + t))
                points = points + origin[offset + t].astype(np.float32)  # back into the world
                check = frame_checks(points, cur, faces_b, edges, rest_length, tunnel_depth=o.retry_depth_m,
                                     pieces=pieces)
                check["substeps"] = substeps
                if best is None or _worse(best[1], check):
                    best = (points, check, sim.get_state())
                if (check["finite"] and check["tunnelled_share"] <= o.retry_penetration_share
                        and check["mean_strain"] <= o.retry_mean_strain):
                    break
                log.info("sim frame %d try %d failed checks (%s)", t, attempt, _describe(check, o.retry_depth_m))
            points, check, state = best
            if attempt:
                retries.append({"frame": t, "tries": attempt + 1, "kept_substeps": check["substeps"]})
                sim.set_state(*state)
            fell = [k for k, (now, rest) in enumerate(zip(check["piece_median_body_distance_m"], rest_medians))
                    if now > o.fail_off_body_m + rest]
            skinned = skin_points(shaped_t, weights_t, transforms_t[offset + t:offset + t + 1])[0].numpy()
            moved = piece_medians(np.linalg.norm(points - skinned, axis=1), pieces, n_pieces)
            left = [k for k, d in enumerate(moved) if d > o.fail_off_place_m]
            if (not check["finite"] or check["tunnelled_share"] > o.fail_penetration_share
                    or check["mean_strain"] > o.fail_mean_strain or fell or left):
                off = ""

                def what(k):
                    return (f"piece {k + 1} of {n_pieces} ({int(np.sum(pieces == k))} vertices, not joined to the "
                            "rest)" if n_pieces > 1 else "the garment")

                if fell and (n_pieces > 1 or not left):
                    k = fell[0]
                    off = (f"; {what(k)} fell or slid off the body: its median distance to it is "
                           f"{check['piece_median_body_distance_m'][k] * 100:.1f} cm, {rest_medians[k] * 100:.1f} cm "
                           f"at rest")
                elif left:
                    k = left[0]
                    off = (f"; {what(k)} fell or slid down the body: its median distance from where skinning puts it "
                           f"is {moved[k] * 100:.0f} cm (over {o.fail_off_place_m * 100:.0f} cm)"
                           + ("" if o.pin == "auto" else "; --pin auto holds waistbands and small pieces"))
                    if o.pin == "auto" and not np.isin(np.flatnonzero(pieces == k), pinned).any():
                        off += ("; nothing held it: no waistband to pin, and it hangs from no shoulders (a patch or "
                                "a piece cut from its garment?): simulate the whole garment, or bake it with --method "
                                "model or lbs")
                raise SimulationError(
                    f"sim: frame {t} of motion '{motion.name}' failed after "
                    + (f"{attempt + 1} tries (up to {substeps} substeps)" if attempt else f"1 try ({substeps} substeps)")
                    + f": {_describe(check, o.retry_depth_m)}{off}"
                    f"{_cut_before(body_pts, offset, t, motion.fps)}")
            out[t] = points
            stats.append(check)
            if self.on_frames is not None:
                self.on_frames(1)
        t_end = time.perf_counter()
        pen = np.array([s["penetration_share"] for s in stats]) * 100.0
        mean_strain = np.array([s["mean_strain"] for s in stats])
        max_strain = np.array([s["max_strain"] for s in stats])
        self.report = {
            "method": self.name,
            "material": asdict(m),
            "options": asdict(o),
            "start_jitter_m": self.jitter_m,
            "solver": {"engine": "newton SolverVBD", "device": sim.device, "newton": package_version("newton"),
                       "warp": package_version("warp-lang"), "dt_s": frame_dt / o.substeps},
            "pinned_vertices": len(pinned),
            "pieces": {"count": n_pieces, "small_pinned_vertices": len(small) if o.pin == "auto" else 0},
            "non_manifold_edges": sim.non_manifold_edges,
            "hem_above_soles_m": hem_m,
            "floor": None if floor_world is None else {"ground_z_m": scene.report["floor"]["ground_z_m"],
                                                       "lowest_z_m": float(floor_world.min()),
                                                       "lifted_onto_it_at_start": lifted},
            "self_contact": ({"detection_gap_m": gap, "relative_speed_max_m_s": speed,
                              "cloth_speed_limit_m_s": cloth_speed_limit(m, gap, frame_dt / o.substeps),
                              "filtered_along_surface": sim.contact_filter,
                              "pairs_last_frame": sim.contact_pairs(), "buffers": buffers.report()}
                             if self_contact else None),
            "settle_frames_internal": n_settle_steps, "blend_frames_internal": len(pre),
            "seconds": {"build": t_built - t_start, "settle": t_pre - t_built, "frames": t_end - t_pre},
            "seconds_per_output_frame": (t_end - t_pre) / T,
            "checks": {"penetration_depth_mm": PENETRATION_DEPTH_M * 1e3,
                       "penetration_percent_max": float(pen.max()), "penetration_percent_mean": float(pen.mean()),
                       "worst_penetration_frame": int(np.argmax(pen)),
                       "edge_strain_mean": float(mean_strain.mean()), "edge_strain_mean_max": float(mean_strain.max()),
                       "edge_strain_max": float(max_strain.max()),
                       "nan": False},
            "per_frame": {"penetration_percent": [round(float(p), 4) for p in pen],
                          "edge_strain_mean": [round(float(s), 6) for s in mean_strain]},
            "retries": retries,
        }
        self.scene = scene.report
        return out


def _relative_lbs_speed(shaped: np.ndarray, weights: np.ndarray, transforms: np.ndarray, origin: np.ndarray,
                        fps: float, chunk: int = 256) -> float:
    """Fastest speed (m/s) of a garment vertex skinned by LBS, relative to the moving `origin`.

    shaped: (V, 3) garment rest positions; weights: (V, J); transforms: (T, J, 4, 4) consecutive frames at
    `fps`; origin: (T, 3) metres. Frames are skinned `chunk` at a time (a long motion's preview would not fit).
    """
    fastest = 0.0
    for i in range(0, len(transforms) - 1, chunk):
        frames = slice(i, min(i + chunk + 1, len(transforms)))
        p = lbs_preview(shaped, weights, transforms[frames]) - origin[frames, None].astype(np.float32)
        fastest = max(fastest, float(np.linalg.norm(np.diff(p, axis=0), axis=-1).max()) * fps)
    return fastest


def _worse(a: dict, b: dict) -> bool:
    """True when check `b` is better than `a` (finite first, then penetration, then strain)."""
    def key(c):
        return (not c["finite"], round(c["tunnelled_share"], 4), c["mean_strain"])

    return key(b) < key(a)


#: Frames before a failing one searched for such a cut (the cloth fails a few frames after it).
CUT_LOOKBACK = 4


def _cut_before(body_pts: np.ndarray, offset: int, t: int, fps: float) -> str:
    """Where the body jumped in the frames up to output frame `t` (body_pts (T', Vb, 3), output frame k at
    `offset` + k), the advice for a failure after it: "" where it did not."""
    lo = max(offset + t - CUT_LOOKBACK, offset, 1)  # a written frame: --frames names it
    hi = offset + t
    if hi < lo:
        return ""
    jumps = np.array([float(np.linalg.norm(body_pts[k] - body_pts[k - 1], axis=1).max()) for k in range(lo, hi + 1)])
    k = int(np.argmax(jumps))
    if jumps[k] * fps <= CUT_SPEED_M_S:
        return ""
    return (f"; the body moved {jumps[k]:.2f} m in one frame at frame {lo + k - offset} ({jumps[k] * fps:.0f} m/s: a "
            "teleport or a cut in the capture?): bake the parts before and after it apart with --frames")


def _describe(check: dict, tunnel_depth_m: float) -> str:
    if not check["finite"]:
        return "NaN/Inf in positions"
    return (f"{check['tunnelled_share'] * 100:.2f}% of vertices > {tunnel_depth_m * 1e3:g} mm inside the body "
            f"({check['penetration_share'] * 100:.2f}% > 2 mm), "
            f"edge strain mean {check['mean_strain'] * 100:.2f}% max {check['max_strain'] * 100:.1f}%, "
            f"median distance to the body {check['median_body_distance_m'] * 100:.1f} cm")

