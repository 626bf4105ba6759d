//! The two baselines `psc eval` renders beside the fit, both from the input photos only:
//!
//! - **pixel median** (IM2CAD, as PhotoScene's paper): per part, the per-channel median of the
//!   photo colours (sRGB decoded to linear) over the part's labelled pixels in all input views,
//!   as a constant albedo, roughness 0.7, flat normal. A part no input view shows gets the median
//!   over every labelled pixel of the input views.
//! - **flat fitted**: a constant albedo per part fitted under the evaluated lights on the coarse
//!   model: start from the pixel median, render the input views (each times the fit's exposure
//!   of that view), multiply each part's albedo by
//!   (photo linear mean / render linear mean) per channel over the part's pixels, clamp to
//!   [0, 1], repeat (the repeats account for interreflections). A part's pixels: labelled as the
//!   part in the photo, showing the part in the coarse model's G-buffer (where the model is
//!   misaligned, the render there shows another part, whose light does not scale with this
//!   part's albedo, and the update would drive it to 0 or 1), not on the part's boundary (both
//!   masks eroded by one pixel). Pixels clipped in the photo count, against the render clipped
//!   the same way (each channel at 1), as in the fit: left out, a partly clipped part would keep
//!   only its darker pixels and come out too dark. Roughness: the fitted material's mean roughness over the
//!   part's pixels in the input views (coarse-model G-buffers), for parts materials.json names
//!   and the input views show; 0.7 otherwise. So flat fitted differs from the fit only in its
//!   lack of texture and normal detail.

use std::collections::BTreeMap;

use psc_render::MaterialBinding;

use super::backend::{self, GeometryContext, RenderSettings};
use super::truth::EvalView;
use super::EvalError;

/// The roughness of the pixel-median baseline (IM2CAD's choice, as the paper).
pub const PIXEL_MEDIAN_ROUGHNESS: f32 = 0.7;

/// Per input view: model part index + 1 of each pixel (0 = none), from the view's labels matched
/// to the model's parts by name, else (no labels) from the coarse model's G-buffer.
pub fn input_masks(ctx: &GeometryContext, inputs: &[&EvalView]) -> Result<Vec<Vec<u16>>, EvalError> {
    let parts = ctx.part_names();
    inputs
        .iter()
        .map(|v| match &v.labels {
            Some((data, names)) => {
                let lut: BTreeMap<u16, u16> = names
                    .iter()
                    .filter_map(|(value, name)| parts.iter().position(|p| p == name).map(|i| (*value, i as u16 + 1)))
                    .collect();
                Ok(data.iter().map(|l| lut.get(l).copied().unwrap_or(0)).collect())
            }
            None => Ok(ctx.part_ids_and_uvs(&v.camera, v.width, v.height)?.0),
        })
        .collect()
}

fn median(values: &mut [f32]) -> f32 {
    values.sort_unstable_by(f32::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Per-channel median of linear photo colours; `None` for an empty set.
fn median_colour(pixels: &[[f32; 3]]) -> Option<[f32; 3]> {
    if pixels.is_empty() {
        return None;
    }
    Some(std::array::from_fn(|k| median(&mut pixels.iter().map(|p| p[k]).collect::<Vec<_>>())))
}

/// The pixel-median albedo of every model part (linear), and the parts no input view shows.
pub fn pixel_median(ctx: &GeometryContext, inputs: &[&EvalView], masks: &[Vec<u16>]) -> (Vec<[f32; 3]>, Vec<String>) {
    let n = ctx.part_names().len();
    let mut per_part: Vec<Vec<[f32; 3]>> = vec![Vec::new(); n];
    for (v, mask) in inputs.iter().zip(masks) {
        for (p, &id) in v.truth.iter().zip(mask) {
            if id > 0 {
                per_part[id as usize - 1].push(p.map(backend::srgb_to_linear));
            }
        }
    }
    let all: Vec<[f32; 3]> = per_part.iter().flatten().copied().collect();
    let fallback = median_colour(&all).unwrap_or([0.5; 3]);
    let mut unseen = Vec::new();
    let albedo = per_part
        .iter()
        .enumerate()
        .map(|(i, px)| {
            median_colour(px).unwrap_or_else(|| {
                unseen.push(ctx.part_names()[i].clone());
                fallback
            })
        })
        .collect();
    (albedo, unseen)
}

/// `masks` (photo labels as model part index + 1) kept only where the coarse model's G-buffer
/// sees the same part, eroded by one pixel (a boundary pixel of the render mixes the part with
/// its neighbours; the fit excludes them too).
pub fn aligned_masks(
    ctx: &GeometryContext,
    inputs: &[&EvalView],
    masks: &[Vec<u16>],
) -> Result<Vec<Vec<u16>>, EvalError> {
    inputs
        .iter()
        .zip(masks)
        .map(|(v, mask)| {
            let (ids, _) = ctx.part_ids_and_uvs(&v.camera, v.width, v.height)?;
            let (w, h) = (v.width, v.height);
            let both: Vec<u16> = mask.iter().zip(&ids).map(|(&m, &g)| if m == g { m } else { 0 }).collect();
            Ok((0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    let inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                    if inside && [i - 1, i + 1, i - w, i + w].iter().all(|&j| both[j] == both[i]) {
                        both[i]
                    } else {
                        0
                    }
                })
                .collect())
        })
        .collect()
}

/// Mean roughness of `fitted[i]` over part i's pixels in the input views (coarse-model
/// G-buffers), for the parts in `named`; [`PIXEL_MEDIAN_ROUGHNESS`] elsewhere.
pub fn fitted_roughness(
    ctx: &GeometryContext,
    inputs: &[&EvalView],
    fitted: &[MaterialBinding],
    named: &[String],
) -> Result<Vec<f32>, EvalError> {
    let n = ctx.part_names().len();
    let mut sum = vec![0.0f64; n];
    let mut count = vec![0usize; n];
    for v in inputs {
        let (ids, uvs) = ctx.part_ids_and_uvs(&v.camera, v.width, v.height)?;
        for (&id, &uv) in ids.iter().zip(&uvs) {
            if id > 0 {
                let i = id as usize - 1;
                if named.contains(&ctx.part_names()[i]) {
                    sum[i] += backend::roughness_at(&fitted[i], uv) as f64;
                    count[i] += 1;
                }
            }
        }
    }
    Ok((0..n).map(|i| if count[i] > 0 { (sum[i] / count[i] as f64) as f32 } else { PIXEL_MEDIAN_ROUGHNESS }).collect())
}

/// Constant materials from albedos and roughnesses.
pub fn constant_materials(albedo: &[[f32; 3]], roughness: &[f32]) -> Vec<MaterialBinding> {
    albedo.iter().zip(roughness).map(|(a, r)| backend::constant_material(*a, *r)).collect()
}

/// Flat-fitted albedos per part and, per round, the largest albedo change and its part.
pub type FlatFit = (Vec<[f32; 3]>, Vec<(f64, String)>);

/// The flat-fitted albedos after `iterations` rounds of the mean-ratio update from `start`, and
/// per round the largest change of a channel (|new − old| of the linear albedo, over parts and
/// channels) with the part it happened on, to show the convergence. `exposure`: per input view,
/// the RGB factor on its renders. `on_render` is called after each render (for progress).
#[allow(clippy::too_many_arguments)]
pub fn flat_fit(
    ctx: &mut GeometryContext,
    inputs: &[&EvalView],
    masks: &[Vec<u16>],
    start: &[[f32; 3]],
    roughness: &[f32],
    slot_radiance: &[[f32; 3]],
    exposure: &[[f32; 3]],
    settings: &RenderSettings,
    iterations: u32,
    on_render: &mut dyn FnMut(String),
) -> Result<FlatFit, EvalError> {
    let n = ctx.part_names().len();
    let mut albedo = start.to_vec();
    let mut changes = Vec::new();
    // The photo side does not change between rounds.
    let mut photo_sum = vec![[0.0f64; 3]; n];
    for (v, mask) in inputs.iter().zip(masks) {
        for (p, &id) in v.truth.iter().zip(mask) {
            if id > 0 {
                for k in 0..3 {
                    photo_sum[id as usize - 1][k] += backend::srgb_to_linear(p[k]) as f64;
                }
            }
        }
    }
    for round in 0..iterations {
        let materials = constant_materials(&albedo, roughness);
        let mut render_sum = vec![[0.0f64; 3]; n];
        for (i, (v, mask)) in inputs.iter().zip(masks).enumerate() {
            let slots = ctx.render_slots(&materials, &v.camera, v.width, v.height, settings)?;
            let img = backend::combine_slots(&slots, slot_radiance);
            let e = exposure.get(i).copied().unwrap_or([1.0; 3]);
            on_render(format!("flat fit round {} view {}", round + 1, v.name));
            for (r, &id) in img.iter().zip(mask) {
                if id > 0 {
                    for k in 0..3 {
                        render_sum[id as usize - 1][k] += (e[k] * r[k]).min(1.0) as f64;
                    }
                }
            }
        }
        let mut change = (0.0f64, String::new());
        for i in 0..n {
            for k in 0..3 {
                // Pixel counts are equal on both sides, so the ratio of sums is that of means.
                if render_sum[i][k] > 0.0 {
                    let old = albedo[i][k] as f64;
                    let new = (old * photo_sum[i][k] / render_sum[i][k]).clamp(0.0, 1.0);
                    // Absolute: a dark channel sliding to its fixed point at 0 moves by a
                    // large fraction of a tiny value.
                    let c = (new - old).abs();
                    if c > change.0 {
                        change = (c, ctx.part_names()[i].clone());
                    }
                    albedo[i][k] = new as f32;
                }
            }
        }
        changes.push(change);
    }
    Ok((albedo, changes))
}
