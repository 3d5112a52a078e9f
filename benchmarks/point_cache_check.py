"""Check that real Blender plays `bake --point-cache` files on the garment as it imports the garment's own OBJ
(its points kept in the file's Y-up frame, the object turned to Blender's Z-up): a Mesh Cache modifier (PC2 and
MDD) on the imported garment, its settings as they come but its Frame Start set to the bake's --start-frame, puts
every vertex where the bake's OBJ frame puts it in the world.

Blender is not a dependency of garment; run this in its own environment:
    python3 -m venv /tmp/bpyvenv && /tmp/bpyvenv/bin/pip install bpy
    garment bake examples/tshirt.obj examples/walk.npz --method lbs --point-cache pc2 --point-cache mdd \
        --start-frame 1 --out /tmp/bake
    /tmp/bpyvenv/bin/python benchmarks/point_cache_check.py -- examples/tshirt.obj /tmp/bake/tshirt_walk
Results: benchmarks/results/point_cache_check.md.
"""
import json
import sys
from pathlib import Path

import bpy
import numpy as np

garment, baked = (Path(p) for p in sys.argv[sys.argv.index("--") + 1:][:2])


def obj_points(path: Path) -> np.ndarray:
    """An OBJ frame's points in the bake's Z-up world (frames written Y-up, as sequence.json's 'up' says since
    2026-12-06, turned back: (x, y, z) -> (x, -z, y), where Blender's import puts them)."""
    points = np.array([[float(x) for x in line.split()[1:4]] for line in path.read_text().splitlines()
                       if line.startswith("v ")])
    return np.stack([points[:, 0], -points[:, 2], points[:, 1]], axis=1) if meta.get("up") == "y" else points


meta = json.loads((baked / "obj" / "sequence.json").read_text())
frames = sorted((baked / "obj").glob("*.obj"))
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath=str(garment))  # Blender's defaults: forward -Z, up Y
obj = bpy.context.selected_objects[0]
scene = bpy.context.scene
scene.render.fps = int(round(meta["fps"]))
print("imported", obj.name, "vertices", len(obj.data.vertices), "OBJ frame vertices", len(obj_points(frames[0])),
      "Blender", bpy.app.version_string)
for kind in ("pc2", "mdd"):
    cache = obj.modifiers.new(f"cache_{kind}", "MESH_CACHE")
    cache.cache_format = kind.upper()
    cache.filepath = str(baked / f"{baked.name}.{kind}")
    cache.frame_start = meta["start"]  # the scene frame of the cache's first sample: the bake's --start-frame
    worst = 0.0
    for k, frame in enumerate(frames):
        scene.frame_set(meta["start"] + k)
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        points = np.array([obj.matrix_world @ v.co for v in mesh.vertices])
        evaluated.to_mesh_clear()
        worst = max(worst, float(np.abs(points - obj_points(frame)).max()))
    print(kind, "frames", len(frames), "from scene frame", meta["start"], "max distance to the bake's OBJ frames (m)",
          f"{worst:.2e}")
    obj.modifiers.remove(cache)
