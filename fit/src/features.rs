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
//!    two opponent axes) and per orientation, `ln(mean E + floor²)`. A contrast change shifts
//!    all entries equally, a scale change moves energy between levels, a rotation between
//!    orientations. Entries below the floor (flat or noisy bands) carry no signal either way.
//! 5. The loss is the weighted mean squared difference of the entries:
//!    `L = Σ_k ω_k (d_k − t_k)²`, ω summing to 1 (chroma entries weigh
//!    [`FeatureConfig::chroma_weight`] relative to achromatic ones). It is 0 when the region
//!    has no active level.
//!
//! Cross-scale correlations of the energies (Portilla–Simoncelli) were not added: the
//! per-band energies alone put the landscape minimum at the true scale and rotation on the dev
//! scenes (see `fit/tests/features_dev.rs`).
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
//! `FeatureLoss` with [`FeatureConfig::max_pixels`] set, and its own target descriptor.

mod filters;
mod pyramid;

use std::fmt;

use filters::{Bank, NUM_BASIS, NUM_FACTORS, RADIUS, TAPS};
use pyramid::{Geometry, Level};

/// Settings of the descriptor. [`FeatureConfig::default`] is what the fit uses.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureConfig {
    /// Pyramid octaves (1..=8). Level l's filters peak at a period of 4.7·2^l working pixels.
    pub levels: usize,
    /// Orientations per level (1..=16), θ = kπ/n.
    pub orientations: usize,
    /// Chroma energies besides the achromatic ones (three filtered axes instead of one).
    pub colour: bool,
    /// Working-resolution cap: the crop is box-reduced by the smallest integer factor that
    /// leaves at most this many pixels. `None`: full resolution.
    pub max_pixels: Option<usize>,
    /// Amplitude (sRGB units) below which band energies are not told apart: the descriptor is
    /// `ln(mean energy + contrast_floor²)`. Must be positive.
    pub contrast_floor: f32,
    /// A level counts when its pooled weight is at least this many of its pixels.
    pub min_level_support: f32,
    /// Weight of each chroma entry relative to an achromatic one (≥ 0).
    pub chroma_weight: f32,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        FeatureConfig {
            levels: 4,
            orientations: 6,
            colour: true,
            max_pixels: None,
            contrast_floor: 0.005,
            min_level_support: 16.0,
            chroma_weight: 1.0,
        }
    }
}

/// The crop of one part in one view: `width × height` pixels, row-major, row 0 at the top, and
/// a weight in [0, 1] per pixel (0 outside the usable mask).
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    pub width: usize,
    pub height: usize,
    pub weight: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq)]
pub enum FeatureError {
    /// A [`FeatureConfig`] value out of range.
    Config(String),
    /// A [`Region`] with a wrong size or weights outside [0, 1].
    Region(String),
    /// An image or gradient buffer whose length is not the region's.
    Size { what: &'static str, expected: usize, got: usize },
    /// A target descriptor made by a different [`FeatureLoss`] (another region or config).
    Mismatch,
}

impl fmt::Display for FeatureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FeatureError::Config(m) => write!(f, "feature loss configuration: {m}"),
            FeatureError::Region(m) => write!(f, "feature loss region: {m}"),
            FeatureError::Size { what, expected, got } => {
                write!(f, "feature loss: the {what} has {got} pixels, the region {expected}")
            }
            FeatureError::Mismatch => {
                f.write_str("feature loss: the target descriptor was made for another region or configuration")
            }
        }
    }
}

impl std::error::Error for FeatureError {}

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
}

/// Pooled statistics of one image over one region: `ln(mean energy + floor²)` per active
/// level, colour group (achromatic, then chroma) and orientation, in that nesting order.
#[derive(Clone, Debug, PartialEq)]
pub struct Descriptor {
    values: Vec<f32>,
    layout: Layout,
}

impl Descriptor {
    pub fn values(&self) -> &[f32] {
        &self.values
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
    rows: Vec<Vec<f32>>,
    line: Vec<f32>,
    tmp: Vec<f32>,
    d_planes: Vec<Vec<Vec<f32>>>,
    d_basis: Vec<f32>,
    d_rows: Vec<Vec<f32>>,
    sums: Vec<f64>,
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
        };
        Ok(FeatureLoss {
            geometry,
            bank: Bank::new(o),
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

    /// The descriptor of a crop image (sRGB values, `width × height`).
    pub fn describe(&self, image: &[[f32; 3]], scratch: &mut Scratch) -> Result<Descriptor, FeatureError> {
        self.check_image(image)?;
        let means = self.forward(image, scratch, false);
        Ok(Descriptor {
            values: means.iter().map(|&m| (m + self.eps).ln() as f32).collect(),
            layout: self.layout.clone(),
        })
    }

    /// The loss between two descriptors of this region (what [`FeatureLoss::loss`] computes).
    pub fn distance(&self, a: &Descriptor, b: &Descriptor) -> Result<f32, FeatureError> {
        self.check_target(a)?;
        self.check_target(b)?;
        let l: f64 = (a.values.iter().zip(&b.values).zip(&self.entry_weight))
            .map(|((&x, &y), &w)| w * f64::from(x - y).powi(2))
            .sum();
        Ok(l as f32)
    }

    /// The loss of a crop image against a target descriptor.
    pub fn loss(&self, image: &[[f32; 3]], target: &Descriptor, scratch: &mut Scratch) -> Result<f32, FeatureError> {
        self.check_image(image)?;
        self.check_target(target)?;
        let means = self.forward(image, scratch, false);
        Ok(self.loss_of_means(&means, target, None) as f32)
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
        let means = self.forward(image, scratch, true);
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

    /// The loss from the pooled means (in f64, so finite differences of it are meaningful),
    /// and optionally dL/d(mean) per entry.
    fn loss_of_means(&self, means: &[f64], target: &Descriptor, mut d_means: Option<&mut [f64]>) -> f64 {
        let mut loss = 0.0f64;
        for (k, ((&m, &t), &w)) in means.iter().zip(&target.values).zip(&self.entry_weight).enumerate() {
            let diff = (m + self.eps).ln() - f64::from(t);
            loss += w * diff * diff;
            if let Some(d) = d_means.as_deref_mut() {
                d[k] = 2.0 * w * diff / (m + self.eps);
            }
        }
        loss
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
    fn forward(&self, image: &[[f32; 3]], s: &mut Scratch, keep: bool) -> Vec<f64> {
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
        s.rows.resize_with(NUM_FACTORS, Vec::new);
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
                filter_level(&self.bank, &s.planes[l][a], level, &mut s.rows, basis);
                let group = usize::from(a > 0);
                let base = self.sum_index(l, group, 0);
                pool_energies(&self.bank, level, basis, &mut s.line, &mut s.sums[base..base + self.orientations]);
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
        s.d_rows.resize_with(NUM_FACTORS, Vec::new);
        for (k, &l) in self.layout.active_levels.iter().enumerate() {
            for a in 0..axes {
                let group = usize::from(a > 0);
                let base = (k * self.layout.groups + group) * o;
                energies_adjoint(&self.bank, &levels[l], &s.basis[l][a], &d_means[base..base + o], &mut s.d_basis);
                filter_level_adjoint(&self.bank, &s.d_basis, &levels[l], &mut s.d_rows, &mut s.d_planes[l][a]);
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

fn validate_config(c: &FeatureConfig) -> Result<(), FeatureError> {
    let err = |m: String| Err(FeatureError::Config(m));
    if !(1..=8).contains(&c.levels) {
        return err(format!("levels must be in 1..=8, got {}", c.levels));
    }
    if !(1..=16).contains(&c.orientations) {
        return err(format!("orientations must be in 1..=16, got {}", c.orientations));
    }
    if c.max_pixels == Some(0) {
        return err("max_pixels must be at least 1".into());
    }
    if !(c.contrast_floor.is_finite() && c.contrast_floor > 0.0) {
        return err(format!("contrast_floor must be positive, got {}", c.contrast_floor));
    }
    if !(c.min_level_support.is_finite() && c.min_level_support >= 0.0) {
        return err(format!("min_level_support must be ≥ 0, got {}", c.min_level_support));
    }
    if !(c.chroma_weight.is_finite() && c.chroma_weight >= 0.0) {
        return err(format!("chroma_weight must be ≥ 0, got {}", c.chroma_weight));
    }
    Ok(())
}

/// The seven basis responses of one plane over the level's pooling box, stored basis-major
/// (`basis[i·n + y·w + x]` for the box of width w and n pixels). The box lies at least RADIUS
/// pixels inside the level (its pooling weights require it), so no padding is needed.
fn filter_level(bank: &Bank, plane: &[f32], level: &Level, rows: &mut [Vec<f32>], basis: &mut Vec<f32>) {
    let lw = level.width;
    let (bw, bh) = (level.cols.len(), level.rows.len());
    let n = bw * bh;
    let rh = bh + TAPS - 1;
    for r in rows.iter_mut() {
        r.resize(rh * bw, 0.0);
    }
    for ry in 0..rh {
        let y = level.rows.start + ry - RADIUS;
        let inp = &plane[y * lw + level.cols.start - RADIUS..y * lw + level.cols.end + RADIUS];
        for (f, r) in bank.factors.iter().zip(rows.iter_mut()) {
            filters::correlate(inp, f, &mut r[ry * bw..(ry + 1) * bw]);
        }
    }
    basis.resize(NUM_BASIS * n, 0.0);
    for (i, &(rf, cf)) in filters::BASIS.iter().enumerate() {
        let out = &mut basis[i * n..(i + 1) * n];
        out.fill(0.0);
        for (k, &c) in bank.factors[cf].iter().enumerate() {
            filters::axpy(c, &rows[rf][k * bw..(k + bh) * bw], out);
        }
    }
}

/// The adjoint of [`filter_level`]: adds the plane gradient given the basis gradient.
fn filter_level_adjoint(bank: &Bank, d_basis: &[f32], level: &Level, d_rows: &mut [Vec<f32>], d_plane: &mut [f32]) {
    let lw = level.width;
    let (bw, bh) = (level.cols.len(), level.rows.len());
    let n = bw * bh;
    let rh = bh + TAPS - 1;
    for r in d_rows.iter_mut() {
        r.clear();
        r.resize(rh * bw, 0.0);
    }
    for (i, &(rf, cf)) in filters::BASIS.iter().enumerate() {
        let d = &d_basis[i * n..(i + 1) * n];
        for (k, &c) in bank.factors[cf].iter().enumerate() {
            filters::axpy(c, d, &mut d_rows[rf][k * bw..(k + bh) * bw]);
        }
    }
    for ry in 0..rh {
        let y = level.rows.start + ry - RADIUS;
        let out = &mut d_plane[y * lw + level.cols.start - RADIUS..y * lw + level.cols.end + RADIUS];
        for (f, r) in bank.factors.iter().zip(d_rows.iter()) {
            filters::correlate_adjoint(&r[ry * bw..(ry + 1) * bw], f, out);
        }
    }
}

/// Adds Σ pool·E(θ) over the box to `sums[θ]`. Pixels of weight 0 are skipped by selection
/// (not multiplication), so non-finite responses there cannot leak in.
fn pool_energies(bank: &Bank, level: &Level, basis: &[f32], line: &mut Vec<f32>, sums: &mut [f64]) {
    let bw = level.cols.len();
    let n = bw * level.rows.len();
    let b: [&[f32]; NUM_BASIS] = std::array::from_fn(|i| &basis[i * n..(i + 1) * n]);
    line.resize(bw, 0.0);
    for (steer, sum) in bank.steer.iter().zip(sums.iter_mut()) {
        for y in 0..level.rows.len() {
            let r = y * bw..(y + 1) * bw;
            let pool = &level.pool[r.clone()];
            let rb: [&[f32]; NUM_BASIS] = std::array::from_fn(|i| &b[i][r.clone()]);
            for x in 0..bw {
                let g = steer[0] * rb[0][x] + steer[1] * rb[1][x] + steer[2] * rb[2][x];
                let h = steer[3] * rb[3][x] + steer[4] * rb[4][x] + steer[5] * rb[5][x] + steer[6] * rb[6][x];
                let p = pool[x];
                line[x] = if p > 0.0 { p * (g * g + h * h) } else { 0.0 };
            }
            *sum += filters::lane_sum(line);
        }
    }
}

/// Basis gradient of one plane at one level given dL/d(mean energy) per orientation.
fn energies_adjoint(bank: &Bank, level: &Level, basis: &[f32], d_means: &[f64], d_basis: &mut Vec<f32>) {
    let bw = level.cols.len();
    let n = bw * level.rows.len();
    d_basis.clear();
    d_basis.resize(NUM_BASIS * n, 0.0);
    for (steer, &dm) in bank.steer.iter().zip(d_means) {
        let two_dm = (2.0 * dm) as f32;
        for (px, &p) in level.pool.iter().enumerate() {
            if p <= 0.0 {
                continue;
            }
            let v: [f32; NUM_BASIS] = std::array::from_fn(|i| basis[i * n + px]);
            let g = steer[0] * v[0] + steer[1] * v[1] + steer[2] * v[2];
            let h = steer[3] * v[3] + steer[4] * v[4] + steer[5] * v[5] + steer[6] * v[6];
            let w = two_dm * p;
            let (dg, dh) = (w * g, w * h);
            for i in 0..3 {
                d_basis[i * n + px] += steer[i] * dg;
            }
            for i in 3..NUM_BASIS {
                d_basis[i * n + px] += steer[i] * dh;
            }
        }
    }
}
