//! Texture lookups (OBJ v-up, bilinear, repeat) and material bindings.

use psc_render::{ImageMaterial, MaterialBinding, Texture};
use std::sync::Arc;

fn tex() -> Texture {
    // 2x2: top row red, green; bottom row blue, white.
    Texture::new(2, 2, vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]]).unwrap()
}

#[test]
fn texel_centres_follow_the_obj_convention() {
    let t = tex();
    assert_eq!(t.sample([0.25, 0.25]), [0.0, 0.0, 1.0], "v = 0.25 is the bottom row");
    assert_eq!(t.sample([0.75, 0.75]), [0.0, 1.0, 0.0], "u = 0.75, v = 0.75: top right");
    assert_eq!(t.sample([1.25, -0.75]), [0.0, 0.0, 1.0], "repeat wrap");
    // Halfway between the two top texels: bilinear mix.
    let m = t.sample([0.5, 0.75]);
    assert!((m[0] - 0.5).abs() < 1e-6 && (m[1] - 0.5).abs() < 1e-6 && m[2].abs() < 1e-6);
    // At u = 0 the filter wraps: half of column 0, half of column 1.
    let e = t.sample([0.0, 0.75]);
    assert!((e[0] - 0.5).abs() < 1e-6 && (e[1] - 0.5).abs() < 1e-6);
}

#[test]
fn srgb8_textures_decode_to_linear() {
    let t = Texture::from_srgb8(1, 1, vec![[255, 128, 0, 0]]).unwrap();
    let v = t.sample([0.3, 0.6]);
    assert!((v[0] - 1.0).abs() < 1e-6);
    assert!((v[1] - 0.2158605).abs() < 1e-5, "{}", v[1]);
    assert_eq!(v[2], 0.0);
}

#[test]
fn binding_applies_uv_transform_and_scales() {
    let b = MaterialBinding {
        material: Arc::new(ImageMaterial::new(tex(), 0.8)),
        uv_transform: [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]], // swap u and v
        albedo_scale: [2.0, 1.0, 1.0],
        roughness_scale: 2.0,
    };
    // mesh uv (0.75, 0.25) → texture (0.25, 0.75): top-left texel, red, ×2 in red.
    let s = b.eval([0.75, 0.25]);
    assert_eq!(s.albedo, [2.0, 0.0, 0.0]);
    assert_eq!(s.roughness, 1.0, "clamped to 1");
    // eval_batch defaults to eval
    let mut out = [Default::default(); 2];
    b.material.eval_batch(&[[0.25, 0.25], [0.75, 0.75]], &mut out);
    assert_eq!(out[0].albedo, [0.0, 0.0, 1.0]);
    assert_eq!(out[1].albedo, [0.0, 1.0, 0.0]);
}
