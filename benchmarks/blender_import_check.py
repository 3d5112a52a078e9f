"""Check that real Blender imports a baked USD stage and sees the garment and body move.

Blender is not a dependency of garment; run this in its own environment (Blender keeps its own USD build):
    python3 -m venv /tmp/bpyvenv && /tmp/bpyvenv/bin/pip install bpy
    garment bake examples/dress.obj examples/walk.npz --out /tmp/bake
    /tmp/bpyvenv/bin/python benchmarks/blender_import_check.py -- /tmp/bake/dress_walk/dress_walk.usd
Result on 2026-11-24 (bpy 5.x): benchmarks/results/blender_import_check.md.
"""
import sys
import bpy
import numpy as np

path = sys.argv[-1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=path)
scene = bpy.context.scene
print("frame range", scene.frame_start, scene.frame_end, "fps", scene.render.fps)
deps = bpy.context.evaluated_depsgraph_get()
for obj in scene.objects:
    if obj.type != "MESH":
        continue
    pts = []
    for f in (0, 30):
        scene.frame_set(f)
        deps = bpy.context.evaluated_depsgraph_get()
        ev = obj.evaluated_get(deps)
        me = ev.to_mesh()
        a = np.array([v.co[:] for v in me.vertices])
        ev.to_mesh_clear()
        pts.append(a)
    print(obj.name, "vertices", len(pts[0]), "moved (max m)", float(np.abs(pts[1] - pts[0]).max()),
          "modifiers", [m.type for m in obj.modifiers])
