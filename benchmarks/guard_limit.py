"""The contact guard and the strain limit alternating (`core.pushout.GUARD_LIMIT_ALTERNATIONS`, `guard_and_limit`):
vertices inside the body, torn frames, the post-processes' time and the error against the simulator, alternating
and once each (the guard, then the limit: before 2026-12-07).

    python benchmarks/guard_limit.py [--out benchmarks/results/guard_limit.md]

The shipped model (float32, one torch thread) on every example garment, on the example run and jump and the
held-out brisk walk's first 15 frames at 30 fps. Inside: vertices more than 2 mm inside the posed body
(`core.bake.penetration_stats`, every frame: mean and worst frame); torn: frames with an edge over twice its rest
length and 2 cm longer; post ms/frame: the guard's and the limit's `seconds_per_frame` together; error: the mean
vertex distance from the simulator's reference where `benchmarks/results/tradeoff_v5/<garment>_walk_brisk/
simulations/` holds one (20 substeps, self-contact). Nothing here is asserted by the tests.
"""

from __future__ import annotations

import platform

from example_scenes import benchmark_start, mean_error_mm, model_variants, write_report  # benchmarks/: its folder

from benchmarks.real_motion_stress import torn_frames
from core.bake import penetration_stats
from core.garment import mesh_edges
from core.geodesic import edge_lengths

#: (row name, constants): the guard's spread rounds and the limit once each (no top-up round), now.
VARIANTS = (("guard, then limit", {"GUARD_LIMIT_ALTERNATIONS": 1}), ("alternating", {}))


def main() -> None:
    out, body = benchmark_start(__doc__, "guard_limit.md")
    rows = []
    for scene, name, model, points in model_variants(body, ("run", "jump"), VARIANTS):
        garment = scene.garment
        edges = mesh_edges(garment.faces)
        torn = int(torn_frames(points, edges, edge_lengths(garment.vertices, edges)).sum())
        inside = penetration_stats(points, scene.posed, body.faces, max_frames=len(points))
        post_ms = 1e3 * (model.report["seconds_per_frame_guard"] + model.report["strain_limit"]["seconds_per_frame"])
        rows.append([scene.garment_name, scene.motion_name, name, f"{inside['mean_percent']:.2f}",
                     f"{inside['max_percent']:.2f}", torn, f"{post_ms:.1f}", mean_error_mm(points, scene.reference)])
        print(rows[-1], flush=True)
    write_report(out, "The contact guard and the strain limit alternating",
                 f"`python benchmarks/guard_limit.py` on {platform.processor() or platform.machine()}, one torch "
                 "thread: the shipped model, contact guard and strain limit on, 30 fps. Inside: vertices more than "
                 "2 mm inside the posed body (every frame); torn: frames with an edge over twice its rest length "
                 "and 2 cm longer; post: the guard's and the limit's time per frame; error: mean vertex distance "
                 "from the simulator's reference (20 substeps, self-contact) where one is stored.",
                 ["garment", "motion", "post-processes", "inside % mean", "inside % worst frame", "torn frames",
                  "post ms/frame", "error mm"], rows)


if __name__ == "__main__":
    main()
