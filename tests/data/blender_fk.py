"""Blender-side check: import a BVH headless and dump world joint (bone head) positions per frame as JSON.

Run as ``blender -b --factory-startup --python blender_fk.py -- IN.bvh OUT.json``. The armature is
imported with Blender's defaults (-Z forward, Y up, scale 1), so positions come back z-up in metres.
"""

import json
import sys

import bpy
from io_anim_bvh import import_bvh

_builtin_open = open


def _open_without_u(file, mode="r", *args, **kwargs):
    """Blender 3.4's importer opens with mode 'rU', which Python 3.11 refuses; drop the 'U'."""
    return _builtin_open(file, mode.replace("U", ""), *args, **kwargs)


import_bvh.open = _open_without_u


def main() -> None:
    src, dst = sys.argv[sys.argv.index("--") + 1 :]
    bpy.ops.import_anim.bvh(
        filepath=src,
        global_scale=1.0,
        axis_forward="-Z",
        axis_up="Y",
        rotate_mode="NATIVE",
        use_fps_scale=False,
    )
    obj = bpy.context.view_layer.objects.active
    scene = bpy.context.scene
    first, last = (round(f) for f in obj.animation_data.action.frame_range)
    names = [bone.name for bone in obj.pose.bones]
    frames = []
    for frame in range(first, last + 1):
        scene.frame_set(frame)
        frames.append([list(obj.matrix_world @ obj.pose.bones[name].head) for name in names])
    with open(dst, "w", encoding="utf-8") as handle:
        json.dump({"names": names, "frames": frames}, handle)


main()
