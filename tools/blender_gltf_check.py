"""Import a glTF into Blender headless and render one frame from its first camera (used by
cli/tests/export.rs where `blender` is installed); optionally compare the frame with an image
of `psc render` of the same scene, assignment, lights and view.

Usage:
    blender -b --factory-startup --python tools/blender_gltf_check.py -- scene.gltf frame.png
    blender -b --factory-startup --python tools/blender_gltf_check.py -- scene.gltf frame.exr \
        --compare psc.exr [--spp 32] [--diffuse] [--perturb drop-light|linear-albedo]

Prints "BLENDER_GLTF_CHECK OK meshes=N cameras=M" on success; exits 1 on any failure. With
--compare the frame is rendered as psc renders (Cycles on the CPU, linear EXR at the size of
the psc image, path depth 6 in Mitsuba's convention, a box filter, no clamping, no denoising,
the "Standard" view transform) and one JSON line comes before the OK line, with the figures
tools/export_mitsuba_check.py prints: image means over the pixels where neither image shows
an emitter, their ratio per channel and overall, and the mean relative difference of 8x8-pixel
block means of luminance. --diffuse replaces every principled BSDF by a diffuse one of the same
colour and normal (compare with `psc render --diffuse-only`). --perturb breaks the imported
scene on purpose (a negative control: the comparison must then fail its tolerance): the first
light mesh deleted, or the base-colour textures read as linear instead of sRGB.
"""
import json
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

try:
    import numpy as np

    # Debian 12's Blender 3.4 glTF importer uses `np.bool`, which NumPy 1.24 removed (its
    # python3-numpy): give the alias back so the importer runs.
    if not hasattr(np, "bool"):
        np.bool = bool
    from image_compare import figures
except ImportError:
    np = None  # the importer says it needs numpy (Debian: apt-get install python3-numpy)


def option(argv, name, default=None):
    return argv[argv.index(name) + 1] if name in argv else default


def load_rgb(path):
    """An image as float64 H x W x 3 (rows bottom-up, as Blender stores them; both images alike)."""
    image = bpy.data.images.load(path)
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(h, w, 4)[..., :3].astype(np.float64)


def perturb(scene, what):
    if what == "drop-light":
        lights = [o for o in scene.objects if o.active_material and o.active_material.name.startswith("light:")]
        if not lights:
            raise RuntimeError("no light mesh to drop")
        bpy.data.objects.remove(min(lights, key=lambda o: o.name), do_unlink=True)
    elif what == "linear-albedo":
        for material in bpy.data.materials:
            if material.node_tree is None:
                continue
            for link in material.node_tree.links:
                if link.to_socket.name == "Base Color" and link.from_node.type == "TEX_IMAGE":
                    link.from_node.image.colorspace_settings.name = "Non-Color"
    else:
        raise RuntimeError(f"unknown --perturb {what}")


def lambert(material):
    """Replace the material's principled BSDF by a diffuse one with the same colour and normal
    (what `psc render --diffuse-only` shades with); emitters are left as they are."""
    tree = material.node_tree
    if tree is None or material.name.startswith("light:"):
        return
    for principled in [n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"]:
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        for name in ("Base Color", "Normal"):
            source = principled.inputs[name]
            target = diffuse.inputs["Color" if name == "Base Color" else "Normal"]
            if source.is_linked:
                tree.links.new(source.links[0].from_socket, target)
            elif name == "Base Color":
                target.default_value = source.default_value
        for link in list(principled.outputs["BSDF"].links):
            tree.links.new(diffuse.outputs["BSDF"], link.to_socket)
        tree.nodes.remove(principled)


def compare_settings(scene, reference, spp):
    h, w = reference.shape[:2]
    scene.render.resolution_x = w
    scene.render.resolution_y = h
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.cycles.samples = spp
    scene.cycles.seed = 1
    # Mitsuba's max_depth 6 (psc render's default): the camera ray, then up to five bounces;
    # Cycles counts bounces after the first hit.
    scene.cycles.max_bounces = 5
    scene.cycles.diffuse_bounces = 5
    scene.cycles.glossy_bounces = 5
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    scene.view_settings.view_transform = "Standard"


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    gltf, frame = argv[0], argv[1]
    reference_path = option(argv, "--compare")
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
    reference = None
    if reference_path:
        if np is None:
            raise RuntimeError("--compare needs numpy (apt-get install python3-numpy)")
        reference = load_rgb(reference_path)
        compare_settings(scene, reference, int(option(argv, "--spp", "32")))
    if option(argv, "--perturb"):
        perturb(scene, option(argv, "--perturb"))
    if "--diffuse" in argv:
        for material in bpy.data.materials:
            lambert(material)
    scene.render.filepath = frame
    bpy.ops.render.render(write_still=True)
    if reference is not None:
        img = load_rgb(frame)
        if img.shape != reference.shape:
            raise RuntimeError(f"image sizes differ: psc {reference.shape}, blender {img.shape}")
        print(json.dumps({**figures(img, reference, "blender"), "blender": bpy.app.version_string}))
    print(f"BLENDER_GLTF_CHECK OK meshes={len(meshes)} cameras={len(cameras)}")


try:
    main()
except Exception as e:  # report and fail the process, Blender otherwise exits 0
    print(f"BLENDER_GLTF_CHECK FAILED: {e}")
    sys.exit(1)
