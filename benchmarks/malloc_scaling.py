"""The model's time per frame against the garment's size, with glibc's malloc keeping freed blocks (what `garment`
sets, `garmentcli.keep_freed_memory`) and with its defaults, in one run.

    python benchmarks/malloc_scaling.py [--repeats 3] [--frames 0:20]

Garments: the example dress, subdivided 0, 1 and 2 times (each triangle into four: 3,240, 12,816 and 50,976
vertices). Each size is baked by `garment bake --method model` (walk_brisk, --frames) in a new process, the two
settings alternating (`GLIBC_TUNABLES` set to a neutral tunable turns the command's own setting off); the
network's milliseconds per frame (`summary.json`), median of --repeats, and the process's minor page faults per
frame (of the whole process) and peak memory. Writes benchmarks/results/malloc_scaling.md (or --out). Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.garment import Garment  # noqa: E402
from core.garmentgen import _subdivide_midpoint  # noqa: E402
from formats.obj import read_garment, write_obj  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402

#: GLIBC_TUNABLES value that changes nothing but makes the command leave malloc's defaults alone.
NEUTRAL_TUNABLE = "glibc.malloc.check=0"
#: `garment` in a new process that reports its own peak memory and page faults when it exits.
COMMAND = ("import atexit, resource, runpy, sys; atexit.register(lambda: print('RUSAGE', resource.getrusage("
           "resource.RUSAGE_SELF).ru_maxrss, resource.getrusage(resource.RUSAGE_SELF).ru_minflt, file=sys.stderr)); "
           "sys.argv = ['garment'] + sys.argv[1:]; runpy.run_module('garmentcli.main', run_name='__main__')")


def subdivided(g: Garment) -> Garment:
    """Each triangle into four at its edges' midpoints (the new vertices after the old ones, as modellers do)."""
    (v,), faces = _subdivide_midpoint([g.vertices], g.faces)
    return Garment(v.astype(np.float32), faces, name=g.name)


def bake(garment_path: Path, motion: Path, frames: str, out: Path, keep: bool) -> tuple[float, float, float]:
    """(network ms/frame, minor page faults per frame, peak resident MB) of one `garment bake` process."""
    env = dict(os.environ)
    env.pop("GLIBC_TUNABLES", None)
    if not keep:
        env["GLIBC_TUNABLES"] = NEUTRAL_TUNABLE
    r = subprocess.run([sys.executable, "-c", COMMAND, "bake", str(garment_path), str(motion), "--method", "model",
                        "--frames", frames, "--out", str(out), "--overwrite", "--no-obj"], check=True, env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    maxrss_kb, faults = (int(x) for x in r.stderr.rsplit("RUSAGE", 1)[1].split()[:2])
    summary = json.loads((out / f"{garment_path.stem}_{motion.stem}" / "summary.json").read_text())
    return 1e3 * summary["deformer"]["seconds_per_frame_network"], faults / summary["frames"], maxrss_kb / 1024


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--frames", default="0:20")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "malloc_scaling.md")
    args = ap.parse_args(argv)
    from core.motiongen import MOTION_LIBRARY
    from formats.motion import save_motion

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        motion = tmp / "walk_brisk.npz"
        save_motion(motion, MOTION_LIBRARY["walk_brisk"](fps=30.0))
        g = read_garment(ROOT / "examples" / "dress.obj")
        for level in range(3):
            path = tmp / f"dress_s{level}.obj"
            write_obj(path, g.vertices, g.faces)
            bake(path, motion, "0:3", tmp / "warm", True)  # preprocessing cached for the timed runs
            runs = {True: [], False: []}
            for _ in range(args.repeats):
                for keep in (False, True):
                    runs[keep].append(bake(path, motion, args.frames, tmp / "out", keep))
            med = {k: np.median(np.array(v), axis=0) for k, v in runs.items()}
            rows.append([f"{len(g.vertices):,}", f"{med[False][0]:.1f}", f"{med[True][0]:.1f}",
                         f"{med[False][0] / med[True][0]:.2f}", f"{med[False][1]:,.0f}", f"{med[True][1]:,.0f}",
                         f"{med[False][2]:,.0f}", f"{med[True][2]:,.0f}"])
            print(rows[-1], flush=True)
            g = subdivided(g)
    table = markdown_table(["vertices", "malloc's defaults ms/frame", "blocks kept ms/frame", "defaults / kept",
                            "page faults per frame (defaults)", "(kept)", "peak MB (defaults)", "(kept)"], rows)
    lines = ["# The model's time per frame against the garment's size: glibc's malloc keeping freed blocks", "",
             f"Made by `python benchmarks/malloc_scaling.py --repeats {args.repeats} --frames {args.frames}` on "
             f"{platform.machine()} ({os.cpu_count()} cores), Python {platform.python_version()}. The example dress "
             "subdivided 0-2 times, baked with the model over walk_brisk in a new process each; the network's "
             "milliseconds per frame, and the process's minor page faults (start-up and preparation included) "
             "per frame and peak resident memory, median of the runs (the two settings alternate).", "", table]
    write_markdown(args.out, lines, show=True)


if __name__ == "__main__":
    main()
