"""How far the reference simulation is from equally valid reruns of itself, and where LBS and the model sit.

    python benchmarks/reference_spread.py [--garments skirt dress ...] [--finer skirt dress]
        [--motion data/heldout/walk_brisk.npz] [--frames 0:30] [--model core/assets/default_model.pt]

Per example garment on the held-out scene of the tradeoff tables (`benchmarks/tradeoff_examples.sh`): the
reference of `garment tradeoff` (20 substeps with self-contact), its rerun from starting positions jittered by
1 um (the `--spread` row: cloth is chaotic, so this is the floor under any method's error), for the garments
named by --finer the simulator at twice the reference's substeps with self-contact (how far the reference is
from a finer discretisation), LBS and the model (float32, contact guard on). E_verts (mm) of each against the
reference and against the finer simulation, and the share of LBS's error above the floor that the model
removes: (LBS - model) / (LBS - spread).

Simulations are kept in benchmarks/results/reference_spread/<scene>/ under their `core.tradeoff` keys
(git-ignored) and reused by a later run; each scene's numbers go to <scene>/result.json and every run rewrites
benchmarks/results/reference_spread.md from all of them, so two runs over different garments can go side by
side (one per core: OMP_NUM_THREADS=1).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

from core.body import default_body  # noqa: E402
from core.metrics import e_verts  # noqa: E402
from core.sim import SIMULATOR_VERSION  # noqa: E402
from core.tradeoff import (  # noqa: E402
    SIM_SUBSTEPS,
    Config,
    configurations,
    load_simulation,
    measure,
    save_simulation,
    sim_file_name,
    simulation_key,
    simulation_scene,
)
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

RESULTS = ROOT / "benchmarks/results/reference_spread"
HEADERS = ("scene", "simulator", "vertices", "frames", "spread mm", "finer sim mm", "LBS mm", "model mm", "model / LBS",
           "gap closed", "LBS vs finer", "model vs finer", "reference vs finer")


def scene_rows(model_path: str, finer: bool) -> list[Config]:
    """LBS, the model in float32 (no push-out), the reference, its jittered rerun, and the finer simulation."""
    keep = [c for c in configurations({"model": model_path}, spread=True)
            if c.method == "lbs" or c.reference or c.spread
            or (c.method == "model" and c.options["precision"] == "float32" and not c.options["push_out"])]
    if finer:
        n = 2 * max(SIM_SUBSTEPS)
        keep.append(Config(f"sim {n} substeps +self-contact", "sim", {"substeps": n, "self_contact": True}))
    return keep


def run_scene(garment_path: Path, motion_path: Path, frames: str, model_path: str, finer: bool) -> dict:
    garment, body = read_obj(garment_path), default_body()
    motion, _ = prepare_motion(str(motion_path), 30.0, frames, 0)
    name = f"{garment_path.stem}_{motion_path.stem}"
    directory = RESULTS / name
    directory.mkdir(parents=True, exist_ok=True)
    scene = simulation_scene(garment, body, motion)
    configs = scene_rows(model_path, finer)
    points = {}
    for config in configs:
        key = simulation_key(config, scene) if config.method == "sim" else None
        m = load_simulation(directory / sim_file_name(config), config, key) if key else None
        if m is None:
            print(f"{name}: {config.name} ...", flush=True)
            m = measure(config, garment, body, motion, repeats=1)
            if key:
                save_simulation(directory / sim_file_name(config), m, key)
        points[config.name] = m.points
    ref = next(c.name for c in configs if c.reference)
    roles = {"spread": next(c.name for c in configs if c.spread), "lbs": "lbs",
             "model": next(c.name for c in configs if c.method == "model")}
    finer_name = configs[-1].name if finer else None

    def err(a: str, b: str) -> float:
        return float(e_verts(points[a], points[b]).mean())

    result = {"scene": name, "simulator_version": SIMULATOR_VERSION, "vertices": garment.n_vertices,
              "frames": motion.n_frames, "reference": ref,
              "finer": finer_name, "against_reference_mm": {c: err(c, ref) for c in points},
              "against_finer_mm": {c: err(c, finer_name) for c in points} if finer else {}, "roles": roles}
    (directory / "result.json").write_text(json.dumps(result, indent=1))
    return result


def table_row(r: dict) -> tuple:
    ref, fin, roles = r["against_reference_mm"], r["against_finer_mm"], r["roles"]
    spread, lbs, model = ref[roles["spread"]], ref[roles["lbs"]], ref[roles["model"]]
    nan = float("nan")
    return (r["scene"], r["simulator_version"], r["vertices"], r["frames"], spread,
            ref[r["finer"]] if r["finer"] else nan, lbs, model,
            f"{100 * model / lbs:.0f} %", f"{100 * (lbs - model) / (lbs - spread):.0f} %",
            fin.get(roles["lbs"], nan), fin.get(roles["model"], nan), fin.get(r["reference"], nan))


def write_summary() -> str:
    results = [json.loads(f.read_text()) for f in sorted(RESULTS.glob("*/result.json"))]
    text = ("# The reference's own spread, and where LBS and the model sit\n\n"
            "E_verts (mm) on the held-out scene of the tradeoff tables. `spread`: the reference (20 substeps with "
            "self-contact) run again from starting positions jittered by 1 um: how far apart two equally valid "
            "simulations of the scene end up (the floor under any method's error against the reference). `finer "
            "sim`: the simulator at 40 substeps with self-contact against the reference (where run). `gap closed`: "
            "(LBS - model) / (LBS - spread), the share of LBS's error above the floor that the model removes. The "
            "last three columns measure against the finer simulation instead. `simulator`: "
            "`core.sim.SIMULATOR_VERSION` of the scene's simulations. Made by "
            "`python benchmarks/reference_spread.py`.\n\n" + markdown_table(HEADERS, [table_row(r) for r in results],
                                                                           digits=3))
    (ROOT / "benchmarks/results/reference_spread.md").write_text(text)
    return text


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garments", nargs="+", default=[p.stem for p in sorted((ROOT / "examples").glob("*.obj"))])
    ap.add_argument("--finer", nargs="*", default=[], help="garments also simulated at twice the reference's substeps")
    ap.add_argument("--motion", type=Path, default=ROOT / "data/heldout/walk_brisk.npz")
    ap.add_argument("--frames", default="0:30", help="source frames (60 fps source, baked at 30 fps)")
    ap.add_argument("--model", default=str(ROOT / "core/assets/default_model.pt"))
    a = ap.parse_args(argv)
    if not a.motion.is_file():
        sys.exit(f"{a.motion}: no such file (benchmarks/tradeoff_examples.sh writes the held-out walk_brisk there)")
    for g in a.garments:
        run_scene(ROOT / "examples" / f"{g}.obj", a.motion, a.frames, a.model, g in a.finer)
    print(write_summary())


if __name__ == "__main__":
    main()
