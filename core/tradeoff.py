"""Speed against accuracy on one scene: every method and configuration, timed and compared with the reference.

Configurations (`configurations`): `lbs`; each model in float32 and bfloat16, each with and without
the penetration push-out (`core.pushout`); the simulator with and without self-contact at two substep
settings, the finest with self-contact being the reference every other row is compared with.

`measure` times one configuration: its preparation (binding, preprocessing) timed apart, a warm-up run not
timed (the simulator's of two frames, which compiles its kernels), then `repeats` timed runs, seconds per frame =
their median; peak memory = the largest rise of the process's resident memory over its level before the timed runs, sampled
every 5 ms. Metrics: `core.metrics.compute_metrics` against the reference (E_verts mm, E_vnorm and
E_fnorm degrees, E_edge %, E_curv) and the penetration rate (% of vertices > 2 mm inside the body).
"""

from __future__ import annotations

import json
import statistics
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from core.body import Body
from core.deform import Deformer, LBSDeformer, LBSOptions
from core.garment import Garment
from core.motion import Motion, poses_for_body, select_frames, written
from core.strain import STRAIN_LIMIT

#: Frames the simulator's rows run before they are timed (`measure`): its kernels compile on their first use.
SIM_WARM_UP_FRAMES = 2

#: Simulator substeps per frame of the two settings; the finest, with self-contact, is the reference.
#: VBD (10 iterations a substep) keeps converging with substeps: on the example skirt (walk_brisk, 15
#: frames) 10 and 20 substeps are 22 mm apart (mean edge strain 1.9 % and 0.8 %), 20 and 40 substeps
#: 20 mm (0.4 %); 20 is the finest a CPU affords for every example garment, 5 was no reference at all.
SIM_SUBSTEPS = (10, 20)
#: Starting-position jitter (metres, standard deviation) of the reference's rerun that measures its spread: about
#: ten float32 roundings of a position. Cloth is chaotic: on the example skirt (walk_brisk, 15 frames, 20
#: substeps with self-contact) a 1 um start moves the result 8.3 mm (4.7 mm in the first output frame, after
#: the settling, 10.8 mm in the last; the dress 8.2 mm: benchmarks/results/reference_spread.md); no method
#: can be expected nearer the reference than this.
SPREAD_JITTER_M = 1e-6
PENETRATION_DEPTH_M = 0.002
METRIC_COLUMNS = ("e_verts", "e_vnorm", "e_fnorm", "e_edge", "e_curv", "penetration_pct")


@dataclass(frozen=True)
class Config:
    """One row: name, method (lbs | psd | model | sim), options of that method, whether it is the reference."""

    name: str
    method: str
    options: dict = field(default_factory=dict)
    reference: bool = False
    spread: bool = False  # the reference rerun from jittered starting positions (`SPREAD_JITTER_M`)


def configurations(models: dict, with_sim: bool = True, spread: bool = False, fits: dict | None = None) -> list[Config]:
    """The rows of a tradeoff run. models: name -> checkpoint path (None: the shipped model). spread: add the
    reference rerun from starting positions jittered by `SPREAD_JITTER_M` (its error is the reference's spread).
    fits: name -> the garment's fitted blend shapes (`garment fit`), a `psd` row each."""
    rows = [Config("lbs", "lbs"), Config(f"lbs +strain-limit {STRAIN_LIMIT:g}", "lbs", {"strain_limit": STRAIN_LIMIT})]
    rows += [Config(f"psd {name}", "psd", {"path": path}) for name, path in (fits or {}).items()]
    for name, path in models.items():
        for precision in ("float32", "bfloat16"):
            for push in (False, True):
                label = f"{name} {precision}" + (" +push-out" if push else "")
                rows.append(Config(label, "model", {"path": path, "precision": precision, "push_out": push}))
    if with_sim:
        for substeps in SIM_SUBSTEPS:
            for contact in (False, True):
                rows.append(Config(f"sim {substeps} substeps" + (" +self-contact" if contact else ""), "sim",
                                   {"substeps": substeps, "self_contact": contact},
                                   reference=contact and substeps == max(SIM_SUBSTEPS)))
        if spread:
            rows.append(Config(f"reference +{SPREAD_JITTER_M * 1e6:g} um jitter", "sim",
                               {"substeps": max(SIM_SUBSTEPS), "self_contact": True, "jitter_m": SPREAD_JITTER_M},
                               spread=True))
    return rows


def make_deformer(config: Config, cache_dir=None, device=None, warm_up: bool = False) -> Deformer:
    """The Deformer of a configuration; a model's network on `device` (None: where its checkpoint loads, the CPU).
    warm_up: the simulator's without its settling and blending in (`measure`'s warm-up: its kernels compile)."""
    if config.method == "lbs":
        return LBSDeformer(LBSOptions(strain_limit=config.options.get("strain_limit")))
    if config.method == "psd":
        from formats.psd import psd_deformer

        return psd_deformer(config.options["path"])
    if config.method == "model":
        from core.model_deform import load_model_deformer

        d = load_model_deformer(config.options["path"], cache_dir=cache_dir, precision=config.options["precision"],
                                device=device)
        if config.options["push_out"]:
            from core.pushout import PushOutDeformer

            d = PushOutDeformer(d)
        return d
    if config.method == "sim":
        from core.sim import Material, SimDeformer, SimOptions

        lead = {"settle_s": 0.0, "blend_frames": 0} if warm_up else {}
        return SimDeformer(Material(), SimOptions(substeps=config.options["substeps"],
                                                  self_contact=config.options["self_contact"], **lead),
                           jitter_m=config.options.get("jitter_m", 0.0))
    raise ValueError(f"unknown method {config.method!r}")


class PeakMemory:
    """Context manager sampling the process's resident memory; `.peak_mb` = largest rise over the start level."""

    def __init__(self, interval_s: float = 0.005):
        import psutil

        self._proc = psutil.Process()
        self.interval = interval_s
        self.peak_mb = 0.0

    def __enter__(self):
        self._start = self._proc.memory_info().rss
        self._peak = self._start
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def _run(self):
        while not self._stop.is_set():
            self._peak = max(self._peak, self._proc.memory_info().rss)
            self._stop.wait(self.interval)

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._peak = max(self._peak, self._proc.memory_info().rss)
        self.peak_mb = (self._peak - self._start) / 2**20
        return False


class GpuPeakMemory:
    """Context manager: `.peak_mb` = the largest rise of the GPU memory torch allocated on `device` over the
    start level (the model's rows on a GPU); None where `device` is not a CUDA device. The simulator's GPU
    memory (Warp's allocator) is not torch's and not counted."""

    def __init__(self, device=None):
        import torch

        self.cuda = torch.cuda if device is not None and torch.device(device).type == "cuda" else None
        self.device = device
        self.peak_mb = None

    def __enter__(self):
        if self.cuda:
            self._start = self.cuda.memory_allocated(self.device)
            self.cuda.reset_peak_memory_stats(self.device)
        return self

    def __exit__(self, *exc):
        if self.cuda:
            self.cuda.synchronize(self.device)
            self.peak_mb = (self.cuda.max_memory_allocated(self.device) - self._start) / 2**20
        return False


@dataclass
class Measurement:
    config: Config
    points: np.ndarray
    seconds_per_frame: float
    seconds_prepare: float
    peak_memory_mb: float
    runs: int
    metrics: dict = field(default_factory=dict)
    #: `GpuPeakMemory`'s (None: not run on a GPU through torch).
    gpu_peak_memory_mb: float | None = None
    #: The simulator's frames run again with more substeps ({"frame", "tries", "kept_substeps"}: `core.sim`).
    retries: list = field(default_factory=list)
    #: A self-contact row that the scene analysis ran without it (no two distant parts of the garment come near on
    #: the motion: `core.scene`), so measured as the row without it.
    self_contact_skipped: bool = False


def measure(config: Config, garment: Garment, body: Body, motion: Motion, repeats: int = 3,
            cache_dir=None, device=None) -> Measurement:
    """Warm-up (preparation timed apart) and `repeats` timed runs (1 for the simulator: minutes per run). The
    motion's lead and tail frames (`Motion.n_lead`, a pre-roll; `n_tail`) are deformed and timed, and left out of
    the points kept.
    device: the model rows' (`make_deformer`)."""
    deformer = make_deformer(config, cache_dir, device)
    t0 = time.perf_counter()
    deformer.prepare(garment, body)
    prep = time.perf_counter() - t0
    runs = 1 if config.method == "sim" else max(1, repeats)
    # warm-up (caches, allocator, first-call costs); the simulator's on the first SIM_WARM_UP_FRAMES frames only
    # (minutes a run), which compile its kernels: on a fresh install their compilation (about 45 s) was timed
    # in its first row (59.5 s a frame against 13.6 warm on a 4-frame scene); without its settling and blending
    # in (25 frames more at 30 fps, half the time of a short scene's row)
    if config.method != "sim":
        deformer.deform(garment, body, motion)
    else:
        from core.sim import SimulationError

        try:
            make_deformer(config, warm_up=True).deform(garment, body,
                                                       select_frames(motion, 0, min(motion.n_frames, SIM_WARM_UP_FRAMES)))
        except SimulationError:
            pass  # started on the motion's first frame unsettled: its kernels compiled all the same
    times = []
    with PeakMemory() as mem, GpuPeakMemory(device if config.method == "model" else None) as gpu:
        for _ in range(runs):
            t = time.perf_counter()
            points = deformer.deform(garment, body, motion)
            times.append(time.perf_counter() - t)
    kept = points[motion.n_lead:motion.n_lead + motion.n_written]
    skipped = bool(config.options.get("self_contact")) and deformer.report.get("self_contact") is None
    return Measurement(config, kept, statistics.median(times) / motion.n_frames, prep, mem.peak_mb, runs,
                       gpu_peak_memory_mb=gpu.peak_mb, retries=list(deformer.report.get("retries", [])),
                       self_contact_skipped=skipped)


def simulation_scene(garment: Garment, body: Body, motion: Motion):
    """sha256 state of what every simulator row of a scene depends on: the garment, the body posed over the
    motion, the frame rate, the simulator's default material and solver settings, its declared behaviour
    version (`core.sim.SIMULATOR_VERSION`, held to a golden simulation by the tests) and the software versions
    (`core.provenance`). Made once per scene; `simulation_key` adds a row's options."""
    import hashlib
    import json

    from core.provenance import software_versions
    from core.sim import SIMULATOR_VERSION, Material, SimOptions

    h = hashlib.sha256(garment.content_hash().encode())
    body_pts, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
    for a in (body_pts, body.faces):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(json.dumps({"fps": motion.fps, "material": repr(Material()), "solver": repr(SimOptions()),
                         "simulator_version": SIMULATOR_VERSION,
                         **software_versions("newton", "warp-lang")}, sort_keys=True).encode())
    return h


def simulation_key(config: Config, scene) -> str:
    """The key of a simulator row: its scene's `simulation_scene` and the configuration's options."""
    import json

    h = scene.copy()
    h.update(json.dumps(config.options, sort_keys=True).encode())
    return h.hexdigest()


def sim_file_name(config: Config) -> str:
    """The file name a simulator row is stored under (`save_simulation`) in a results directory."""
    return config.name.replace(" ", "_").replace("+", "") + ".npz"


def save_simulation(path, m: Measurement, key: str, faces: np.ndarray, fps: float) -> None:
    """Store a simulator row (points and timings) for `load_simulation`; with the garment's faces and the frame
    rate, an `.npz` sequence that `garment metrics` and `render` read (a bake measured against the reference)."""
    np.savez_compressed(path, points=m.points.astype(np.float32), faces=np.asarray(faces, dtype=np.int64),
                        fps=float(fps), key=key, seconds_per_frame=m.seconds_per_frame,
                        seconds_prepare=m.seconds_prepare, peak_memory_mb=m.peak_memory_mb, runs=m.runs,
                        retries=json.dumps(m.retries), self_contact_skipped=m.self_contact_skipped)


def load_simulation(path, config: Config, key: str) -> Measurement | None:
    """The stored row of `config` when `path` holds one made with the same `key` (else None)."""
    from pathlib import Path

    if not Path(path).is_file():
        return None
    with np.load(path) as d:
        if str(d["key"]) != key:
            return None
        return Measurement(config, np.array(d["points"]), float(d["seconds_per_frame"]),
                           float(d["seconds_prepare"]), float(d["peak_memory_mb"]), int(d["runs"]),
                           retries=json.loads(str(d["retries"])) if "retries" in d else [],
                           self_contact_skipped=bool(d["self_contact_skipped"]) if "self_contact_skipped" in d
                           else False)


def memory_needed(n_rows: int, garment: Garment, body: Body, n_frames: int) -> int:
    """Bytes a tradeoff run of `n_rows` configurations over `n_frames` frames (the lead frames included) holds
    at most, about: every row's points (float32) kept until `compare`, one row more being measured, and the
    posed body twice (the simulator's collider, `compare`'s penetration; float64)."""
    return n_frames * (12 * (n_rows + 1) * garment.n_vertices + 2 * 24 * body.n_vertices)


def compare(measurements: list[Measurement], garment: Garment, body: Body, motion: Motion) -> None:
    """Fill each measurement's metrics against the reference configuration's points (in place)."""
    from core.geometry import points_inside_mesh
    from core.metrics import compute_metrics, frames_inside

    ref = next(m for m in measurements if m.config.reference)
    shown = written(motion)  # the frames `measure` keeps
    body_pts, _ = body.pose(poses_for_body(shown, body.n_joints), shown.trans, shown.betas)
    inside = frames_inside(lambda p, v, f: points_inside_mesh(p, v, f, depth=PENETRATION_DEPTH_M))
    for m in measurements:
        res = compute_metrics(m.points, ref.points, garment.faces, body_pts, body.faces, inside,
                              pred_name=m.config.name, gt_name=ref.config.name)
        m.metrics = {k: res.overall[k] for k in METRIC_COLUMNS}


#: Errors (mm) closer than this are one error on the Pareto front: a row 3x slower was on it, and the scene's
#: "best model row", for 0.00004 mm less (the push-out moving a vertex or two).
PARETO_TOLERANCE_MM = 0.01


def pareto_front(points: list[tuple[float, float]], tolerance: float = PARETO_TOLERANCE_MM) -> list[bool]:
    """For (cost, error) pairs: True where no other pair is at least as good in both and better in one (errors
    within `tolerance` of each other counted equal)."""
    out = []
    for i, (c, e) in enumerate(points):
        out.append(not any((c2 <= c and e2 <= e + tolerance) and (c2 < c or e2 < e - tolerance)
                           for j, (c2, e2) in enumerate(points) if j != i))
    return out


def scene_summary(result: dict, model: str) -> dict:
    """One scene's line of the cross-garment summary from its tradeoff.json `result`: LBS, the model row
    `model` (float32, no push-out) and the fastest simulator row; E_verts against the reference, ms per
    frame, the model's error as a share of LBS's, and whether the time order lbs < model < sim holds
    (slowest LBS row faster than the fastest model row, slowest model row faster than the fastest simulator).
    Where the run measured the reference's spread (`--spread`): `spread_mm`, and `gap_closed`, the share of
    LBS's error above that floor the model removes, (LBS - model) / (LBS - spread); else both NaN."""
    rows = {r["config"]: r for r in result["rows"]}
    ref = next(r["config"] for r in result["rows"] if r["reference"])
    lbs, mdl = rows["lbs"], rows.get(f"{model} float32")
    if mdl is None:
        raise KeyError(f"{result['garment']}: no row '{model} float32' (rows: {', '.join(rows)})")
    for r in (lbs, mdl):
        if r.get("failed"):
            raise KeyError(f"{result['garment']}: row '{r['config']}' failed ({r['failed']})")
    done = [r for r in result["rows"] if not r.get("failed")]
    spread = next((r["e_verts"] for r in done if r.get("spread")), float("nan"))
    by_method = {m: [r["seconds_per_frame"] for r in done if r["method"] == m and not r.get("spread")]
                 for m in ("lbs", "model", "sim")}
    sims = [r for r in done if r["method"] == "sim" and not r["reference"] and not r.get("spread")]
    closest_sim = min(sims, key=lambda r: r["e_verts"]) if sims else None
    above = lbs["e_verts"] - spread
    return {"garment": result["garment"], "vertices": result["vertices"], "frames": result["frames"],
            "reference": ref, "lbs_mm": lbs["e_verts"], "model_mm": mdl["e_verts"],
            "model_share_of_lbs": mdl["e_verts"] / lbs["e_verts"] if lbs["e_verts"] > 0 else float("nan"),
            "spread_mm": spread, "gap_closed": (lbs["e_verts"] - mdl["e_verts"]) / above if above > 0 else float("nan"),
            "closest_sim": closest_sim["config"] if closest_sim else "", "closest_sim_mm":
            closest_sim["e_verts"] if closest_sim else float("nan"),
            "lbs_ms": 1e3 * lbs["seconds_per_frame"], "model_ms": 1e3 * mdl["seconds_per_frame"],
            "sim_s": min(by_method["sim"]) if by_method["sim"] else float("nan"),
            "time_ordered": bool(by_method["sim"]) and max(by_method["lbs"]) < min(by_method["model"])
            and max(by_method["model"]) < min(by_method["sim"])}
