"""Training-set planning: items over garments x motion clips x body shapes, splits, and one item's simulation.

Pure computation; `formats.dataset` stores what this produces and
`garment dataset` runs it. The plan is deterministic given its inputs and seed:

- Body shapes: body 0 is the mean shape (betas 0); bodies 1..N-1 draw each of
  the body's shape coefficients uniformly in [-betas_range, +betas_range]
  (default 2.0, i.e. +-2 standard deviations of an SMPL-style PCA basis).
- Splits share no motion: the motions are shuffled (seed) and dealt into train /
  val / test (fractions 0.7 / 0.15 / 0.15, at least one motion each when there are
  three or more). A resumed dataset's motions keep their splits; motions added since
  are shuffled and dealt the same way among themselves. With two or more garments,
  one garment (chosen with the seed) is held out unless asked otherwise: it appears
  only in the test split, which uses every garment.
- Each motion is cut into clips of at most `frames_per_clip` frames (at the
  dataset's fps); every clip gets `settle_frames` blend frames from the rest pose
  (`core.motion.settle`), stored and flagged by `n_settle`.
- A clip that does not start its motion is preceded by up to `preroll` frames of the
  motion before it (`DatasetItem.preroll`), simulated after the settle blend and flagged
  with it by `n_settle`: the cloth enters the clip moving with the body, as it would
  in the whole motion, instead of starting there at rest.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass, replace

import numpy as np

from core.body import Body
from core.deform import Deformer
from core.errors import InputError
from core.garment import Garment
from core.motion import Motion, poses_for_body, select_frames, settle

SPLIT_FRACTIONS = (0.7, 0.15, 0.15)
DEFAULT_BETAS_RANGE = 2.0


@dataclass(frozen=True)
class DatasetItem:
    """One sequence to simulate. clip: index of the clip within the motion; body: index into the sampled betas.
    preroll: frames of the motion before start_frame simulated ahead of the clip (after the settle blend)."""

    id: str
    garment: str
    motion: str
    clip: int
    start_frame: int
    n_frames: int
    body: int
    split: str
    preroll: int = 0


def sample_betas(n_bodies: int, n_betas: int, betas_range: float = DEFAULT_BETAS_RANGE, seed: int = 0) -> np.ndarray:
    """(n_bodies, n_betas) float32: row 0 zeros (mean shape), the others uniform in [-range, range]."""
    if n_bodies < 1:
        raise InputError(f"--bodies: expected at least 1 body shape, got {n_bodies}")
    if not (np.isfinite(betas_range) and betas_range >= 0):
        raise InputError(f"--betas-range: expected a non-negative number, got {betas_range}")
    rng = np.random.default_rng(seed)
    out = np.zeros((n_bodies, n_betas), dtype=np.float32)
    out[1:] = rng.uniform(-betas_range, betas_range, size=(n_bodies - 1, n_betas))
    return out


def split_motions(motion_names: list[str], seed: int = 0, fractions=SPLIT_FRACTIONS,
                  kept: dict[str, str] | None = None) -> dict[str, str]:
    """motion name -> 'train' | 'val' | 'test'; no motion in two splits.

    kept: motion name -> split of the motions an earlier plan had (a resumed dataset). Those among `motion_names`
      keep theirs (a model trained on the earlier plan keeps its test set); only the others are shuffled with the
      seed and dealt among themselves, as a plan of them alone would be. Names of `kept` not in `motion_names`
      (motions removed since) are ignored.
    """
    names = sorted(set(motion_names))
    if len(names) != len(motion_names):
        raise InputError("--motions: expected distinct motion file names (stems), got duplicates")
    kept = {m: s for m, s in (kept or {}).items() if m in names}
    bad = next((m for m, s in kept.items() if s not in ("train", "val", "test")), None)
    if bad is not None:
        raise InputError(f"split of motion '{bad}': expected train, val or test, got {kept[bad]!r}")
    new = [m for m in names if m not in kept]
    rng = np.random.default_rng(seed)
    order = [new[i] for i in rng.permutation(len(new))]
    n = len(order)
    if n >= 3:
        n_val = max(1, int(round(fractions[1] * n)))
        n_test = max(1, int(round(fractions[2] * n)))
        n_train = n - n_val - n_test
    else:  # too few motions for three splits: train first, then test
        n_train, n_val, n_test = (1, 0, n - 1) if n == 2 else (1, 0, 0)
    splits = ["train"] * n_train + ["val"] * n_val + ["test"] * n_test
    return kept | dict(zip(order, splits))


def held_out_garments(garment_names: list[str], seed: int = 0, chosen: str | bool | None = None) -> list[str]:
    """Garments used only in the test split: one of two or more (`chosen`, else drawn with the seed), none of one.

    chosen: a garment name, None (drawn with the seed) or False (none: every garment is trained on).
    """
    names = sorted(garment_names)
    if chosen is False:
        return []
    if chosen is not None:
        if chosen not in names:
            raise InputError(f"--held-out: expected one of the garments ({', '.join(names)}), got '{chosen}'")
        if len(names) < 2:
            raise InputError("--held-out: needs at least two garments (the others are trained on)")
        return [chosen]
    if len(names) < 2:
        return []
    return [names[int(np.random.default_rng(seed + 1).integers(len(names)))]]


def clip_ranges(n_frames: int, frames_per_clip: int | None) -> list[tuple[int, int]]:
    """[start, stop) frame ranges of consecutive clips of at most `frames_per_clip` frames (None: one clip)."""
    if frames_per_clip is None or frames_per_clip >= n_frames:
        return [(0, n_frames)]
    if frames_per_clip < 1:
        raise InputError(f"--frames-per-clip: expected a positive number of frames, got {frames_per_clip}")
    return [(s, min(s + frames_per_clip, n_frames)) for s in range(0, n_frames, frames_per_clip)
            if min(s + frames_per_clip, n_frames) - s >= max(2, frames_per_clip // 4)] or [(0, n_frames)]


def plan_items(garment_names: list[str], motion_frames: dict[str, int], n_bodies: int,
               frames_per_clip: int | None = None, seed: int = 0,
               max_clips_per_motion: int | None = None, bodies_per_clip: int | None = None,
               held_out: str | bool | None = None, preroll: int = 0,
               kept_splits: dict[str, str] | None = None,
               kept_bodies: dict[tuple, list[int]] | None = None) -> tuple[list[DatasetItem], dict]:
    """Items over garments x motion clips x bodies and the split description.

    motion_frames: motion name -> frame count at the dataset's fps.
    max_clips_per_motion: keep only the first clips of each motion (None: all).
    bodies_per_clip: simulate each (garment, clip) on this many of the bodies, taken in turn
      (body k, k+1, ... modulo n_bodies, k counting the pairs in motion/clip/garment order, the motions of
      `kept_splits` first), so every body shape appears at a fraction of the cost; None: every body.
    held_out: the garment kept for the test split (None: drawn with the seed; False: none).
    preroll: frames of the motion simulated ahead of a clip that does not start it (fewer where it starts sooner).
    kept_splits: motion name -> split of a resumed dataset's motions, which keep it (`split_motions`); they
      also take their bodies in turn before the motions added since, so a motion added keeps the items planned.
    kept_bodies: (garment, motion, clip) -> the bodies a resumed dataset's plan gave that clip
      (`manifest_bodies`), kept, so that a motion removed does not move the turns of the motions after it.
    Returns (items sorted by id, {"motions": {split: [...]}, "garments": {split: [...]}, "held_out_garments": [...]}).
    """
    if len(set(garment_names)) != len(garment_names):
        raise InputError("--garments: expected distinct garment file names (stems), got duplicates")
    motion_split = split_motions(list(motion_frames), seed, kept=kept_splits)
    held = held_out_garments(garment_names, seed, held_out)
    per_clip = n_bodies if bodies_per_clip is None else min(bodies_per_clip, n_bodies)
    if per_clip < 1:
        raise InputError(f"--bodies-per-clip: expected at least 1, got {bodies_per_clip}")
    if preroll < 0:
        raise InputError(f"--preroll: expected a non-negative number of frames, got {preroll}")
    items, turn = [], 0
    kept = kept_splits or {}
    for motion in sorted(motion_frames, key=lambda m: m not in kept):  # stable: the given order within each
        n, split = motion_frames[motion], motion_split[motion]
        garments = garment_names if split == "test" else [g for g in garment_names if g not in held]
        for c, (start, stop) in enumerate(clip_ranges(n, frames_per_clip)[:max_clips_per_motion]):
            for g in garments:
                bodies = (kept_bodies or {}).get((g, motion, c)) or sorted({(turn + k) % n_bodies
                                                                           for k in range(per_clip)})
                turn += per_clip
                for b in bodies:
                    items.append(DatasetItem(id=f"{g}__{motion}__c{c:02d}__b{b:02d}", garment=g, motion=motion, clip=c,
                                             start_frame=start, n_frames=stop - start, body=b, split=split,
                                             preroll=min(preroll, start)))
    items.sort(key=lambda it: it.id)
    _refuse_shared_ids(items)
    splits = {"motions": {s: sorted(m for m, v in motion_split.items() if v == s) for s in ("train", "val", "test")},
              "garments": {s: sorted({it.garment for it in items if it.split == s}) for s in ("train", "val", "test")},
              "held_out_garments": held}
    return items, splits


def _refuse_shared_ids(items: list[DatasetItem]) -> None:
    """InputError where two items would be named alike (their sequence files one file): a garment's or motion's
    name holding '__', the names' separator (garment a__b on motion c and garment a on motion b__c), or names
    that differ in case only (one file on a case-insensitive file system)."""
    first: dict[str, DatasetItem] = {}
    for it in items:
        other = first.setdefault(it.id.casefold(), it)
        if other is not it:
            why = ("so that no name holds '__'" if other.id == it.id else
                   f"(with '{other.id}': names that differ in case only are one file on macOS's or Windows' file "
                   "systems)")
            raise InputError(f"items of garment '{other.garment}' on motion '{other.motion}' and of garment "
                             f"'{it.garment}' on motion '{it.motion}' would both be named '{it.id}' (one sequence "
                             f"file): rename a garment or motion file {why}")


def manifest_motion_splits(manifest: dict) -> dict[str, str]:
    """motion name -> split of the plan a manifest holds (its `splits.motions`, else its items'): what a resume
    keeps (`split_motions(kept=...)`)."""
    recorded = manifest.get("splits", {}).get("motions")
    if isinstance(recorded, dict):
        return {m: s for s, names in recorded.items() for m in names}
    return {it["motion"]: it["split"] for it in manifest.get("items", [])
            if isinstance(it, dict) and {"motion", "split"} <= set(it)}


def manifest_bodies(manifest: dict) -> dict[tuple, list[int]]:
    """(garment, motion, clip) -> the bodies of the plan a manifest holds: what a resume keeps
    (`plan_items(kept_bodies=...)`)."""
    out: dict[tuple, list[int]] = {}
    for it in manifest.get("items", []):
        if isinstance(it, dict) and {"garment", "motion", "clip", "body"} <= set(it):  # else planned afresh
            out.setdefault((it["garment"], it["motion"], int(it["clip"])), []).append(int(it["body"]))
    return {k: sorted(set(v)) for k, v in out.items()}


def item_motion(motion: Motion, item: DatasetItem, betas: np.ndarray, settle_frames: int) -> Motion:
    """The clip of `motion` (already at the dataset fps) for `item`, after its pre-roll frames, with its body
    shape and the settle blend into the first of them."""
    clip = select_frames(motion, item.start_frame - item.preroll, item.start_frame + item.n_frames)
    return settle(replace(clip, betas=np.asarray(betas, dtype=np.float32), name=item.id), settle_frames)


def simulate_item(garment: Garment, body: Body, motion: Motion, deformer: Deformer, preroll: int = 0) -> dict:
    """Run `deformer` on one item's prepared motion (`item_motion`); the arrays of a sequence file plus the
    deformer's report.

    Returns positions (T, V, 3) float32, poses (T, J, 3) float32 in the body's layout, trans (T, 3),
    betas (S,), fps, n_settle (the settle blend and the item's `preroll` frames: all before the clip), report.
    """
    positions = deformer.deform(garment, body, motion)
    return {"positions": positions, "poses": poses_for_body(motion, body.n_joints),
            "trans": motion.trans.astype(np.float32), "betas": body.fit_betas(motion.betas),
            "fps": float(motion.fps), "n_settle": int(motion.n_settle) + int(preroll), "report": deformer.report}


def plan_key(settings: dict) -> str:
    """A short hash of the settings that define a dataset (so a resume with other settings is refused)."""
    import json

    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


def differing_settings(old: dict, new: dict) -> dict[str, tuple]:
    """{dotted key: (old value, new value)} of the settings that differ between two manifests' `settings`
    ("absent" for a key only one of them has)."""
    a, b = _flat(old), _flat(new)
    return {k: (a.get(k, "absent"), b.get(k, "absent")) for k in sorted(a.keys() | b.keys())
            if a.get(k, "absent") != b.get(k, "absent")}


def settings_difference(old: dict, new: dict, limit: int = 3) -> str:
    """The settings that differ between two manifests' `settings`, as "key: old -> new" (dotted keys, at most `limit`)."""
    diff = differing_settings(old, new)
    parts = [f"{k}: {a} -> {b}" for k, (a, b) in list(diff.items())[:limit]]
    return "; ".join(parts) + (f"; {len(diff) - limit} more" if len(diff) > limit else "")


def only_stop_checks_differ(old: dict, new: dict) -> bool:
    """Whether two manifests' `settings` differ, and only in the simulator's stop checks
    (`core.sim.STOP_CHECK_OPTIONS`): the sequences simulated under the old ones stay valid, as a run that
    completes gives the same cloth whatever they are, so such a dataset can be resumed."""
    from core.sim import STOP_CHECK_OPTIONS

    diff = differing_settings(old, new)
    return bool(diff) and all(k.startswith("solver.") and k[len("solver."):] in STOP_CHECK_OPTIONS for k in diff)


def item_frames(item: DatasetItem, settings: dict) -> int:
    """Frames simulated for `item`: its settle blend, pre-roll and clip."""
    return item.n_frames + item.preroll + int(settings.get("settle", 0))


def build_manifest(settings: dict, items: list[DatasetItem], splits: dict, betas: np.ndarray, inputs: dict,
                   software: dict) -> dict:
    """The manifest's content: settings (incl. material and solver), inputs' hashes, software, splits, items."""
    return {
        "format": "garment-dataset/1",
        "plan_key": plan_key(settings),
        "settings": settings,
        "inputs": inputs,
        "software": software,
        "betas": {"range": settings.get("betas_range"), "seed": settings.get("seed"),
                  "per_body": betas.round(6).tolist()},
        "splits": splits,
        "items": [asdict(it) | {"file": f"sequences/{it.id}.npz"} for it in items],
        "totals": {"items": len(items), "frames": int(sum(item_frames(it, settings) for it in items)),
                   "frames_per_split": {s: int(sum(item_frames(it, settings) for it in items if it.split == s))
                                        for s in ("train", "val", "test")}},
    }
