//! The whole loss of a part (statistics, features, contrast): its gradient against central
//! finite differences, the photo's pixel noise not read as texture, and the lighting of a
//! part's faces not read as texture either.

mod flat_view;

use flat_view::flat_view;
use psc_base::SplitMix64;
use psc_fit::contrast::luma;
use psc_fit::features::{estimate_noise_sigma, FeatureConfig, Scratch};
use psc_fit::loss::{LossWeights, Moments, PartLoss};

const SIZE: usize = 48;

/// A grey photo with Gaussian pixel noise of `sigma` (the same on the three channels, as a path
/// tracer's noise mostly is).
fn noisy_grey(size: usize, sigma: f32, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = SplitMix64::new(seed);
    (0..size * size)
        .map(|_| {
            let (u1, u2) = (rng.next_f64().max(1e-12), rng.next_f64());
            let z = ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32;
            let v = 0.45 + sigma * z;
            [v, v * 0.95, v * 0.9]
        })
        .collect()
}

/// A smooth texture: a sum of two oblique waves of amplitude `amplitude`.
fn waves(size: usize, amplitude: f32, period: f32) -> Vec<[f32; 3]> {
    (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f32, (i / size) as f32);
            let t = std::f32::consts::TAU / period;
            let v =
                0.45 + amplitude * ((t * (x + 0.4 * y)).sin() + (t * (0.7 * x - y)).cos()) / std::f32::consts::SQRT_2;
            [v, v * 0.95, v * 0.9]
        })
        .collect()
}

/// Per pixel of a `size`×`size` crop: face 0 on the left half, face 1 on the right.
fn halves(size: usize) -> Vec<u8> {
    (0..size * size).map(|i| u8::from(i % size >= size / 2)).collect()
}

#[test]
fn the_gradient_of_the_whole_loss_matches_central_differences() {
    gradient_matches_central_differences(Vec::new());
}

#[test]
fn the_gradient_of_the_whole_loss_on_two_faces_matches_central_differences() {
    gradient_matches_central_differences(halves(SIZE));
}

fn gradient_matches_central_differences(faces: Vec<u8>) {
    let mut view = flat_view(SIZE, 0.02);
    view.target = waves(SIZE, 0.06, 9.0);
    // The right half of the photo is lit a fifth brighter.
    for (t, &f) in view.target.iter_mut().zip(&faces) {
        *t = t.map(|v| v * (1.0 + 0.2 * f32::from(f)));
    }
    view.faces = faces;
    let mut scratch = Scratch::default();
    let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
    let candidate = waves(SIZE, 0.03, 6.0);
    let mut grad = Vec::new();
    let value = loss.value_and_grad(&candidate, &mut scratch, &mut grad);
    assert!(value.contrast > 0.0 && value.features > 0.0 && value.statistics > 0.0, "{value:?}");
    let total = |img: &[[f32; 3]], scratch: &mut Scratch| f64::from(loss.value(img, scratch).total);
    assert!((total(&candidate, &mut scratch) - f64::from(value.total)).abs() < 1e-6);
    // Directional derivatives along random directions: every pixel moves, so kinks of the L1
    // and Wasserstein terms average out, and the check covers the whole gradient at once.
    let mut rng = SplitMix64::new(7);
    for _ in 0..4 {
        let direction: Vec<[f32; 3]> =
            (0..SIZE * SIZE).map(|_| [0, 1, 2].map(|_| rng.next_f32() * 2.0 - 1.0)).collect();
        let step = 1e-3f32;
        let moved = |s: f32| -> Vec<[f32; 3]> {
            candidate.iter().zip(&direction).map(|(p, d)| [0, 1, 2].map(|c| p[c] + s * d[c])).collect()
        };
        let fd = (total(&moved(step), &mut scratch) - total(&moved(-step), &mut scratch)) / (2.0 * f64::from(step));
        let analytic: f64 =
            grad.iter().zip(&direction).map(|(g, d)| (0..3).map(|c| f64::from(g[c] * d[c])).sum::<f64>()).sum();
        assert!((fd - analytic).abs() < 0.05 * fd.abs().max(analytic.abs()) + 1e-4, "fd {fd} vs adjoint {analytic}");
    }
}

#[test]
fn pixel_noise_in_a_plain_photo_is_not_fitted_as_texture() {
    // The photo is a flat grey with noise; a candidate with a texture as strong as the noise
    // matches its standard deviation and its gradient magnitudes, if the noise is ignored.
    let sigma = 0.02;
    let size = 128;
    let mut view = flat_view(size, 0.01);
    view.target = noisy_grey(size, sigma, 3);
    // The photo's noise, estimated as the fit estimates it (on the crop).
    view.noise = std::array::from_fn(|c| {
        let plane: Vec<f32> = view.target.iter().map(|&p| if c < 3 { p[c] } else { luma(p) }).collect();
        estimate_noise_sigma(&plane, &view.weight, size, size)
    });
    assert!((view.noise[0] - sigma).abs() < 0.2 * sigma, "estimated noise {:?}", view.noise);
    let mut scratch = Scratch::default();
    let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
    let flat = waves(size, 0.0, 9.0);
    let textured = waves(size, sigma, 4.0);
    let (lf, lt) = (loss.value(&flat, &mut scratch), loss.value(&textured, &mut scratch));
    // Without a noise model the flat candidate's statistics would be the photo's deviations.
    let photo = Moments::of(&view.target, &view.weight);
    let without_noise_model: f32 = photo.std.iter().sum();
    assert!(lf.statistics < 0.5 * without_noise_model, "statistics: flat {lf:?}, photo {photo:?}");
    assert!(lf.contrast < lt.contrast, "contrast: flat {lf:?}, textured {lt:?}");
    assert!(lf.total < lt.total, "flat {lf:?}, textured {lt:?}");
}

#[test]
fn the_lighting_of_a_parts_faces_is_not_fitted_as_texture() {
    // A plain part with two faces lit differently (0.7 and 0.3 in the photo) that the render
    // lights alike (0.5 and 0.45). Pooled over the crop, the photo's spread is the difference
    // between its faces, and a strong texture matches it better than the plain colour does;
    // face by face, the photo has no spread, and the plain colour wins.
    let size = 48;
    let mut view = flat_view(size, 0.01);
    let faces = halves(size);
    view.target = faces.iter().map(|&f| [if f == 0 { 0.7 } else { 0.3 }; 3]).collect();
    let plain: Vec<[f32; 3]> = faces.iter().map(|&f| [if f == 0 { 0.5 } else { 0.45 }; 3]).collect();
    let textured = waves(size, 0.2, 9.0).iter().map(|p| [p[0] + 0.05; 3]).collect::<Vec<_>>();
    let weights = LossWeights { statistics: 1.0, features: 0.0, contrast: 0.0 };
    let mut scratch = Scratch::default();
    let statistics = |view: &psc_fit::layer::PartView, image: &[[f32; 3]], scratch: &mut Scratch| {
        let loss = PartLoss::new(view, weights, &FeatureConfig::default(), scratch).unwrap();
        loss.value(image, scratch).statistics
    };
    let pooled = (statistics(&view, &plain, &mut scratch), statistics(&view, &textured, &mut scratch));
    assert!(pooled.1 < pooled.0, "pooled: plain {}, textured {}", pooled.0, pooled.1);
    view.faces = faces;
    let by_face = (statistics(&view, &plain, &mut scratch), statistics(&view, &textured, &mut scratch));
    assert!(by_face.0 < 0.75 * by_face.1, "face by face: plain {}, textured {}", by_face.0, by_face.1);
}
