//! The feature loss's gradient against central finite differences, on random images and
//! region shapes (full, soft-edged, thin, ring-shaped), with and without colour, the noise
//! model's dead zone and working-resolution reduction.

mod features_support;

use features_support::{random_pattern, shape, Rng};
use psc_fit::features::{FeatureConfig, FeatureLoss, Region, Scratch};

struct Case {
    name: &'static str,
    region: Region,
    config: FeatureConfig,
}

fn cases() -> Vec<Case> {
    let base = FeatureConfig { levels: 3, orientations: 6, min_level_support: 4.0, ..FeatureConfig::default() };
    vec![
        Case { name: "rect 40x34", region: shape("rect", 40, 34), config: base.clone() },
        Case { name: "rect 76x66, three levels", region: shape("rect", 76, 66), config: base.clone() },
        Case { name: "soft disc 46x46", region: shape("disc", 46, 46), config: base.clone() },
        Case { name: "thin band 64x40", region: shape("band", 64, 40), config: base.clone() },
        Case { name: "ring 56x56", region: shape("ring", 56, 56), config: base.clone() },
        Case {
            name: "disc, working resolution /2",
            region: shape("disc", 70, 66),
            config: FeatureConfig { max_pixels: Some(1300), ..base.clone() },
        },
        Case {
            name: "rect, no noise model",
            region: shape("rect", 40, 34),
            config: FeatureConfig { photo_noise: false, ..base.clone() },
        },
        Case {
            name: "rect, achromatic only, 4 orientations",
            region: shape("rect", 36, 30),
            config: FeatureConfig { colour: false, orientations: 4, levels: 2, ..base.clone() },
        },
    ]
}

fn loss_at(loss: &FeatureLoss, image: &[[f32; 3]], target: &psc_fit::features::Descriptor, s: &mut Scratch) -> f64 {
    f64::from(loss.loss(image, target, s).unwrap())
}

/// Fourth-order central difference of `f` at 0 with step `h`: truncation O(h⁴), so the step
/// can be large enough that the f32 loss value's rounding stays small.
fn central_difference(h: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    (8.0 * (f(h) - f(-h)) - (f(2.0 * h) - f(-2.0 * h))) / (12.0 * h)
}

#[test]
fn gradient_matches_central_differences() {
    let mut rng = Rng(7);
    for case in cases() {
        let (w, h) = (case.region.width, case.region.height);
        let loss = FeatureLoss::new(&case.config, &case.region).unwrap();
        assert!(!loss.is_empty(), "{}: no active level", case.name);
        if case.name.contains("three levels") {
            assert_eq!(loss.active_levels(), [0, 1, 2]);
        }
        let target_image = random_pattern(w, h, &mut rng);
        let mut s = Scratch::default();
        let target = loss.describe(&target_image, &mut s).unwrap();
        let image = random_pattern(w, h, &mut rng);
        let mut grad = vec![[f32::NAN; 3]; w * h];
        let l0 = loss.loss_and_grad(&image, &target, &mut s, &mut grad).unwrap();
        assert!(l0 > 0.0 && l0.is_finite(), "{}: loss {l0}", case.name);
        assert_eq!(f64::from(l0), loss_at(&loss, &image, &target, &mut s), "{}: loss_and_grad vs loss", case.name);

        // Outside the mask the gradient is exactly zero.
        for (i, g) in grad.iter().enumerate() {
            if case.region.weight[i] == 0.0 {
                assert_eq!(*g, [0.0; 3], "{}: gradient at weight-0 pixel {i}", case.name);
            }
        }

        // Directional derivatives along random directions over every pixel and channel.
        for _ in 0..3 {
            let dir: Vec<[f32; 3]> =
                (0..w * h).map(|_| [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)]).collect();
            let analytic: f64 =
                grad.iter().zip(&dir).map(|(g, d)| (0..3).map(|c| f64::from(g[c] * d[c])).sum::<f64>()).sum();
            let numeric = central_difference(2e-3, |t| {
                let moved: Vec<[f32; 3]> =
                    image.iter().zip(&dir).map(|(p, d)| std::array::from_fn(|c| p[c] + t as f32 * d[c])).collect();
                loss_at(&loss, &moved, &target, &mut s)
            });
            // The loss is returned in f32: its rounding (~1e-7 L) over the stencil's 12h.
            let tolerance = 1e-3 * analytic.abs() + 2e-4 * f64::from(l0);
            println!("{}: directional {analytic:.6e} vs FD {numeric:.6e} (tolerance {tolerance:.1e})", case.name);
            assert!(
                (analytic - numeric).abs() < tolerance,
                "{}: directional derivative {analytic} vs FD {numeric}",
                case.name
            );
        }

        // Single pixels: the largest gradients and a few random masked ones, every channel.
        let mut order: Vec<usize> = (0..w * h).collect();
        order.sort_by(|&a, &b| {
            let m = |i: usize| grad[i].iter().map(|v| v.abs()).fold(0.0f32, f32::max);
            m(b).total_cmp(&m(a))
        });
        let masked: Vec<usize> = (0..w * h).filter(|&i| case.region.weight[i] > 0.0).collect();
        let mut picks: Vec<usize> = order[..6].to_vec();
        picks.extend((0..6).map(|_| masked[(rng.next_u64() % masked.len() as u64) as usize]));
        let mut worst = 0.0f64;
        for &i in &picks {
            for c in 0..3 {
                let numeric = central_difference(2e-2, |t| {
                    let mut moved = image.clone();
                    moved[i][c] += t as f32;
                    loss_at(&loss, &moved, &target, &mut s)
                });
                let analytic = f64::from(grad[i][c]);
                // Rounding of the f32 loss over the stencil: about 0.75 ulp(L) / h.
                let tolerance = 3e-3 * analytic.abs() + 1e-5 * f64::from(l0);
                worst = worst.max((analytic - numeric).abs() / tolerance);
                assert!(
                    (analytic - numeric).abs() < tolerance,
                    "{}: pixel ({}, {}) channel {c}: analytic {analytic:.4e}, FD {numeric:.4e}",
                    case.name,
                    i % w,
                    i / w
                );
            }
        }
        println!("{}: worst single-pixel error / tolerance {worst:.2} (levels {:?})", case.name, loss.active_levels());
    }
}

#[test]
fn scratch_reuse_across_regions_gives_identical_results() {
    // One scratch serving regions of different sizes in turn must not change any result.
    let mut rng = Rng(99);
    let config = FeatureConfig { levels: 3, min_level_support: 4.0, ..FeatureConfig::default() };
    let regions = [shape("rect", 40, 30), shape("disc", 60, 60), shape("band", 50, 30)];
    let images: Vec<Vec<[f32; 3]>> = regions.iter().map(|r| random_pattern(r.width, r.height, &mut rng)).collect();
    let mut shared = Scratch::default();
    for _round in 0..2 {
        for (r, img) in regions.iter().zip(&images) {
            let loss = FeatureLoss::new(&config, r).unwrap();
            let fresh = loss.describe(img, &mut Scratch::default()).unwrap();
            assert_eq!(loss.describe(img, &mut shared).unwrap(), fresh);
            let mut g1 = vec![[0.0; 3]; img.len()];
            let mut g2 = vec![[0.0; 3]; img.len()];
            let t = loss
                .describe(&images[0].iter().cycle().take(img.len()).copied().collect::<Vec<_>>(), &mut shared)
                .unwrap();
            let l1 = loss.loss_and_grad(img, &t, &mut shared, &mut g1).unwrap();
            let l2 = loss.loss_and_grad(img, &t, &mut Scratch::default(), &mut g2).unwrap();
            assert_eq!(l1.to_bits(), l2.to_bits());
            assert_eq!(g1, g2);
        }
    }
}

#[test]
fn bad_input_is_an_error() {
    let config = FeatureConfig::default();
    let bad_weight = Region { width: 4, height: 4, weight: vec![1.5; 16] };
    assert!(FeatureLoss::new(&config, &bad_weight).is_err());
    let nan_weight = Region { width: 4, height: 4, weight: vec![f32::NAN; 16] };
    assert!(FeatureLoss::new(&config, &nan_weight).is_err());
    assert!(FeatureLoss::new(&config, &Region { width: 4, height: 4, weight: vec![1.0; 15] }).is_err());
    assert!(FeatureLoss::new(&config, &Region { width: 0, height: 4, weight: vec![] }).is_err());
    assert!(FeatureLoss::new(&FeatureConfig { levels: 0, ..config.clone() }, &shape("rect", 8, 8)).is_err());
    assert!(FeatureLoss::new(&FeatureConfig { contrast_floor: 0.0, ..config.clone() }, &shape("rect", 8, 8)).is_err());

    let region = shape("rect", 30, 30);
    let loss = FeatureLoss::new(&config, &region).unwrap();
    let mut s = Scratch::default();
    assert!(loss.describe(&[[0.5; 3]; 10], &mut s).is_err());
    let target = loss.describe(&vec![[0.5; 3]; 900], &mut s).unwrap();
    let other = FeatureLoss::new(&config, &shape("disc", 30, 30)).unwrap();
    assert!(other.loss(&vec![[0.5; 3]; 900], &target, &mut s).is_err(), "descriptor of another region");
    let mut shifted = shape("rect", 30, 30);
    shifted.weight[0] = 0.0;
    let same_size = FeatureLoss::new(&config, &shifted).unwrap();
    assert!(same_size.loss(&vec![[0.5; 3]; 900], &target, &mut s).is_err(), "region of the same size, other mask");
    let mut grad = vec![[0.0; 3]; 899];
    assert!(loss.loss_and_grad(&vec![[0.5; 3]; 900], &target, &mut s, &mut grad).is_err());

    // A region too small for any level is valid but empty: loss 0, gradient 0.
    let tiny = FeatureLoss::new(&config, &shape("rect", 6, 6)).unwrap();
    assert!(tiny.is_empty());
    let t = tiny.describe(&vec![[0.3; 3]; 36], &mut s).unwrap();
    let mut g = vec![[1.0; 3]; 36];
    assert_eq!(tiny.loss_and_grad(&vec![[0.9; 3]; 36], &t, &mut s, &mut g).unwrap(), 0.0);
    assert!(g.iter().all(|v| *v == [0.0; 3]));
}

#[test]
fn shared_across_threads_gives_the_sequential_bits() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<FeatureLoss>();
    assert_send_sync::<psc_fit::features::Descriptor>();
    use rayon::prelude::*;
    let mut rng = Rng(5);
    let region = shape("disc", 64, 64);
    let loss = FeatureLoss::new(&FeatureConfig::default(), &region).unwrap();
    let target = loss.describe(&random_pattern(64, 64, &mut rng), &mut Scratch::default()).unwrap();
    let images: Vec<Vec<[f32; 3]>> = (0..16).map(|_| random_pattern(64, 64, &mut rng)).collect();
    let run = |img: &Vec<[f32; 3]>, s: &mut Scratch| {
        let mut g = vec![[0.0; 3]; img.len()];
        let l = loss.loss_and_grad(img, &target, s, &mut g).unwrap();
        (l.to_bits(), g)
    };
    let mut s = Scratch::default();
    let sequential: Vec<_> = images.iter().map(|img| run(img, &mut s)).collect();
    let parallel: Vec<_> = images.par_iter().map_init(Scratch::default, |s, img| run(img, s)).collect();
    assert_eq!(sequential, parallel);
}
