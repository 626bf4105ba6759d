#!/usr/bin/env python3
"""Render a `psc export` folder's scene_mitsuba.xml with Mitsuba 3 and compare it with an image
of `psc render` of the same scene, assignment, lights and view (used by cli/tests/export.rs).

Usage:
    python3 tools/export_mitsuba_check.py EXPORT_DIR PSC_IMAGE.exr [--view view0]
           [--size 160x120] [--spp 32] [--variant scalar_rgb] [--out mitsuba.exr]
           [--perturb drop-light|linear-albedo]

The XML is loaded as exported, except that the chosen sensor's film is resized to --size (a
copy of the XML with that change is written beside it and removed afterwards). --perturb
breaks the scene on purpose (a negative control: the comparison must then fail its tolerance). Prints one JSON
line: the image means (linear RGB) over the pixels that show no emitter in either image, their
ratio per channel and overall, and the mean relative difference of 8x8-pixel block means of luminance (noise mostly averaged out), as
tools/mitsuba_check.py measures. Exit 0 once the numbers are printed; 2 when Mitsuba is missing.
"""
import argparse
import json
import os
import sys
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

try:
    import numpy as np
    import mitsuba as mi
    from image_compare import figures
except ImportError as e:  # the caller prints the SKIPPED line
    print(f"mitsuba not available: {e}", file=sys.stderr)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("export_dir")
    ap.add_argument("psc_image")
    ap.add_argument("--view", default="view0")
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--out")
    ap.add_argument("--diffuse", action="store_true",
                    help="replace every principled BSDF by Lambert (compare with psc render --diffuse-only)")
    ap.add_argument("--perturb", choices=["drop-light", "linear-albedo"],
                    help="negative control: drop the first light, or read the sRGB base colours as linear")
    args = ap.parse_args()
    mi.set_variant(args.variant)
    w, h = (int(x) for x in args.size.lower().split("x"))
    src = os.path.join(args.export_dir, "scene_mitsuba.xml")
    tree = ET.parse(src)
    sensors = tree.getroot().findall("sensor")
    index = next(i for i, s in enumerate(sensors) if s.get("id") == args.view)
    film = sensors[index].find("film")
    for e in film.findall("integer"):
        e.set("value", str(w if e.get("name") == "width" else h))
    if args.perturb == "drop-light":
        root = tree.getroot()
        root.remove(next(s for s in root.findall("shape") if s.get("id", "").startswith("light:")))
    elif args.perturb == "linear-albedo":
        for tex in tree.getroot().iter("texture"):
            if tex.get("name") == "base_color":
                next(b for b in tex.findall("boolean") if b.get("name") == "raw").set("value", "true")
    if args.diffuse:
        for b in tree.getroot().iter("bsdf"):
            if b.get("type") == "principled":
                keep = [c for c in b if c.get("name") == "base_color"]
                for c in list(b):
                    b.remove(c)
                b.set("type", "diffuse")
                for c in keep:
                    c.set("name", "reflectance")
                    b.append(c)
    tmp = os.path.join(args.export_dir, ".check_scene_mitsuba.xml")
    tree.write(tmp)
    try:
        scene = mi.load_file(tmp, spp=str(args.spp))
    finally:
        os.remove(tmp)
    img = np.array(mi.render(scene, sensor=index, spp=args.spp, seed=1)).astype(np.float64)[..., :3]
    if args.out:
        mi.Bitmap(img.astype(np.float32)).write(args.out)
    ref = np.array(mi.Bitmap(args.psc_image)).astype(np.float64)[..., :3]
    if ref.shape != img.shape:
        print(f"image sizes differ: psc {ref.shape}, mitsuba {img.shape}", file=sys.stderr)
        sys.exit(1)
    print(json.dumps({**figures(img, ref, "mitsuba"), "mitsuba": mi.__version__, "variant": args.variant}))


if __name__ == "__main__":
    main()
