"""Re-simulate part of a dataset with cloth self-contact on: the same items, a finer physics.

The shipped model was trained on `data/sim_v1`, simulated without self-contact, while the tradeoff reference
(`garment tradeoff`) simulates with it; the two physics differ by 40-73 mm on the example garments. This
script takes items of an existing dataset (same garment, motion clip, body shape and split), simulates them
again with self-contact, and writes a dataset in the same format that `garment train --init` fine-tunes on.

    python benchmarks/self_contact_data.py --like data/sim_v1 --out data/sim_sc1 --workers 2 \
        --garments dress,skirt --minutes 40

Items are taken motion by motion in the order of --motions (default: the source's train motions, walks and
runs first), every garment of a motion in turn, so a run cut short by --minutes still covers every garment.
An evaluation set of the source's held-out motions:

    python benchmarks/self_contact_data.py --like data/sim_v1 --out data/sim_sc1_test --motions none \
        --val-motions none --test-motions walk_brisk,turn_right_wide,arm_swing_fast,kick_right

It resumes: finished sequences are kept. The manifest lists only the finished items, so the result is a
complete dataset whenever the run stops (rerun with --minutes 0 to only rewrite the manifest).
"""

from __future__ import annotations

import argparse
import copy
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

# Walks and runs first (the tradeoff's held-out motion is a walk), then the rest of the usual train motions.
PRIORITY = ["walk", "run", "walk_fast", "turn", "run_jog", "walk_slow", "twist", "turn_right", "kick_high",
            "arm_swing", "jump_small", "sit_down", "bend_forward", "crouch", "jump", "arms_raise",
            "bend_side_left", "bend_side_right", "sit_down_slow", "jump_high", "arms_raise_half", "bend_forward_deep"]


def select_items(manifest: dict, garments: list[str], motions: list[str], val_motions: list[str],
                 test_motions: list[str] = ()) -> list[dict]:
    """The source items of `garments` on `motions` (train), `val_motions` (val) and `test_motions` (test), in
    run order (validation first, then motion by motion)."""
    items = [it for it in manifest["items"] if it["garment"] in garments]
    order = []
    for split, names in (("val", val_motions), ("test", test_motions), ("train", motions)):
        for m in names:
            found = [it for it in items if it["motion"] == m and it["split"] == split]
            if not found:
                raise SystemExit(f"--like: no {split} item of motion '{m}' for garments {garments}")
            order += sorted(found, key=lambda it: garments.index(it["garment"]))
    return order


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--like", required=True, help="source dataset (its items, bodies, material and solver)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--garments", default="dress,skirt,trousers")
    ap.add_argument("--motions", default=None,
                    help="comma-separated train motions (default: all, walks first; 'none' for no train items)")
    ap.add_argument("--val-motions", default="turn_left_sharp", help="comma-separated ('none': no val items)")
    ap.add_argument("--test-motions", default="none",
                    help="comma-separated test motions, e.g. the source's test split for an evaluation set")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--minutes", type=float, default=None, help="start no item after this many minutes")
    args = ap.parse_args()

    from core.dataset import DatasetItem, build_manifest
    from core.distributed import run_items
    from core.provenance import software_versions
    from core.sim import SIMULATOR_VERSION, Material, SimOptions
    from formats.dataset import (
        copy_garment_template,
        read_manifest,
        sequence_path,
        write_manifest,
    )

    src = Path(args.like)
    old = read_manifest(src)
    if old is None:
        raise SystemExit(f"--like: no manifest in '{src}'")
    garments = args.garments.split(",")
    train_motions = old["splits"]["motions"]["train"]
    motions = _names(args.motions) if args.motions else (
        [m for m in PRIORITY if m in train_motions] + [m for m in train_motions if m not in PRIORITY])
    fields = DatasetItem.__dataclass_fields__
    chosen = [DatasetItem(**{k: it[k] for k in fields})
              for it in select_items(old, garments, motions, _names(args.val_motions), _names(args.test_motions))]

    settings = copy.deepcopy(old["settings"])
    settings["solver"]["self_contact"] = True
    settings["resimulated_from"] = {"dataset": str(src), "plan_key": old["plan_key"]}
    material = Material(**settings["material"])
    options = SimOptions(**settings["solver"])
    settings["solver"] = asdict(options)  # the options this run uses, fields added since the source included
    settings["simulator_version"] = SIMULATOR_VERSION  # re-simulated with this code, whatever the source's was
    out = Path(args.out)
    for g in garments:
        copy_garment_template(out, src / "garments" / f"{g}.obj", g)
    garment_paths = [str(out / "garments" / f"{g}.obj") for g in garments]
    betas = np.asarray(old["betas"]["per_body"], dtype=np.float64)

    old_out = read_manifest(out) or {}
    stats = dict(old_out.get("item_stats", {}))
    failed = dict(old_out.get("failed_items", {}))

    def write() -> dict:
        """The manifest of the finished items (a complete dataset whenever the run stops)."""
        items = [it for it in chosen if sequence_path(out, it.id).is_file()]
        splits = {"motions": {s: sorted({it.motion for it in items if it.split == s}) for s in ("train", "val", "test")},
                  "garments": {s: sorted({it.garment for it in items if it.split == s}) for s in ("train", "val", "test")},
                  "held_out_garments": []}
        inputs = {"garments": {g: {"path": p} for g, p in zip(garments, garment_paths)}, "motions": {},
                  "motion_library": old["inputs"].get("motion_library", []), "body": old["inputs"]["body"]}
        man = build_manifest(settings, items, splits, betas, inputs,
                             software_versions("garment", "newton", "warp-lang", "numpy", "torch"))
        man["item_stats"] = {it.id: stats[it.id] for it in items if it.id in stats}
        man["failed_items"] = failed
        write_manifest(out, man)
        return man

    write()
    todo = [it for it in chosen if not sequence_path(out, it.id).is_file() and it.id not in failed]
    print(f"{out}: {len(chosen)} items chosen, {len(chosen) - len(todo)} done, {len(todo)} to simulate", flush=True)
    if args.minutes != 0 and todo:
        init = (garment_paths, [], bool(settings["library"]), None, float(settings["fps"]), material, options)
        t0 = time.time()
        deadline = None if args.minutes is None else t0 + 60 * args.minutes
        calls = [(deadline, (init, it, betas[it.body], int(settings["settle"]), out, settings["body"])) for it in todo]
        for iid, res in run_items(_gated, calls, [it.id for it in todo], workers=args.workers):
            if isinstance(res, str):
                failed[iid] = res
                print(f"{time.time() - t0:7.0f} s  {iid}: FAILED {res}", flush=True)
            elif res is not None:
                _, n, sec, checks = res
                stats[iid] = {"seconds_per_frame": sec / n, **checks}
                print(f"{time.time() - t0:7.0f} s  {iid}: {sec / n:.2f} s/frame", flush=True)
                write()
    man = write()
    print(f"{out}: {man['totals']['items']} sequences ({man['totals']['frames_per_split']})")


def _names(text: str) -> list[str]:
    return [] if text in ("", "none") else text.split(",")


def _gated(deadline, call):
    """dataset_task unless the deadline has passed (then None: the item is left for a later run).

    A simulation that fails (core.sim.SimulationError, e.g. a blow-up the retries could not mend) returns its
    message instead of stopping the whole run: the item is left out of the dataset and reported.
    """
    from core.sim import SimulationError
    from garmentcli.dataset import dataset_task

    if deadline is not None and time.time() > deadline:
        return None
    try:
        return dataset_task(*call)
    except SimulationError as exc:
        return str(exc)


if __name__ == "__main__":
    main()
