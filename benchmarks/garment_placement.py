"""How `bind_garment` judges where a garment sits on the rest body: bound, warned about or refused, and which fix
it names, over garments placed right and wrong, in one run.

Groups (the embedded body unless --body):
- the example garments as authored, and moved down and up by 0.15-0.30 m (as garments authored on a body whose
  origin stands elsewhere, such as SMPL's rest body, sit on this one), sideways, forwards and back;
- 96 loose tube skirts and dresses (2 waists or tops, 4 hems, 3 eases, 4 flares: `core.garmentgen`'s tube);
- the example garments scaled as by a unit mix-up (inches read as centimetres and back, millimetres read as
  centimetres and back), and the loose tubes scaled by 2.54;
- the example t-shirt, trousers and dress generated on other body shapes (betas 0-3 drawn in [-3, 3], seed 0):
  garments authored on another body, which no move puts right;
- any --garment files (e.g. garments authored on SMPL's rest body).

Writes benchmarks/results/garment_placement.md: per group, how many were bound without a word, warned about
(inside the body), refused naming a move back, refused naming a scale back, or refused otherwise (the loosest tubes, whose closest 5 %
stand more than 5 cm from the body: not resting on it); then a row per moved, given or refused garment.

    python benchmarks/garment_placement.py [--shapes 12] [--garment PATH ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.errors import InputError  # noqa: E402
from core.garment import Garment  # noqa: E402
from core.garmentgen import _levels, _RestBody, _tube_garment, generate_example_garments  # noqa: E402
from core.skinning import bind_garment  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import collected_warnings  # noqa: E402

#: (x, y, z) metres: down and up (as on a body whose origin stands higher or lower, such as SMPL's), sideways, forwards
#: and back (an object exported away from the origin), and all three.
MOVES_M = ((0.0, -0.30, 0.0), (0.0, -0.23, 0.0), (0.0, -0.15, 0.0), (0.0, 0.15, 0.0), (0.0, 0.23, 0.0),
           (0.30, 0.0, 0.0), (-0.15, 0.0, 0.0), (0.0, 0.0, 0.10), (0.0, 0.0, -0.20), (0.20, -0.10, 0.10))
#: Scales a unit mix-up gives: inches read as centimetres and back, millimetres read as centimetres and back.
MIXUPS = (0.01 / 0.0254, 2.54, 0.1, 10.0)


def judge(garment: Garment, body) -> tuple[str, str]:
    """(outcome: bound, warned, move, scale, refused; the move or scale named or the message's fix, else "")."""
    with collected_warnings() as warned:
        try:
            bind_garment(garment, body)
        except InputError as err:
            found = re.search(r"--pose tpose (--scale [^`]+)`$", str(err))
            if found:
                return "scale", found[1]
            found = re.search(r"--move (\S+)`$", str(err))
            if found:
                return "move", found[1]
            fix = str(err).split("; ", 1)
            return "refused", fix[1][:60] if len(fix) > 1 else str(err).split("got ", 1)[-1][:60]
    inside = [m for m in warned if "inside the body's rest surface" in m]
    return ("warned", "") if inside else ("bound", "")


def tubes(body) -> dict[str, Garment]:
    rest = _RestBody(body)
    lv = _levels(rest)
    out = {}
    for top_name, top in (("waist", lv["pelvis"] + 0.5 * (lv["spine1"] - lv["pelvis"])),
                          ("chest", lv["armpits"] - 0.03)):
        for hem_name, hem in (("hips", lv["hips"] - 0.1), ("thighs", lv["knees"] + 0.3 * (lv["hips"] - lv["knees"])),
                              ("knees", lv["knees"] - 0.06), ("ankles", lv["ankles"] + 0.04)):
            for ease in (0.012, 0.05, 0.12):
                for slope in (0.0, 0.22, 0.6, 1.0):
                    name = f"{top_name}-{hem_name} ease {ease:g} flare {slope:g}"
                    out[name] = _tube_garment(rest, name, y_top=top, y_bottom=hem, ease=ease,
                                              flare_from_y=lv["hips"], flare_slope=slope)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shapes", type=int, default=12, help="other body shapes to generate the examples on")
    ap.add_argument("--garment", type=Path, action="append", default=[], help="a garment file to judge too")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "garment_placement.md")
    args = ap.parse_args(argv)
    body = default_body()
    examples = generate_example_garments(body)
    groups: dict[str, dict[str, Garment]] = {"examples as authored": examples}
    groups["examples moved"] = {f"{name} moved {','.join(f'{m:g}' for m in move)}": dataclasses.replace(
        g, vertices=g.vertices + np.float32(move)) for name, g in examples.items() for move in MOVES_M}
    groups["examples in mixed-up units"] = {f"{name} scaled by {s:.4g}": dataclasses.replace(
        g, vertices=(g.vertices * s).astype(np.float32)) for name, g in examples.items() for s in MIXUPS}
    groups["loose tubes"] = tubes(body)
    groups["loose tubes scaled by 2.54"] = {f"{name} scaled by 2.54": dataclasses.replace(
        g, vertices=g.vertices * np.float32(2.54)) for name, g in groups["loose tubes"].items()}
    rng = np.random.default_rng(0)
    shaped = {}
    for k in range(args.shapes):
        betas = np.zeros(body.n_betas, dtype=np.float32)
        betas[:4] = rng.uniform(-3.0, 3.0, 4)
        other = dataclasses.replace(body, v_template=body.shaped(betas)[0])
        for name, g in generate_example_garments(other, ("tshirt", "trousers", "dress")).items():
            shaped[f"{name} on shape {k} ({', '.join(f'{b:+.1f}' for b in betas[:4])})"] = g
    groups["examples on other shapes"] = shaped
    if args.garment:
        groups["given files"] = {p.name: read_garment(p) for p in args.garment}

    counts, rows = [], []
    for group, garments in groups.items():
        outcomes = {name: judge(g, body) for name, g in garments.items()}
        tally = {k: sum(o == k for o, _ in outcomes.values()) for k in ("bound", "warned", "move", "scale", "refused")}
        counts.append([group, len(garments), *tally.values()])
        for name, (outcome, fix) in outcomes.items():
            if group in ("examples moved", "examples in mixed-up units", "given files") or outcome in (
                    "move", "scale", "refused"):
                rows.append([group, name, outcome, fix])
        print(group, tally, flush=True)
    text = ["# Where a garment sits on the rest body: bound, warned or refused", "",
            f"Made by `python benchmarks/garment_placement.py --shapes {args.shapes}"
            + "".join(f" --garment {p.name}" for p in args.garment)
            + f"` on {platform.machine()} ({os.cpu_count()} cores), body '{body.name}'. `move`: refused naming "
            "the `--move X,Y,Z` back (`core.skinning.SHIFT_RANGE_M`, `SHIFT_SIDE_RANGE_M`); `scale`: refused naming the "
            "`--scale S` back (`core.skinning.UNIT_MIXUPS`); `warned`: bound with the "
            "warning of a garment partly inside the body; `refused`: refused naming another fix or none.", "",
            markdown_table(["group", "garments", "bound", "warned", "move", "scale", "refused"], counts), "",
            markdown_table(["group", "garment", "outcome", "move or scale named / fix"], rows)]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(text))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
