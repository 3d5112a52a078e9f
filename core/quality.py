"""`bake --quality auto`: pick the cheapest configuration expected to stay under an error budget.

A scene is described by two numbers (`scene_features`): how loose the garment is (mean distance of
its rest vertices from the rest body, metres) and how fast the motion is (95th percentile of the
joints' speeds, m/s). LBS is exact for cloth glued to the skin and errs more the looser the garment
and the faster the motion; the learned model and the simulator cut that error at a price.

A calibration (JSON, stored next to a model: `<model>.calibration.json`) holds, per configuration,
its cost (milliseconds per frame per 1,000 garment vertices) and measured errors against the
simulator on calibration scenes (points: looseness, speed, E_verts mm). It is made by `garment
tradeoff --calibrate FILE` (one scene per call, appended) or from the Table-1 evaluation
(benchmarks/calibrate_quality.py). The expected error of a configuration on a new scene is the
inverse-distance weighted mean of its k nearest calibration points in (log looseness, log speed);
the choice is the cheapest configuration whose expected error is within the budget (the reference
simulator, expected error 0, when nothing cheaper is), else the most accurate one.

A scene beyond the calibration's scenes (a feature under OUTSIDE_FACTOR times below the smallest, or above
the largest, of the calibration's: a still pose, a motion faster than any calibrated) has no measured
neighbour: there the learned methods (the model, a fit) are expected no better than LBS, as measured on real
motion capture outside the shipped calibration's speeds (the model kept 98 % of LBS's error on jumping jacks at
6.6 m/s; README "The shipped model"), and the choice says so.

The shipped calibration holds synthetic scenes (the model's held-out test motions) and real ones (twelve motion
captures on four garments, `benchmarks/results/model_table_real.md`, on which the model keeps 81-98 % of LBS's
error where it keeps about half on the synthetic ones): a scene's expected errors are its nearest scenes' of
either kind.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.body import Body
from core.errors import InputError
from core.garment import Garment
from core.motion import Motion, joint_speeds, poses_for_body

#: Default error budget of `--quality auto` (E_verts against the simulator, mm).
DEFAULT_BUDGET_MM = 40.0
#: Neighbours averaged for an expected error.
K_NEAREST = 4
#: The methods a calibration's configurations may name (`garment tradeoff --calibrate` leaves out psd: a fit
#: belongs to one garment).
CALIBRATED_METHODS = ("lbs", "model", "sim")
#: Floors of the features before the logarithm (a skin-tight garment, a still pose).
MIN_LOOSENESS_M, MIN_SPEED_M_S = 0.002, 0.05
#: How far beyond the calibration's range of a feature (a factor below its smallest or above its largest) a
#: scene still counts as calibrated: the example run (5.6 m/s) lies 1.22 times above the shipped calibration's
#: fastest scene (4.6 m/s), the AMASS jumping jacks (6.6 m/s) 1.44 times; its seated subject (0.05 m/s) lay 14
#: times below the synthetic scenes' slowest, and lies among the real idle captures (0.01 m/s and up).
OUTSIDE_FACTOR = 1.25
#: What the model kept of LBS's error beyond the shipped calibration's scenes (README "The shipped model").
OUTSIDE_MEASURED = ("on AMASS's jumping jacks, beyond it, the model kept 98 % of LBS's error, and 81-98 % on the "
                    "real captures within it")
#: Methods whose gain over LBS was learnt from (or fitted to) training motions: beyond the calibration's
#: scenes they are expected no better than LBS.
LEARNED_METHODS = ("model", "psd")
#: The features a calibration point holds, in order, with how a scene's value is described.
FEATURES = (("looseness_m", "garment {:.1f} cm from the body on average", "looseness", 100.0, "cm"),
            ("speed_m_s", "joints up to {:.2f} m/s (95th percentile)", "speed", 1.0, "m/s"))


def looseness(garment: Garment, body: Body, betas=None) -> float:
    """Mean distance (metres) of the garment's rest vertices to the rest body shaped by `betas`."""
    from core.geometry import TriangleMesh

    verts, _ = body.shaped(betas)
    return float(TriangleMesh(verts, body.faces).closest(garment.vertices, exact=False).distance.mean())


def scene_features(garment: Garment, body: Body, motion: Motion) -> dict:
    """looseness_m: mean distance of the garment's rest vertices to the rest body (shaped by the motion's betas);
    speed_m_s: 95th percentile over frames and joints of joint speed; vertices; frames."""
    return {"looseness_m": looseness(garment, body, motion.betas), "speed_m_s": joint_speed(body, motion),
            "vertices": int(garment.n_vertices), "frames": int(motion.n_frames)}


def joint_speed(body: Body, motion: Motion) -> float:
    """The 95th percentile over frames and joints of the joints' speed (m/s) of `body` posed by `motion`."""
    speeds = joint_speeds(body, poses_for_body(motion, body.n_joints), motion.trans, motion.betas, motion.fps)
    return float(np.percentile(speeds, 95)) if speeds.size else 0.0


def _point(looseness: float, speed: float) -> np.ndarray:
    return np.log(np.array([max(looseness, MIN_LOOSENESS_M), max(speed, MIN_SPEED_M_S)]))


@dataclass
class Calibration:
    """configs: name -> {"method", "options", "ms_per_frame_per_kvert", "points": [[looseness, speed, e_mm], ...],
    "reference": true for the configuration the errors are measured against (expected error 0, no points)}."""

    configs: dict
    source: str = ""
    provenance: dict = field(default_factory=dict)  # the last `tradeoff --calibrate`'s date and software

    @classmethod
    def load(cls, path: str | os.PathLike) -> Calibration:
        path = Path(path)
        try:
            data = json.loads(path.read_text())
            configs = data["configs"]
            if not isinstance(configs, dict):
                raise TypeError(f"'configs' must be an object of configurations, not {type(configs).__name__}")
            for name, c in configs.items():
                if c.get("method") not in CALIBRATED_METHODS:
                    raise ValueError(f"'{name}': method must be one of {', '.join(CALIBRATED_METHODS)}, "
                                     f"not {c.get('method')!r}")
                if not isinstance(c.get("options", {}), dict):
                    raise TypeError(f"'{name}': options must be an object")
                cost = float(c["ms_per_frame_per_kvert"])
                if not (np.isfinite(cost) and cost >= 0):
                    raise ValueError(f"'{name}': ms_per_frame_per_kvert must be a finite number >= 0, not {cost}")
                if not c.get("reference"):
                    pts = np.asarray(c["points"], dtype=np.float64)
                    if pts.ndim != 2 or pts.shape[1] != 3 or not len(pts) or not np.isfinite(pts).all():
                        raise ValueError(f"'{name}': points must be a non-empty list of [looseness, speed, error]")
        except UnicodeDecodeError:
            raise InputError(f"quality calibration '{path}': expected the JSON `garment tradeoff --calibrate` writes, "
                             "got binary content") from None
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise InputError(f"quality calibration '{path}': expected the JSON `garment tradeoff --calibrate` writes, "
                             f"got {type(exc).__name__}: {exc}") from None
        provenance = data.get("provenance")
        return cls(configs=configs, source=str(path), provenance=provenance if isinstance(provenance, dict) else {})

    def save(self, path: str | os.PathLike) -> None:
        from formats.atomic import atomic_file

        with atomic_file(Path(path)) as tmp:
            Path(tmp).write_text(json.dumps({"configs": self.configs, **({"provenance": self.provenance}
                                                                         if self.provenance else {})}, indent=1))

    def models(self) -> set[str]:
        """The sha256 of every model file whose scenes the model configurations hold (`add_scene`'s
        "model_sha256"; empty for a calibration made before 2026-12-06, which recorded none)."""
        return {sha for c in self.configs.values() if c.get("method") == "model" for sha in c.get("models", {})}

    def expected_error(self, name: str, features: dict) -> float:
        """Expected E_verts (mm) of configuration `name` on a scene with `features`; 0 for the reference."""
        c = self.configs[name]
        if c.get("reference"):
            return 0.0
        pts = np.asarray(c["points"], dtype=np.float64)
        x = _point(features["looseness_m"], features["speed_m_s"])
        d = np.linalg.norm(np.log(np.maximum(pts[:, :2], [MIN_LOOSENESS_M, MIN_SPEED_M_S])) - x, axis=1)
        near = np.argsort(d)[:K_NEAREST]
        w = 1.0 / np.maximum(d[near], 1e-3)
        return float(np.sum(w * pts[near, 2]) / np.sum(w))

    def outside(self, features: dict) -> list[dict]:
        """The features of a scene beyond the calibration's scenes by more than OUTSIDE_FACTOR:
        [{"feature", "value", "calibrated": [smallest, largest]}]; empty for a calibrated scene."""
        pts = [np.asarray(c["points"], dtype=np.float64)[:, :2] for c in self.configs.values()
               if not c.get("reference")]
        if not pts:
            return []
        pts = np.concatenate(pts)
        out = []
        for i, (key, *_) in enumerate(FEATURES):
            lo, hi = float(pts[:, i].min()), float(pts[:, i].max())
            value = float(features[key])
            if value < lo / OUTSIDE_FACTOR or value > hi * OUTSIDE_FACTOR:
                out.append({"feature": key, "value": value, "calibrated": [lo, hi]})
        return out


#: How far apart two equally valid simulations of the tradeoff scenes end up, E_verts mm (the reference rerun from
#: starting positions jittered by 1 um: `benchmarks/results/reference_spread.md`): the floor under any error.
REFERENCE_SPREAD_MM = (5.6, 8.3)


def choose(calibration: Calibration, features: dict, budget_mm: float, extra=()) -> dict:
    """The cheapest configuration expected within `budget_mm`: {"config", "method", "options", "expected_mm",
    "candidates": [{name, expected_mm, ms_per_frame}], "reason"}. extra: more candidates of that form (a
    garment's fitted blend shapes: `psd_candidate`)."""
    if not calibration.configs:
        raise InputError(f"quality calibration '{calibration.source}': expected configurations to choose from, "
                         "got none: add scenes with `garment tradeoff --calibrate`")
    kvert = features["vertices"] / 1000.0
    cands = list(extra)
    for name, c in calibration.configs.items():
        cands.append({"config": name, "method": c["method"], "options": c.get("options", {}),
                      "expected_mm": calibration.expected_error(name, features),
                      "ms_per_frame": float(c["ms_per_frame_per_kvert"]) * kvert})
    cands.sort(key=lambda c: c["ms_per_frame"])
    outside = calibration.outside(features)
    scene = ", ".join(text.format(features[key] * scale) for key, text, _, scale, _ in FEATURES)
    if outside:
        lbs = next((c["expected_mm"] for c in cands if c["method"] == "lbs"), None)
        for c in cands:
            if lbs is not None and c["method"] in LEARNED_METHODS and c["expected_mm"] < lbs:
                c["expected_mm_calibration"], c["expected_mm"] = c["expected_mm"], lbs
        beyond = "; ".join(describe_outside(o) for o in outside)
        scene += (f"; beyond the calibration's scenes ({beyond}): its errors are extrapolated"
                  + (", and the learned methods are expected no better than lbs there" if lbs is not None else ""))
    ok = [c for c in cands if c["expected_mm"] <= budget_mm]
    if ok:
        pick = ok[0]
        cheaper = [c for c in cands if c["ms_per_frame"] < pick["ms_per_frame"]]
        reference = calibration.configs.get(pick["config"], {}).get("reference", False)
        expected = (f"is the calibration's reference, 0 mm by definition (two equally valid simulations of a scene "
                    f"differ by {REFERENCE_SPREAD_MM[0]:g}-{REFERENCE_SPREAD_MM[1]:g} mm: a smaller budget asks "
                    "more than the reference can tell)" if reference else
                    f"is expected at {pick['expected_mm']:.1f} mm <= {budget_mm:g} mm")
        why = (f"{scene}: '{pick['config']}' {expected}, {pick['ms_per_frame']:.2f} ms/frame"
               + "".join(f"; '{c['config']}' is cheaper but expected at {c['expected_mm']:.1f} mm" for c in cheaper))
        # taken over a learned method only because the scene is beyond the calibration: name what that costs
        held = [c for c in cheaper if c.get("expected_mm_calibration", budget_mm + 1) <= budget_mm]
        if held:
            c = held[-1]
            why += (f" (the calibration's nearest scenes would expect '{c['config']}' at "
                    f"{c['expected_mm_calibration']:.1f} mm: `--method {c['method']}` bakes it regardless, "
                    f"{pick['ms_per_frame'] / max(c['ms_per_frame'], 1e-9):.0f}x cheaper)")
    else:
        pick = min(cands, key=lambda c: c["expected_mm"])
        why = (f"{scene}: no configuration is expected within {budget_mm:g} mm: the most accurate, "
               f"'{pick['config']}', expected at {pick['expected_mm']:.1f} mm")
    return {**pick, "budget_mm": budget_mm, "features": features, "candidates": cands, "reason": why,
            "outside_calibration": outside}


def describe_outside(o: dict) -> str:
    """One feature of `Calibration.outside` in words: "speed 0.048 m/s, under the smallest calibrated, 0.69"."""
    _, _, name, scale, unit = next(f for f in FEATURES if f[0] == o["feature"])
    lo, hi = (v * scale for v in o["calibrated"])
    side = f"under the smallest calibrated, {lo:.2g}" if o["value"] * scale < lo else \
        f"over the largest calibrated, {hi:.2g}"
    return f"{name} {o['value'] * scale:.2g} {unit}, {side}"


def add_scene(calibration: Calibration, features: dict, rows: list[dict]) -> None:
    """Append one tradeoff run (rows: config, method, seconds_per_frame, e_verts, options, and for a model its
    file's model_sha256; self_contact_skipped: its error counted, not its cost) to `calibration`."""
    kvert = max(features["vertices"], 1) / 1000.0
    for r in rows:
        c = calibration.configs.setdefault(r["config"], {"method": r["method"], "options": r.get("options", {}),
                                                         "ms_per_frame_per_kvert": 0.0, "points": [], "scenes": 0,
                                                         "reference": bool(r.get("reference", False))})
        n = c.get("costed_scenes", c.get("scenes", 0))  # the scenes its cost is the average of
        cost = r["seconds_per_frame"] * 1e3 / kvert
        if not r.get("self_contact_skipped"):
            c["ms_per_frame_per_kvert"] = (c["ms_per_frame_per_kvert"] * n + cost) / (n + 1)
            c["costed_scenes"] = n + 1
        elif n == 0:  # a row the scene analysis ran without self-contact measured the row without it: its error
            # holds, its cost stands in (under the configuration's) only until a scene measures it with
            c["ms_per_frame_per_kvert"], c["costed_scenes"] = max(c["ms_per_frame_per_kvert"], cost), 0
        c["scenes"] = c.get("scenes", 0) + 1
        c["points"].append([features["looseness_m"], features["speed_m_s"], float(r["e_verts"])])
        if r.get("model_sha256"):  # which model's errors these are (`Calibration.models`)
            models = c.setdefault("models", {})
            models[r["model_sha256"]] = models.get(r["model_sha256"], 0) + 1


#: psd's cost per frame against LBS's, its contact guard and strain limit included (on by default): the example
#: trousers, fitted to the real captures of the calibration, on the example run and walk (151 and 181 frames, one
#: thread, three runs): 3.8-4.1 and 3.1-3.4 ms against LBS's 0.38-0.39 and 0.31-0.41 (about 10x); the guard about
#: 2.5 ms of it, the limit 1.2-1.3 and 0.5 (117 and 91 frames limited), the fit alone 0.4-0.6. (Before the limit
#: and the guard's spread: 7.5x, 2.7 ms against 0.36; with them, before the guard posed the body at its anchors
#: only: 13x.)
PSD_COST_OVER_LBS = 10.0


def psd_candidate(calibration: Calibration, features: dict, fit_meta: dict) -> dict:
    """A garment's fitted blend shapes as a `choose` candidate: expected at LBS's expected error on the scene
    times the share of LBS's error the fit kept on its dataset's held-out motions (validation, else test; 1
    without either), at PSD_COST_OVER_LBS times LBS's cost. Needs an 'lbs' configuration in the calibration."""
    if "lbs" not in calibration.configs:
        raise InputError("--quality auto with --fit: the calibration has no 'lbs' configuration to scale")
    errors = fit_meta.get("errors", {})
    held = errors.get("val") or errors.get("test")
    share = float(held["psd_mm"] / held["lbs_mm"]) if held and held.get("lbs_mm") else 1.0
    kvert = features["vertices"] / 1000.0
    return {"config": "psd", "method": "psd", "options": {},
            "expected_mm": share * calibration.expected_error("lbs", features),
            "ms_per_frame": PSD_COST_OVER_LBS * float(calibration.configs["lbs"]["ms_per_frame_per_kvert"]) * kvert}
