"""Check that real Blender imports a baked USD stage and sees the garment and body move, and that the garment's
materials (preview shaders bound to its subsets in the USD; the copied .mtl of the OBJ frames) come in with
their colours, opacity and textures.

Blender is not a dependency of garment; run this in its own environment (Blender keeps its own USD build):
    python3 -m venv /tmp/bpyvenv && /tmp/bpyvenv/bin/pip install bpy
    garment bake examples/dress.obj examples/walk.npz --out /tmp/bake
    /tmp/bpyvenv/bin/python benchmarks/blender_import_check.py -- /tmp/bake/dress_walk/dress_walk.usd \
        [/tmp/bake/dress_walk/obj/frame_0000.obj]
Results: benchmarks/results/blender_import_check.md.
"""
import os
import sys

import bpy
import numpy as np

paths = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[-1:]


def materials_report(label: str) -> None:
    """Each mesh's material slots: base colour, alpha, image textures (path, whether it loads, size), faces."""
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH" or not obj.material_slots:
            continue
        faces = np.bincount([p.material_index for p in obj.data.polygons], minlength=len(obj.material_slots))
        for slot, n in zip(obj.material_slots, faces.tolist()):
            m = slot.material
            nodes = m.node_tree.nodes if m and m.use_nodes else []
            bsdf = next((node for node in nodes if node.type == "BSDF_PRINCIPLED"), None)
            images = [(node.image.filepath, os.path.isfile(bpy.path.abspath(node.image.filepath)),
                       tuple(node.image.size)) for node in nodes if node.type == "TEX_IMAGE" and node.image]
            base = tuple(round(x, 3) for x in bsdf.inputs["Base Color"].default_value[:3]) if bsdf else None
            alpha = round(bsdf.inputs["Alpha"].default_value, 3) if bsdf else None
            print(label, obj.name, "material", m.name if m else None, "faces", n, "base colour", base,
                  "alpha", alpha, "images (path, found, size)", images)


bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=paths[0])
scene = bpy.context.scene
print("frame range", scene.frame_start, scene.frame_end, "fps", scene.render.fps)
for obj in scene.objects:
    if obj.type != "MESH":
        continue
    pts = []
    for f in (0, min(30, scene.frame_end)):
        scene.frame_set(f)
        deps = bpy.context.evaluated_depsgraph_get()
        ev = obj.evaluated_get(deps)
        me = ev.to_mesh()
        a = np.array([v.co[:] for v in me.vertices])
        ev.to_mesh_clear()
        pts.append(a)
    print(obj.name, "vertices", len(pts[0]), "moved (max m)", float(np.abs(pts[1] - pts[0]).max()),
          "modifiers", [m.type for m in obj.modifiers])
materials_report("USD")
if len(paths) > 1:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=paths[1])
    materials_report("OBJ")
