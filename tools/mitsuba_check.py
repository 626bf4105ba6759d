#!/usr/bin/env python3
"""Cross-check `psc render` against Mitsuba 3 on a dev scene (not part of CI).

Renders the same scene, camera, materials, lights and sample count with both renderers and
prints their differences, then times both at the same settings.

Setup (Debian):
    pip install mitsuba numpy
    apt-get update && apt-get install -y libllvm19
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so
    cargo build --release -p psc

Usage:
    python3 tools/mitsuba_check.py ../shared/scenes/dev_1 [--spp 64] [--size 320x240]
           [--checks diffuse,karis,aov,truth,time] [--psc target/release/psc]

Checks:
  diffuse  Lambertian materials (Mitsuba `diffuse`, psc `--diffuse-only`), truth textures.
  karis    The Karis BRDF: a Python BSDF plugin in Mitsuba with the exact formulas of
           render/src/brdf.rs (the same model the dev scenes' truth images were made with).
  aov      G-buffer uv / geometric normal / part id against Mitsuba's `aov` integrator.
  truth    psc vs the scene's own truth/view0.exr (Mitsuba, 256 spp).
  time     320x240 (or --size) at --spp: wall and CPU seconds, samples/s, for both.

Metrics: relative difference of the image means (bias), mean per-pixel relative difference of
luminance (includes both renderers' Monte Carlo noise) and the same on 8x8-pixel block means
(noise mostly averaged out). Geometry is truth/scene_true.obj, materials truth/truth.json,
light radiances from truth.json: the dev-scene ground truth.
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

# The BSDF base class exists only once a variant is set: pick it before defining the plugin.
VARIANT = sys.argv[sys.argv.index("--variant") + 1] if "--variant" in sys.argv else "llvm_ad_rgb"
mi.set_variant(VARIANT)

F0 = 0.05


def cpu_self():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def cpu_children():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


# ----------------------------------------------------------------------------- Karis BSDF
class Karis(mi.BSDF):
    """f = albedo/pi + D F G / (4 n.v n.l), exactly as render/src/brdf.rs (incl. sampling)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        albedo = props["reflectance"]
        if not isinstance(albedo, mi.Texture):  # a constant arrives as a colour
            albedo = mi.load_dict({"type": "rgb", "value": [float(albedo[0]), float(albedo[1]), float(albedo[2])]})
        self.albedo = albedo
        self.r = dr.clip(mi.Float(props["roughness"]), 0.02, 1.0)
        flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
        self.m_components = [flags]
        self.m_flags = flags

    def _terms(self, si, wi, wo):
        r = self.r
        a = r * r
        a2 = a * a
        h = dr.normalize(wi + wo)
        nh = mi.Frame3f.cos_theta(h)
        vh = dr.maximum(dr.dot(wi, h), 0.0)
        d = nh * nh * (a2 - 1.0) + 1.0
        D = a2 / (dr.pi * d * d)
        F = F0 + (1.0 - F0) * dr.exp2((-5.55473 * vh - 6.98316) * vh)
        k = (r + 1.0) * (r + 1.0) / 8.0
        ci = mi.Frame3f.cos_theta(wi)
        co = mi.Frame3f.cos_theta(wo)
        G = ci / (ci * (1.0 - k) + k) * co / (co * (1.0 - k) + k)
        spec = D * F * G / (4.0 * ci * co)
        albedo = self.albedo.eval(si)
        # sampling lobe probability: same as Karis::specular_probability
        s = F0 + (1.0 - F0) * dr.exp2((-5.55473 * ci - 6.98316) * ci)
        lum = mi.luminance(albedo)
        ps = dr.clip(s / (s + lum), 0.1, 0.9)
        pdf = ps * D * nh / (4.0 * dr.maximum(dr.abs(dr.dot(wi, h)), 1e-8)) + (1.0 - ps) * co / dr.pi
        f = albedo / dr.pi + spec
        valid = (ci > 0) & (co > 0)
        return f, pdf, valid

    def eval(self, ctx, si, wo, active=True):
        f, _, valid = self._terms(si, si.wi, wo)
        return dr.select(valid & active, f * mi.Frame3f.cos_theta(wo), 0.0)

    def pdf(self, ctx, si, wo, active=True):
        _, pdf, valid = self._terms(si, si.wi, wo)
        return dr.select(valid & active, pdf, 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        f, pdf, valid = self._terms(si, si.wi, wo)
        ok = valid & active
        return dr.select(ok, f * mi.Frame3f.cos_theta(wo), 0.0), dr.select(ok, pdf, 0.0)

    def sample(self, ctx, si, sample1, sample2, active=True):
        wi = si.wi
        ci = mi.Frame3f.cos_theta(wi)
        albedo = self.albedo.eval(si)
        s = F0 + (1.0 - F0) * dr.exp2((-5.55473 * ci - 6.98316) * ci)
        ps = dr.clip(s / (s + mi.luminance(albedo)), 0.1, 0.9)
        a = self.r * self.r
        a2 = a * a
        cos2 = dr.clip((1.0 - sample2.x) / (1.0 + (a2 - 1.0) * sample2.x), 0.0, 1.0)
        ct = dr.sqrt(cos2)
        st = dr.sqrt(dr.maximum(1.0 - cos2, 0.0))
        phi = 2.0 * dr.pi * sample2.y
        h = mi.Vector3f(st * dr.cos(phi), st * dr.sin(phi), ct)
        wo_spec = 2.0 * dr.dot(wi, h) * h - wi
        rr = dr.sqrt(sample2.x)
        wo_diff = mi.Vector3f(rr * dr.cos(phi), rr * dr.sin(phi), dr.sqrt(dr.maximum(1.0 - sample2.x, 0.0)))
        spec_lobe = sample1 < ps
        wo = dr.select(spec_lobe, wo_spec, wo_diff)
        f, pdf, valid = self._terms(si, wi, wo)
        ok = active & valid & (mi.Frame3f.cos_theta(wo) > 1e-7) & (pdf > 0)
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.pdf = dr.select(ok, pdf, 0.0)
        bs.eta = 1.0
        bs.sampled_component = 0
        bs.sampled_type = dr.select(spec_lobe, mi.UInt32(+mi.BSDFFlags.GlossyReflection), mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
        weight = dr.select(ok, f * mi.Frame3f.cos_theta(wo) / pdf, 0.0)
        return bs, weight

    def traverse(self, callback):
        pass

    def to_string(self):
        return "Karis[]"


# ----------------------------------------------------------------------------- scene building
def split_obj_by_usemtl(path, out_dir):
    """One OBJ per usemtl name (Mitsuba loads one shape per file); returns {part: file}."""
    verts, faces = [], {}
    cur = "default"
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] in ("v", "vt", "vn"):
                verts.append(line)
            elif t[0] == "usemtl":
                cur = " ".join(t[1:])
            elif t[0] == "f":
                faces.setdefault(cur, []).append(t[1:])
    # Keep global numbering: write all v/vt lines, then this part's faces.
    files = {}
    header = "".join(verts)
    for part, fs in faces.items():
        p = os.path.join(out_dir, f"part_{len(files)}.obj")
        with open(p, "w") as f:
            f.write(header)
            for face in fs:
                f.write("f " + " ".join(face) + "\n")
        files[part] = p
    return files


def look_at(cam):
    return mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["look_at"], up=cam.get("up", [0, 1, 0]))


def albedo_texture(part, truth_dir, v_flipped):
    alb = part["albedo"]
    if "texture" in alb:
        m = alb.get("uv_transform", [[1, 0, 0], [0, 1, 0]])
        # psc: (s, t) = M (u, v, 1), row = (1 - t) H. Mitsuba bitmaps: row = uv''.y H with
        # uv'' = to_uv (u', v') where (u', v') is the uv the OBJ loader produced.
        if v_flipped:  # u' = u, v' = 1 - v
            to_uv = [[m[0][0], -m[0][1], m[0][1] + m[0][2]], [-m[1][0], m[1][1], 1 - m[1][1] - m[1][2]], [0, 0, 1]]
        else:
            to_uv = [[m[0][0], m[0][1], m[0][2]], [-m[1][0], -m[1][1], 1 - m[1][2]], [0, 0, 1]]
        return {
            "type": "bitmap",
            "filename": os.path.join(truth_dir, alb["texture"]),
            "raw": False,  # sRGB -> linear
            "filter_type": "bilinear",
            "wrap_mode": "repeat",
            "to_uv": mi.ScalarTransform3f(np.array(to_uv, dtype=np.float32)),
        }
    return {"type": "rgb", "value": alb["rgb_linear"]}


def build_scene(scene_dir, cam, size, spp, bsdf_kind, integrator, v_flipped, tmp, id_codes=None):
    truth = json.load(open(os.path.join(scene_dir, "truth", "truth.json")))
    manifest = json.load(open(os.path.join(scene_dir, "scene.json")))
    truth_dir = os.path.join(scene_dir, "truth")
    parts = {p["name"]: p for p in truth["parts"]}
    files = split_obj_by_usemtl(os.path.join(truth_dir, "scene_true.obj"), tmp)
    w, h = size
    sampler = {"type": "independent", "sample_count": spp}
    if integrator["type"] == "aov":
        sampler = {"type": "stratified", "sample_count": 1, "jitter": False}
    d = {
        "type": "scene",
        "integrator": integrator,
        "sensor": {
            "type": "perspective",
            "fov": cam["fov_y_deg"],
            "fov_axis": "y",
            "to_world": look_at(cam),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": sampler,
        },
    }
    for part, f in files.items():
        p = parts.get(part)
        tex = albedo_texture(p, truth_dir, v_flipped) if p else {"type": "rgb", "value": 0.5}
        rough = p["roughness"] if p else 0.5
        if id_codes is not None:  # part id encoded in a constant albedo, read back by aov "albedo"
            id_codes[part] = len(id_codes) + 1
            tex = {"type": "rgb", "value": id_codes[part] / 256.0}
        if bsdf_kind == "diffuse":
            inner = {"type": "diffuse", "reflectance": tex}
        elif bsdf_kind == "principled":
            inner = {"type": "principled", "base_color": tex, "roughness": rough, "specular": 0.625, "metallic": 0.0}
        else:
            inner = {"type": "karis", "reflectance": tex, "roughness": rough}
        d["part:" + part] = {"type": "obj", "filename": f, "face_normals": True, "bsdf": {"type": "twosided", "bsdf": inner}}
    radiance = {l["name"]: l["radiance_rgb"] for l in truth["lights"]}
    for l in manifest.get("lights", []):
        d["light:" + l["name"]] = {
            "type": "obj",
            "filename": os.path.join(scene_dir, l["mesh"]),
            "face_normals": True,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 255.0 / 256.0 if id_codes is not None else 0.0}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance.get(l["name"], [1, 1, 1])}},
        }
    return mi.load_dict(d)


# ----------------------------------------------------------------------------- comparisons
def read_exr(path):
    return np.array(mi.Bitmap(path)).astype(np.float64)[..., :3]


def metrics(ours, ref):
    la, lb = ours.mean(-1), ref.mean(-1)
    per_pixel = (np.abs(la - lb) / np.maximum(lb, 1e-2)).mean()
    H, W = la.shape
    k = 8
    A = la[: H // k * k, : W // k * k].reshape(H // k, k, W // k, k).mean((1, 3))
    B = lb[: H // k * k, : W // k * k].reshape(H // k, k, W // k, k).mean((1, 3))
    block = (np.abs(A - B) / np.maximum(B, 1e-2)).mean()
    return {"mean_ratio": la.mean() / lb.mean(), "per_pixel": per_pixel, "block8": block}


def show(name, m):
    print(f"  {name:34s} mean ratio {m['mean_ratio']:.4f} ({100 * abs(m['mean_ratio'] - 1):.2f}% off), "
          f"per-pixel rel. diff {100 * m['per_pixel']:.2f}%, 8x8-block rel. diff {100 * m['block8']:.2f}%")


def run_psc(args, extra, out):
    cmd = [args.psc, "render", args.scene, "--geometry", "truth", "--materials", "truth", "--lights", "truth",
           "--size", args.size,
           "--quiet", "--out", out] + extra
    c0, t0 = cpu_children(), time.time()
    subprocess.run(cmd, check=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    return time.time() - t0, cpu_children() - c0


def mitsuba_render(scene, spp, seed=0):
    c0, t0 = cpu_self(), time.time()
    img = mi.render(scene, spp=spp, seed=seed)
    arr = np.array(img).astype(np.float64)[..., :3]  # forces evaluation
    return arr, time.time() - t0, cpu_self() - c0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--view", default="view0")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--psc", default="target/release/psc")
    ap.add_argument("--checks", default="aov,diffuse,karis,truth,time")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    args = ap.parse_args()
    mi.register_bsdf("karis", lambda props: Karis(props))
    size = tuple(int(x) for x in args.size.lower().split("x"))
    checks = args.checks.split(",")
    manifest = json.load(open(os.path.join(args.scene, "scene.json")))
    cam = next(v for v in manifest["views"] if v["name"] == args.view)["camera"]
    tmp = tempfile.mkdtemp(prefix="psc-mitsuba-")
    print(f"scene {args.scene}, view {args.view}, {args.size}, {args.spp} spp, Mitsuba {mi.__version__} {args.variant}")
    integ = {"type": "path", "max_depth": 6, "rr_depth": 5}

    v_flipped = True
    if "aov" in checks:
        aov = {"type": "aov", "aovs": "uv:uv,ng:geo_normal,al:albedo,dd:depth"}
        codes = {}
        scene = build_scene(args.scene, cam, size, 1, "diffuse", aov, v_flipped, tmp, id_codes=codes)
        img = np.array(mi.render(scene, spp=1)).astype(np.float64)
        # The aov integrator alone outputs its AOVs in order: uv (2), ng (3), albedo (3), depth (1).
        uv_m, ng_m, al_m, dep_m = img[..., 0:2], img[..., 2:5], img[..., 5:8], img[..., 8]
        code_to_part = {v: k for k, v in codes.items()}
        code = np.rint(al_m[..., 0] * 256.0).astype(np.int64)
        mits_name = np.vectorize(lambda c: code_to_part.get(int(c), "light"))(code)
        mits_name = np.where(dep_m > 0, mits_name, "-")
        gdir = os.path.join(tmp, "gbuffer")
        run_psc(args, ["--view", args.view, "--gbuffer"], gdir)
        gb = json.load(open(os.path.join(gdir, "gbuffer.json")))
        pid = np.array(mi.Bitmap(os.path.join(gdir, "part_id.png"))).astype(np.int64)
        if pid.ndim == 3:
            pid = pid[..., 0]
        ours_uv = read_exr(os.path.join(gdir, "uv.exr"))[..., :2]
        ours_ng = read_exr(os.path.join(gdir, "normal_geometric.exr"))
        ours_depth = read_exr(os.path.join(gdir, "depth.exr"))[..., 0]
        id_names = {int(k): v for k, v in gb["part_ids"].items()}
        ours_short = np.vectorize(lambda i: "light" if id_names.get(int(i), "-").startswith("light:") else id_names.get(int(i), "-"))(pid)
        hit = (dep_m > 0) | (pid > 0)
        part_ok = (ours_short == mits_name)[hit].mean()
        both = (dep_m > 0) & (pid > 0) & (ours_short == mits_name)
        for flip in (True, False):
            mv = 1 - uv_m[..., 1] if flip else uv_m[..., 1]
            uv_ok = ((np.abs(ours_uv[..., 0] - uv_m[..., 0]) < 1e-3) & (np.abs(ours_uv[..., 1] - mv) < 1e-3))[both].mean()
            print(f"  uv agreement (|du|,|dv| < 1e-3) assuming Mitsuba v {'= 1 - v_obj' if flip else '= v_obj'}: {100 * uv_ok:.2f}%")
        # Mitsuba's geometric normal is the winding normal; psc's faces the camera.
        ngm = ng_m * np.where((ng_m * ours_ng).sum(-1, keepdims=True) < 0, -1.0, 1.0)
        n_ok = ((ngm * ours_ng).sum(-1) > np.cos(np.radians(1.0)))[both].mean()
        # Mitsuba starts camera rays on its near plane (near_clip = 0.01): its aov depth is
        # the distance from there; psc's is from the camera centre.
        W, H = size
        ty = np.tan(np.radians(cam["fov_y_deg"]) / 2)
        xs = (2 * (np.arange(W) + 0.5) / W - 1) * ty * W / H
        ys = (1 - 2 * (np.arange(H) + 0.5) / H) * ty
        cos = 1 / np.sqrt(1 + xs[None, :] ** 2 + ys[:, None] ** 2)
        dep_ok = (np.abs(ours_depth - (dep_m + 0.01 / cos)) < 1e-3 * np.maximum(dep_m, 1))[both].mean()
        print(f"  part id agreement: {100 * part_ok:.2f}% of {hit.sum()} pixels with a hit")
        print(f"  geometric normal within 1 deg: {100 * n_ok:.2f}%, depth within 0.1%: {100 * dep_ok:.2f}%")

    results = {}
    for kind in ("diffuse", "karis"):
        if kind not in checks:
            continue
        scene = build_scene(args.scene, cam, size, args.spp, kind, integ, v_flipped, tmp)
        ref, _, _ = mitsuba_render(scene, args.spp, seed=1)
        out = os.path.join(tmp, f"psc_{kind}.exr")
        extra = ["--view", args.view, "--spp", str(args.spp), "--seed", "1"] + (["--diffuse-only"] if kind == "diffuse" else [])
        run_psc(args, extra, out)
        results[kind] = metrics(read_exr(out), ref)
        show(f"psc vs Mitsuba, {kind}:", results[kind])

    if "truth" in checks:
        tpath = os.path.join(args.scene, "truth", f"{args.view}.exr")
        if os.path.exists(tpath):
            out = os.path.join(tmp, "psc_truth.exr")
            run_psc(args, ["--view", args.view, "--spp", str(args.spp), "--seed", "1"], out)
            ref = read_exr(tpath)
            if ref.shape[:2] == (size[1], size[0]):
                show("psc vs truth image (256 spp):", metrics(read_exr(out), ref))
                if "karis" in checks:
                    scene = build_scene(args.scene, cam, size, args.spp, "karis", integ, v_flipped, tmp)
                    mimg, _, _ = mitsuba_render(scene, args.spp, seed=2)
                    show("Mitsuba(karis) vs truth image:", metrics(mimg, ref))

    if "time" in checks:
        scene = build_scene(args.scene, cam, size, args.spp, "karis", integ, v_flipped, tmp)
        _, w0, c0 = mitsuba_render(scene, args.spp, seed=3)  # includes JIT compilation
        _, w1, c1 = mitsuba_render(scene, args.spp, seed=4)  # kernel cache warm
        scene_d = build_scene(args.scene, cam, size, args.spp, "diffuse", integ, v_flipped, tmp)
        mitsuba_render(scene_d, args.spp, seed=3)
        _, wd, cd = mitsuba_render(scene_d, args.spp, seed=4)
        out = os.path.join(tmp, "psc_time.exr")
        wp, cp = run_psc(args, ["--view", args.view, "--spp", str(args.spp), "--seed", "1"], out)
        samples = size[0] * size[1] * args.spp
        print(f"  timing {args.size} @ {args.spp} spp (wall s / CPU s / Msamples per CPU s):")
        print(f"    Mitsuba llvm, karis (Python BSDF), first run: {w0:.2f} / {c0:.2f} / {samples / c0 / 1e6:.2f}")
        print(f"    Mitsuba llvm, karis (Python BSDF), warm:      {w1:.2f} / {c1:.2f} / {samples / c1 / 1e6:.2f}")
        print(f"    Mitsuba llvm, diffuse (native BSDF), warm:    {wd:.2f} / {cd:.2f} / {samples / cd / 1e6:.2f}")
        print(f"    psc render (whole process, incl. loading):    {wp:.2f} / {cp:.2f} / {samples / cp / 1e6:.2f}")


if __name__ == "__main__":
    sys.exit(main())
