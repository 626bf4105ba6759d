//! The feature loss: a fixed, weight-free, multi-scale texture descriptor with an exact adjoint.
//!
//! It compares the *pattern* of a candidate rendering of a part with the photo's: invariant to
//! the pattern's phase (a fitted texture cannot match a photo pixel for pixel), sensitive to its
//! scale, orientation and contrast, so that UV search can find them. It stands in for
//! PhotoScene's VGG Gram-matrix loss, whose weights cannot be had here and which costs tens of
//! GFLOP per iteration.
//!
//! # What is computed
//! 1. The crop (sRGB values in [0, 1], row-major, row 0 at the top) is optionally reduced to a
//!    working resolution (box average by an integer factor, so that it has at most
//!    [`FeatureConfig::max_pixels`] pixels) and projected on three orthogonal colour axes of
//!    equal norm: achromatic `(r + g + b)/3` and two opponent axes `(r − g)/√6` and
//!    `(r + g − 2b)/(3√2)`. The sum of squares over the three axes is the mean of squares over
//!    r, g, b, so energies are in sRGB amplitude² units whichever axis carries the pattern.
//!    With [`FeatureConfig::colour`] off only the achromatic axis is used.
//! 2. Each axis gets a Gaussian pyramid ([`FeatureConfig::levels`] octaves, 5-tap binomial).
//! 3. At every level, a steerable quadrature pair (Freeman–Adelson G2/H2, 9×9, seven separable
//!    basis filters, peak at a period of 4.7 pixels of that level, about 1.2 octaves wide) is
//!    steered to [`FeatureConfig::orientations`] orientations θ = kπ/n, and the local energy
//!    E = G2(θ)² + H2(θ)² (phase-invariant by construction) is pooled over the mask.
//! 4. The descriptor is, per active level, per colour group (achromatic; chroma = sum of the
//!    two opponent axes) and per orientation, the log amplitude `½·ln(mean E + floor²)`. A
//!    contrast change shifts all entries equally, a scale change moves energy between levels,
//!    a rotation between orientations; the descriptor is exactly invariant to a 180° rotation.
//!    Entries below [`FeatureConfig::contrast_floor`] (flat bands) carry no signal either way.
//! 5. The loss is the weighted mean squared difference of the entries,
//!    `L = Σ_k ω_k (d_k − t_k)²`, ω summing to 1 (chroma entries weigh
//!    [`FeatureConfig::chroma_weight`] relative to achromatic ones), with the photo's noise
//!    handled as below. It is 0 when the region has no active level.
//!
//! # The photo's noise
//! Photos carry pixel noise (the dev photos: path tracing at 256 spp, σ ≈ 0.01 in sRGB) that
//! rendered candidates lack. On faint textures (plaster) it dominates the finest band, and a
//! loss blind to it prefers candidates scaled finer than the truth, whose extra fine energy
//! mimics the noise. Independent noise adds its own energy σ²‖k‖² to a band of filter k in
//! expectation (the gains ‖k‖² are computed exactly, through the pyramid; `noise.rs`).
//! [`FeatureLoss::describe`] estimates σ per colour axis on the target (Immerkær's mask,
//! median absolute response), and the loss forgives a candidate whose band energy falls short
//! of the target's by up to the target's noise energy: a dead zone below the target (the
//! squared loss stays C¹). A dead zone rather than adding the noise energy, because the
//! estimate also counts fine *texture* as noise (on the dev_1 gravel it reads 0.032 where the
//! noise is about 0.013): adding it would then double-count that energy, whereas the dead zone
//! only stops penalising deficits. Measured on the dev scenes (`fit/tests/features_dev.rs`,
//! every textured part and view at the UV search's resolution): 14 of 17 landscape minima near
//! the truth with the dead zone, 11 adding the estimate, 10 without a noise model.
//! [`FeatureConfig::photo_noise`] turns it off.
//!
//! Tried and left out, for lack of measured benefit on the dev scenes: pooling amplitudes
//! √(E + floor²) instead of energies (one minimum fewer, in an earlier version of the test),
//! and weighting each entry by its reliability estimated from the target (the spread of the
//! entry over a 4×4 grid of blocks: the same count with and without, at both resolutions).
//! Cross-scale correlations of the energies (Portilla–Simoncelli) were not added: the failures
//! that remain come from the pattern's phase when a region shows few repeats (two or three
//! plank joints), which no statistic pooled over that region can remove.
//!
//! An energy-sparsity entry per band was built (session 54) and left out:
//! `ln((mean E² + floor⁴) / (mean E + floor²)²)`, a kurtosis of the local energy. It is ln 2
//! for Gaussian texture or noise and 0 for a pure grating. On the clean dev textures at the
//! finest level it is about 3 for plank joints and at most 2.1 for the linen, leather, concrete
//! and marble graphs that win plank floors. It had an exact adjoint (E² pooled beside E) and a
//! noise dead zone: the target may lie anywhere between the candidate's value and that value
//! with the target's noise energy added. Measured, each weight per entry relative to an
//! amplitude entry:
//!
//! | where | weight | landscape minima near the truth (`features_dev`) | selection bench crops |
//! | --- | --- | --- | --- |
//! | none (the head) | – | 14 of 17 | 13 of 20 |
//! | whole loss | 0.1 | 11 | 11 |
//! | whole loss | 0.3 | 9 | 14 |
//! | vote only | 0.3 | 14 (unchanged) | 12 |
//! | vote only | 1.0 | 14 (unchanged) | 14 |
//!
//! - In the loss that the UV search and the fit descend, it moved minima off the true scale.
//!   On a crop of a few plank joints the statistic depends on their phase.
//! - In the selection, every weighting turned 4 to 7 of the 20 judged crops (against the
//!   head's choices), both ways. Plank crops went to polished concrete, linoleum or the
//!   acoustic ceiling. Plaster crops came back (dev_4's plaster at 160 px a tile went from a
//!   marble to plaster at every weighting). That is the churn a change of seed makes.
//!
//! # Masking
//! Exact erosion (see `pyramid.rs`): every filter response is pooled with the *minimum* of the
//! crop weights over the crop pixels it depends on (through the working-resolution box and
//! the pyramid's blurs), so pixels of weight 0 — outside the part, clipped, or on a boundary —
//! never reach the statistics, whatever they hold (NaN included), and their gradient is 0.
//! The price: a level only sees the mask eroded by its footprint (4, 10, 22, 46 crop pixels
//! at levels 0–3 without working-resolution reduction). A level whose pooled weight is below
//! [`FeatureConfig::min_level_support`] (in that level's pixels) is dropped; a thin part may
//! keep only the finest levels, or none ([`FeatureLoss::is_empty`]). The descriptor of a
//! region depends on the region, so target and candidates must share one [`FeatureLoss`].
//!
//! # Adjoint
//! [`FeatureLoss::loss_and_grad`] gives dL/d(pixel value) for all three channels of every crop
//! pixel: it keeps the basis responses of the forward pass and runs every linear stage
//! transposed (filters, pyramid reductions, working-resolution box, colour projection).
//!
//! # Use
//! ```ignore
//! let loss = FeatureLoss::new(&FeatureConfig::default(), &Region { width, height, weight })?;
//! let mut scratch = Scratch::default();                 // one per thread
//! let target = loss.describe(&photo_crop, &mut scratch)?;
//! let l = loss.loss_and_grad(&candidate, &target, &mut scratch, &mut grad)?;
//! ```
//! `FeatureLoss` is immutable after construction (`&self` everywhere) and `Sync`: several rayon
//! threads may use one at once, each with its own [`Scratch`]. Results do not depend on the
//! thread or on what the scratch held before. For UV search over large crops use a second
//! `FeatureLoss` with [`FeatureConfig::max_pixels`] set, and its own target descriptor (or
//! render candidates at the reduced size directly and give it the reduced region).
//!
//! Candidates must be filtered over their pixel footprint like the photo (a camera or a path
//! tracer integrates each pixel): point-sampled, minified textures alias, gain fine-scale
//! energy, and pull the minimum to coarser or finer scales. In the dev-scene test, one
//! mip-filtered sample per footprint (instead of two) multiplied the loss at the truth by 70
//! on one part and lost 4 of 14 minima.
//!
//! Throughput (`cargo bench -p psc-fit --bench features`, one thread, shared 2-core machine):
//! describe 12–14 Mpx/s on colour crops of 16–77 k pixels (about 1000 flops a pixel),
//! 30–57 Mpx/s achromatic, 100+ Mpx/s of crop with a 128² working-resolution cap;
//! loss + gradient 1.5–2× the time of describe.

mod bank;
mod config;
mod filters;
mod noise;
mod pyramid;

pub use config::{FeatureConfig, FeatureError, Region};

use config::validate_config;
use filters::Bank;
use pyramid::Geometry;

/// Immerkær's estimate of the pixel-noise standard deviation of a plane (median absolute
/// response of his mask) over the pixels whose whole 3×3 window has a positive weight; 0 when
/// there are none. On a crop it also counts the part's finest texture as noise.
pub fn estimate_noise_sigma(plane: &[f32], weight: &[f32], width: usize, height: usize) -> f32 {
    noise::estimate_sigma(plane, weight, width, height, &mut Vec::new())
}

/// Which entries a descriptor has; two descriptors compare only with equal layouts.
#[derive(Clone, Debug, PartialEq)]
struct Layout {
    width: usize,
    height: usize,
    factor: usize,
    active_levels: Vec<usize>,
    groups: usize,
    orientations: usize,
    floor_bits: u32,
    /// FNV-1a hash of the region's weights: equal sizes do not make regions equal.
    region_hash: u64,
}

/// Pooled statistics of one image over one region: `½·ln(mean energy + floor²)` (a log
/// amplitude) per active level, colour group (achromatic, then chroma) and orientation, in that
/// nesting order; and the image's estimated pixel noise, which sets the dead zone of losses
/// against it as a target.
#[derive(Clone, Debug, PartialEq)]
pub struct Descriptor {
    values: Vec<f32>,
    /// Pooled mean energies, per entry.
    means: Vec<f64>,
    /// Expected noise energy of the image per entry (zero without `photo_noise`).
    noise: Vec<f64>,
    sigma: [f32; 3],
    layout: Layout,
}

impl Descriptor {
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Estimated noise standard deviation of the described image on each colour axis
    /// (achromatic, then the two opponent axes; sRGB units at the working resolution), or
    /// zeros without [`FeatureConfig::photo_noise`].
    pub fn noise_sigma(&self) -> [f32; 3] {
        self.sigma
    }

    /// Takes only the fraction `scale` (in (0, 1]) of the estimated noise as noise: the
    /// render-noise check found the rest to be texture ([`crate::render_noise`]).
    pub fn scale_noise(&mut self, scale: f32) {
        self.sigma.iter_mut().for_each(|s| *s *= scale);
        let s2 = f64::from(scale).powi(2);
        self.noise.iter_mut().for_each(|n| *n *= s2);
    }
}

/// Reusable buffers for [`FeatureLoss`] calls; one per thread. Grows to the largest region it
/// served and never shrinks.
#[derive(Default)]
pub struct Scratch {
    /// Pyramid planes, `[level][axis]`.
    planes: Vec<Vec<Vec<f32>>>,
    /// Basis responses over each level's pooling box, `[level][axis]` (only `[0][0]` when no
    /// gradient is wanted).
    basis: Vec<Vec<Vec<f32>>>,
    rows: Vec<f32>,
    line: Vec<f32>,
    tmp: Vec<f32>,
    d_planes: Vec<Vec<Vec<f32>>>,
    d_basis: Vec<f32>,
    d_rows: Vec<f32>,
    sums: Vec<f64>,
}

/// What a forward pass keeps besides the pooled means.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Nothing: a loss or a description.
    Loss,
    /// The basis responses, for [`FeatureLoss::backward`].
    Gradient,
}

/// Colour axes: achromatic, then the two opponent axes (orthogonal, equal norms).
const AXES: [[f32; 3]; 3] =
    [[1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], [0.408_248_3, -0.408_248_3, 0.0], [0.235_702_27, 0.235_702_27, -0.471_404_54]];

/// The feature loss of one region: its pyramid masks and pooling weights, built once.
#[derive(Clone, Debug)]
pub struct FeatureLoss {
    geometry: Geometry,
    bank: Bank,
    layout: Layout,
    /// Number of colour axes filtered (1 or 3).
    axes: usize,
    orientations: usize,
    /// floor², added to every mean energy before the logarithm.
    eps: f64,
    /// Weight of each descriptor entry in the loss (sums to 1).
    entry_weight: Vec<f64>,
    photo_noise: bool,
    /// Noise energy per unit noise variance, `[level][orientation]` (see `noise.rs`).
    gains: Vec<Vec<f64>>,
}

impl FeatureLoss {
    pub fn new(config: &FeatureConfig, region: &Region) -> Result<FeatureLoss, FeatureError> {
        validate_config(config)?;
        let (w, h) = (region.width, region.height);
        let n = w.checked_mul(h).ok_or_else(|| FeatureError::Region(format!("{w}x{h} is too large")))?;
        if n == 0 {
            return Err(FeatureError::Region(format!("{w}x{h} has no pixels")));
        }
        if region.weight.len() != n {
            return Err(FeatureError::Region(format!("{w}x{h} needs {n} weights, got {}", region.weight.len())));
        }
        if let Some(i) = region.weight.iter().position(|v| !(0.0..=1.0).contains(v)) {
            return Err(FeatureError::Region(format!(
                "weight {} at pixel ({}, {}) is not in [0, 1]",
                region.weight[i],
                i % w,
                i / w
            )));
        }
        let factor = match config.max_pixels {
            None => 1,
            Some(cap) => (1..).find(|f| w.div_ceil(*f) * h.div_ceil(*f) <= cap).unwrap_or(1),
        };
        let geometry = Geometry::new(w, h, &region.weight, factor, config.levels, f64::from(config.min_level_support));
        let active_levels: Vec<usize> = (0..geometry.levels.len()).filter(|&l| geometry.levels[l].active).collect();
        let groups = if config.colour { 2 } else { 1 };
        let o = config.orientations;
        let mut entry_weight = Vec::with_capacity(active_levels.len() * groups * o);
        for _ in &active_levels {
            for g in 0..groups {
                let wgt = if g == 0 { 1.0 } else { f64::from(config.chroma_weight) };
                entry_weight.extend(std::iter::repeat_n(wgt, o));
            }
        }
        let total: f64 = entry_weight.iter().sum();
        if total > 0.0 {
            entry_weight.iter_mut().for_each(|v| *v /= total);
        }
        let layout = Layout {
            width: w,
            height: h,
            factor,
            active_levels,
            groups,
            orientations: o,
            floor_bits: config.contrast_floor.to_bits(),
            region_hash: region.weight.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, w| {
                (h ^ u64::from(w.to_bits())).wrapping_mul(0x0000_0100_0000_01b3)
            }),
        };
        let bank = Bank::new(o);
        let gains = noise::band_gains(&bank, geometry.levels.len());
        Ok(FeatureLoss {
            geometry,
            bank,
            photo_noise: config.photo_noise,
            gains,
            layout,
            axes: if config.colour { 3 } else { 1 },
            orientations: o,
            eps: f64::from(config.contrast_floor).powi(2),
            entry_weight,
        })
    }

    /// Pyramid levels that contribute (0 = finest).
    pub fn active_levels(&self) -> &[usize] {
        &self.layout.active_levels
    }

    /// True when no level has enough support: the loss is then always 0.
    pub fn is_empty(&self) -> bool {
        self.layout.active_levels.is_empty()
    }

    /// Size of the working-resolution crop and the reduction factor.
    pub fn working_size(&self) -> (usize, usize, usize) {
        let (w, h) = self.geometry.working_size();
        (w, h, self.geometry.factor)
    }

    /// Number of descriptor entries.
    pub fn descriptor_len(&self) -> usize {
        self.entry_weight.len()
    }

    /// The descriptor of a crop image (sRGB values, `width × height`). Describe the photo
    /// (the target) with this; candidates go to [`FeatureLoss::loss`].
    pub fn describe(&self, image: &[[f32; 3]], scratch: &mut Scratch) -> Result<Descriptor, FeatureError> {
        self.check_image(image)?;
        let means = self.forward(image, scratch, Pass::Loss);
        let mut sigma = [0.0f32; 3];
        let mut noise = vec![0.0f64; means.len()];
        if self.photo_noise && !means.is_empty() {
            let (w0, h0) = self.geometry.working_size();
            for (a, s) in sigma.iter_mut().enumerate().take(self.axes) {
                *s = noise::estimate_sigma(&scratch.planes[0][a], &self.geometry.weight0, w0, h0, &mut scratch.tmp);
            }
            let variance = [f64::from(sigma[0]).powi(2), f64::from(sigma[1]).powi(2) + f64::from(sigma[2]).powi(2)];
            let mut k = 0;
            for &l in &self.layout.active_levels {
                for var in variance.iter().take(self.layout.groups) {
                    for gain in &self.gains[l] {
                        noise[k] = var * gain;
                        k += 1;
                    }
                }
            }
        }
        Ok(Descriptor {
            values: means.iter().map(|&m| self.log_stat(m) as f32).collect(),
            means,
            noise,
            sigma,
            layout: self.layout.clone(),
        })
    }

    /// The loss of a candidate's descriptor against a target's (what [`FeatureLoss::loss`]
    /// computes for the candidate's image).
    pub fn distance(&self, candidate: &Descriptor, target: &Descriptor) -> Result<f32, FeatureError> {
        self.check_target(candidate)?;
        self.check_target(target)?;
        Ok(self.loss_of_means(&candidate.means, target, None) as f32)
    }

    /// The loss of a crop image against a target descriptor.
    pub fn loss(&self, image: &[[f32; 3]], target: &Descriptor, scratch: &mut Scratch) -> Result<f32, FeatureError> {
        self.check_image(image)?;
        self.check_target(target)?;
        let means = self.forward(image, scratch, Pass::Loss);
        Ok(self.loss_of_means(&means, target, None) as f32)
    }

    /// The loss of a crop image against a target descriptor at the best of the descriptor's
    /// orientation shifts: the candidate's energies rotated by every multiple of π/n (cyclic
    /// in the orientation index, exact for rotations of a fronto-parallel pattern). For ranking
    /// candidates whose orientation is not yet searched: a pattern that matches the photo once
    /// turned is not penalised against an isotropic one for the turn.
    pub fn loss_any_orientation(
        &self,
        image: &[[f32; 3]],
        target: &Descriptor,
        scratch: &mut Scratch,
    ) -> Result<f32, FeatureError> {
        self.check_image(image)?;
        self.check_target(target)?;
        let means = self.forward(image, scratch, Pass::Loss);
        let o = self.orientations;
        let mut turned = vec![0.0f64; means.len()];
        let mut best = f64::INFINITY;
        for shift in 0..o {
            for (band, out) in means.chunks_exact(o).zip(turned.chunks_exact_mut(o)) {
                for (j, v) in out.iter_mut().enumerate() {
                    *v = band[(j + shift) % o];
                }
            }
            best = best.min(self.loss_of_means(&turned, target, None));
        }
        Ok(best as f32)
    }

    /// The loss and its gradient with respect to every channel of every crop pixel, written
    /// (not added) to `grad` (`width × height`; zero where the weight is 0).
    pub fn loss_and_grad(
        &self,
        image: &[[f32; 3]],
        target: &Descriptor,
        scratch: &mut Scratch,
        grad: &mut [[f32; 3]],
    ) -> Result<f32, FeatureError> {
        self.check_image(image)?;
        self.check_target(target)?;
        let n = self.geometry.width * self.geometry.height;
        if grad.len() != n {
            return Err(FeatureError::Size { what: "gradient buffer", expected: n, got: grad.len() });
        }
        let means = self.forward(image, scratch, Pass::Gradient);
        let mut d_means = vec![0.0; means.len()];
        let loss = self.loss_of_means(&means, target, Some(&mut d_means));
        self.backward(&d_means, scratch, grad);
        Ok(loss as f32)
    }

    /// Pooled weight of each pyramid level in its own pixels (before normalisation), and
    /// whether it reaches [`FeatureConfig::min_level_support`]; levels past the last active
    /// one are not listed.
    pub fn level_supports(&self) -> Vec<(f64, bool)> {
        self.geometry.levels.iter().map(|l| (l.support, l.active)).collect()
    }

    /// The loss from a candidate's pooled means (in f64, so finite differences of it are
    /// meaningful), with the target's noise energy added, and optionally dL/d(mean) per entry.
    fn loss_of_means(&self, means: &[f64], target: &Descriptor, mut d_means: Option<&mut [f64]>) -> f64 {
        let mut loss = 0.0f64;
        for (k, ((&m, &t), &w)) in means.iter().zip(&target.values).zip(&self.entry_weight).enumerate() {
            // Dead zone: a candidate short of the target by at most the target's noise energy
            // matches (its shortfall may be the photo's noise); the squared loss stays C¹.
            let shortfall = (target.means[k] - m).clamp(0.0, target.noise[k]);
            let m = m + shortfall;
            let diff = self.log_stat(m) - f64::from(t);
            loss += w * diff * diff;
            if let Some(d) = d_means.as_deref_mut() {
                d[k] = 2.0 * w * diff * 0.5 / (m + self.eps);
            }
        }
        loss
    }

    /// A descriptor entry from its pooled mean energy: a log amplitude.
    fn log_stat(&self, m: f64) -> f64 {
        0.5 * (m + self.eps).ln()
    }

    fn check_image(&self, image: &[[f32; 3]]) -> Result<(), FeatureError> {
        let n = self.geometry.width * self.geometry.height;
        if image.len() != n {
            return Err(FeatureError::Size { what: "image", expected: n, got: image.len() });
        }
        Ok(())
    }

    fn check_target(&self, target: &Descriptor) -> Result<(), FeatureError> {
        if target.layout != self.layout || target.values.len() != self.entry_weight.len() {
            return Err(FeatureError::Mismatch);
        }
        Ok(())
    }

    /// Index of the pooled sum of (level, group, orientation) in `Scratch::sums`.
    fn sum_index(&self, level: usize, group: usize, o: usize) -> usize {
        (level * 2 + group) * self.orientations + o
    }

    /// Builds the pyramids, filters every active level and returns the pooled mean energy of
    /// every descriptor entry. With `keep`, the basis responses stay in the scratch for
    /// [`FeatureLoss::backward`].
    fn forward(&self, image: &[[f32; 3]], s: &mut Scratch, pass: Pass) -> Vec<f64> {
        let keep = pass == Pass::Gradient;
        let levels = &self.geometry.levels;
        let nl = levels.len();
        let axes = self.axes;
        s.planes.resize_with(nl.max(1), Vec::new);
        for p in &mut s.planes {
            p.resize_with(axes, Vec::new);
        }
        s.basis.resize_with(nl.max(1), Vec::new);
        for b in &mut s.basis {
            b.resize_with(axes, Vec::new);
        }
        s.sums.clear();
        s.sums.resize(nl * 2 * self.orientations, 0.0);
        if nl == 0 {
            return Vec::new();
        }
        self.geometry.reduce_image(image, &AXES[..axes], &mut s.planes[0]);
        for l in 0..nl {
            if l > 0 {
                let (done, rest) = s.planes.split_at_mut(l);
                let (pw, ph) = (levels[l - 1].width, levels[l - 1].height);
                for a in 0..axes {
                    pyramid::reduce(&done[l - 1][a], pw, ph, &mut rest[0][a], &mut s.tmp);
                }
            }
            let level = &levels[l];
            if !level.active {
                continue;
            }
            for a in 0..axes {
                let basis = if keep { &mut s.basis[l][a] } else { &mut s.basis[0][0] };
                bank::filter_level(&self.bank, &s.planes[l][a], level, &mut s.rows, basis);
                let group = usize::from(a > 0);
                let base = self.sum_index(l, group, 0);
                let sums = &mut s.sums[base..base + self.orientations];
                bank::pool_energies(&self.bank, level, basis, &mut s.line, sums);
            }
        }
        let mut means = Vec::with_capacity(self.entry_weight.len());
        for &l in &self.layout.active_levels {
            for g in 0..self.layout.groups {
                let base = self.sum_index(l, g, 0);
                means.extend_from_slice(&s.sums[base..base + self.orientations]);
            }
        }
        means
    }

    /// Gradient of the loss with respect to the crop, given its gradient with respect to the
    /// pooled means (in descriptor order) and the scratch of a `forward(.., keep = true)`.
    fn backward(&self, d_means: &[f64], s: &mut Scratch, grad: &mut [[f32; 3]]) {
        let levels = &self.geometry.levels;
        let nl = levels.len();
        let axes = self.axes;
        let o = self.orientations;
        s.d_planes.resize_with(nl.max(1), Vec::new);
        for (l, p) in s.d_planes.iter_mut().enumerate() {
            p.resize_with(axes, Vec::new);
            if l < nl {
                for plane in p.iter_mut() {
                    plane.clear();
                    plane.resize(levels[l].width * levels[l].height, 0.0);
                }
            }
        }
        if nl == 0 {
            grad.fill([0.0; 3]);
            return;
        }
        for (k, &l) in self.layout.active_levels.iter().enumerate() {
            for a in 0..axes {
                let group = usize::from(a > 0);
                let base = (k * self.layout.groups + group) * o;
                let d = &d_means[base..base + o];
                bank::energies_adjoint(&self.bank, &levels[l], &s.basis[l][a], d, &mut s.line, &mut s.d_basis);
                bank::filter_level_adjoint(&self.bank, &s.d_basis, &levels[l], &mut s.d_rows, &mut s.d_planes[l][a]);
            }
        }
        for l in (1..nl).rev() {
            let (finer, coarser) = s.d_planes.split_at_mut(l);
            let (pw, ph) = (levels[l - 1].width, levels[l - 1].height);
            for a in 0..axes {
                pyramid::reduce_adjoint(&coarser[0][a], pw, ph, &mut finer[l - 1][a], &mut s.tmp);
            }
        }
        self.geometry.reduce_image_adjoint(&s.d_planes[0], &AXES[..axes], grad);
    }
}
