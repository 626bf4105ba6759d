"""The figures the export checks print when they compare a renderer's image of an exported room
with `psc render`'s (tools/export_mitsuba_check.py, tools/blender_gltf_check.py): image means
over the pixels where neither image shows an emitter, their ratio per channel and overall, and
the mean relative difference of 8x8-pixel block means of luminance (noise mostly averaged out).
Images are float arrays H x W x 3 of linear RGB."""
import numpy as np

EMITTER = 4.0  # linear value above which a pixel is taken to show a light


def block_rel(a, b, k=8):
    la, lb = a.mean(-1), b.mean(-1)
    H, W = la.shape
    A = la[: H // k * k, : W // k * k].reshape(H // k, k, W // k, k).mean((1, 3))
    B = lb[: H // k * k, : W // k * k].reshape(H // k, k, W // k, k).mean((1, 3))
    return float((np.abs(A - B) / np.maximum(B, 1e-2)).mean())


def figures(img, ref, name):
    """`img` (the other renderer's, called `name`) against `ref` (psc's), as a JSON-ready dict."""
    # Lights seen directly (radiance in the tens) would dominate plain means.
    surface = (ref.max(-1) < EMITTER) & (img.max(-1) < EMITTER)
    i_mean, p_mean = img[surface].mean(0), ref[surface].mean(0)
    return {
        f"{name}_mean": i_mean.tolist(),
        "psc_mean": p_mean.tolist(),
        "channel_ratio": (i_mean / np.maximum(p_mean, 1e-12)).tolist(),
        "mean_ratio": float(img[surface].mean() / max(ref[surface].mean(), 1e-12)),
        "surface_fraction": float(surface.mean()),
        "block8": block_rel(img, ref),
    }
