//! The optimiser: Adam over the fitted variables, each in the space its gradient steps are
//! meaningful in: graph parameters normalised to [0, 1] by their declared ranges (colours are
//! already in [0, 1]), the UV rotation in radians and log-scale in base-1.5 steps, the offset in
//! tile units, the albedo scale as log₂, the roughness as itself. Every step is projected back
//! onto the variables' ranges; discrete parameters are not variables (they are searched).

use psc_compiler::{GraphInfo, ParamKind};

use crate::layer::{Gradient, MaterialState};
use crate::uvmap::LOG_SCALE_RANGE;

/// Which parts of a material state are variables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Free {
    pub params: bool,
    pub uv: bool,
    /// Albedo scale and roughness (the re-fit frees only these).
    pub appearance: bool,
}

impl Free {
    pub const ALL: Free = Free { params: true, uv: true, appearance: true };
    pub const APPEARANCE: Free = Free { params: false, uv: false, appearance: true };
}

/// Albedo scales are kept within 2^±6.
const LOG2_SCALE_RANGE: f32 = 6.0;

/// The part-wide roughness the fit may choose. The renderer takes any roughness (and `psc
/// render --set` can give one), but the layer integrates the specular lobe against a light grid
/// of 11°-by-22° bins at the bins' centres (`shading.rs`), so it cannot see the highlights of a
/// lobe narrower than a bin: below about 0.4 (GGX α = 0.16, a lobe some 0.3 rad wide) it
/// predicts glossy reflections the path tracer does not render where they are, and misses the
/// ones it does. Left free, the fit went there on parts that are not glossy (dev_2's plaster
/// wall at 0.24 against the truth's 0.76: a mirror-like sheen over the whole relit view; four
/// of the five fitted roughnesses below 0.4 on dev_1 and dev_2 were below truths of 0.38–0.84).
pub const FIT_ROUGHNESS_RANGE: (f32, f32) = (0.4, 1.0);

/// The mapping between a [`MaterialState`] and the optimiser's flat vector.
#[derive(Clone, Debug)]
pub struct Packing {
    /// (slot, min, max) of every continuous parameter slot that is a variable.
    slots: Vec<(usize, f32, f32)>,
    free: Free,
}

impl Packing {
    pub fn new(info: &GraphInfo, free: Free) -> Packing {
        let mut slots = Vec::new();
        if free.params {
            for p in &info.params {
                match p.kind {
                    ParamKind::Continuous { min, max } if max > min => slots.push((p.slot, min, max)),
                    ParamKind::Color => slots.extend((p.slot..p.slot + 3).map(|s| (s, 0.0, 1.0))),
                    _ => {}
                }
            }
        }
        Packing { slots, free }
    }

    pub fn len(&self) -> usize {
        self.slots.len() + if self.free.uv { 4 } else { 0 } + if self.free.appearance { 4 } else { 0 }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn pack(&self, s: &MaterialState) -> Vec<f32> {
        let mut z: Vec<f32> = self.slots.iter().map(|&(slot, lo, hi)| (s.params[slot] - lo) / (hi - lo)).collect();
        if self.free.uv {
            z.extend([s.uv.rotation, s.uv.log_scale, s.uv.offset[0], s.uv.offset[1]]);
        }
        if self.free.appearance {
            z.extend(s.albedo_scale.map(|a| a.max(1e-6).log2()));
            z.push(s.roughness);
        }
        z
    }

    /// The state of `z` (projected onto the ranges), other fields from `base`.
    pub fn unpack(&self, z: &[f32], base: &MaterialState) -> MaterialState {
        let mut s = base.clone();
        for (&(slot, lo, hi), &x) in self.slots.iter().zip(z) {
            s.params[slot] = lo + (hi - lo) * x.clamp(0.0, 1.0);
        }
        let mut i = self.slots.len();
        if self.free.uv {
            s.uv.rotation = z[i];
            s.uv.log_scale = z[i + 1].clamp(LOG_SCALE_RANGE.0, LOG_SCALE_RANGE.1);
            s.uv.offset = [z[i + 2], z[i + 3]];
            s.uv = s.uv.canonical();
            i += 4;
        }
        if self.free.appearance {
            for c in 0..3 {
                s.albedo_scale[c] = z[i + c].clamp(-LOG2_SCALE_RANGE, LOG2_SCALE_RANGE).exp2();
            }
            s.roughness = z[i + 3].clamp(FIT_ROUGHNESS_RANGE.0, FIT_ROUGHNESS_RANGE.1);
        }
        s
    }

    /// Projects `z` onto the ranges in place (so Adam's state stays consistent with the state).
    pub fn project(&self, z: &mut [f32]) {
        for x in z.iter_mut().take(self.slots.len()) {
            *x = x.clamp(0.0, 1.0);
        }
        let mut i = self.slots.len();
        if self.free.uv {
            z[i + 1] = z[i + 1].clamp(LOG_SCALE_RANGE.0, LOG_SCALE_RANGE.1);
            i += 4;
        }
        if self.free.appearance {
            for c in 0..3 {
                z[i + c] = z[i + c].clamp(-LOG2_SCALE_RANGE, LOG2_SCALE_RANGE);
            }
            z[i + 3] = z[i + 3].clamp(FIT_ROUGHNESS_RANGE.0, FIT_ROUGHNESS_RANGE.1);
        }
    }

    /// The gradient with respect to `z` of a loss whose gradient with respect to the state `s`
    /// is `g`.
    pub fn gradient(&self, g: &Gradient, s: &MaterialState) -> Vec<f64> {
        let mut out: Vec<f64> = self
            .slots
            .iter()
            .map(|&(slot, lo, hi)| g.params.get(slot).copied().unwrap_or(0.0) * f64::from(hi - lo))
            .collect();
        if self.free.uv {
            out.extend(g.uv);
        }
        if self.free.appearance {
            for c in 0..3 {
                // d/d(log2 a) = a ln 2 d/da
                out.push(g.albedo_scale[c] * f64::from(s.albedo_scale[c]) * std::f64::consts::LN_2);
            }
            out.push(g.roughness);
        }
        out
    }

    /// Adam learning rates per variable.
    pub fn learning_rates(&self, base: f32) -> Vec<f32> {
        let mut lr = vec![base; self.slots.len()];
        if self.free.uv {
            // Rotation (radians), log-scale (base-1.5 steps), offset (tiles).
            lr.extend([base, 2.0 * base, 0.5 * base, 0.5 * base]);
        }
        if self.free.appearance {
            lr.extend([2.0 * base, 2.0 * base, 2.0 * base, base]);
        }
        lr
    }
}

/// Adam (Kingma and Ba 2015) with per-variable learning rates.
#[derive(Clone, Debug)]
pub struct Adam {
    lr: Vec<f32>,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPSILON: f64 = 1e-8;

impl Adam {
    pub fn new(lr: Vec<f32>) -> Adam {
        let n = lr.len();
        Adam { lr, m: vec![0.0; n], v: vec![0.0; n], t: 0 }
    }

    /// Multiplies every variable's learning rate by `factor`, keeping the moments.
    pub fn scale_learning_rates(&mut self, factor: f32) {
        self.lr.iter_mut().for_each(|lr| *lr *= factor);
    }

    /// Forgets the direction of travel (the first moment) but keeps each variable's gradient
    /// scale (the second moment): after a jump the old direction is stale, but a fresh start
    /// would make the next step a full learning rate in every variable at once.
    pub fn forget_momentum(&mut self) {
        self.m.iter_mut().for_each(|m| *m = 0.0);
    }

    /// One descent step of `x` along `grad`.
    pub fn step(&mut self, x: &mut [f32], grad: &[f64]) {
        self.t += 1;
        let (c1, c2) = (1.0 - BETA1.powi(self.t), 1.0 - BETA2.powi(self.t));
        for i in 0..x.len() {
            let g = if grad[i].is_finite() { grad[i] } else { 0.0 };
            self.m[i] = BETA1 * self.m[i] + (1.0 - BETA1) * g;
            self.v[i] = BETA2 * self.v[i] + (1.0 - BETA2) * g * g;
            let step = f64::from(self.lr[i]) * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + EPSILON);
            x[i] -= step as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adam_minimises_a_quadratic() {
        let mut x = vec![3.0f32, -2.0];
        let mut adam = Adam::new(vec![0.1, 0.1]);
        for _ in 0..500 {
            let g = [2.0 * f64::from(x[0] - 1.0), 8.0 * f64::from(x[1] + 0.5)];
            adam.step(&mut x, &g);
        }
        assert!((x[0] - 1.0).abs() < 1e-2 && (x[1] + 0.5).abs() < 1e-2, "{x:?}");
    }

    /// The first step after `n` steps of the same gradients, for an Adam changed by `change`.
    fn step_after(n: usize, change: impl Fn(&mut Adam)) -> Vec<f32> {
        let mut adam = Adam::new(vec![0.1, 0.1]);
        let mut x = vec![0.0f32; 2];
        for _ in 0..n {
            adam.step(&mut x, &[1.0, -4.0]);
        }
        change(&mut adam);
        let before = x.clone();
        adam.step(&mut x, &[-1.0, 4.0]);
        x.iter().zip(&before).map(|(a, b)| a - b).collect()
    }

    #[test]
    fn scaled_learning_rates_scale_the_steps() {
        let full = step_after(20, |_| {});
        let quarter = step_after(20, |a| a.scale_learning_rates(0.25));
        for (f, q) in full.iter().zip(&quarter) {
            assert!((q - 0.25 * f).abs() < 1e-3 * f.abs() + 1e-6, "{full:?} {quarter:?}");
        }
    }

    #[test]
    fn forgetting_the_momentum_keeps_the_gradient_scale() {
        // Twenty steps one way, then the gradient turns: with the momentum the first step still
        // goes the old way; forgotten, it goes the new way, but by a tenth of the rate (the
        // kept second moment), not by a full step as a fresh Adam would.
        let kept = step_after(20, |_| {});
        let forgotten = step_after(20, Adam::forget_momentum);
        let fresh = step_after(20, |a| *a = Adam::new(vec![0.1, 0.1]));
        assert!(kept[0] < 0.0 && kept[1] > 0.0, "{kept:?}");
        assert!(forgotten[0] > 0.0 && forgotten[1] < 0.0, "{forgotten:?}");
        for i in 0..2 {
            assert!((fresh[i].abs() - 0.1).abs() < 1e-4, "{fresh:?}");
            assert!(forgotten[i].abs() < 0.2 * fresh[i].abs(), "{forgotten:?} {fresh:?}");
        }
    }
}
