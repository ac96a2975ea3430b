"""Run inside Blender (`blender -b --factory-startup --python tests/blender_import.py -- IN.bvh OUT.json`): import a
BVH with Blender's own importer and write the armature's joint (bone head) positions at some frames as JSON."""

import builtins
import json
import sys

import bpy

# Debian's Blender 3.4 BVH add-on opens files with mode "rU", which Python 3.11 removed: map it to "r".
_open = builtins.open
builtins.open = lambda f, mode="r", *a, **k: _open(f, mode.replace("U", ""), *a, **k)

path, out = sys.argv[-2], sys.argv[-1]
bpy.ops.import_anim.bvh(filepath=path, global_scale=1.0, frame_start=1, use_fps_scale=False, axis_forward="-Z", axis_up="Y")
armature = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
frames = {}
for frame in (1, 5, 10):
    bpy.context.scene.frame_set(frame)
    bpy.context.view_layer.update()
    frames[frame] = {b.name: list(armature.matrix_world @ b.head) for b in armature.pose.bones}
with _open(out, "w") as f:
    json.dump(frames, f)
