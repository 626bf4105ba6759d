#!/usr/bin/env python3
"""Make a hold-out room from a dev scene: a room the fit was not tuned on (not part of CI).

The dev scenes are what every choice in the fit was measured on; the rooms photoscene is judged
on are made the same way with other textures and furniture. This keeps a dev scene's geometry,
furniture, cameras and label images and redraws what the fit has to find:

- the walls, floor, ceiling and rug (and any part with a generated texture) get a new kind
  (planks, plaster, a photo texture, stripes or a plain colour), drawn per part;
- textured parts take a texture of that kind from the dev scenes' pool, recoloured (a new mean
  colour and contrast) under a new uv transform (rotation, scale, offset); stripes are new
  bands of 3–5 colours; plain parts a new colour; every redrawn part a new roughness; the
  colours' brightness is drawn per kind of part in the ranges the dev scenes show (light
  ceilings and walls, dark floors): drawn wider, a room's unobserved walls came out dark,
  where the fit's documented mid-grey default is then judged against a colour no dev scene has;
- the lights new radiances (a scale and a tint each) and new relit radiances.

The furniture's own textures stay. The photos, the novel and relit views and the linear views
are rendered by `psc render` (truth materials on the true geometry, 256 spp), which agrees with
the Mitsuba 3 renders of the dev scenes (`tools/mitsuba_check.py`); so a hold-out room differs
from a judged one in its renderer's noise and its texture pool (the dev scenes' own, recoloured),
not its format: `psc fit` and `psc eval` read it as they read a dev scene.

Setup: `pip install numpy pillow`, `cargo build --release -p psc`.

Usage:
    python3 tools/holdout_room.py ../shared/scenes/dev_2 --seed 101 --out holdout/g2
    mkdir fit_in && (cd holdout/g2 && tar cf - --exclude=truth .) | (cd fit_in && tar xf -)
    psc fit fit_in --out fitted_g2/ && psc eval fitted_g2/ holdout/g2

The README's hold-out rooms are dev_1 … dev_4 at seeds 111, 101, 103, 114.
"""
import argparse
import json
import os
import shutil
import subprocess
import tempfile

import numpy as np
from PIL import Image

GENERATED = ("planks", "plaster", "photo", "stripes")
# The kinds each large part is drawn from; other generated-texture parts get a textured kind.
LARGE_PART_KINDS = {
    "floor": ["planks", "planks", "plain", "plaster"],
    "ceiling": ["plain", "plaster"],
    "walls": ["plaster", "photo", "stripes", "plain"],
    "rug": ["stripes", "stripes", "plaster", "photo"],
}
# Linear mean albedo per large part, as the dev scenes' (their ceilings and walls light, their
# floors dark); other parts take DEFAULT_BRIGHTNESS.
BRIGHTNESS = {"ceiling": (0.45, 0.85), "walls": (0.3, 0.75), "floor": (0.05, 0.4), "rug": (0.05, 0.6)}
DEFAULT_BRIGHTNESS = (0.05, 0.6)
TEXTURE_SIZE = 512


def srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)


def save_linear(img, path):
    Image.fromarray((linear_to_srgb(img) * 255 + 0.5).astype(np.uint8)).save(path, quality=92)


def tinted(rng, brightness, concentration):
    """A linear colour of mean `brightness`, its hue the further from grey the lower
    `concentration` is."""
    return brightness * rng.dirichlet([concentration] * 3) * 3


def recoloured(rng, src, dst, brightness):
    """Writes `src` with a new mean colour (of a brightness in the given range) and contrast;
    returns its linear mean."""
    img = srgb_to_linear(np.asarray(Image.open(src).convert("RGB")).astype(np.float64) / 255)
    mean = img.reshape(-1, 3).mean(0)
    img = img / np.maximum(mean, 1e-4) * tinted(rng, rng.uniform(*brightness), 12)
    centre = img.mean((0, 1))
    img = (img - centre) * rng.uniform(0.7, 1.3) + centre
    save_linear(img, dst)
    return np.clip(img, 0, 1).reshape(-1, 3).mean(0)


def stripes(rng, dst, brightness):
    """Writes bands of 3–5 colours across the rows with a weave and a fibre noise (the band
    sequence repeats down the image, cut where the image ends; the weave's period divides its
    size); returns its mean."""
    n = rng.integers(3, 6)
    colours = np.array([np.clip(tinted(rng, rng.uniform(0.03, brightness[1]), 5), 0.005, 0.9) for _ in range(n)])
    # The colours in a fixed order, once at each of n band widths.
    band_of_row = np.concatenate([np.repeat(np.arange(n), w) for w in rng.integers(12, 60, n)])
    band_of_row = np.resize(band_of_row, TEXTURE_SIZE)
    img = np.repeat(colours[band_of_row][:, None, :], TEXTURE_SIZE, axis=1)
    wave = np.sin(np.arange(TEXTURE_SIZE) * 2 * np.pi / 4)
    img = img * (1 + 0.08 * wave[None, :, None] * wave[:, None, None])
    img = img * rng.normal(1, 0.04, (TEXTURE_SIZE, TEXTURE_SIZE, 1))
    save_linear(img, dst)
    return np.clip(img, 0, 1).reshape(-1, 3).mean(0)


def uv_transform(rng):
    turn = np.radians(rng.choice([0, 90, 180, 270]) + rng.uniform(-15, 15))
    scale = 1 / rng.uniform(0.6, 1.6) * rng.uniform(0.7, 1.3)
    c, s = np.cos(turn) * scale, np.sin(turn) * scale
    return [[float(c), float(-s), float(rng.uniform(0, 1))], [float(s), float(c), float(rng.uniform(0, 1))]]


def texture_pool(scenes_dir):
    """Per kind, the generated textures of every scene beside the base, each once (from the last
    scene, in name order, that has it), in path order."""
    pool = {}
    for scene in sorted(os.listdir(scenes_dir)):
        folder = os.path.join(scenes_dir, scene, "truth", "textures")
        if not os.path.isdir(folder):
            continue
        for f in sorted(os.listdir(folder)):
            kind = f.split("_")[0]
            if kind in GENERATED:
                pool.setdefault(kind, {})[f] = os.path.join(folder, f)
    return {k: sorted(v.values()) for k, v in pool.items()}


def make_writable(tree):
    """The shared scenes are read-only, and copies keep their modes."""
    os.chmod(tree, os.stat(tree).st_mode | 0o200)
    for root, dirs, files in os.walk(tree):
        for name in dirs + files:
            path = os.path.join(root, name)
            os.chmod(path, os.stat(path).st_mode | 0o200)


def copy_inputs(base, out):
    """The scene without its photos' content: the base's photos are copied as stand-ins (a
    scene loads only with its photos present) and rendered over."""
    shutil.copytree(base, out, ignore=shutil.ignore_patterns("truth"))
    make_writable(out)
    truth = os.path.join(out, "truth")
    shutil.copytree(os.path.join(base, "truth", "textures"), os.path.join(truth, "textures"))
    make_writable(truth)
    os.makedirs(os.path.join(truth, "novel"))
    os.makedirs(os.path.join(truth, "relit"))
    for f in os.listdir(os.path.join(base, "truth", "novel")):
        if f.endswith("_parts.png"):
            shutil.copyfile(os.path.join(base, "truth", "novel", f), os.path.join(truth, "novel", f))
    for f in ("scene_true.obj", "scene_true.mtl"):
        if os.path.exists(os.path.join(base, "truth", f)):
            shutil.copyfile(os.path.join(base, "truth", f), os.path.join(truth, f))


def redraw_parts(rng, truth, pool, out, seed):
    for i, part in enumerate(truth["parts"]):
        name = part["name"]
        key = "walls" if name.startswith("walls") else name
        if key in LARGE_PART_KINDS:
            kind = str(rng.choice(LARGE_PART_KINDS[key]))
        elif part["kind"] in GENERATED:
            kind = str(rng.choice(["planks", "plaster", "photo"]))
        elif part["kind"] == "plain":
            kind = "plain"
        else:
            continue
        part["kind"] = kind
        part["roughness"] = round(float(rng.uniform(0.3, 0.85)), 3)
        part.pop("texture_info", None)
        brightness = BRIGHTNESS.get(key, DEFAULT_BRIGHTNESS)
        if kind == "plain":
            colour = [round(float(x), 6) for x in np.clip(tinted(rng, rng.uniform(*brightness), 15), 0.01, 0.95)]
            part["albedo"] = {"rgb_linear": colour}
            part["albedo_mean_linear"] = colour
            continue
        file = f"{kind}_h{seed}_{i}.jpg"
        dst = os.path.join(out, "truth", "textures", file)
        if kind == "stripes":
            mean = stripes(rng, dst, brightness)
        else:
            mean = recoloured(rng, str(rng.choice(pool[kind])), dst, brightness)
        part["albedo"] = {"texture": f"textures/{file}", "encoding": "sRGB", "uv_transform": uv_transform(rng),
                          "wrap": "repeat", "filter": "bilinear"}
        part["albedo_mean_linear"] = [round(float(x), 6) for x in mean]
        part["texture_info"] = {"generator": kind, "holdout_seed": seed}


def drop_unused_textures(truth, work):
    """The base's textures of the parts redrawn are not this room's: left in truth/textures,
    they would pass for part of its truth."""
    used = {os.path.basename(p["albedo"]["texture"]) for p in truth["parts"] if "texture" in p["albedo"]}
    folder = os.path.join(work, "truth", "textures")
    for f in os.listdir(folder):
        if f not in used:
            os.remove(os.path.join(folder, f))


def redraw_lights(rng, truth):
    for light in truth["lights"]:
        tint = rng.dirichlet([20, 20, 20]) * 3
        scale = rng.uniform(0.6, 1.2)
        light["radiance_rgb"] = [float(x * scale * t) for x, t in zip(light["radiance_rgb"], tint)]
        relit = rng.uniform(0.5, 2.0) * rng.dirichlet([20, 20, 20]) * 3
        light["relit_radiance_rgb"] = [float(x * s) for x, s in zip(light["radiance_rgb"], relit)]


def build(args, rng, pool, work):
    """Writes the room into `work`; returns its truth."""
    copy_inputs(args.base, work)
    truth_path = os.path.join(work, "truth", "truth.json")
    truth = json.load(open(os.path.join(args.base, "truth", "truth.json")))
    truth["scene"] = os.path.basename(os.path.normpath(args.out))
    truth["split"] = "holdout"
    truth["renderer"] = f"psc render, truth materials on the true geometry, {args.spp} spp (tools/holdout_room.py)"
    redraw_parts(rng, truth, pool, work, args.seed)
    drop_unused_textures(truth, work)
    redraw_lights(rng, truth)
    with open(truth_path, "w") as f:
        json.dump(truth, f, indent=1)

    def render(camera, size, dst, lights="truth"):
        with tempfile.NamedTemporaryFile("w", suffix=".json") as cam:
            json.dump({"camera": camera}, cam)
            cam.flush()
            run = subprocess.run([args.psc, "render", work, "--geometry", "truth", "--materials", "truth",
                                  "--lights", lights, "--spp", str(args.spp), "--seed", str(args.seed),
                                  "--camera", cam.name, "--size", size, "--out", os.path.join(work, dst)],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if run.returncode != 0:
                errors = [line for line in run.stderr.splitlines() if line.startswith("error")]
                raise RuntimeError(f"psc render {dst}: {(errors or [run.stderr.strip()])[0]}")

    scene = json.load(open(os.path.join(work, "scene.json")))
    sizes = {}
    for view in scene["views"]:
        w, h = Image.open(os.path.join(work, view["image"])).size
        sizes[view["name"]] = f"{w}x{h}"
        render(view["camera"], sizes[view["name"]], view["image"])
        if view["name"] in truth.get("linear_views", {}):
            render(view["camera"], sizes[view["name"]], truth["linear_views"][view["name"]])
    first = next(iter(sizes.values()))
    for novel in truth["novel_views"]:
        render(novel["camera"], first, novel["image"])
    with tempfile.NamedTemporaryFile("w", suffix=".json") as relit:
        json.dump({"lights": [{"name": l["name"], "radiance_rgb": l["relit_radiance_rgb"]} for l in truth["lights"]]},
                  relit)
        relit.flush()
        for view in truth["relit_views"]:
            # Only this key's radiances are redrawn (redraw_lights).
            if view.get("radiance_key", "relit_radiance_rgb") != "relit_radiance_rgb":
                raise ValueError(f"relit view {view['name']}: radiance_key {view['radiance_key']} is not redrawn")
            render(view["camera"], sizes.get(view.get("view"), first), view["image"], lights=relit.name)
    return truth


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("base", help="a dev scene folder (with truth/)")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True, help="the new scene folder (must not exist)")
    ap.add_argument("--psc", default="target/release/psc")
    ap.add_argument("--spp", type=int, default=256)
    args = ap.parse_args()
    if os.path.exists(args.out):
        ap.error(f"{args.out} exists")
    rng = np.random.default_rng(args.seed)
    pool = texture_pool(os.path.dirname(os.path.abspath(args.base)))
    # Built beside its destination and renamed into place when whole: an interrupted run
    # leaves no room with the base's photos standing in for its own.
    work = os.path.join(os.path.dirname(os.path.abspath(args.out)), f".holdout-tmp-{os.getpid()}")
    try:
        truth = build(args, rng, pool, work)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    os.rename(work, args.out)
    print(args.out, ", ".join(f"{p['name']}: {p['kind']}" for p in truth["parts"] if p["kind"] != "model_texture"))


if __name__ == "__main__":
    main()
