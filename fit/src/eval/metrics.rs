//! The image metrics of `psc eval`, on sRGB-encoded values in [0, 1] (renders are encoded with
//! the sRGB transfer and clamped before they get here).
//!
//! Per part (the pixels the truth label image gives the part):
//! - **RMSE**: √(mean over pixels and channels of (render − truth)²) — PhotoScene's metric;
//! - **mean colour error**: ‖mean(render) − mean(truth)‖₂ / √3 over the part's pixels, the RMS
//!   over channels of the difference of the mean colours;
//! - **colour W1**: the 1-Wasserstein distance between the render's and the truth's value
//!   distributions, per channel, averaged over channels;
//! - **contrast W1**: the 1-Wasserstein distance between the distributions of luminance-gradient
//!   magnitudes √(dx² + dy²): Rec. 709 luma of the sRGB values, smoothed by a Gaussian of
//!   σ = [`CONTRAST_SIGMA`] px (truncated at 2σ), forward differences, at the pixels of the part
//!   eroded by the filter's radius whose right and lower neighbours are in it too (so only the
//!   part's own pixels enter): `crate::contrast::gradient_magnitudes`, the statistic the fit's
//!   contrast loss matches, so the two cannot drift apart. The smoothing is there because at the pixel scale the gradients of
//!   a 64-spp render are mostly Monte Carlo noise: unsmoothed, the true materials score no better
//!   than a constant colour (measured on dev_4: oracle / pixel median 0.96–1.17×; smoothed with
//!   σ = 1: 0.19–0.38× on the true geometry).
//!
//! Whole image: **SSIM** (Wang et al. 2004): 11×11 Gaussian window with σ = 1.5, K1 = 0.01,
//! K2 = 0.03, L = 1, per channel over the positions where the window fits inside the image
//! ("valid"), averaged over positions and channels.
//!
//! Sums run in f64 in a fixed order, so the numbers do not depend on the thread count (the
//! contrast samples themselves are computed in f32, as the fit computes them).

use std::collections::BTreeMap;

/// Parts with fewer labelled pixels in an image are left out of that image's averages.
pub const MIN_PART_PIXELS: usize = 200;

pub use crate::contrast::erode;
/// Gaussian smoothing (px) of the luma before the gradients of the contrast metric.
pub use crate::contrast::SIGMA as CONTRAST_SIGMA;

/// Fitted light radiances against the true ones. Albedo and light trade a global scale, so each
/// light's fitted/true luminance ratio is compared with their geometric mean (`scale`).
#[derive(Clone, Debug)]
pub struct LightRatios {
    /// Per light, fitted over true luminance.
    pub ratios: Vec<f64>,
    /// Their geometric mean: the global scale.
    pub scale: f64,
}

impl LightRatios {
    pub fn new(fitted: &[[f32; 3]], truth: &[[f32; 3]]) -> LightRatios {
        let luminance = |c: &[f32; 3]| f64::from(psc_base::color::luminance(*c));
        let ratios: Vec<f64> = fitted.iter().zip(truth).map(|(f, t)| luminance(f) / luminance(t).max(1e-12)).collect();
        let scale = (ratios.iter().map(|r| r.max(1e-12).ln()).sum::<f64>() / ratios.len() as f64).exp();
        LightRatios { ratios, scale }
    }

    /// Per light, its ratio over the global scale.
    pub fn relative(&self) -> Vec<f64> {
        self.ratios.iter().map(|r| r / self.scale).collect()
    }

    /// The largest relative deviation of one light from the global scale.
    pub fn worst(&self) -> f64 {
        self.ratios.iter().map(|r| (r / self.scale - 1.0).abs()).fold(0.0, f64::max)
    }

    /// The two lights whose ratio is furthest off the truth's: the most scaled and the least
    /// (light 0 twice without lights).
    pub fn extreme_pair(&self) -> (usize, usize) {
        let by = |better: fn(f64, f64) -> bool| {
            (0..self.ratios.len()).fold(0, |best, k| if better(self.ratios[k], self.ratios[best]) { k } else { best })
        };
        (by(|a, b| a > b), by(|a, b| a < b))
    }

    /// The ratio between two lights off the truth's, the stricter reading: the most scaled light
    /// over the least scaled, minus 1 (0 without lights).
    pub fn between_two(&self) -> f64 {
        let (hi, lo) = self.extreme_pair();
        self.ratios.get(hi).zip(self.ratios.get(lo)).map_or(0.0, |(hi, lo)| hi / lo.max(1e-12) - 1.0)
    }
}

/// The metrics of one part in one image.
#[derive(Clone, Debug, PartialEq)]
pub struct PartMetrics {
    pub part: String,
    pub pixels: usize,
    pub rmse: f64,
    pub mean_colour: f64,
    pub colour_w1: f64,
    /// `None` when the eroded part has no pixel with both forward neighbours inside it.
    pub contrast_w1: Option<f64>,
}

/// √(mean of squared differences over all channels of all pixels); 0 for empty input.
pub fn rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    if a.is_empty() {
        return 0.0;
    }
    let mut s = 0.0f64;
    for (p, q) in a.iter().zip(b) {
        for k in 0..3 {
            let d = p[k] as f64 - q[k] as f64;
            s += d * d;
        }
    }
    (s / (3 * a.len()) as f64).sqrt()
}

/// Mean colour (per channel) of a set of pixels; zeros for an empty set.
pub fn mean_colour(a: &[[f32; 3]]) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in a {
        for k in 0..3 {
            m[k] += p[k] as f64;
        }
    }
    let n = a.len().max(1) as f64;
    m.map(|x| x / n)
}

/// ‖mean(a) − mean(b)‖₂ / √3.
pub fn mean_colour_error(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let (ma, mb) = (mean_colour(a), mean_colour(b));
    let s: f64 = (0..3).map(|k| (ma[k] - mb[k]).powi(2)).sum();
    (s / 3.0).sqrt()
}

/// The 1-Wasserstein distance between the empirical distributions of `a` and `b` (any sizes):
/// ∫ |F_a(x) − F_b(x)| dx, by a merge of the sorted samples. Sorts both in place. 0 if either
/// is empty.
pub fn wasserstein1(a: &mut [f32], b: &mut [f32]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    a.sort_unstable_by(f32::total_cmp);
    b.sort_unstable_by(f32::total_cmp);
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j) = (0usize, 0usize);
    let mut x = a[0].min(b[0]) as f64;
    let mut total = 0.0f64;
    while i < a.len() || j < b.len() {
        // The next breakpoint of either CDF.
        let next = match (a.get(i), b.get(j)) {
            (Some(&u), Some(&v)) => u.min(v) as f64,
            (Some(&u), None) => u as f64,
            (None, Some(&v)) => v as f64,
            (None, None) => break,
        };
        total += (i as f64 / na - j as f64 / nb).abs() * (next - x);
        x = next;
        while i < a.len() && a[i] as f64 == next {
            i += 1;
        }
        while j < b.len() && b[j] as f64 == next {
            j += 1;
        }
    }
    total
}

/// Per-channel W1 between two pixel sets, averaged over channels.
pub fn colour_w1(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    (0..3)
        .map(|k| {
            let mut x: Vec<f32> = a.iter().map(|p| p[k]).collect();
            let mut y: Vec<f32> = b.iter().map(|p| p[k]).collect();
            wasserstein1(&mut x, &mut y)
        })
        .sum::<f64>()
        / 3.0
}

/// The samples of the contrast metric: gradient magnitudes of the smoothed luma inside the
/// eroded part (see the module doc).
pub fn contrast_samples(img: &[[f32; 3]], width: usize, height: usize, mask: &[bool]) -> Vec<f32> {
    crate::contrast::gradient_magnitudes(img, width, height, mask)
}

/// The metrics of every part of `names` with at least [`MIN_PART_PIXELS`] pixels in `labels`
/// (label value → part name), in the order of the label values.
pub fn part_metrics(
    render: &[[f32; 3]],
    truth: &[[f32; 3]],
    width: usize,
    height: usize,
    labels: &[u16],
    names: &BTreeMap<u16, String>,
) -> Vec<PartMetrics> {
    let mut out = Vec::new();
    for (&value, name) in names {
        let mask: Vec<bool> = labels.iter().map(|&l| l == value).collect();
        let pixels = mask.iter().filter(|&&m| m).count();
        if pixels < MIN_PART_PIXELS {
            continue;
        }
        let pick = |img: &[[f32; 3]]| -> Vec<[f32; 3]> {
            img.iter().zip(&mask).filter(|(_, &m)| m).map(|(p, _)| *p).collect()
        };
        let (r, t) = (pick(render), pick(truth));
        let mut gr = contrast_samples(render, width, height, &mask);
        let mut gt = contrast_samples(truth, width, height, &mask);
        let contrast_w1 = (!gr.is_empty()).then(|| wasserstein1(&mut gr, &mut gt));
        out.push(PartMetrics {
            part: name.clone(),
            pixels,
            rmse: rmse(&r, &t),
            mean_colour: mean_colour_error(&r, &t),
            colour_w1: colour_w1(&r, &t),
            contrast_w1,
        });
    }
    out
}

const SSIM_RADIUS: usize = 5;
const SSIM_SIGMA: f64 = 1.5;

fn gaussian_window() -> [f64; 2 * SSIM_RADIUS + 1] {
    let mut w = [0.0; 2 * SSIM_RADIUS + 1];
    for (i, v) in w.iter_mut().enumerate() {
        let d = i as f64 - SSIM_RADIUS as f64;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = w.iter().sum();
    w.map(|v| v / s)
}

/// Separable Gaussian filter, "valid" region: output (w − 10) × (h − 10).
fn filter_valid(img: &[f64], w: usize, h: usize, g: &[f64]) -> Vec<f64> {
    let n = g.len();
    let (ow, oh) = (w + 1 - n, h + 1 - n);
    let mut rows = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            rows[y * ow + x] = (0..n).map(|k| g[k] * img[y * w + x + k]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..n).map(|k| g[k] * rows[(y + k) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM of two RGB images (values in [0, 1]), averaged over channels; `None` when an image
/// is smaller than the 11×11 window.
pub fn ssim(a: &[[f32; 3]], b: &[[f32; 3]], width: usize, height: usize) -> Option<f64> {
    let n = 2 * SSIM_RADIUS + 1;
    if width < n || height < n || a.len() != width * height || b.len() != width * height {
        return None;
    }
    let g = gaussian_window();
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let mut total = 0.0;
    for k in 0..3 {
        let x: Vec<f64> = a.iter().map(|p| p[k] as f64).collect();
        let y: Vec<f64> = b.iter().map(|p| p[k] as f64).collect();
        let prod = |u: &[f64], v: &[f64]| -> Vec<f64> { u.iter().zip(v).map(|(p, q)| p * q).collect() };
        let mx = filter_valid(&x, width, height, &g);
        let my = filter_valid(&y, width, height, &g);
        let sxx = filter_valid(&prod(&x, &x), width, height, &g);
        let syy = filter_valid(&prod(&y, &y), width, height, &g);
        let sxy = filter_valid(&prod(&x, &y), width, height, &g);
        let mut s = 0.0;
        for i in 0..mx.len() {
            let (mu_x, mu_y) = (mx[i], my[i]);
            let vx = sxx[i] - mu_x * mu_x;
            let vy = syy[i] - mu_y * mu_y;
            let cxy = sxy[i] - mu_x * mu_y;
            s += ((2.0 * mu_x * mu_y + c1) * (2.0 * cxy + c2)) / ((mu_x * mu_x + mu_y * mu_y + c1) * (vx + vy + c2));
        }
        total += s / mx.len() as f64;
    }
    Some(total / 3.0)
}
