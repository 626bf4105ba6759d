//! The descriptor's settings, the region it pools over, and its errors.

use std::fmt;

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
    /// `½·ln(mean energy + contrast_floor²)`. Must be positive.
    pub contrast_floor: f32,
    /// A level counts when its pooled weight is at least this many of its pixels.
    pub min_level_support: f32,
    /// Weight of each chroma entry relative to an achromatic one (≥ 0).
    pub chroma_weight: f32,
    /// Model the target's pixel noise: [`FeatureLoss::describe`](super::FeatureLoss::describe) estimates it, and the losses
    /// do not penalise a (noise-free) candidate for falling short of a band's energy by up to
    /// the noise's share of it (see the module docs).
    pub photo_noise: bool,
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
            photo_noise: true,
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
    /// A target descriptor made by a different [`FeatureLoss`](super::FeatureLoss) (another region or config).
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

pub(super) fn validate_config(c: &FeatureConfig) -> Result<(), FeatureError> {
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
