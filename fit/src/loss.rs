//! Losses between a rendered crop and the photo: PhotoScene's statistics loss (masked
//! per-channel mean and standard deviation, L1), the feature loss of [`crate::features`] and
//! the contrast loss of [`crate::contrast`], weighted.
//!
//! The photo's pixel noise adds to its standard deviation, and a rendered candidate has none:
//! matching the two would ask a plain part for a texture as strong as the noise. So the
//! standard-deviation term has a dead zone, as the feature loss's bands do: a candidate whose
//! deviation lies between √(σ_photo² − σ_noise²) and σ_photo (per channel, the photo's noise
//! as [`PartView::noise`] gives it) is not penalised.

use serde::Serialize;

use crate::contrast::{ContrastLoss, ContrastScratch};
use crate::error::FitError;
use crate::features::{Descriptor, FeatureConfig, FeatureLoss, Region, Scratch};
use crate::layer::PartView;

/// Weights of the loss terms.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct LossWeights {
    pub statistics: f32,
    pub features: f32,
    /// Results written before the contrast term existed read as 0 (their fits had none).
    #[serde(default)]
    pub contrast: f32,
}

impl Default for LossWeights {
    fn default() -> Self {
        LossWeights { statistics: 1.0, features: 1.0, contrast: CONTRAST_WEIGHT }
    }
}

/// The contrast term's weight: its value is a mean gradient-magnitude difference of the luma,
/// one channel where the statistics term sums three, so it weighs as much as they do.
const CONTRAST_WEIGHT: f32 = 3.0;

/// The terms of one evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct LossValue {
    pub total: f32,
    pub statistics: f32,
    pub features: f32,
    #[serde(default)]
    pub contrast: f32,
}

/// An exemplar's two selection scores (see [`PartLoss::selection_scores`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelectionScores {
    pub pattern: f32,
    pub whole: f32,
}

/// Weighted per-channel mean and standard deviation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Moments {
    pub mean: [f32; 3],
    pub std: [f32; 3],
}

impl Moments {
    pub fn of(image: &[[f32; 3]], weight: &[f32]) -> Moments {
        let total: f64 = weight.iter().map(|&w| f64::from(w)).sum::<f64>().max(1e-12);
        let mut mean = [0.0f64; 3];
        for (px, &w) in image.iter().zip(weight) {
            for c in 0..3 {
                mean[c] += f64::from(w) * f64::from(px[c]);
            }
        }
        mean.iter_mut().for_each(|m| *m /= total);
        let mut var = [0.0f64; 3];
        for (px, &w) in image.iter().zip(weight) {
            for c in 0..3 {
                let d = f64::from(px[c]) - mean[c];
                var[c] += f64::from(w) * d * d;
            }
        }
        Moments { mean: mean.map(|m| m as f32), std: var.map(|v| (v / total).sqrt() as f32) }
    }
}

/// The loss of one part against its photo crop.
pub struct PartLoss {
    weights: LossWeights,
    weight: Vec<f32>,
    total_weight: f32,
    target: Moments,
    /// Per channel, the lowest standard deviation the photo's may stand for once its noise is
    /// taken out (the lower end of the dead zone).
    target_std_floor: [f32; 3],
    features: FeatureLoss,
    target_features: Descriptor,
    contrast: ContrastLoss,
}

impl PartLoss {
    pub fn new(
        view: &PartView,
        weights: LossWeights,
        config: &FeatureConfig,
        scratch: &mut Scratch,
    ) -> Result<PartLoss, FitError> {
        let region = Region { width: view.width, height: view.height, weight: view.weight.clone() };
        let features = FeatureLoss::new(config, &region).map_err(feature_error)?;
        let mut target_features = features.describe(&view.target, scratch).map_err(feature_error)?;
        target_features.scale_noise(view.noise_scale);
        let target = Moments::of(&view.target, &view.weight);
        let target_std_floor = std::array::from_fn(|c| (target.std[c].powi(2) - view.noise[c].powi(2)).max(0.0).sqrt());
        let contrast = ContrastLoss::new(view.width, view.height, &view.weight, &view.target, view.noise[3]);
        Ok(PartLoss {
            weights,
            total_weight: view.total_weight().max(1e-6),
            weight: view.weight.clone(),
            target,
            target_std_floor,
            features,
            target_features,
            contrast,
        })
    }

    pub fn target_moments(&self) -> Moments {
        self.target
    }

    pub fn value(&self, image: &[[f32; 3]], scratch: &mut Scratch) -> LossValue {
        let m = Moments::of(image, &self.weight);
        let statistics = self.statistics(&m);
        let features = if self.weights.features > 0.0 {
            // The image and target come from this loss's own region: a mismatch is a bug.
            self.features.loss(image, &self.target_features, scratch).unwrap_or(f32::INFINITY)
        } else {
            0.0
        };
        let contrast = self.contrast_value(image);
        self.combine(statistics, features, contrast)
    }

    fn contrast_value(&self, image: &[[f32; 3]]) -> f32 {
        if self.weights.contrast > 0.0 {
            self.contrast.value(image, &mut ContrastScratch::default())
        } else {
            0.0
        }
    }

    /// What graph selection ranks an exemplar by (see `select.rs`): its pattern, the feature
    /// term at the exemplar's best orientation (see [`FeatureLoss::loss_any_orientation`]), as
    /// PhotoScene ranks by its VGG loss, or the statistics where the region is too thin for any
    /// level of the descriptor; and its whole loss, the statistics beside that pattern term.
    pub fn selection_scores(&self, image: &[[f32; 3]], scratch: &mut Scratch) -> SelectionScores {
        let statistics = self.statistics(&Moments::of(image, &self.weight));
        let contrast = self.contrast_value(image);
        let finite = |x: f32| if x.is_finite() { x } else { f32::INFINITY };
        if self.weights.features > 0.0 && !self.features.is_empty() {
            let pattern = finite(
                self.features.loss_any_orientation(image, &self.target_features, scratch).unwrap_or(f32::INFINITY),
            );
            SelectionScores { pattern, whole: finite(self.combine(statistics, pattern, contrast).total) }
        } else {
            SelectionScores {
                pattern: finite(statistics),
                whole: finite(self.combine(statistics, 0.0, contrast).total),
            }
        }
    }

    /// The loss and its gradient with respect to every crop pixel (written to `grad`).
    pub fn value_and_grad(&self, image: &[[f32; 3]], scratch: &mut Scratch, grad: &mut Vec<[f32; 3]>) -> LossValue {
        grad.clear();
        grad.resize(image.len(), [0.0; 3]);
        let features = if self.weights.features > 0.0 {
            let f = self.features.loss_and_grad(image, &self.target_features, scratch, grad).unwrap_or(f32::INFINITY);
            grad.iter_mut().for_each(|g| *g = g.map(|x| x * self.weights.features));
            f
        } else {
            0.0
        };
        let contrast = if self.weights.contrast > 0.0 {
            self.contrast.value_and_grad(image, self.weights.contrast, &mut ContrastScratch::default(), grad)
        } else {
            0.0
        };
        let m = Moments::of(image, &self.weight);
        let statistics = self.statistics(&m);
        let ws = self.weights.statistics;
        for c in 0..3 {
            let d_mean = ws * sign(m.mean[c] - self.target.mean[c]) / self.total_weight;
            let d_std = if m.std[c] > 1e-6 {
                ws * self.std_error_sign(c, m.std[c]) / (self.total_weight * m.std[c])
            } else {
                0.0
            };
            for ((g, px), &w) in grad.iter_mut().zip(image).zip(&self.weight) {
                if w > 0.0 {
                    g[c] += w * (d_mean + d_std * (px[c] - m.mean[c]));
                }
            }
        }
        self.combine(statistics, features, contrast)
    }

    fn statistics(&self, m: &Moments) -> f32 {
        (0..3).map(|c| (m.mean[c] - self.target.mean[c]).abs() + self.std_error(c, m.std[c])).sum()
    }

    /// Distance of a candidate's standard deviation from the dead zone of channel `c`.
    fn std_error(&self, c: usize, std: f32) -> f32 {
        if std > self.target.std[c] {
            std - self.target.std[c]
        } else {
            (self.target_std_floor[c] - std).max(0.0)
        }
    }

    fn std_error_sign(&self, c: usize, std: f32) -> f32 {
        if std > self.target.std[c] {
            1.0
        } else if std < self.target_std_floor[c] {
            -1.0
        } else {
            0.0
        }
    }

    fn combine(&self, statistics: f32, features: f32, contrast: f32) -> LossValue {
        LossValue {
            total: self.weights.statistics * statistics
                + self.weights.features * features
                + self.weights.contrast * contrast,
            statistics,
            features,
            contrast,
        }
    }
}

fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

fn feature_error(e: crate::features::FeatureError) -> FitError {
    FitError::Input(format!("feature loss: {e}"))
}
