"""Make real exporters' files of a motion with Blender (from PyPI, `bpy`): a BVH or FBX imported into Blender and
written as UsdSkel (.usd/.usda/.usdc), COLLADA (.dae), glTF (.glb) or FBX, as Blender's own exporters write them;
or a Rigify rig generated in Blender, its left arm raised by its FK control, as FBX. What the motion readers were
checked against (README "Inputs"; `benchmarks/results/retarget_fidelity.md`); nothing here is run by the tests.

Blender is not a dependency of garment; run this in its own environment:
    python3 -m venv /tmp/bpyvenv && /tmp/bpyvenv/bin/pip install bpy==4.2.0
    /tmp/bpyvenv/bin/python benchmarks/blender_exports.py -- SOURCE.bvh OUT.usdc [--skinned] [--frame N] [--posed]
    /tmp/bpyvenv/bin/python benchmarks/blender_exports.py -- --rigify OUT.fbx

--skinned: a sphere bound to the armature with automatic weights (a skin: glTF, COLLADA and USD then hold a bind
pose); --frame N: the scene's frame when exporting (the pose some exporters write as the joints' own transforms);
--posed: glTF's joints written as they stand at that frame (`export_rest_position_armature` off).
"""
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
flags = {a for a in args if a.startswith("--")}
paths = [a for a in args if not a.startswith("--")]
frame = int(args[args.index("--frame") + 1]) if "--frame" in args else None
paths = [p for p in paths if p != str(frame)]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene

if "--rigify" in flags:
    import addon_utils  # Blender's: importable once bpy is

    out = paths[0]
    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    meta = bpy.context.object
    bpy.ops.pose.rigify_generate()
    rig = next(o for o in bpy.data.objects if o.type == "ARMATURE" and o != meta)
    bpy.data.objects.remove(meta)
    scene.frame_start, scene.frame_end = 1, 20
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="POSE")
    for bone in rig.pose.bones:
        if "IK_FK" in bone.keys():
            bone["IK_FK"] = 1.0  # the limbs follow their FK controls
    control = rig.pose.bones["upper_arm_fk.L"]
    control.rotation_mode = "XYZ"
    for f, angle in ((1, 0.0), (20, 1.2)):
        control.rotation_euler = (0.0, 0.0, angle)
        control.keyframe_insert("rotation_euler", frame=f)
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.ops.export_scene.fbx(filepath=out, bake_anim=True, use_armature_deform_only=True, add_leaf_bones=False)
    print("written", out)
    sys.exit(0)

source, out = paths[:2]
if source.lower().endswith(".bvh"):
    bpy.ops.import_anim.bvh(filepath=source, update_scene_fps=True, update_scene_duration=True)
else:
    bpy.ops.import_scene.fbx(filepath=source)
armature = next(o for o in scene.objects if o.type == "ARMATURE")
actions = list(bpy.data.actions)
if actions:
    scene.frame_start, scene.frame_end = (int(x) for x in actions[0].frame_range)
if "--skinned" in flags:
    bpy.ops.mesh.primitive_uv_sphere_add(radius=50.0, location=armature.location)
    mesh = bpy.context.object
    mesh.select_set(True)
    armature.select_set(True)
    bpy.context.view_layer.objects.active = armature
    bpy.ops.object.parent_set(type="ARMATURE_AUTO")
if frame is not None:
    scene.frame_set(frame)
suffix = out.lower().rsplit(".", 1)[-1]
if suffix in ("usd", "usda", "usdc"):
    bpy.ops.wm.usd_export(filepath=out, export_animation=True, export_armatures=True)
elif suffix == "dae":
    bpy.ops.wm.collada_export(filepath=out, include_animations=True, selected=False)
elif suffix == "glb":
    bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_animations=True,
                              export_rest_position_armature="--posed" not in flags)
elif suffix == "fbx":
    bpy.ops.export_scene.fbx(filepath=out, bake_anim=True, add_leaf_bones=False)
else:
    raise SystemExit(f"expected an OUT of .usd, .usda, .usdc, .dae, .glb or .fbx, got '{out}'")
print("written", out, "at", scene.render.fps, "fps")
