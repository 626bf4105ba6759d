"""Import a glTF into Blender headless and render one frame from its first camera (used by
cli/tests/export.rs where `blender` is installed).

Usage: blender -b --factory-startup --python tools/blender_gltf_check.py -- scene.gltf frame.png
Prints "BLENDER_GLTF_CHECK OK meshes=N cameras=M" on success; exits 1 on any failure.
"""
import sys

import bpy

try:
    import numpy

    # Debian 12's Blender 3.4 glTF importer uses `np.bool`, which NumPy 1.24 removed (its
    # python3-numpy): give the alias back so the importer runs.
    if not hasattr(numpy, "bool"):
        numpy.bool = bool
except ImportError:
    pass  # the importer says it needs numpy (Debian: apt-get install python3-numpy)

try:
    argv = sys.argv[sys.argv.index("--") + 1:]
    gltf, frame = argv[0], argv[1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=gltf)
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH"]
    cameras = [o for o in scene.objects if o.type == "CAMERA"]
    if not meshes or not cameras:
        raise RuntimeError(f"imported {len(meshes)} meshes and {len(cameras)} cameras")
    scene.camera = cameras[0]
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False  # Debian builds Cycles without OpenImageDenoise
    scene.render.resolution_x = 160
    scene.render.resolution_y = 120
    scene.render.resolution_percentage = 100
    scene.render.filepath = frame
    bpy.ops.render.render(write_still=True)
    print(f"BLENDER_GLTF_CHECK OK meshes={len(meshes)} cameras={len(cameras)}")
except Exception as e:  # report and fail the process, Blender otherwise exits 0
    print(f"BLENDER_GLTF_CHECK FAILED: {e}")
    sys.exit(1)
