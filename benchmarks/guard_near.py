"""The contact guard's nearest-vertex planes (`core.pushout.GUARD_NEAR_FROM_M`, `GUARD_NEAR_TO_M`): vertices inside
the body, the guard's time and the error against the simulator, with them and without (before 2026-12-06).

    python benchmarks/guard_near.py [--out benchmarks/results/guard_near.md]

The shipped model (float32, contact guard and strain limit on, one torch thread) on every example garment, on the
example run and jump and the held-out brisk walk's first 15 frames at 30 fps. Inside: vertices more than 2 mm
inside the posed body (`core.bake.penetration_stats`, every frame: mean and worst frame); guard ms/frame: the
deformer's `seconds_per_frame_guard`; error: the mean vertex distance from the simulator's reference where
`benchmarks/results/tradeoff_v5/<garment>_walk_brisk/simulations/` holds one (20 substeps, self-contact).
Writes benchmarks/results/guard_near.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import platform

from example_scenes import benchmark_start, mean_error_mm, model_variants, write_report  # benchmarks/: its folder

from core.bake import penetration_stats

#: (row name, constants): the anchors' planes alone (beyond any lateral distance), now.
VARIANTS = (("anchor planes alone", {"GUARD_NEAR_FROM_M": 1e3, "GUARD_NEAR_TO_M": 1e3 + 0.02}),
            ("nearest vertex beyond", {}))


def main() -> None:
    out, body = benchmark_start(__doc__, "guard_near.md")
    rows = []
    for scene, name, model, points in model_variants(body, ("run", "jump"), VARIANTS):
        inside = penetration_stats(points, scene.posed, body.faces, max_frames=len(points))
        guard_ms = model.report.get("seconds_per_frame_guard", float("nan")) * 1e3
        rows.append([scene.garment_name, scene.motion_name, name, f"{inside['mean_percent']:.2f}",
                     f"{inside['max_percent']:.2f}", f"{guard_ms:.1f}", mean_error_mm(points, scene.reference)])
        print(rows[-1], flush=True)
    write_report(out, "The contact guard's nearest-vertex planes",
                 f"`python benchmarks/guard_near.py` on {platform.processor() or platform.machine()}, one torch "
                 "thread: the shipped model, contact guard and strain limit on, 30 fps. Inside: vertices more than "
                 "2 mm inside the posed body (every frame); guard: its time per frame; error: mean vertex distance "
                 "from the simulator's reference (20 substeps, self-contact) where one is stored.",
                 ["garment", "motion", "guard", "inside % mean", "inside % worst frame", "guard ms/frame",
                  "error mm"], rows)


if __name__ == "__main__":
    main()
