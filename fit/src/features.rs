//! The feature loss: a fixed, weight-free, multi-scale texture descriptor with an exact adjoint.
//!
//! PLACEHOLDER (lead's local stub with the agreed API; the real module comes from the
//! `features` branch and replaces this file when merged).

#[derive(Clone, Debug, Default)]
pub struct FeatureConfig {}

#[derive(Clone, Debug)]
pub struct Region {
    pub width: usize,
    pub height: usize,
    pub weight: Vec<f32>,
}

#[derive(Clone, Debug)]
pub struct Descriptor {}

#[derive(Default)]
pub struct Scratch {}

pub struct FeatureLoss {}

impl FeatureLoss {
    pub fn new(_config: &FeatureConfig, _region: &Region) -> FeatureLoss {
        FeatureLoss {}
    }
    pub fn describe(&self, _image: &[[f32; 3]], _scratch: &mut Scratch) -> Descriptor {
        Descriptor {}
    }
    pub fn loss(&self, _image: &[[f32; 3]], _target: &Descriptor, _scratch: &mut Scratch) -> f32 {
        0.0
    }
    pub fn loss_and_grad(
        &self,
        _image: &[[f32; 3]],
        _target: &Descriptor,
        _scratch: &mut Scratch,
        grad: &mut [[f32; 3]],
    ) -> f32 {
        grad.iter_mut().for_each(|g| *g = [0.0; 3]);
        0.0
    }
}
