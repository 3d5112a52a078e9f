"""`bake --method model`: the learned garment model as a `core.deform.Deformer`.

Runs a trained `core.model.GarmentModel` (loaded by `formats.checkpoint.load_model`)
on any garment authored on the body's rest pose: the rest-pose features are
computed once per (garment, body shape), frames are evaluated in batches.
"""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from core.body import SMPL_JOINT_NAMES, Body
from core.deform import Deformer
from core.errors import InputError
from core.garment import Garment
from core.model import (
    GarmentInputs,
    GarmentModel,
    body_distances,
    motion_features,
    shaped_rest,
    tensors_to,
    window_index,
)
from core.model_data import prepare_garment
from core.motion import Motion, joint_speeds, poses_for_body, prepend_blend
from core.pushout import (ContactAnchors, alternate_guard_limit, anchored_body, body_anchors, guard_and_limit,
                          guard_contact, guard_report)
from core.scene import SceneAnalysis, scene_levels
from core.strain import STRAIN_ITERATIONS, STRAIN_LIMIT, garment_strain, limit_strain, still_over, strain_report
from core.threads import ThreadTuner

log = logging.getLogger(__name__)

#: The model shipped in the package (trained by the command in core/assets/README.md); `bake`'s default.
DEFAULT_MODEL = Path(__file__).resolve().parent / "assets" / "default_model.pt"
PRECISIONS = ("float32", "bfloat16")
#: Body shapes whose prepared inputs a ModelDeformer keeps per garment (`_Shaped`): a bake of many motions of one
#: subject prepares them once.
SHAPED_CACHE = 4


@functools.cache
def _cpuinfo() -> str | None:
    """/proc/cpuinfo, read once per process (a bfloat16 bake asks twice: the CLI's warning and the report)."""
    try:
        return Path("/proc/cpuinfo").read_text()
    except OSError:
        return None


def native_bfloat16(cpuinfo: str | None = None) -> bool | None:
    """Whether this CPU does bfloat16 arithmetic natively (x86: avx512_bf16 or amx_bf16; Arm: bf16), from
    /proc/cpuinfo (or the text `cpuinfo`); None where that cannot be told (no /proc/cpuinfo). Without it oneDNN
    emulates bfloat16: on an AVX2-only AMD EPYC the network ran 2.1x slower in bfloat16 than in float32
    (91 against 43 ms/frame, 3,960 vertices, one thread, 2026-12-02)."""
    if cpuinfo is None:
        cpuinfo = _cpuinfo()
        if cpuinfo is None:
            return None
    flags = set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() in ("flags", "Features"):
            flags.update(value.split())
    if not flags:
        return None
    return bool(flags & {"avx512_bf16", "amx_bf16", "bf16"})


#: A joint counts as covered by training when some training garment puts at least this share of its
#: skinning weight on it.
COVERED_JOINT_SHARE = 0.01
#: A garment with more than this share of its skinning weight on joints no training garment covered is
#: outside the model's range (measured: the training garments 0-1.3 %, the held-out t-shirt 30 % and
#: jumpsuit 11 %, on which the shipped model is worse than LBS).
MAX_UNCOVERED_SHARE = 0.05


#: Frames per forward pass where ModelDeformer is not told: on a CPU 2, the fastest measured on a 2-core
#: AMD EPYC for a 3,960-vertex dress (15 ms/frame against 20 at 4 and 23 at 8: the graph attention's
#: per-layer temporaries of a few frames stay in cache; benchmarks/throughput.py); elsewhere `default_batch_frames`.
#: Measured again with freed memory kept (benchmarks/results/cpu_batch.md, 2,016-12,816 vertices, 1 and 2
#: threads): within 8 % of the fastest batch for every garment, 1.1-1.25x faster than 32.
DEFAULT_BATCH_FRAMES = {"cpu": 2}

#: On a GPU, vertex-frames per forward pass where ModelDeformer is not told (128 frames of a 4,096-vertex garment):
#: on an H200 the network alone ran the 3,960-vertex dress at 1,911 frames/s in batches of 8, 6,483 of 32, 9,494
#: of 128 and 10,544 of 512 (benchmarks/results/throughput_gpu.md), its memory growing with the batch.
GPU_VERTEX_FRAMES = 1 << 19
#: Most frames per forward pass on a GPU (a small garment's).
GPU_MAX_BATCH_FRAMES = 512


#: Lead-in of a model whose checkpoint records none (meta "lead_in_s"), seconds: the settle blend of the
#: datasets the shipped models were trained on (README: `garment dataset ... --settle 6` at 30 fps).
DEFAULT_LEAD_IN_S = 0.2
#: Frames over which the lead-in's last effect fades out (`_lead_fade`): the network's output at the last frame
#: whose window holds a lead-in velocity (written frame `window - 1`) minus its output there from a window that
#: starts still, added to the next frames with weights 3/4, 1/2, 1/4. Without it the transient stopped dead at
#: written frame 5 (a 146 mm jump on the skirt's brisk walk where the frames around it moved 79-108; 14 mm on a
#: still body that then stood dead still); with it 93 and 4 mm, and the error against the simulator over the
#: first 15 frames 20.43 mm against 20.72 (dress: 20.77 against 20.71; fades of 5 and 8 frames cost 0.6 and
#: 1.4 mm there).
LEAD_FADE_FRAMES = 3


#: A body whose joints all move slower than this (m/s) over its first STILL_START_FRAMES frames starts still: the
#: network's window is given a body that stood still before it, not the lead-in blend from the rest pose, whose
#: transient, faded out, slid a still body's dress 61 mm over its first eight frames (15 mm a frame at frames 4-8,
#: then a dead stop; now 0.2-0.3 mm a frame, the frames from the ninth on the same). Against the simulator, whose
#: cloth falls from its rest shape at the start (33 mm a frame), the dress on the example arms_raise's first 7
#: frames: 26.28 mm with the lead-in, 26.63 without. A standing capture's joints jitter well under this; a walk's
#: move about 1 m/s.
STILL_START_M_S = 0.1
STILL_START_FRAMES = 3


def starts_still(body: Body, poses: np.ndarray, trans: np.ndarray, betas, fps: float) -> bool:
    """Whether the body posed by `poses` (T, J, 3) and `trans` (T, 3) starts still: every joint slower than
    STILL_START_M_S between its first STILL_START_FRAMES frames (a single frame: still)."""
    n = min(STILL_START_FRAMES, len(poses))
    if n < 2:
        return True
    return float(joint_speeds(body, poses[:n], trans[:n], betas, fps).max()) < STILL_START_M_S


def default_batch_frames(device: torch.device | str, n_vertices: int = 4096) -> int:
    """Frames per forward pass of an `n_vertices` garment on `device` where ModelDeformer is not told."""
    kind = torch.device(device).type
    if kind in DEFAULT_BATCH_FRAMES:
        return DEFAULT_BATCH_FRAMES[kind]
    return int(np.clip(GPU_VERTEX_FRAMES // max(n_vertices, 1), 1, GPU_MAX_BATCH_FRAMES))


def joint_shares(weights) -> np.ndarray:
    """(S,) share of a garment's total skinning weight (V, S) on each joint."""
    w = np.asarray(weights, dtype=np.float64)
    return w.sum(axis=0) / max(float(w.sum()), 1e-12)


def joint_coverage(garment_weights) -> list[float]:
    """Per joint, the largest share of a training garment's skinning weight on it (checkpoint meta
    "joint_coverage"): from the prior weights (V, S) of every training garment."""
    return np.max([joint_shares(w) for w in garment_weights], axis=0).round(6).tolist()


#: A garment whose median edge lies more than EDGE_RANGE_FACTOR times beyond the training garments' (checkpoint
#: meta "garment_edge_m": the least and largest of their median edges, metres) is warned of: the network's messages
#: pass along the mesh's edges, trained at those lengths (the shipped model's garments: 11.0-18.5 mm; the example
#: skirt subdivided twice, 4.4 mm: 5.2 mm from its own bake on the walk, mean, 82 max; cut to 120 vertices, 99 mm:
#: 29 mm, LBS 12).
EDGE_RANGE_FACTOR = 2.0


def median_edge_m(garment: Garment) -> float:
    """The median length of a garment's rest edges, metres."""
    from core.garment import mesh_edges
    from core.geodesic import edge_lengths

    edges = mesh_edges(garment.faces)
    return float(np.median(edge_lengths(garment.vertices, edges))) if len(edges) else 0.0


def garment_edge_range(garments, before: list | None = None) -> list[float]:
    """Checkpoint meta "garment_edge_m": [least, largest] `median_edge_m` of the training garments (and of the
    model's --init's range `before`, where it has one), metres."""
    found = [median_edge_m(g) for g in garments] + list(before or [])
    return [round(min(found), 6), round(max(found), 6)]


def edge_range_report(garment: Garment, trained: list | None) -> dict | None:
    """{"median_edge_m", "trained_edge_m": the training garments' range, "within": the median edge within
    EDGE_RANGE_FACTOR of it} of a garment, or None where the model records no range."""
    if not trained:
        return None
    edge = median_edge_m(garment)
    within = trained[0] / EDGE_RANGE_FACTOR <= edge <= trained[1] * EDGE_RANGE_FACTOR
    return {"median_edge_m": round(edge, 6), "trained_edge_m": list(trained), "within": bool(within)}


def training_range(weights, coverage, joint_names=None) -> dict:
    """How far a garment (prior weights (V, S)) lies outside the training garments' joints.

    Returns {"uncovered_share": share of its weight on uncovered joints, "uncovered_joints": their names
    (largest first), "within": share <= MAX_UNCOVERED_SHARE}.
    """
    shares = joint_shares(weights)
    uncovered = np.asarray(coverage) < COVERED_JOINT_SHARE
    share = float(shares[uncovered].sum())
    order = [j for j in np.argsort(-shares) if uncovered[j] and shares[j] > 1e-3]
    names = [joint_names[j] if joint_names is not None and j < len(joint_names) else str(j) for j in order]
    return {"uncovered_share": share, "uncovered_joints": names, "within": share <= MAX_UNCOVERED_SHARE}


@dataclass
class _Shaped:
    """What a deform needs of one garment on one body shape, on the network's device: the garment's inputs,
    its rest vertices on the shaped body, the encoded rest pose (X^fuse), the suggested levels and the contact
    guard's anchors (None until a guard on the device needs them)."""

    g: GarmentInputs
    rest: torch.Tensor
    fused: torch.Tensor
    levels: dict
    anchors: ContactAnchors | None = None
    #: The rest vertices on the shape the network is given (`network_betas`), where that is not the body's.
    shape_view: torch.Tensor | None = None


class _CopiesBack:
    """Batches of frames written into `out` (T, V, 3) numpy. From a CUDA device each copy trails the network by
    one batch: batch k goes into pinned memory without waiting, and is written into `out` once batch k+1 is
    queued, so the GPU runs k+1 while the host waits for k. `finish` writes the last."""

    def __init__(self, out: np.ndarray, device: torch.device):
        self.out, self.cuda, self.pending = out, device.type == "cuda", None

    def put(self, start: int, verts: torch.Tensor) -> None:
        if not self.cuda:
            self.out[start:start + len(verts)] = verts.numpy()
            return
        host, done = self._start_copy(verts)
        self.finish()
        self.pending = (start, host, done)

    @staticmethod
    def _start_copy(verts: torch.Tensor):
        """verts' copy into pinned host memory, queued on its stream, and the event marking its end."""
        host = torch.empty(verts.shape, dtype=verts.dtype, pin_memory=True)
        host.copy_(verts, non_blocking=True)
        done = torch.cuda.Event()
        done.record(torch.cuda.current_stream(verts.device))
        return host, done

    def finish(self) -> None:
        if self.pending is not None:
            start, host, done = self.pending
            done.synchronize()
            self.out[start:start + len(host)] = host.numpy()
            self.pending = None


class ModelDeformer(Deformer):
    """The paper's network. model: a GarmentModel; batch_frames: frames per forward pass (None: the device's
    default, `default_batch_frames`).

    precision: "float32", or "bfloat16" (the network under autocast; skinning weights and the final
    world-space skinning stay float32). The network runs on `device` (None: where `model`'s parameters are).

    lead_in_s: a motion without settle frames of its own starts, in the network's input window only, with
    this many seconds of frames blending from the rest pose into its first frame (`core.motion.prepend_blend`; not
    output; in seconds, so the blend turns the joints as fast at any frame rate).
    That is how every training sequence starts (the dataset's settle blend) and how the simulator starts a
    bake (its internal blend): the window then holds what the simulator's cloth went through, not a body
    that stood still in its first pose forever. On the held-out walk of the tradeoff scenes, against the
    version-4 references: trousers 22.0 -> 19.2 mm, t-shirt 22.0 -> 20.5 mm (0: none). Where the window leaves
    the blend behind, its effect fades out over `LEAD_FADE_FRAMES` frames (`_lead_fade`), not at once.
    """

    name = "model"

    def __init__(self, model: GarmentModel, batch_frames: int | None = None, cache_dir=None, model_name: str = "model",
                 precision: str = "float32", coverage=None, contact_guard: bool = True,
                 lead_in_s: float | None = None, device: torch.device | str | None = None,
                 strain_limit: float | None = STRAIN_LIMIT, trained_body: dict | None = None,
                 trained_betas: tuple[np.ndarray, np.ndarray] | None = None, edge_range: list | None = None):
        super().__init__()
        if precision not in PRECISIONS:
            raise InputError(f"model precision: expected one of {', '.join(PRECISIONS)}, got {precision!r}")
        self.model = model.eval() if device is None else model.eval().to(device)
        self.precision = precision
        self.batch_frames = batch_frames
        self.cache_dir = cache_dir
        self.model_name = model_name
        #: Per joint, the largest share of a training garment's weight on it (None: not recorded).
        self.coverage = coverage
        #: The training garments' median edges (checkpoint meta "garment_edge_m"; None: not recorded).
        self.edge_range = edge_range
        self._garments: dict = {}
        self._trims: dict = {}  # garment content hash -> its `Trims` (or None), found once
        self._shaped: dict = {}
        #: Keep vertices outside the body faces they rest on (`core.pushout.guard_contact`).
        self.contact_guard = contact_guard
        #: The guard and the strain limit batch by batch on the network's device (True), or afterwards over the
        #: sequence on the CPU (False); None: on the network's device where that is not the CPU. The guard's two
        #: agree to float32 rounding, the limit's to the rounding it amplifies (millimetres where it undoes a tear:
        #: `core.strain`).
        self.post_on_device: bool | None = None
        #: No edge longer than this times its rest length, after the guard (`core.strain`); None: off.
        self.strain_limit = strain_limit
        #: On a CPU, choose the threads of the network's batches while they run (`core.threads.ThreadTuner`);
        #: False: torch's count throughout.
        self.tune_threads = True
        self.lead_in_s = DEFAULT_LEAD_IN_S if lead_in_s is None else float(lead_in_s)
        #: The body the network was trained on, {"name", "sha256"} (`trained_body`); None: not recorded.
        self.trained_body = trained_body
        #: (least, largest) of each shape coefficient the network was trained on (`trained_betas`): beyond them it
        #: is given the nearest of them (`network_betas`); None: the body's shape as it is.
        self.trained_betas = trained_betas
        self._other_bodies: dict = {}
        if not (np.isfinite(self.lead_in_s) and self.lead_in_s >= 0):
            raise InputError(f"model lead-in: expected a non-negative number of seconds, got {lead_in_s!r}")

    def _body(self, body: Body) -> Body:
        """The body the network runs on: `body`, or its view on the model's skeleton (`model_body`); InputError
        where it has none."""
        view = model_body(body, self.model.config.n_joints)
        if view is None:
            raise InputError(skeleton_mismatch(self.model_name, self.model.config.n_joints, body))
        return view

    def body_difference(self, body: Body) -> str:
        """Where `body` (as the network reads it: `_body`) is not the body the model was trained on, what a user
        should know ("" where it is, or where the checkpoint does not say); warned once per body (log)."""
        body = self._body(body)
        if self.trained_body is None or self.trained_body.get("sha256") in (None, body.content_hash()):
            return ""
        if id(body) not in self._other_bodies:
            trained = self.trained_body
            what = (f"model '{self.model_name}' was trained on body '{trained.get('name')}' (sha256 "
                    f"{trained['sha256'][:8]}), got body '{body.name}' (sha256 {body.content_hash()[:8]}): its "
                    "accuracy on this body is not measured (`garment tradeoff --body` measures it; `garment dataset "
                    "--body` and `garment train --init` fit a model to it)")
            log.warning(what)
            self._other_bodies[id(body)] = (body, what)  # the body kept, so its id is not reused
        return self._other_bodies[id(body)][1]

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        self.body_difference(body)
        body = self._body(body)
        key = (garment.content_hash(), id(body))
        if key not in self._garments:
            self._garments[key] = prepare_garment(garment, body, self.model.config, self.cache_dir, source,
                                                     near=False)
            self._trims[garment.content_hash()] = trims_of(garment)
            outfit = garments_in_one(garment)
            if outfit:
                log.warning("garment mesh '%s': %s (an outfit of several garments?): the model reads them as one "
                            "garment, its size, shape and looseness those of all (a skirt baked with a t-shirt from "
                            "one file lay 51 mm from the skirt baked alone, mean): bake each garment from a file of "
                            "its own", source or garment.name, outfit)

    def _shaped_inputs(self, garment: Garment, body: Body, motion_betas, device: torch.device) -> _Shaped:
        """The garment's `_Shaped` inputs on the body shaped by `motion_betas`, made once per garment, body shape,
        device, precision and state of the network's weights (the last `SHAPED_CACHE` kept)."""
        betas = body.fit_betas(motion_betas)
        weights = tuple(p._version for p in self.model.parameters())  # bumped by every in-place change
        key = (garment.content_hash(), id(body), betas.tobytes(), str(device), self.precision, id(self.model),
               weights)
        if key not in self._shaped:
            g = tensors_to(self._garments[(garment.content_hash(), id(body))].inputs, device)
            seen, view = network_shape(g, body, betas, self.trained_betas)
            with torch.inference_mode(), torch.autocast(device.type, dtype=torch.bfloat16,
                                                        enabled=self.precision == "bfloat16"):
                fused = self.model.encode(g, body_distances(body, seen).to(device))
            while len(self._shaped) >= SHAPED_CACHE:
                self._shaped.pop(next(iter(self._shaped)))
            self._shaped[key] = _Shaped(g, shaped_rest(g, body, betas), fused, scene_levels(garment, body, motion_betas),
                                        shape_view=view)
        return self._shaped[key]

    def network_betas(self, betas: np.ndarray) -> np.ndarray:
        """The shape coefficients (n,) the network is given for a body of `betas` (n,): each within the least and
        largest it was trained on (`trained_betas`; one it never saw varied, 0), the garment still shaped and posed
        on the body's own. The shipped model, trained on three shapes, tore a jumpsuit's trouser leg off at rest on
        a tall body (betas[0] = 4: 4.35 % of the vertices inside on the example walk, 0.33 so given) and ballooned
        a t-shirt to the chin on a thin one (all -3: 1.72 %, none so given). Against the simulator it costs
        accuracy wherever it clips (the jumpsuit at betas[0] = 4: 45.6 -> 74.5 mm, the dress and trousers 0.3-9.5
        mm: `benchmarks/shape_range.py`)."""
        return within_trained(betas, self.trained_betas)

    def _shape_beyond_training(self, betas: np.ndarray) -> dict | None:
        """Where the body's shape `betas` lies beyond the network's training (`network_betas`), the report's entry
        ({"betas", "network_betas", "coefficients"}), warned once per deform; None where it does not."""
        seen = self.network_betas(betas)
        beyond = np.flatnonzero(seen != betas)
        if not len(beyond):
            return None
        least, largest = trained_bounds(self.trained_betas, len(betas))
        listed = [f"betas[{k}] {betas[k]:.3g} (trained {least[k]:.3g} to {largest[k]:.3g})" for k in beyond[:4]]
        more = f" and {len(beyond) - 4} more" if len(beyond) > 4 else ""
        log.warning(f"model '{self.model_name}': the body's shape lies beyond the shapes it was trained on, "
                    f"{', '.join(listed)}{more}: the network is given each within its trained range, the garment fitted "
                    "and posed on the body's own (its accuracy there is not measured)")
        rounded = lambda b: np.round(np.asarray(b, dtype=np.float64), 6).tolist()  # noqa: E731
        return {"betas": rounded(betas), "network_betas": rounded(seen),
                "coefficients": beyond.tolist()}

    def training_range(self, garment: Garment, body: Body) -> dict | None:
        """`training_range` of a prepared garment against the model's training garments (None: unknown), with its
        edges' `edge_range_report` ("edges", where the model records its garments' range)."""
        if self.coverage is None:
            return None
        body = self._body(body)
        g = self._garments[(garment.content_hash(), id(body))].inputs
        found = training_range(g.prior_weights.numpy(), self.coverage, body.joint_names)
        edges = edge_range_report(garment, self.edge_range)
        return found if edges is None else {**found, "edges": edges}

    def _lead_fade(self, network, mf, lead: int, body: Body, poses: np.ndarray, motion: Motion, betas,
                   device) -> tuple[torch.Tensor, torch.Tensor] | None:
        """(weights (T,), residual (V, 3) in the root's frame) that fade the lead-in's last effect out over
        `LEAD_FADE_FRAMES` frames after the last frame whose window holds a lead-in velocity, or None (no lead-in,
        or no frame after it). network(features, frames): the network's vertices at `frames` of `features`
        (windows as the bake's)."""
        last = self.model.config.window - 1
        if lead == 0 or motion.n_frames <= last + 1:
            return None
        with torch.autocast(device.type, enabled=False):  # the body posed in float32, as the bake's features
            still = tensors_to(motion_features(body, poses[:last + 1], motion.trans[:last + 1], betas, motion.fps),
                               device)  # its window clamped at frame 0: a body that stood still before it
        residual = (network(mf, torch.tensor([lead + last], device=device))
                    - network(still, torch.tensor([last], device=device)))[0]
        # in the root's frame at that frame, carried with the root after it (a turning body turns it along); in
        # float32 under bfloat16 autocast too, as every world coordinate
        with torch.autocast(device.type, enabled=False):
            residual = residual.float() @ mf.transforms[lead + last, 0, :3, :3].float()
        weights = torch.zeros(motion.n_frames, device=device)
        k = torch.arange(1, min(LEAD_FADE_FRAMES, motion.n_frames - last - 1) + 1, device=device)
        weights[last + k] = 1.0 - k / (LEAD_FADE_FRAMES + 1)
        return weights, residual

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        self.prepare(garment, body)
        given, body = body, self._body(body)
        # Inputs on the network's device (a GPU where the model was moved to one); results come back as numpy.
        device = next(self.model.parameters()).device
        betas = body.fit_betas(motion.betas)
        poses = poses_for_body(motion, body.n_joints)
        # A settle blend of its own is one already; a body that starts still stood still before it.
        still_start = starts_still(body, poses, motion.trans, betas, motion.fps)
        lead = int(round(self.lead_in_s * motion.fps)) if motion.n_settle == 0 and not still_start else 0
        window_poses, window_trans = prepend_blend(poses, motion.trans, lead)
        t0 = time.perf_counter()
        shaped = self._shaped_inputs(garment, body, motion.betas, device)
        g, rest = shaped.g, shaped.rest
        mf = tensors_to(motion_features(body, window_poses, window_trans, betas, motion.fps), device)
        batch = self.batch_frames or default_batch_frames(device, garment.n_vertices)
        out = np.empty((motion.n_frames, garment.n_vertices, 3), dtype=np.float32)
        scene = SceneAnalysis(self.skips)
        used = (g.prior_weights > 0).any(0)
        scene.record("joints", not bool(used.all()), used=int(used.sum()), joints=len(used))
        scene.report["levels"] = {**shaped.levels, "model": self.model.config.levels,
                                  "matches": shaped.levels["suggested"] == self.model.config.levels}
        # The contact guard and the strain limit batch by batch where the network runs (a GPU's frames stay there),
        # else afterwards over the whole sequence (on a CPU: the body posed `guard_chunk_frames` at a time, faster
        # than per batch).
        here = device.type != "cpu" if self.post_on_device is None else self.post_on_device
        guard_here = self.contact_guard and here
        limit = None
        if here and self.strain_limit is not None:
            limit = garment_strain(garment, rest.cpu().numpy(), self.strain_limit, self._strain)
            over, left, passes, limit_s = [], [], 0, 0.0
        if self.contact_guard and shaped.anchors is None:
            shaped.anchors = body_anchors(rest.cpu().numpy(), garment.faces, body, betas)
        # Progress (`on_frames`): each frame's share of the passes over the frames, the network's and, on a CPU,
        # the guard's and the limit's after it (one: `guard_and_limit` alternates them chunk by chunk).
        sweeps = 1 + (not here and (self.contact_guard or self.strain_limit is not None))
        tick = None if self.on_frames is None else (lambda n: self.on_frames(n / sweeps))
        if guard_here:
            pose_t = torch.as_tensor(poses, dtype=torch.float32, device=device)
            trans_t = torch.as_tensor(motion.trans, dtype=torch.float32, device=device)
            body_ids, anchors_here = anchored_body(shaped.anchors)
            moved, alternations = [], 1
        with torch.inference_mode(), torch.autocast(device.type, dtype=torch.bfloat16,
                                                    enabled=self.precision == "bfloat16"):
            t1 = time.perf_counter()
            copies = _CopiesBack(out, device)
            tuner = ThreadTuner() if device.type == "cpu" and self.tune_threads else None
            try:
                def network(features, frames):
                    win = window_index(frames, self.model.config.window)
                    return self.model.forward_frames(shaped.fused, g, rest, features.pose[win],
                                                     features.velocity[win], features.transforms[frames],
                                                     skip_joints=scene.enabled("joints"),
                                                     shape_rest=shaped.shape_view).verts.float()

                fade = self._lead_fade(network, mf, lead, body, poses, motion, betas, device)
                for s in range(0, motion.n_frames, batch):
                    if tuner:
                        tuner.before()
                    fr = torch.arange(lead + s, lead + min(s + batch, motion.n_frames), device=device)
                    verts = network(mf, fr)
                    if fade is not None:  # the root's rotation of each frame turns the residual
                        with torch.autocast(device.type, enabled=False):
                            turned = torch.einsum("vj,bij->bvi", fade[1], mf.transforms[fr, 0, :3, :3].float())
                            verts = verts + fade[0][s:s + len(fr), None, None] * turned
                    if guard_here:
                        with torch.autocast(device.type, enabled=False):  # the body posed in float32
                            at = slice(s, s + len(fr))
                            posed = body.pose_at(body_ids, pose_t[at], trans_t[at], betas)
                            if limit is not None:  # as `guard_and_limit` does on the CPU
                                verts, done = alternate_guard_limit(verts, posed, anchors_here, limit,
                                                                    lambda: _synchronized(device))
                                moved.append(done["moved"])
                                alternations = done["alternations"]
                                over.append(done["over"])
                                left.append(done["left"])
                                passes, limit_s = max(passes, done["passes"]), limit_s + done["limit_seconds"]
                            else:
                                verts, n = guard_contact(verts, posed, anchors_here)
                                moved.append(n)
                    elif limit is not None:
                        t_limit = _synchronized(device)
                        verts, n, done = limit_strain(verts, limit)
                        over.append(n)
                        left.append(still_over(verts, limit))
                        passes, limit_s = max(passes, done), limit_s + time.perf_counter() - t_limit
                    copies.put(s, verts)
                    if tuner:
                        tuner.after(len(fr))
                    if tick is not None:
                        tick(len(fr))
                copies.finish()
            finally:
                if tuner:
                    tuner.close()
        t2 = time.perf_counter()
        self.report = {"method": self.name, "model": self.model_name, "device": str(device), "batch_frames": batch,
                       "precision": self.precision, "training_range": self.training_range(garment, body),
                       "lead_in_frames": lead, "lead_in_fade_frames": 0 if fade is None else int((fade[0] > 0).sum()),
                       "starts_still": still_start,
                       "prepare_seconds": t1 - t0,
                       "preprocess_cache": self._garments[(garment.content_hash(), id(body))].preprocess_cache,
                       "seconds_per_frame_network": (t2 - t1) / max(motion.n_frames, 1)}
        if tuner:
            self.report["cpu_threads"] = tuner.report()
        if body is not given:
            self.report["body_view"] = body_view_note(given)
        if self.body_difference(given):
            self.report["trained_body"] = {**self.trained_body, "body": body.name, "body_sha256": body.content_hash()}
        beyond = self._shape_beyond_training(betas)
        if beyond:
            self.report["shape_beyond_training"] = beyond
        if self.precision == "bfloat16":
            self.report["native_bfloat16"] = native_bfloat16()
        self.scene = scene.report
        if here:
            guard = guard_report([m.cpu() for m in moved], None, motion.n_frames) if guard_here else {}
            if guard:
                guard["contact_guard"]["alternations_with_strain_limit"] = alternations
            if limit is not None:
                self.report["strain_limit"] = strain_report(limit, STRAIN_ITERATIONS, over, passes, limit_s,
                                                            motion.n_frames, left)
        else:  # outside autocast: the body is posed in float32
            out, guard = guard_and_limit(self, out, garment, rest.cpu().numpy(), body, poses, motion.trans, betas,
                                         shaped.anchors if self.contact_guard else None, self.strain_limit, tick)
        if guard:
            guard["contact_guard"]["device"] = str(device) if guard_here else "cpu"
        self.report.update(guard)
        if "strain_limit" in self.report:
            self.report["strain_limit"]["device"] = str(device) if limit is not None else "cpu"
        trims = self._trims[garment.content_hash()]  # (found by `prepare`, once per garment: not per motion)
        if trims is not None:
            out = carry_trims(out, garment, trims)
            self.report["trims_carried"] = trims.pieces
        return out


#: Pieces of a garment file holding at least this share of its vertices each, apart in height by more than half
#: the smaller one's (not layers of one cloth), are several garments (`garments_in_one`).
OUTFIT_PIECE_SHARE = 0.15


def garments_in_one(garment: Garment) -> str:
    """"" or, for a garment file holding several garments (pieces of OUTFIT_PIECE_SHARE of its vertices or more
    whose heights overlap by under half the smaller one's: a t-shirt and a skirt, not a cloth's two layers), what
    they are: "2 pieces of 6,698 and 2,016 vertices, at y -0.02 to 0.55 m and -0.28 to 0.04 m"."""
    n, labels = garment.pieces
    if n < 2:
        return ""
    sizes = np.bincount(labels, minlength=n)
    large = [k for k in np.argsort(-sizes) if sizes[k] >= OUTFIT_PIECE_SHARE * garment.n_vertices]
    ranges = [(float(garment.vertices[labels == k, 1].min()), float(garment.vertices[labels == k, 1].max()))
              for k in large]
    for a in range(len(large)):
        for b in range(a + 1, len(large)):
            (lo_a, hi_a), (lo_b, hi_b) = ranges[a], ranges[b]
            overlap = min(hi_a, hi_b) - max(lo_a, lo_b)
            if overlap < 0.5 * min(hi_a - lo_a, hi_b - lo_b):
                return (f"{len(large)} pieces of {' and '.join(f'{sizes[k]:,}' for k in large)} vertices, at y "
                        + " and ".join(f"{lo:.2f} to {hi:.2f} m" for lo, hi in ranges))
    return ""


#: A piece of a garment file of at most this share of its vertices and this extent (metres) beside a piece of over
#: half of them is a trim on the cloth (a button, a rivet, a label), carried rigidly by the cloth face nearest it
#: (`carry_trims`): the network, which learns cloth, moved buttons 6 -> 19.7 mm off their place and stretched
#: them by 27 %.
TRIM_SHARE = 0.02
TRIM_EXTENT_M = 0.1


@dataclass(frozen=True)
class Trims:
    """Trims of a garment and where each rides: vertices (N,) of the trims, face (N,) the cloth face each trim's
    rides on (every vertex of a trim the same), offset (N, 3) in that face's rest frame (`_face_frames`), corner
    (N, 3) weights of the face's corners that the frame's origin is; pieces: how many trims."""

    pieces: int
    vertices: np.ndarray
    face: np.ndarray
    offset: np.ndarray
    corner: np.ndarray


def _face_frames(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(..., F, 3, 3) each face's frame (columns: its first edge, the in-plane normal to it, its normal) of points
    (..., V, 3)."""
    a, b, c = (points[..., faces[:, k], :] for k in range(3))
    e1 = b - a
    n = np.cross(e1, c - a)
    e1 = e1 / np.maximum(np.linalg.norm(e1, axis=-1, keepdims=True), 1e-12)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return np.stack([e1, np.cross(n, e1), n], axis=-1)


def trims_of(garment: Garment) -> Trims | None:
    """The garment's trims (TRIM_SHARE, TRIM_EXTENT_M) and the cloth face each rides on (the one nearest its
    centre, at rest), or None where it has none."""
    from core.geometry import TriangleMesh

    n, labels = garment.pieces
    if n < 2:
        return None
    sizes = np.bincount(labels, minlength=n)
    if sizes.max() <= 0.5 * garment.n_vertices:
        return None
    v = garment.vertices.astype(np.float64)
    small = [k for k in range(n) if sizes[k] <= TRIM_SHARE * garment.n_vertices
             and np.ptp(v[labels == k], axis=0).max() <= TRIM_EXTENT_M]
    if not small:
        return None
    cloth_faces = np.flatnonzero(~np.isin(labels[garment.faces[:, 0]], small))
    mesh = TriangleMesh(v, garment.faces[cloth_faces])
    centres = np.array([v[labels == k].mean(axis=0) for k in small])
    hit = mesh.closest(centres)
    frames = _face_frames(v, garment.faces[cloth_faces[hit.face_index]])  # (S, 3, 3)
    vertices, face, offset, corner = [], [], [], []
    for i, k in enumerate(small):
        ids = np.flatnonzero(labels == k)
        vertices.append(ids)
        face.append(np.full(len(ids), cloth_faces[hit.face_index[i]]))
        offset.append((v[ids] - hit.closest[i]) @ frames[i])
        corner.append(np.broadcast_to(hit.barycentric[i], (len(ids), 3)))
    return Trims(len(small), np.concatenate(vertices), np.concatenate(face), np.concatenate(offset),
                 np.concatenate(corner))


def carry_trims(points: np.ndarray, garment: Garment, trims: Trims) -> np.ndarray:
    """`points` (T, V, 3) with each trim's vertices placed rigidly on its cloth face as deformed (in place)."""
    tri = garment.faces[trims.face]  # (N, 3)
    for s in range(0, len(points), 256):
        p = points[s:s + 256].astype(np.float64)
        origin = np.einsum("tnkc,nk->tnc", p[:, tri], trims.corner)
        frames = _face_frames(p, tri)  # (t, N, 3, 3)
        points[s:s + 256, trims.vertices] = origin + np.einsum("tnij,nj->tni", frames, trims.offset)
    return points


def _synchronized(device: torch.device) -> float:
    """perf_counter() once the work queued on `device` is done (at once on a CPU)."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    return time.perf_counter()


def model_body(body: Body, n_joints: int) -> Body | None:
    """The body a model of `n_joints` runs on for `body`: itself where the skeletons agree, an SMPL+H or SMPL-X
    body's view on SMPL's 24 joints for a model of SMPL's (`Body.smpl_view`: the hands at rest, following the
    wrists), else None."""
    if body.n_joints == n_joints:
        return body
    return body.smpl_view() if n_joints == len(SMPL_JOINT_NAMES) else None


def body_view_note(body: Body) -> str:
    """What a model of SMPL's joints reads of the SMPL+H or SMPL-X `body` (`summary.json`'s deformer)."""
    return (f"body '{body.name}' ({body.layout}, {body.n_joints} joints) read on SMPL's 24: the fingers follow the "
            "wrists" + (", the jaw and eyes the head" if body.layout == "smplx" else ""))


def skeleton_mismatch(model_name: str, n_joints: int, body: Body) -> str:
    """Why a model of `n_joints` cannot run on `body` (a body of SMPL's 24 joints for a model of SMPL+H's 52), or
    "" when it can (`model_body`)."""
    if model_body(body, n_joints) is not None:
        return ""
    return (f"model '{model_name}' was trained for a body of {n_joints} joints, got body '{body.name}' with "
            f"{body.n_joints}")


def load_model_deformer(path=None, **kwargs) -> ModelDeformer:
    """A ModelDeformer for the checkpoint at `path`, default the shipped model (InputError naming it when unusable)."""
    from formats.checkpoint import load_model

    if path is None:
        if not DEFAULT_MODEL.is_file():
            raise InputError(f"the default model '{DEFAULT_MODEL}' is missing from this installation: reinstall garment, "
                             "pass --model PATH or use --method lbs")
        path = DEFAULT_MODEL
    model, data = load_model(path)
    kwargs.setdefault("lead_in_s", data["meta"].get("lead_in_s"))
    return ModelDeformer(model, model_name=str(path), coverage=data["meta"].get("joint_coverage"),
                         trained_body=trained_body(data["meta"]), trained_betas=trained_betas(data["meta"]),
                         edge_range=data["meta"].get("garment_edge_m"), **kwargs)


def trained_bounds(trained: tuple[np.ndarray, np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """(least, largest) (n,) of each of a body's `n` shape coefficients in `trained` (`trained_betas`): one beyond
    its record 0 to 0."""
    least, largest = np.zeros(n), np.zeros(n)
    k = min(n, len(trained[0]))
    least[:k], largest[:k] = trained[0][:k], trained[1][:k]
    return least, largest


#: How far beyond its trained range a shape coefficient still counts as within it (`within_trained`): a training
#: shape's coefficients are recorded to 6 decimals (and a float32 shape lies up to 1e-7 beyond its record), and a
#: shape typed as the warning prints it (3 digits) up to 0.005 beyond; each warned of and clipped by a hair.
TRAINED_BETAS_SLACK = 0.01


def within_trained(betas: np.ndarray, trained: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """`betas` (n,) with each coefficient clipped to `trained`'s (least, largest) (`trained_bounds`) widened by
    TRAINED_BETAS_SLACK; None: `betas` as they are."""
    if trained is None:
        return betas
    least, largest = trained_bounds(trained, len(betas))
    return np.clip(betas, least - TRAINED_BETAS_SLACK, largest + TRAINED_BETAS_SLACK).astype(betas.dtype)


def network_shape(g: GarmentInputs, body: Body, betas: np.ndarray,
                  trained: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, torch.Tensor | None]:
    """(the betas the network is given for a body of `betas` (`within_trained`), the garment's rest on that shape
    for the network's shape input: None where it is the body's own)."""
    seen = within_trained(betas, trained)
    return seen, None if np.array_equal(seen, betas) else shaped_rest(g, body, seen)


def trained_shapes(betas: list, before: tuple[np.ndarray, np.ndarray] | None) -> dict:
    """The "trained_betas" a checkpoint records: {"min", "max"} lists, each shape coefficient's least and largest
    over the training sequences' `betas` ((n,) arrays) and the range `before` (its --init's, where given)."""
    rows = [np.asarray(b, dtype=np.float64).reshape(-1) for b in betas]
    n = max([len(r) for r in rows] + [len(before[0]) if before is not None else 0])
    padded = [np.pad(r, (0, n - len(r))) for r in rows]  # a coefficient a sequence lacks is 0
    if before is not None:
        padded += [np.pad(b, (0, n - len(b))) for b in before]
    if not padded:
        return {"min": [], "max": []}
    stack = np.stack(padded)
    return {"min": stack.min(axis=0).round(6).tolist(), "max": stack.max(axis=0).round(6).tolist()}


#: The body shapes of `garment dataset`'s defaults (`--bodies 3 --betas-range 2 --seed 0`, the embedded body's 10
#: coefficients): those the shipped model was trained on, and what a checkpoint that records none is taken to
#: have seen (`trained_betas`).
DEFAULT_TRAINED_BODIES = 3


def trained_betas(meta: dict) -> tuple[np.ndarray, np.ndarray]:
    """(least, largest) of each shape coefficient a checkpoint's model was trained on (its `meta`'s
    "trained_betas", which `garment train` records since 2026-12-07; before, those of `garment dataset`'s default
    bodies: DEFAULT_TRAINED_BODIES)."""
    record = meta.get("trained_betas")
    if isinstance(record, dict) and {"min", "max"} <= set(record):
        return np.asarray(record["min"], dtype=np.float64), np.asarray(record["max"], dtype=np.float64)
    from core.dataset import DEFAULT_BETAS_RANGE, sample_betas

    shapes = sample_betas(DEFAULT_TRAINED_BODIES, 10, DEFAULT_BETAS_RANGE, seed=0)
    return shapes.min(axis=0).astype(np.float64), shapes.max(axis=0).astype(np.float64)


def trained_body(meta: dict) -> dict | None:
    """{"name", "sha256"} of the body a checkpoint's model was trained on (its `meta`): `garment train` records
    both; a model trained before it did records the name only, and one named 'default' was trained on the
    embedded body (unchanged since 2026-11-24, before the first model). None: the checkpoint does not say."""
    name, sha = meta.get("body"), meta.get("body_sha256")
    if isinstance(sha, str) and sha:
        return {"name": str(name), "sha256": sha}
    if name == "default":
        from core.body import default_body

        return {"name": name, "sha256": default_body().content_hash()}
    return None
