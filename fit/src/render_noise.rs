//! Stage 3b, how much of what a photo's noise estimator reads is noise: the renderer's own
//! noise as the reference that tells a part's pixel noise from its finest texture.
//!
//! The losses forgive a candidate for lacking as much variation as the photo's pixel noise
//! (`targets` estimates it per crop with Immerkær's mask). That estimator cannot tell noise from
//! texture near the pixel scale: dev_3's brick wall, courses three pixels apart, reads 0.0205
//! where the plain wall beside it reads 0.0091, so a candidate that hides the bricks is
//! forgiven for it. One noise level for the whole photo is wrong the other way, because
//! path-tracing noise is not one level: dev_1's ceiling, plain and lit only by bounces, reads
//! 0.028 beside its plain floor's 0.010 (see `targets::crop_noise` for what that did to a fit).
//!
//! The renderer knows where its noise is large. Two independent renders of every input view
//! ([`SPP`] each, different seeds, the current materials and lights) differ by their noise
//! alone; over a set of pixels the median of their difference gives the render's noise `σ_r`,
//! and the photo's noise over the render's, `σ_p / σ_r`, is about constant over a view's plain
//! parts. Under the pixel-median materials the fit starts from: 0.31–0.47 on the large plain
//! parts of dev_1 and dev_3 (dev_1's ceiling 0.43; a small cabinet trim 0.63), 0.86 on dev_1's
//! gravel wall and 1.05 on dev_3's brick wall. Per view, `k` is the lower quartile of the
//! ratios over the parts with at least 500 usable pixels (rooms hold textured parts too; the
//! median of dev_3's 13 parts was 0.60, pulled up by its furniture), and a crop's estimates are
//! capped at [`TOLERANCE`]` · k · σ_r`, σ_r over the crop's own pixels: the excess is texture,
//! which the losses then ask a candidate to have. The cap is one factor on all of a crop's
//! estimates (r, g, b, luma, and the feature loss's colour axes), the luma's: the photo's noise
//! is that fraction of what its estimator read, whatever the channel. On the dev scenes it cuts
//! the brick wall's estimate to 0.59 of itself, the brick rug's to 0.60 and the gravel wall's
//! to 0.63, and leaves every plain part's alone (`fit/tests/render_noise_dev.rs`).
//!
//! Measured (`psc eval --spp 128`, fits at `--texture-size 256 --render-spp 32`), texture
//! contrast over the pixel median's on the true geometry, input / novel / relit, before → with
//! the check:
//!
//! | room | seed 0 | seed 1 |
//! | --- | --- | --- |
//! | dev_1 | 0.39 / 0.34 / 0.44 → 0.38 / 0.31 / 0.42 | 0.27 / 0.40 / 0.27 → 0.26 / 0.34 / 0.24 |
//! | dev_2 | 0.53 / 0.42 / 0.73 → 0.53 / 0.42 / 0.72 | 0.66 / 0.50 / 0.85 → 0.66 / 0.49 / 0.88 |
//! | dev_3 | 0.46 / 0.67 / 0.50 → 0.48 / 0.60 / 0.52 | 0.60 / 0.74 / 0.64 → 0.52 / 0.74 / 0.57 |
//! | dev_4 | 0.33 / 0.76 / 0.36 → 0.45 / 0.85 / 0.44 | 0.53 / 0.81 / 0.45 → 0.36 / 0.77 / 0.35 |
//!
//! The 12 cells sum to 5.95 → 6.12 at seed 0 and 6.71 → 6.18 at seed 1: better over the two
//! seeds, and the two seeds closer together. Seed 0's loss is dev_4's wooden table, which went
//! from a laminate to a checker marble (its forgiven noise had suited the laminate). On the
//! four hold-out rooms at seed 0 the sum went from 3.81 to 3.73. The light ratios: dev_1 13.2%
//! → 13.2% and 37.2% → 11.8% off the truth's (seeds 0, 1), dev_2 0.1% → 2.2% and 5.9% → 8.4%,
//! dev_4 1.0% → 2.8% and 1.1% → 2.0%. RMSE and mean-colour cells moved by up to 0.02 but on
//! dev_3 at seed 0 (up to 0.09: its chair trim, 2 usable pixels, got another flat colour). The
//! brick wall itself kept its quartz: without the forgiveness the loss still ranks a plain
//! quartz above the library's imperfect bricks. It costs two renders at [`SPP`] per view
//! (1.5 s on dev_3).
//!
//! Tried and not landed: a crop beyond the band takes the view's typical noise `k · σ_r`
//! rather than the band's edge (the cap leaves such a crop 1.5 times the typical noise, and a
//! candidate that has the texture gets that on top of it). It put the three photo-textured
//! walls' and rug's estimates at 0.39–0.42 of themselves. The probe that led to it: dev_3's
//! brick wall forced to `red_brick` ends at a loss of 0.0092 against the quartz's 0.0082, yet
//! `psc eval` gives the brick a texture contrast on the true geometry of 0.0022 against the
//! quartz's 0.0030 (novel views; the pixel median 0.0038), and with the contrast term's noise
//! field halved the losses turn, 0.0075 against 0.0087. With the change the wall got a cut
//! pile, at 0.11 of the pixel median's contrast on the novel views. Fits and `psc eval` as
//! above, texture contrast summed over the 12 true-geometry cells, head → change:
//! dev scenes 5.33 → 5.09 (seed 0) and 5.48 → 5.06 (seed 1), the same four cells above half
//! the baseline at each seed (dev_3's relit views 0.51 → 0.43 at seed 0, dev_2's input views
//! 0.494 → 0.501); the hold-out rooms 3.79 → 3.85 and 4.09 → 4.02, RMSE summed 12.10 → 12.39
//! over their 24 cells (the dev scenes' 11.94 → 11.78); the graph family 14 → 13 of 26 judged
//! parts. The lights lost most: between two lights dev_1 10.4% → 22.4% and 12.0% → 43.5% off
//! the truth's ratio (at seed 1 its gravel walls got a wicker at 0.08 of the baseline's
//! contrast, the linen had 0.30), dev_2 2.0% → 2.7% and 8.6% → 10.2%, the hold-out rooms g1 and
//! g2 up by 0.1–2.1 points, dev_4 0.3% → 0.1% and 1.0% → 1.9%, g4 unchanged: worse in 9 of
//! the 12 runs of rooms with several lights. The gain is the dev scenes' near-pixel-scale
//! bricks and gravel; the hold-out rooms, whose photo textures are the same images recoloured
//! at other scales, did not gain (−0.01 over their 24 contrast cells).

use psc_render::image_io::linear_to_srgb;
use psc_render::Renderer;

use crate::align::{model_pixel, AlignedPart};
use crate::contrast::luma;
use crate::error::FitError;
use crate::features::estimate_noise_sigma;
use crate::lighting;
use crate::observe::ViewObservation;

/// Samples per pixel of each of the two renders.
pub const SPP: u32 = 16;
/// How far above the view's typical photo/render noise ratio a part's may lie before the
/// excess counts as texture.
pub const TOLERANCE: f32 = 1.5;
/// Parts with fewer usable pixels than this do not vote on a view's ratio.
const MIN_PART_PIXELS: usize = 500;
/// The median absolute value of a unit normal variable.
const MAD_NORMAL: f32 = 0.6745;

/// The render noise of one input view.
pub struct RenderNoise {
    width: usize,
    height: usize,
    /// Per model pixel, the luma difference of the two renders (sRGB, absolute).
    difference: Vec<f32>,
    /// The photo's noise over the render's in this view; None when no part could say.
    ratio: Option<f32>,
}

/// Renders every input view twice under `radiance` (per emitter slot) with the renderer's
/// current materials and measures each view's photo/render noise ratio over `aligned`.
pub fn estimate(
    renderer: &Renderer,
    views: &[ViewObservation],
    aligned: &[Vec<AlignedPart>],
    radiance: &[[f32; 3]],
    seed: u64,
) -> Result<Vec<RenderNoise>, FitError> {
    let a = lighting::unit_renders_at(renderer, views, psc_base::mix64(seed ^ 0x0015_e001), SPP)?;
    let b = lighting::unit_renders_at(renderer, views, psc_base::mix64(seed ^ 0x0015_e002), SPP)?;
    let combine = |slots: &[Vec<[f32; 3]>], i: usize| -> f32 {
        let mut linear = [0.0f32; 3];
        for (image, r) in slots.iter().zip(radiance) {
            (0..3).for_each(|c| linear[c] += image[i][c] * r[c]);
        }
        luma(linear.map(|x| linear_to_srgb(x.clamp(0.0, 1.0))))
    };
    Ok(views
        .iter()
        .enumerate()
        .map(|(v, obs)| {
            let (width, height) = (obs.camera.width, obs.camera.height);
            let difference: Vec<f32> =
                (0..width * height).map(|i| (combine(&a[v], i) - combine(&b[v], i)).abs()).collect();
            let mut noise = RenderNoise { width, height, difference, ratio: None };
            noise.ratio = view_ratio(obs, &aligned[v], &noise);
            noise
        })
        .collect())
}

impl RenderNoise {
    /// The photo's noise over the render's in this view.
    pub fn ratio(&self) -> Option<f32> {
        self.ratio
    }

    /// The render's noise (a standard deviation, sRGB luma) over the model pixels under the
    /// given photo positions; None when none lands in the raster.
    fn sigma_at(&self, aligned: &AlignedPart, photo_positions: impl Iterator<Item = [f32; 2]>) -> Option<f32> {
        let mut d: Vec<f32> = photo_positions
            .filter_map(|[x, y]| model_pixel(&aligned.warp, x, y, self.width, self.height))
            .map(|j| self.difference[j])
            .collect();
        (!d.is_empty()).then(|| lighting::median(&mut d) / (MAD_NORMAL * std::f32::consts::SQRT_2))
    }

    /// The factor in (0, 1] on a crop's noise estimate whose luma reads `photo_sigma`: the
    /// part of it the render's noise at the crop's pixels (photo raster positions) accounts
    /// for, within [`TOLERANCE`]. 1 where the view has no ratio or the render no noise there.
    pub fn factor(
        &self,
        aligned: &AlignedPart,
        photo_positions: impl Iterator<Item = [f32; 2]>,
        photo_sigma: f32,
    ) -> f32 {
        let (Some(k), Some(sigma)) = (self.ratio, self.sigma_at(aligned, photo_positions)) else { return 1.0 };
        cap_factor(photo_sigma, TOLERANCE * k * sigma)
    }
}

/// `cap / estimate`, at most 1 (and 1 for a non-positive cap or estimate).
fn cap_factor(estimate: f32, cap: f32) -> f32 {
    if estimate > 0.0 && cap > 0.0 && cap < estimate {
        cap / estimate
    } else {
        1.0
    }
}

/// The lower quartile of the photo/render noise ratios over the view's parts with at least
/// [`MIN_PART_PIXELS`] usable pixels, each measured on the usable pixels whose 3×3
/// neighbourhood is usable too (the photo's sRGB luma by the estimator `targets` uses).
fn view_ratio(obs: &ViewObservation, aligned: &[AlignedPart], noise: &RenderNoise) -> Option<f32> {
    let (w, h) = (obs.photo.width, obs.photo.height);
    let photo_luma: Vec<f32> = obs.photo.encoded.iter().map(|&p| luma(p)).collect();
    let mut ratios = Vec::new();
    let mut usable = vec![0.0f32; w * h];
    for part in aligned.iter().filter(|a| a.usable.len() >= MIN_PART_PIXELS) {
        part.usable.iter().for_each(|&i| usable[i as usize] = 1.0);
        let inner = part.usable.iter().map(|&i| i as usize).filter(|&i| {
            let (x, y) = (i % w, i / w);
            x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && (0..9).all(|k| usable[(y + k / 3 - 1) * w + x + k % 3 - 1] > 0.0)
        });
        let positions = inner.map(|i| [(i % w) as f32 + 0.5, (i / w) as f32 + 0.5]);
        let render = noise.sigma_at(part, positions);
        let photo = estimate_noise_sigma(&photo_luma, &usable, w, h);
        part.usable.iter().for_each(|&i| usable[i as usize] = 0.0);
        if let Some(r) = render.filter(|&r| r > 0.0 && photo > 0.0) {
            ratios.push(photo / r);
        }
    }
    lower_quartile(&mut ratios)
}

/// The lower quartile of `values` (nearest rank).
fn lower_quartile(values: &mut [f32]) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let q = (values.len() - 1) / 4;
    let (_, v, _) = values.select_nth_unstable_by(q, f32::total_cmp);
    Some(*v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cap_only_ever_lowers_an_estimate() {
        assert_eq!(cap_factor(0.02, 0.01), 0.5);
        assert_eq!(cap_factor(0.01, 0.02), 1.0);
        assert_eq!(cap_factor(0.0, 0.01), 1.0);
        assert_eq!(cap_factor(0.01, 0.0), 1.0);
    }
}
