//! The metrics of `psc eval` against independent computations on synthetic images.

use std::collections::BTreeMap;

use psc_fit::eval::metrics::{
    colour_w1, contrast_samples, erode, mean_colour_error, part_metrics, rmse, ssim, wasserstein1, LightRatios,
    MIN_PART_PIXELS,
};

/// A small deterministic generator (xorshift), values in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn random_image(w: usize, h: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut r = Rng(seed);
    (0..w * h).map(|_| [r.next(), r.next(), r.next()]).collect()
}

#[test]
fn w1_of_a_shifted_distribution_is_the_shift() {
    let mut r = Rng(7);
    let a: Vec<f32> = (0..1000).map(|_| r.next() * 0.5).collect();
    for shift in [0.0f32, 0.03, 0.25] {
        let mut x = a.clone();
        let mut y: Vec<f32> = a.iter().map(|v| v + shift).collect();
        let d = wasserstein1(&mut x, &mut y);
        assert!((d - shift as f64).abs() < 1e-6, "shift {shift}: W1 {d}");
    }
}

#[test]
fn w1_matches_the_sorted_difference_and_replicated_samples() {
    let mut r = Rng(11);
    let a: Vec<f32> = (0..300).map(|_| r.next()).collect();
    let b: Vec<f32> = (0..300).map(|_| r.next() * r.next()).collect();
    // Equal sizes: the mean absolute difference of the sorted samples.
    let (mut sa, mut sb) = (a.clone(), b.clone());
    sa.sort_by(f32::total_cmp);
    sb.sort_by(f32::total_cmp);
    let direct: f64 = sa.iter().zip(&sb).map(|(x, y)| (x - y).abs() as f64).sum::<f64>() / sa.len() as f64;
    assert!((wasserstein1(&mut a.clone(), &mut b.clone()) - direct).abs() < 1e-6);

    // Unequal sizes (n, m): the same as n·m samples each, every a repeated m times and every b
    // n times, compared sorted.
    let b2: Vec<f32> = b[..70].to_vec();
    let mut ra: Vec<f32> = a.iter().flat_map(|&x| std::iter::repeat_n(x, b2.len())).collect();
    let mut rb: Vec<f32> = b2.iter().flat_map(|&x| std::iter::repeat_n(x, a.len())).collect();
    ra.sort_by(f32::total_cmp);
    rb.sort_by(f32::total_cmp);
    let replicated: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - y).abs() as f64).sum::<f64>() / ra.len() as f64;
    let d = wasserstein1(&mut a.clone(), &mut b2.clone());
    assert!((d - replicated).abs() < 1e-6, "{d} vs {replicated}");

    // Point masses at 0 and 1.
    assert!((wasserstein1(&mut [0.0; 5], &mut [1.0; 3]) - 1.0).abs() < 1e-12);
}

#[test]
fn rmse_and_mean_colour_on_known_arrays() {
    let a = vec![[0.2f32, 0.2, 0.2]; 10];
    let b = vec![[0.5f32, 0.5, 0.5]; 10];
    assert!((rmse(&a, &b) - 0.3).abs() < 1e-6);
    let c = vec![[0.5f32, 0.2, 0.2]; 10];
    assert!((rmse(&a, &c) - (0.09f64 / 3.0).sqrt()).abs() < 1e-6);
    // Half the pixels off by 0.4 in every channel: RMSE √(0.16 / 2).
    let d: Vec<[f32; 3]> = (0..10).map(|i| if i % 2 == 0 { [0.6; 3] } else { [0.2; 3] }).collect();
    assert!((rmse(&a, &d) - 0.08f64.sqrt()).abs() < 1e-6);
    // Mean colours (0.2, 0.2, 0.2) and (0.4, 0.5, 0.2): difference (0.2, 0.3, 0).
    let e = vec![[0.4f32, 0.5, 0.2]; 10];
    let want = ((0.2f64 * 0.2 + 0.3 * 0.3) / 3.0).sqrt();
    assert!((mean_colour_error(&a, &e) - want).abs() < 1e-6);
    // Mean colour ignores the arrangement; RMSE does not.
    let f: Vec<[f32; 3]> = (0..10).map(|i| if i % 2 == 0 { [0.0; 3] } else { [0.4; 3] }).collect();
    assert!(mean_colour_error(&a, &f) < 1e-6);
    assert!((rmse(&a, &f) - 0.2).abs() < 1e-6);
}

#[test]
fn colour_w1_averages_the_channel_shifts() {
    let a = random_image(20, 10, 3);
    let b: Vec<[f32; 3]> = a.iter().map(|p| [p[0] + 0.1, p[1] + 0.2, p[2] + 0.3]).collect();
    assert!((colour_w1(&a, &b) - 0.2).abs() < 1e-6);
    // A permutation of the pixels has the same distribution.
    let mut c = a.clone();
    c.reverse();
    assert!(colour_w1(&a, &c) < 1e-9);
    assert!(rmse(&a, &c) > 0.1);
}

/// SSIM by its definition, window by window with 2-D Gaussian weights (no separable filtering).
fn ssim_direct(a: &[[f32; 3]], b: &[[f32; 3]], w: usize, h: usize) -> f64 {
    let (c1, c2) = (1e-4f64, 9e-4f64);
    let g = |d: i32| (-(d * d) as f64 / (2.0 * 1.5 * 1.5)).exp();
    let norm: f64 = (-5..=5).flat_map(|i| (-5..=5).map(move |j| g(i) * g(j))).sum();
    let mut total = 0.0;
    let mut count = 0usize;
    for k in 0..3 {
        for y in 5..h - 5 {
            for x in 5..w - 5 {
                let (mut mx, mut my, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for dy in -5i32..=5 {
                    for dx in -5i32..=5 {
                        let wt = g(dx) * g(dy) / norm;
                        let i = (y as i32 + dy) as usize * w + (x as i32 + dx) as usize;
                        let (p, q) = (a[i][k] as f64, b[i][k] as f64);
                        mx += wt * p;
                        my += wt * q;
                        sxx += wt * p * p;
                        syy += wt * q * q;
                        sxy += wt * p * q;
                    }
                }
                let (vx, vy, cxy) = (sxx - mx * mx, syy - my * my, sxy - mx * my);
                total += ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
                count += 1;
            }
        }
    }
    total / count as f64
}

#[test]
fn ssim_is_one_for_equal_images_and_falls_with_noise() {
    let (w, h) = (40, 30);
    let smooth: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            [0.5 + 0.3 * (x * 0.3).sin(), 0.4 + 0.2 * (y * 0.2).cos(), 0.3 + 0.002 * (x + y)]
        })
        .collect();
    assert!((ssim(&smooth, &smooth, w, h).unwrap() - 1.0).abs() < 1e-12);
    let mut previous = 1.0;
    for level in [0.02f32, 0.05, 0.1, 0.2] {
        let noise = random_image(w, h, 5);
        let noisy: Vec<[f32; 3]> =
            smooth.iter().zip(&noise).map(|(p, n)| std::array::from_fn(|k| p[k] + level * (n[k] - 0.5))).collect();
        let s = ssim(&smooth, &noisy, w, h).unwrap();
        assert!(s < previous, "noise {level}: SSIM {s} not below {previous}");
        let direct = ssim_direct(&smooth, &noisy, w, h);
        assert!((s - direct).abs() < 1e-9, "separable {s} vs direct {direct}");
        previous = s;
    }
    // Constant images: only the luminance term, (2 μx μy + C1) / (μx² + μy² + C1).
    let (ma, mb) = (0.3f64, 0.6f64);
    let a = vec![[ma as f32; 3]; w * h];
    let b = vec![[mb as f32; 3]; w * h];
    let want = (2.0 * ma * mb + 1e-4) / (ma * ma + mb * mb + 1e-4);
    assert!((ssim(&a, &b, w, h).unwrap() - want).abs() < 1e-6);
    assert_eq!(ssim(&a[..100], &b[..100], 10, 10), None, "smaller than the window");
}

#[test]
fn erosion_shrinks_a_rectangle_by_the_radius() {
    let (w, h) = (20, 15);
    let mask: Vec<bool> = (0..w * h).map(|i| (3..15).contains(&(i % w)) && (2..12).contains(&(i / w))).collect();
    let e = erode(&mask, w, h, 2);
    for (i, &kept) in e.iter().enumerate() {
        let (x, y) = (i % w, i / w);
        assert_eq!(kept, (5..13).contains(&x) && (4..10).contains(&y), "pixel ({x}, {y})");
    }
}

#[test]
fn contrast_of_a_ramp_is_its_slope() {
    // Grey ramp v = a·x + b·y: luma = v (the weights sum to 1), smoothing keeps it (a symmetric
    // normalised kernel away from the borders), forward differences give (a, b).
    let (w, h) = (30, 20);
    let ramp = |a: f32, b: f32| -> Vec<[f32; 3]> {
        (0..w * h).map(|i| [0.1 + a * (i % w) as f32 + b * (i / w) as f32; 3]).collect()
    };
    let mask = vec![true; w * h];
    let s = contrast_samples(&ramp(0.01, 0.02), w, h, &mask);
    // Eroded by 2 on every side: 26 × 16 pixels, of which 25 × 15 have both forward neighbours.
    assert_eq!(s.len(), 25 * 15);
    let want = (0.01f32.powi(2) + 0.02f32.powi(2)).sqrt();
    assert!(s.iter().all(|v| (v - want).abs() < 1e-5), "{:?}", &s[..4]);
    // W1 between two ramps' contrasts is the difference of their slopes.
    let mut t = contrast_samples(&ramp(0.02, 0.04), w, h, &mask);
    let mut s2 = s.clone();
    assert!((wasserstein1(&mut s2, &mut t) - want as f64).abs() < 1e-5);
}

#[test]
fn parts_below_200_pixels_are_left_out() {
    let (w, h) = (40, 20);
    // Label 1: 200 pixels (columns 0..10), label 2: 199 (columns 10..20 less one), label 3 absent.
    let mut labels: Vec<u16> = (0..w * h)
        .map(|i| {
            if i % w < 10 {
                1
            } else if i % w < 20 {
                2
            } else {
                0
            }
        })
        .collect();
    labels[10] = 0;
    assert_eq!(labels.iter().filter(|&&l| l == 1).count(), MIN_PART_PIXELS);
    let names: BTreeMap<u16, String> = [(1, "a"), (2, "b"), (3, "c")].into_iter().map(|(k, v)| (k, v.into())).collect();
    let truth = random_image(w, h, 9);
    let render: Vec<[f32; 3]> = truth.iter().map(|p| [p[0] * 0.5, p[1], p[2]]).collect();
    let m = part_metrics(&render, &truth, w, h, &labels, &names);
    assert_eq!(m.len(), 1);
    assert_eq!((m[0].part.as_str(), m[0].pixels), ("a", 200));
    // The part's numbers use its pixels only.
    let pick = |img: &[[f32; 3]]| -> Vec<[f32; 3]> { (0..w * h).filter(|i| labels[*i] == 1).map(|i| img[i]).collect() };
    assert!((m[0].rmse - rmse(&pick(&render), &pick(&truth))).abs() < 1e-12);
    // A render equal to the truth scores zero everywhere.
    let same = part_metrics(&truth, &truth, w, h, &labels, &names);
    assert_eq!((same[0].rmse, same[0].mean_colour, same[0].colour_w1, same[0].contrast_w1), (0.0, 0.0, 0.0, Some(0.0)));
}

/// The light figures against ratios worked by hand: lights fitted at 2×, 1× and 4× their truth's
/// luminance (grey, so luminance is the value).
#[test]
fn light_ratios_name_the_pair_furthest_off() {
    let truth = [[10.0f32; 3], [20.0; 3], [5.0; 3]];
    let fitted = [[20.0f32; 3], [20.0; 3], [20.0; 3]];
    let lights = LightRatios::new(&fitted, &truth);
    assert!((lights.scale - 2.0).abs() < 1e-6, "geometric mean of 2, 1, 4: {}", lights.scale);
    assert!((lights.between_two() - 3.0).abs() < 1e-6, "4 over 1, minus 1: {}", lights.between_two());
    assert!((lights.worst() - 1.0).abs() < 1e-6, "4 / 2 − 1: {}", lights.worst());
    assert_eq!(lights.extreme_pair(), (2, 1));
}
