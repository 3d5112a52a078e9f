"""Training data of the learned model: simulated sequences as windows of m frames, per-garment inputs cached.

Reads a simulator dataset directory (the layout `formats/dataset.py` writes):
manifest.json with `splits` {"train"|"val"|"test": [item ids]} and `items`
(a list of {"id", "garment", "motion", "betas", optional "file"}, or a dict
id -> such a record), garments/<name>.obj rest templates, and one .npz per
item (`<id>.npz` beside the manifest or under sequences/, or the item's
"file") with positions (T, V, 3) float32 Z-up metres, poses (T, J, 3), trans
(T, 3), betas, fps. Garment preprocessing goes through `core.preprocess`
(cached by mesh hash when `cache_dir` is set) and the LBS binding through
`core.skinning`; both are computed once per garment. Sequence features
(`core.model.motion_features`) once per item.
# TODO(lead): move the file reading to formats/dataset.py's reader once it exists.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import torch

from core.body import Body
from core.errors import InputError
from core.garment import Garment
from core.geodesic import SELF_COLLISION_GEODESIC_M
from core.losses import rest_uv_frame, vertex_masses
from core.model import (GarmentInputs, ModelConfig, MotionFeatures, body_distances, garment_inputs, motion_features,
                        shaped_rest, tensors_to)
from core.preprocess import preprocess_garment
from core.skinning import bind_garment, oriented_outward

log = logging.getLogger(__name__)

#: Weight-smoothing passes of the LBS prior (as the `lbs` method's default).
PRIOR_SMOOTH_ITERATIONS = 10


@dataclass(frozen=True, eq=False)
class GarmentData:
    """One garment ready for training and inference.

    inputs: GarmentInputs. near: (V, V) sparse rest 10 cm neighbourhood (Eq. 6), None where not built
    (`prepare_garment(near=False)`, inference). masses: (V,) kg.
    dm_inv: (F, 2, 2) rest (u, v) frames (Eq. 10); area: (F,) m^2. preprocess_cache: where its preprocessing
    came from: "hit" (the cache), "miss" (computed, and stored where the cache can be written), "off" (no cache).
    """

    garment: Garment
    inputs: GarmentInputs
    near: sp.csr_matrix | None
    masses: torch.Tensor
    dm_inv: torch.Tensor
    area: torch.Tensor
    preprocess_cache: str = "off"


def prepare_garment(garment: Garment, body: Body, config: ModelConfig, cache_dir=None,
                    source: str | None = None, near: bool = True) -> GarmentData:
    """Preprocess (cached) and bind `garment` on `body` for a model of `config`.

    near: build the rest neighbourhood of the self-collision loss (Eq. 6; training only). Its pairs grow as the
    square of the vertex count at a given size (a 213k-vertex garment: about 10^9 pairs), so inference leaves
    it out (`GarmentData.near` None)."""
    garment = oriented_outward(garment, body, source)  # the network reads the rest normals
    prep = preprocess_garment(garment, body, levels=config.levels, n_landmarks=config.n_landmarks,
                              n_eigenvalues=config.n_eigenvalues, cache_dir=cache_dir, cache_optional=True,
                              collision_radius_m=SELF_COLLISION_GEODESIC_M if near else 0.0)
    binding = bind_garment(garment, body, PRIOR_SMOOTH_ITERATIONS, 0.5, source=source)
    dm, area = rest_uv_frame(garment.vertices, garment.faces, garment.uvs, garment.face_uvs)
    return GarmentData(garment=garment, inputs=garment_inputs(prep, binding, garment.faces, config.levels),
                       near=prep.collision_near,
                       masses=torch.from_numpy(vertex_masses(garment.vertices, garment.faces)),
                       dm_inv=torch.from_numpy(dm), area=torch.from_numpy(area),
                       preprocess_cache="hit" if prep.cache_hit else "miss" if cache_dir is not None else "off")


@dataclass(frozen=True, eq=False)
class Sequence:
    """One simulated sequence of one garment on one body shape.

    positions: (T, V, 3) float32 world metres (ground truth). poses: (T, J, 3); trans: (T, 3); betas: (S,).
    motion: MotionFeatures. rest: (V, 3) garment rest on the shaped body. body_dist: (N_b, S).
    n_settle: leading frames before the clip, the settle blend from the rest pose (`core.motion.settle`) and
    any pre-roll (`garment dataset --preroll`): inputs of the frames after them (their window), never targets.
    """

    item_id: str
    garment_name: str
    positions: torch.Tensor
    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    fps: float
    motion: MotionFeatures
    rest: torch.Tensor
    body_dist: torch.Tensor
    n_settle: int = 0

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    def draw_frames(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """`n` target frames drawn uniformly, with repeats, after the settle blend: (n,) int64 sorted."""
        return np.sort(rng.integers(self.n_settle, self.n_frames, size=n))

    def even_frames(self, n: int) -> np.ndarray:
        """Up to `n` target frames evenly spread over those after the settle blend (validation): sorted int64."""
        first, last = self.n_settle, self.n_frames - 1
        return np.unique(np.linspace(first, last, min(n, last - first + 1)).round().astype(np.int64))


def sequence_from_arrays(item_id: str, garment_name: str, arrays: dict, body: Body, garment: GarmentData,
                         source: str) -> Sequence:
    """Build a Sequence from an item's arrays (see module docstring); InputError naming `source` when bad."""
    for key in ("positions", "poses", "trans", "fps"):
        if key not in arrays:
            raise InputError(f"dataset sequence '{source}': expected key '{key}', got {sorted(arrays)}")
    pos = np.asarray(arrays["positions"], dtype=np.float32)
    poses = np.asarray(arrays["poses"], dtype=np.float32)
    trans = np.asarray(arrays["trans"], dtype=np.float32)
    V = garment.inputs.n_vertices
    if pos.ndim != 3 or pos.shape[1:] != (V, 3):
        raise InputError(f"dataset sequence '{source}': expected positions of shape (T, {V}, 3) for garment "
                         f"'{garment_name}', got {tuple(pos.shape)}")
    T = pos.shape[0]
    if poses.shape != (T, body.n_joints, 3):
        raise InputError(f"dataset sequence '{source}': expected poses of shape ({T}, {body.n_joints}, 3), "
                         f"got {tuple(poses.shape)}")
    if trans.shape != (T, 3):
        raise InputError(f"dataset sequence '{source}': expected trans of shape ({T}, 3), got {tuple(trans.shape)}")
    betas = body.fit_betas(arrays.get("betas"))
    fps = float(np.asarray(arrays["fps"]))
    n_settle = int(np.asarray(arrays.get("n_settle", 0)))
    if not 0 <= n_settle < T:
        raise InputError(f"dataset sequence '{source}': expected n_settle in [0, {T}) (settle frames before the "
                         f"motion's {T} frames end), got {n_settle}")
    _refuse_far_off(pos, body, poses, trans, betas, garment.inputs.rest.numpy(), source)
    return Sequence(item_id=item_id, garment_name=garment_name, positions=torch.from_numpy(pos), poses=poses,
                    trans=trans, betas=betas, fps=fps, motion=motion_features(body, poses, trans, betas, fps),
                    rest=shaped_rest(garment.inputs, body, betas), body_dist=body_distances(body, betas),
                    n_settle=n_settle)


#: How far (in the garment's own sizes, the diagonal of its rest box) a training sequence's cloth may lie beyond
#: its body (the box of its posed joints widened by the body's own reach from them): further is a broken sequence.
FAR_OFF_SIZES = 2.0


def _refuse_far_off(pos: np.ndarray, body: Body, poses: np.ndarray, trans: np.ndarray, betas: np.ndarray,
                    rest: np.ndarray, source: str) -> None:
    """InputError where a frame's cloth `pos` (T, V, 3) lies further from the body than FAR_OFF_SIZES of the
    garment's own size: a simulation that blew up but stayed finite (a vertex 100 m off trained on with a finite
    loss, one 1e30 m off diverged at its first step). Measured from the box of the posed joints, widened by the
    furthest any vertex of the shaped body lies from its nearest joint (a bound of the body's surface)."""
    verts, joints_rest = body.shaped(betas)
    reach = float(np.sqrt(((verts[:, None, :] - joints_rest[None]) ** 2).sum(-1).min(1)).max())
    size = float(np.linalg.norm(rest.max(0) - rest.min(0)))
    joints = body.posed_joints(poses, trans, betas)  # (T, J, 3)
    lo, hi = joints.min(1, keepdims=True) - reach, joints.max(1, keepdims=True) + reach
    far, t, v = -1.0, 0, 0
    step = max(1, 2_000_000 // max(pos.shape[1], 1))  # frames at once: a few temporaries of 2M points each
    for s in range(0, len(pos), step):
        out = np.maximum(lo[s:s + step] - pos[s:s + step], 0.0) + np.maximum(pos[s:s + step] - hi[s:s + step], 0.0)
        beyond = np.hypot(np.hypot(out[..., 0], out[..., 1]), out[..., 2])  # (t, V) metres (1e30 m: no overflow)
        k = int(beyond.argmax())
        if beyond.flat[k] > far:
            far, t, v = float(beyond.flat[k]), s + k // beyond.shape[1], k % beyond.shape[1]
    if far > FAR_OFF_SIZES * size:
        raise InputError(f"dataset sequence '{source}': expected its cloth within {FAR_OFF_SIZES:g} times the "
                         f"garment's size ({FAR_OFF_SIZES * size:.2f} m) of the body, got vertex {v} "
                         f"{far:.4g} m from it at frame {t}: a simulation that blew up? simulate it "
                         "again, or leave the item out of the manifest")


def manifest_items(manifest: dict, source: str) -> dict:
    """A dataset manifest's items by id (its 'items' a list of records with an 'id', or a mapping); InputError naming
    `source` otherwise."""
    items = manifest.get("items", {})
    if isinstance(items, list):
        out = {}
        for rec in items:
            if not isinstance(rec, dict) or "id" not in rec:
                raise InputError(f"dataset manifest '{source}': expected items with an 'id', got {rec!r:.80}")
            out[str(rec["id"])] = rec
        return out
    if isinstance(items, dict):
        return {str(k): v for k, v in items.items()}
    raise InputError(f"dataset manifest '{source}': expected 'items' as a list or a mapping, got {type(items).__name__}")


#: Key of the dataset directory in the item records ModelDataset merges (not a manifest field).
_ROOT = "_root"

#: Item fields that make two records of one id the same simulated item.
_SAME_ITEM = ("garment", "motion", "clip", "start_frame", "n_frames", "body", "split")


def _item_file(item_id: str, rec: dict) -> Path:
    from formats.dataset import sequence_path

    root = rec[_ROOT]
    return root / str(rec["file"]) if "file" in rec else sequence_path(root, item_id)


def _merged_manifests(roots: list[Path]) -> tuple[dict, dict, dict]:
    """The first dataset's manifest, every dataset's items (id -> record with its directory) and garment
    templates (name -> path); InputError when the datasets disagree (see ModelDataset)."""
    from formats.dataset import MANIFEST, read_manifest
    from formats.obj import read_obj

    first, items, templates, motion_split = None, {}, {}, {}
    for root in roots:
        mpath = root / MANIFEST
        manifest = read_manifest(root)
        if manifest is None:
            raise InputError(f"dataset '{root}': expected a {MANIFEST} in it, found none")
        recs = manifest_items(manifest, str(mpath))
        unknown = sorted({str(rec.get("split")) for rec in recs.values()} - {"train", "val", "test"})
        if unknown:
            raise InputError(f"dataset manifest '{mpath}': expected every item's 'split' to be train, val or test, "
                             f"got {unknown[0]!r}")
        if first is None:
            first = manifest
        else:
            lead = {k: first.get("settings", {}).get(k) for k in ("settle", "fps")}
            here = {k: manifest.get("settings", {}).get(k) for k in ("settle", "fps")}
            if here != lead:
                raise InputError(f"dataset '{root}': expected the settle blend of dataset '{roots[0]}' ({lead}), got "
                                 f"{here}: the model learns one lead-in")
        for gname in sorted({str(rec.get("garment")) for rec in recs.values()}):
            gpath = root / "garments" / f"{gname}.obj"
            if not gpath.is_file():
                continue
            _refuse_edited_template(gpath, manifest.get("inputs", {}).get("garments", {}).get(gname))
            if gname not in templates:
                templates[gname] = gpath
            elif read_obj(gpath).content_hash() != read_obj(templates[gname]).content_hash():
                raise InputError(f"dataset '{root}': expected its garment '{gname}' to be the mesh of "
                                 f"'{templates[gname]}', got a different '{gpath}'")
        for item_id, rec in recs.items():
            motion, split = rec.get("motion"), rec["split"]
            if motion is not None and motion_split.setdefault(motion, (split, root))[0] != split:
                raise InputError(f"dataset '{root}': expected motion '{motion}' in the '{motion_split[motion][0]}' "
                                 f"split as in dataset '{motion_split[motion][1]}', got '{split}' (a motion "
                                 f"trained on and tested on)")
            if item_id in items:
                if any(items[item_id].get(k) != rec.get(k) for k in _SAME_ITEM):
                    raise InputError(f"dataset '{root}': expected item '{item_id}' to be the item of that id in "
                                     f"dataset '{items[item_id][_ROOT]}', got a different one")
                if _item_file(item_id, items[item_id]).is_file():
                    continue  # the same item: kept once, from wherever it is simulated
            items[item_id] = {**rec, _ROOT: root}
    return first, items, templates


def _refuse_edited_template(path: Path, recorded) -> None:
    """InputError where a dataset's garment template is no longer the garment its sequences were simulated with
    (one vertex moved 1 cm was trained on unnoticed; only another vertex count was caught). recorded: the
    manifest's `inputs.garments[name]` ({"path", "sha256", "template_sha256"}): a garment read from an OBJ is a
    byte copy of it (compared by the file's sha256); one read from USD is written anew as the OBJ of its mesh
    (compared by that file's sha256, `template_sha256`, recorded since 2026-12-07: its 6 decimals are not the
    USD's floats, so the mesh's own hash cannot be); one not recorded is not compared."""
    from core.provenance import file_sha256

    if not isinstance(recorded, dict):
        return
    key = "sha256" if str(recorded.get("path", "")).lower().endswith(".obj") else "template_sha256"
    edited = recorded.get(key) not in (None, file_sha256(path))
    was = f"sha256 {str(recorded.get(key))[:12]}"
    if edited:
        raise InputError(f"dataset garment '{path}': expected the file its sequences were simulated with "
                         f"('{recorded.get('path')}', {was}), got a file edited since: restore it, or simulate the "
                         "dataset again")


class ModelDataset:
    """Simulator datasets loaded for training: garments (shared) and sequences per split.

    root: a dataset directory, or a list of them trained on together (`garment train --data A --data B`): their
    garments of one name must be the same mesh, their motions in the same split, their settle blends alike, and
    an item id in two of them the same item (kept once, e.g. a dataset that links another's sequences).
    body: the body the sequences were simulated on. splits: which to load. cache_dir: preprocessing cache
    (None = compute). partial: load the sequences simulated so far of a dataset whose `garment dataset` run has
    not finished (`missing` counts the others per split) instead of refusing it. garments: load only these
    garments' sequences (a garment's own fine-tune); None: every garment.
    """

    def __init__(self, root, body: Body, config: ModelConfig, splits=("train", "val"), cache_dir=None,
                 partial: bool = False, garments=None):
        from dataclasses import asdict

        from formats.dataset import read_sequence
        from formats.obj import read_obj  # file reading lives in formats/

        self.roots = [Path(r) for r in (root if isinstance(root, (list, tuple)) else [root])]
        self.root = self.roots[0]
        self.body = body
        self.config = config
        self.manifest, items, templates = _merged_manifests(self.roots)
        name = "dataset " + ", ".join(f"'{r}'" for r in self.roots)
        if garments is not None:
            known = {str(rec.get("garment")) for rec in items.values()}
            garments = set(garments)
            unknown = sorted(garments - known)
            if unknown:
                raise InputError(f"{name}: expected a garment of its sequences ({', '.join(sorted(known))}), "
                                 f"got '{unknown[0]}'")
            items = {i: rec for i, rec in items.items() if str(rec.get("garment")) in garments}
        missing = [i for i, rec in items.items() if rec["split"] in splits and not _item_file(i, rec).is_file()]
        if missing and not partial:
            raise InputError(f"{name}: {len(missing)} of {len(items)} sequences are missing (e.g. '{missing[0]}'); "
                             f"the `garment dataset` run has not finished: rerun it to resume (or train on what it "
                             f"has simulated with --partial)")
        self.missing = {split: sum(items[i]["split"] == split for i in missing) for split in splits}
        if missing:
            missing = set(missing)
            for split in splits:
                if self.missing[split] and all(i in missing for i, rec in items.items() if rec["split"] == split):
                    raise InputError(f"{name}: expected sequences in its '{split}' split, got none simulated yet")
            log.warning("%s: %d of its %s sequences are not simulated yet; training on the others",
                        name, len(missing), "/".join(splits))
            items = {i: rec for i, rec in items.items() if i not in missing}
        self.device = torch.device("cpu")
        self.body_faces = torch.as_tensor(np.asarray(body.faces), dtype=torch.long)
        self.garments: dict[str, GarmentData] = {}
        self.splits: dict[str, list[Sequence]] = {}
        for split in splits:
            seqs = []
            for item_id, rec in items.items():
                if rec["split"] != split:
                    continue
                gname = str(rec["garment"])
                if gname not in self.garments:
                    gpath = templates.get(gname, rec[_ROOT] / "garments" / f"{gname}.obj")
                    if not gpath.is_file():
                        raise InputError(f"dataset '{rec[_ROOT]}': expected garment template '{gpath}', found none")
                    self.garments[gname] = prepare_garment(read_obj(gpath), body, config, cache_dir, str(gpath))
                spath = _item_file(item_id, rec)
                arrays = asdict(read_sequence(spath))
                seqs.append(sequence_from_arrays(item_id, gname, arrays, body, self.garments[gname], str(spath)))
            self.splits[split] = seqs
            log.info("dataset split '%s': %d sequences", split, len(seqs))

    def to(self, device) -> ModelDataset:
        """Move every tensor of the garments and sequences to `device` (in place); returns self."""
        self.device = torch.device(device)
        self.garments = {k: tensors_to(g, self.device) for k, g in self.garments.items()}
        self.splits = {k: [tensors_to(s, self.device) for s in seqs] for k, seqs in self.splits.items()}
        self.body_faces = self.body_faces.to(self.device)
        return self

    def posed_body(self, seq: Sequence, frames: np.ndarray) -> torch.Tensor:
        """The body of `seq` at `frames` (B,): (B, N_b, 3) float32 world metres (no gradient), on the data's device."""
        v, _ = self.body.pose(seq.poses[frames], seq.trans[frames], seq.betas)
        return torch.from_numpy(v).to(self.device)
