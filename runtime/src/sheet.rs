//! Contact sheets of the material library: every graph at its defaults and a few random
//! variants, each baked small and shown as a flat sample lit by a fixed directional light and a
//! soft ambient term, seen from straight above, with its name written under it.
//!
//! The shading is the renderer's Karis BRDF (`psc_render::brdf`), the one the path tracer and
//! the fit use, so a sheet shows a material as a render will: dielectric with F0 = 0.05, the
//! metallic channel ignored (the renderer has none).

use std::io;
use std::path::Path;

use psc_render::brdf::{clamp_roughness, specular, Cosines};

use crate::bake::{linear_to_srgb, Maps};

/// One tile of the sheet.
pub struct Cell {
    pub label: String,
    pub maps: Maps,
}

/// Light direction (towards the light): from the upper left of the image, 40° above the plane.
const LIGHT: [f32; 3] = [-0.45, 0.55, 0.70];
/// Irradiance of the light on a plane facing it (so a white Lambertian facing it shows 1.3).
const LIGHT_IRRADIANCE: f32 = 1.3 * std::f32::consts::PI;
const AMBIENT: f32 = 0.22;
/// Presentation only: highlights of near-mirror texels are capped before tone mapping.
const MAX_SPECULAR: f32 = 8.0;

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-12);
    [v[0] / l, v[1] / l, v[2] / l]
}

/// Shades one texel (tangent-space normal; the viewer is straight above): linear RGB out.
pub fn shade_texel(albedo: [f32; 3], roughness: f32, normal: [f32; 3]) -> [f32; 3] {
    let n = normalize(normal);
    let l = normalize(LIGHT);
    let (c, _) = Cosines::new(n, [0.0, 0.0, 1.0], l);
    let r = clamp_roughness(roughness);
    let spec = specular(c, r).min(MAX_SPECULAR);
    let n_l = c.n_l.max(0.0);
    let mut out = [0.0; 3];
    for k in 0..3 {
        let a = if albedo[k].is_finite() { albedo[k].max(0.0) } else { 0.0 };
        // The ambient term carries a little of the specular colour so glossy samples read as such.
        let ambient = AMBIENT * (a + psc_render::brdf::F0 * (1.0 - 0.6 * r) * (0.6 + 0.4 * n[2]));
        out[k] = ambient + LIGHT_IRRADIANCE * (a / std::f32::consts::PI + spec) * n_l;
    }
    out
}

/// Shades baked maps into 8-bit sRGB pixels.
pub fn shade(maps: &Maps) -> Vec<u8> {
    let n = maps.size * maps.size;
    let mut out = Vec::with_capacity(3 * n);
    for k in 0..n {
        let a = [maps.albedo[3 * k], maps.albedo[3 * k + 1], maps.albedo[3 * k + 2]];
        let nn = [maps.normal[3 * k], maps.normal[3 * k + 1], maps.normal[3 * k + 2]];
        let c = shade_texel(a, maps.roughness[k], nn);
        for x in c {
            let s = if x.is_finite() { linear_to_srgb(x / (1.0 + 0.15 * x)) } else { 1.0 };
            out.push((s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
        }
    }
    out
}

/// Lays out cells in rows of `per_row`, each cell `size`×`size` pixels with a label strip
/// under it, and writes the sheet as a PNG (atomically).
pub fn write_sheet(path: &Path, cells: &[Cell], per_row: usize) -> io::Result<()> {
    let (w, h, rgb) = compose(cells, per_row);
    crate::bake::write_png_rgb(path, (w as u32, h as u32), &rgb)
}

/// The sheet's pixels: `(width, height, rgb)`.
pub fn compose(cells: &[Cell], per_row: usize) -> (usize, usize, Vec<u8>) {
    let per_row = per_row.max(1);
    let size = cells.iter().map(|c| c.maps.size).max().unwrap_or(64);
    let pad = 4;
    let label_h = 2 * GLYPH_H + 6;
    let cw = size + 2 * pad;
    let ch = size + pad + label_h;
    let rows = cells.len().div_ceil(per_row);
    let w = per_row * cw;
    let h = rows.max(1) * ch;
    let mut img = vec![24u8; 3 * w * h];
    for (idx, cell) in cells.iter().enumerate() {
        let x0 = (idx % per_row) * cw + pad;
        let y0 = (idx / per_row) * ch + pad;
        let px = shade(&cell.maps);
        let s = cell.maps.size;
        for y in 0..s {
            for x in 0..s {
                let src = 3 * (y * s + x);
                let dst = 3 * ((y0 + y) * w + x0 + x);
                img[dst..dst + 3].copy_from_slice(&px[src..src + 3]);
            }
        }
        draw_text(&mut img, w, x0, y0 + s + 3, &cell.label, size, [230, 230, 230]);
    }
    (w, h, img)
}

const GLYPH_W: usize = 5;
const GLYPH_H: usize = 7;

/// Draws `text` (lower-case letters, digits, `_ - . # :` and spaces) with a 5×7 bitmap font,
/// wrapping onto a second line when it is wider than `max_w` pixels.
fn draw_text(img: &mut [u8], w: usize, x0: usize, y0: usize, text: &str, max_w: usize, color: [u8; 3]) {
    let per_line = (max_w / (GLYPH_W + 1)).max(1);
    for (i, ch) in text.chars().enumerate() {
        let line = i / per_line;
        if line > 1 {
            break;
        }
        let gx = x0 + (i % per_line) * (GLYPH_W + 1);
        let gy = y0 + line * (GLYPH_H + 2);
        let bits = glyph(ch.to_ascii_lowercase());
        for (r, row) in bits.iter().enumerate() {
            for c in 0..GLYPH_W {
                if row & (1 << (GLYPH_W - 1 - c)) != 0 {
                    let x = gx + c;
                    let y = gy + r;
                    let k = 3 * (y * w + x);
                    if x < w && k + 3 <= img.len() {
                        img[k..k + 3].copy_from_slice(&color);
                    }
                }
            }
        }
    }
}

/// 5×7 glyphs, one byte per row, high bit on the left.
fn glyph(c: char) -> [u8; 7] {
    match c {
        'a' => [0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F],
        'b' => [0x10, 0x10, 0x1E, 0x11, 0x11, 0x11, 0x1E],
        'c' => [0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E],
        'd' => [0x01, 0x01, 0x0F, 0x11, 0x11, 0x11, 0x0F],
        'e' => [0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E],
        'f' => [0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08],
        'g' => [0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'h' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11],
        'i' => [0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E],
        'j' => [0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0C],
        'k' => [0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12],
        'l' => [0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'm' => [0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11],
        'n' => [0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11],
        'o' => [0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E],
        'p' => [0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10],
        'q' => [0x00, 0x00, 0x0F, 0x11, 0x0F, 0x01, 0x01],
        'r' => [0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10],
        's' => [0x00, 0x00, 0x0F, 0x10, 0x0E, 0x01, 0x1E],
        't' => [0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06],
        'u' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D],
        'v' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'w' => [0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A],
        'x' => [0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11],
        'y' => [0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'z' => [0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        '_' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F],
        '-' => [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C],
        ':' => [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00],
        '#' => [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A],
        '/' => [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00],
        _ => [0; 7],
    }
}
