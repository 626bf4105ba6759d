//! The light solve's unit tests: NNLS against brute force, and synthetic rooms whose lights,
//! albedo errors, exposures, render noise, misalignment and clipping are known.

use super::*;
use psc_base::SplitMix64;

/// The true NNLS minimiser by enumerating every active set (small problems only).
fn brute_force(g: &DMatrix<f64>, h: &DVector<f64>) -> Vec<f64> {
    let n = h.len();
    let objective = |x: &[f64]| {
        let gx: Vec<f64> = (0..n).map(|i| (0..n).map(|j| g[(i, j)] * x[j]).sum()).collect();
        0.5 * (0..n).map(|i| x[i] * gx[i]).sum::<f64>() - (0..n).map(|i| h[i] * x[i]).sum::<f64>()
    };
    let mut best = (0.0f64, vec![0.0; n]);
    for mask in 1..(1u32 << n) {
        let passive: Vec<bool> = (0..n).map(|i| mask >> i & 1 == 1).collect();
        let s = solve_passive(g, h, &passive);
        if s.iter().all(|&v| v >= 0.0) {
            let f = objective(&s);
            if f < best.0 {
                best = (f, s);
            }
        }
    }
    best.1
}

#[test]
fn nnls_finds_the_constrained_minimum() {
    let mut rng = SplitMix64::new(11);
    for trial in 0..300 {
        let (rows, n) = (12, 1 + trial % 5);
        let a = DMatrix::from_fn(rows, n, |_, _| rng.next_f64() - 0.3);
        let b = DVector::from_fn(rows, |_, _| rng.next_f64() * 2.0 - 0.8);
        let (g, h) = (a.transpose() * &a, a.transpose() * &b);
        let x = nnls(&g, &h);
        let y = brute_force(&g, &h);
        for (p, q) in x.iter().zip(&y) {
            assert!((p - q).abs() < 1e-8 * (1.0 + q.abs()), "trial {trial}: {x:?} vs {y:?}");
        }
    }
}

const JOINT: Unknowns = Unknowns { part_scales: true, exposure: true };
const PLAIN: Unknowns = Unknowns { part_scales: false, exposure: false };

/// Three parts under two lights whose mix varies across each part and differs between parts; the albedos the renders
/// assumed are off by a factor per part. The joint solve recovers the lights' ratio and the
/// factors (up to the global scale), and the plain solve, which trusts the albedos, does not.
#[test]
fn the_joint_solve_separates_lights_from_albedo_errors() {
    let mut rng = SplitMix64::new(5);
    let true_radiance = [[30.0f32, 20.0, 10.0], [10.0, 12.0, 14.0]];
    let albedo_error = [0.6f32, 1.0, 1.5];
    let mut samples = Samples { slots: 2, ..Samples::default() };
    for p in 0..3000 {
        let part = p % 3;
        // Part 0 lies mostly under light 0, part 2 under light 1 (as furniture near a lamp).
        let t = 1.0 - (part as f32 + 1.5 * rng.next_f64() as f32) / 3.5;
        let unit = [[t * 0.01; 3], [(1.0 - t) * 0.01 + 0.002; 3]];
        let photo: [f32; 3] = std::array::from_fn(|c| {
            let clean = albedo_error[part] * (true_radiance[0][c] * unit[0][c] + true_radiance[1][c] * unit[1][c]);
            clean * (1.0 + 0.02 * (rng.next_f64() as f32 - 0.5))
        });
        samples.push(PhotoValue::recorded(photo), part, 0, unit.into_iter(), None);
    }
    let joint = solve_samples(&samples, JOINT);
    let plain = solve_samples(&samples, PLAIN);
    // One view: its exposure is the global scale, not fitted.
    assert_eq!(joint.exposure, vec![[1.0f32; 3]]);
    let geo_mean = (albedo_error.iter().map(|a| a.ln()).sum::<f32>() / 3.0).exp();
    #[allow(clippy::needless_range_loop)] // c indexes four arrays in parallel
    for c in 0..3 {
        let true_ratio = true_radiance[0][c] / true_radiance[1][c];
        let joint_ratio = joint.radiance[0][c] / joint.radiance[1][c];
        let plain_ratio = plain.radiance[0][c] / plain.radiance[1][c];
        assert!((joint_ratio / true_ratio - 1.0).abs() < 0.02, "channel {c}: {joint_ratio} vs {true_ratio}");
        assert!((plain_ratio / true_ratio - 1.0).abs() > 0.05, "the plain solve should be off: {plain_ratio}");
        for (part, (error, found)) in albedo_error.iter().zip(&joint.part_scales).enumerate() {
            let expected = error / geo_mean;
            assert!((found[c] / expected - 1.0).abs() < 0.02, "part {part}: {:?}", joint.part_scales);
        }
    }
}

/// The pixel-count-weighted geometric mean per channel of `values[group]` over `groups`.
fn weighted_geo_mean(values: &[[f32; 3]], groups: &[usize]) -> [f32; 3] {
    std::array::from_fn(|c| {
        (groups.iter().map(|&g| f64::from(values[g][c]).ln()).sum::<f64>() / groups.len() as f64).exp() as f32
    })
}

/// Three views of four parts under two lights, each view at its own RGB exposure, every
/// part's assumed albedo off by a factor, and each view seeing three of the parts (so that
/// every part is seen at two exposures). The joint solve recovers the exposures, the lights'
/// ratio and the part factors (up to the global scales its geometric means fix); with the
/// exposures held at 1 the part factors must absorb them and cannot, so it fits worse.
#[test]
fn the_joint_solve_recovers_per_view_exposures() {
    let mut rng = SplitMix64::new(17);
    let true_radiance = [[30.0f32, 20.0, 10.0], [10.0, 12.0, 14.0]];
    let true_exposure = [[1.0f32, 1.0, 1.0], [1.5, 1.35, 1.2], [0.7, 0.8, 0.9]];
    let albedo_error = [[0.6f32; 3], [1.0; 3], [1.5, 1.4, 1.3], [0.8, 0.9, 1.0]];
    let seen: [&[usize]; 3] = [&[0, 1, 2], &[1, 2, 3], &[0, 2, 3]];
    let mut samples = Samples { slots: 2, ..Samples::default() };
    let (mut view_of, mut part_of) = (Vec::new(), Vec::new());
    for (view, parts) in seen.iter().enumerate() {
        for p in 0..1200 {
            let part = parts[p % parts.len()];
            // Each part lies more under one light than the other, differently in each view.
            let t = 1.0 - (0.7 * part as f32 + 0.2 * view as f32 + 1.5 * rng.next_f64() as f32) / 4.0;
            let unit = [[t * 0.01; 3], [(1.0 - t) * 0.01 + 0.002; 3]];
            let photo: [f32; 3] = std::array::from_fn(|c| {
                let clean = true_exposure[view][c]
                    * albedo_error[part][c]
                    * (true_radiance[0][c] * unit[0][c] + true_radiance[1][c] * unit[1][c]);
                clean * (1.0 + 0.02 * (rng.next_f64() as f32 - 0.5))
            });
            samples.push(PhotoValue::recorded(photo), part, view, unit.into_iter(), None);
            view_of.push(view);
            part_of.push(part);
        }
    }
    let joint = solve_samples(&samples, JOINT);
    let without = solve_samples(&samples, Unknowns { part_scales: true, exposure: false });
    assert_eq!(without.exposure, vec![[1.0f32; 3]; 3], "exposures disabled stay at 1");
    let exposure_mean = weighted_geo_mean(&true_exposure, &view_of);
    let albedo_mean = weighted_geo_mean(&albedo_error, &part_of);
    let mut worst_without = 0.0f32;
    #[allow(clippy::needless_range_loop)] // c indexes several arrays in parallel
    for c in 0..3 {
        let true_ratio = true_radiance[0][c] / true_radiance[1][c];
        let ratio = |s: &LightSolve| s.radiance[0][c] / s.radiance[1][c];
        assert!((ratio(&joint) / true_ratio - 1.0).abs() < 0.02, "channel {c}: {} vs {true_ratio}", ratio(&joint));
        for (view, (truth, found)) in true_exposure.iter().zip(&joint.exposure).enumerate() {
            let expected = truth[c] / exposure_mean[c];
            assert!((found[c] / expected - 1.0).abs() < 0.02, "view {view}, channel {c}: {:?}", joint.exposure);
        }
        for (part, (error, found)) in albedo_error.iter().zip(&joint.part_scales).enumerate() {
            let expected = error[c] / albedo_mean[c];
            assert!((found[c] / expected - 1.0).abs() < 0.02, "part {part}, channel {c}: {:?}", joint.part_scales);
            worst_without = worst_without.max((without.part_scales[part][c] / expected - 1.0).abs());
        }
        // The residual is the noise (uniform ±1%, rms 0.6%) with the exposures and several
        // times it without.
        assert!(joint.relative_rms[c] < 0.01, "channel {c}: {:?}", joint.relative_rms);
        assert!(without.relative_rms[c] > 3.0 * joint.relative_rms[c], "{:?}", without.relative_rms);
    }
    assert!(worst_without > 0.05, "without exposures the part factors should be off: {worst_without}");
}

/// Two parts under two lights; the unit renders of light 1 (lit by indirect paths, say)
/// carry ±30% Monte Carlo noise per pixel, light 0's ±10%, while the photo is clean. With
/// one estimate the noise counts as signal and light 1 comes out too dim (by 12–17% here);
/// with two independent estimates the cross products recover the ratio within 4%. What is
/// left comes from the robust weights, which depend on the residual and so on the noise.
#[test]
fn two_independent_estimates_remove_the_bias_of_noisy_renders() {
    let mut rng = SplitMix64::new(23);
    let true_radiance = [[40.0f32, 30.0, 20.0], [15.0, 15.0, 15.0]];
    let (mut one, mut two) = (Samples { slots: 2, ..Samples::default() }, Samples { slots: 2, ..Samples::default() });
    let noisy = |clean: [[f32; 3]; 2], rng: &mut SplitMix64| -> [[f32; 3]; 2] {
        let n0 = 1.0 + 0.2 * (rng.next_f64() as f32 - 0.5);
        let n1 = 1.0 + 0.6 * (rng.next_f64() as f32 - 0.5);
        [clean[0].map(|x| x * n0), clean[1].map(|x| x * n1)]
    };
    for p in 0..20000 {
        let part = p % 2;
        let t = 1.0 - (part as f32 + 1.5 * rng.next_f64() as f32) / 2.5;
        let clean = [[t * 0.01; 3], [(1.0 - t) * 0.01 + 0.002; 3]];
        let photo: [f32; 3] =
            std::array::from_fn(|c| true_radiance[0][c] * clean[0][c] + true_radiance[1][c] * clean[1][c]);
        let (a, b) = (noisy(clean, &mut rng), noisy(clean, &mut rng));
        one.push(PhotoValue::recorded(photo), part, 0, a.into_iter(), None);
        two.push(PhotoValue::recorded(photo), part, 0, a.into_iter(), Some(b.to_vec()));
    }
    let (biased, unbiased) = (solve_samples(&one, JOINT), solve_samples(&two, JOINT));
    #[allow(clippy::needless_range_loop)] // c indexes three arrays in parallel
    for c in 0..3 {
        let true_ratio = true_radiance[0][c] / true_radiance[1][c];
        let ratio = |s: &LightSolve| s.radiance[0][c] / s.radiance[1][c];
        let (bias_one, bias_two) = (ratio(&biased) / true_ratio - 1.0, ratio(&unbiased) / true_ratio - 1.0);
        assert!(bias_two.abs() < 0.04, "channel {c}: {} vs {true_ratio}", ratio(&unbiased));
        assert!(bias_one > 0.08, "one estimate should dim light 1: {}", ratio(&biased));
        assert!(bias_one > 3.0 * bias_two.abs(), "channel {c}: bias {bias_one} with one estimate, {bias_two} with two");
    }
}

/// Two parts under one light, both albedos right, their photos ±10% textured; the second
/// part's two render estimates are noisy the way few-sample indirect light is (log-normal,
/// σ = 0.5: mostly too dark, now and then far too bright, right on average). Weighted on the
/// residual alone, the skew reads as model error: the too-bright pixels are down-weighted
/// and the part's factor comes out 1.21 (the pipeline then brightens its albedo by that).
/// Widened by each pixel's own render noise, the weights leave 1.10.
#[test]
fn render_noise_is_not_taken_for_model_error() {
    let mut rng = SplitMix64::new(17);
    let mut rng_photo = SplitMix64::new(18);
    let mut samples = Samples { slots: 1, ..Samples::default() };
    let mut skewed = |clean: f32| -> [f32; 3] {
        let sigma = 0.5f64;
        let (u1, u2) = (rng.next_f64().max(1e-12), rng.next_f64());
        let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        [clean * (sigma * z - 0.5 * sigma * sigma).exp() as f32; 3]
    };
    for p in 0..40000 {
        let part = p % 2;
        let clean = 0.01 * (0.5 + (p % 89) as f32 / 89.0);
        let (a, b) = if part == 0 { ([clean; 3], [clean; 3]) } else { (skewed(clean), skewed(clean)) };
        // The photo's own texture and noise: ±10%.
        let photo = [20.0 * clean * (1.0 + 0.2 * (rng_photo.next_f64() as f32 - 0.5)); 3];
        samples.push(PhotoValue::recorded(photo), part, 0, [a].into_iter(), Some(vec![b]));
    }
    let solve = solve_samples(&samples, JOINT);
    for c in 0..3 {
        let ratio = solve.part_scales[1][c] / solve.part_scales[0][c];
        println!("channel {c}: factor of the noisy part over the clean one {ratio:.3}");
        assert!((ratio - 1.0).abs() < 0.15, "channel {c}: {:?}", solve.part_scales);
    }
}

/// Two lights whose renders differ by 2% across the pixels (lamps side by side), equal
/// radiances, and a 3% model error that happens to follow their difference. Solved without
/// the noise floor, the cross products hand one light all the light; with it, the
/// direction the data cannot resolve above the renders' ±20% noise stays near equal.
#[test]
fn directions_below_the_noise_floor_are_not_fitted() {
    let mut rng = SplitMix64::new(31);
    let mut two = Samples { slots: 2, ..Samples::default() };
    let mut noisy = |x: f32| x * (1.0 + 0.4 * (rng.next_f64() as f32 - 0.5));
    for p in 0..20000 {
        let (t, d) = (0.5 + (p % 97) as f32 / 97.0, ((p * 7919) % 101) as f32 / 50.0 - 1.0);
        let clean = [t * 0.01, t * 0.01 * (1.0 + 0.02 * d)];
        let photo = [20.0 * (clean[0] + clean[1]) * (1.0 + 0.03 * d); 3];
        let a = [[noisy(clean[0]); 3], [noisy(clean[1]); 3]];
        let b = vec![[noisy(clean[0]); 3], [noisy(clean[1]); 3]];
        two.push(PhotoValue::recorded(photo), 0, 0, a.into_iter(), Some(b));
    }
    let n = two.photo.len();
    let (g, h) = normal_equations(&two, 1, &vec![1.0; n], &vec![1.0; n]);
    let unfloored = nnls(&g, &h);
    assert!(unfloored[0].min(unfloored[1]) < 5.0, "without the floor one light takes all: {unfloored:?}");
    let solved = solve_samples(&two, PLAIN);
    for r in &solved.radiance {
        assert!((r[1] / 20.0 - 1.0).abs() < 0.15, "{:?}", solved.radiance);
    }
}

/// A box the coarse model puts 6 pixels left of where the photo shows it, under two lights
/// that only the box tells apart (the wall's two renders are proportional). Read at the
/// model position its alignment gives each photo pixel, the box's renders explain the photo
/// and the solve recovers the lights' ratio; read at the photo pixel itself, the same
/// pixels give a different ratio.
#[test]
fn renders_are_read_where_the_alignment_puts_each_photo_pixel() {
    use crate::align::{align_view, Warp};
    use crate::observe::{GeoBuffer, Photo};
    use crate::working::WorkingRaster;
    use psc_render::camera::{Camera, CameraSpec};

    let (w, h, shift) = (48usize, 8usize, 6usize);
    let (box_start, box_end) = (8usize, 20usize);
    let true_radiance = [[30.0f32, 25.0, 20.0], [10.0, 10.0, 10.0]];
    let model_part = |x: usize| u32::from((box_start..box_end).contains(&x));
    let unit = |x: usize| -> [[f32; 3]; 2] {
        if model_part(x) == 1 {
            let u = (x - box_start) as f32 / (box_end - box_start) as f32;
            [[0.01 * (0.2 + u); 3], [0.01 * (1.2 - u); 3]]
        } else {
            [[0.01 * (1.0 + x as f32 / w as f32); 3]; 2]
        }
    };
    let shade = |x: usize| -> [f32; 3] {
        let i = unit(x);
        std::array::from_fn(|c| true_radiance[0][c] * i[0][c] + true_radiance[1][c] * i[1][c])
    };
    // The photo: the wall where the model has it, the box shifted right by `shift`.
    let photo_part = |x: usize| u32::from((box_start + shift..box_end + shift).contains(&x));
    let linear: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let x = i % w;
            if photo_part(x) == 1 {
                shade(x - shift)
            } else {
                [0.01 * (1.0 + x as f32 / w as f32) * 40.0, 0.01 * (1.0 + x as f32 / w as f32) * 35.0, 0.3]
                    .map(|v| v.min(0.9))
            }
        })
        .collect();
    let spec =
        CameraSpec { position: [0.0, 0.0, 0.0], look_at: [0.0, 0.0, -1.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 };
    let obs = ViewObservation {
        name: "view".into(),
        camera: Camera::new(&spec, w, h, "test camera").unwrap(),
        photo: Photo::from_parts(w, h, linear.clone(), linear, vec![false; w * h]),
        labels: Some((0..w * h).map(|i| photo_part(i % w)).collect()),
        geo: GeoBuffer {
            width: w,
            height: h,
            part: (0..w * h).map(|i| model_part(i % w)).collect(),
            emitter: vec![false; w * h],
            depth: vec![1.0; w * h],
        },
        raster: WorkingRaster::for_photo(w, h, 0),
    };
    let renders: UnitRenders = vec![(0..2).map(|k| (0..w * h).map(|i| unit(i % w)[k]).collect()).collect()];
    let aligned = vec![align_view(&obs, 0, 2)];
    let box_warp = aligned[0].iter().find(|a| a.part == 1).unwrap().warp;
    assert_eq!(box_warp, Warp { scale: [1.0, 1.0], offset: [shift as f32, 0.0] });
    let ratio_error = |aligned: &[Vec<AlignedPart>]| -> f32 {
        let solve = solve_with_part_scales(std::slice::from_ref(&obs), aligned, &renders, &renders).unwrap();
        (0..3)
            .map(|c| {
                let ratio = solve.radiance[0][c] / solve.radiance[1][c];
                (ratio / (true_radiance[0][c] / true_radiance[1][c]) - 1.0).abs()
            })
            .fold(0.0f32, f32::max)
    };
    let aligned_error = ratio_error(&aligned);
    assert!(aligned_error < 0.01, "read at the aligned positions, the ratio is off by {aligned_error}");
    // The same photo pixels read in place: those whose own model pixel is on the box.
    let mut in_place = aligned.clone();
    for part in in_place[0].iter_mut().filter(|a| a.part == 1) {
        part.warp = Warp::IDENTITY;
        part.usable.retain(|&i| model_part(i as usize % w) == 1);
    }
    let in_place_error = ratio_error(&in_place);
    println!("ratio error: {aligned_error:.5} aligned, {in_place_error:.3} in place");
    assert!(in_place_error > 0.1, "read in place, the ratio should be off: {in_place_error}");
}

/// Three parts under two lights; the first (a white rug under the lamps) is clipped in every
/// pixel, and the albedo the renders assumed for it is half its true one. Left out, its
/// pixels say nothing and its factor stays where it was: its darkest pixel renders at about
/// 0.6 of the clip it is above in the photo. As lower bounds, every pixel its render leaves
/// below the clip pulls its factor up, and the render reaches the clip. The other parts, and
/// so the lights, are solved as well either way.
#[test]
fn clipped_pixels_are_lower_bounds() {
    let mut rng = SplitMix64::new(41);
    let true_radiance = [[30.0f32, 27.0, 24.0], [10.0, 10.0, 10.0]];
    let assumed = [0.5f32, 1.0, 1.0];
    let (mut bounds, mut left_out) =
        (Samples { slots: 2, ..Samples::default() }, Samples { slots: 2, ..Samples::default() });
    let mut rug_units = Vec::new();
    for p in 0..3000 {
        let part = p % 3;
        let t = 1.0 - (part as f32 + 1.5 * rng.next_f64() as f32) / 3.5;
        // The renders at the assumed albedos; in truth the rug is 1.3-2.6 times the clip.
        let shade = if part == 0 { 0.06 * assumed[0] } else { 0.01 };
        let unit = [[t * shade; 3], [(1.0 - t) * shade + 0.2 * shade; 3]];
        let value: [f32; 3] = std::array::from_fn(|c| {
            let clean = (true_radiance[0][c] * unit[0][c] + true_radiance[1][c] * unit[1][c]) / assumed[part];
            clean * (1.0 + 0.02 * (rng.next_f64() as f32 - 0.5))
        });
        if part == 0 {
            assert!(value.iter().all(|&v| v >= 1.0), "the rug should be clipped everywhere: {value:?}");
            bounds.push(PhotoValue { value: [1.0; 3], at_least: [true; 3] }, part, 0, unit.into_iter(), None);
            rug_units.push(unit);
        } else {
            bounds.push(PhotoValue::recorded(value), part, 0, unit.into_iter(), None);
            left_out.push(PhotoValue::recorded(value), part, 0, unit.into_iter(), None);
        }
    }
    // Left out entirely, the rug keeps the factor of the other parts' mean: one part of three.
    left_out.n_parts = 3;
    for (name, samples) in [("as bounds", &bounds), ("left out", &left_out)] {
        let solve = solve_samples(samples, JOINT);
        // The rug's darkest pixel as the solve models it (its factor times its renders under the
        // solved lights), relative to the clip at 1.
        let darkest = (0..3)
            .flat_map(|c| {
                let (s, r) = (solve.part_scales[0][c], &solve.radiance);
                rug_units.iter().map(move |u| s * (r[0][c] * u[0][c] + r[1][c] * u[1][c]))
            })
            .fold(f32::INFINITY, f32::min);
        let ratio = (0..3)
            .map(|c| {
                let truth = true_radiance[0][c] / true_radiance[1][c];
                (solve.radiance[0][c] / solve.radiance[1][c] / truth - 1.0).abs()
            })
            .fold(0.0f32, f32::max);
        println!("{name}: the rug's darkest pixel renders at {darkest:.3} of the clip; light ratio off by {ratio:.3}");
        assert!(ratio < 0.03, "{name}: the lights' ratio is off by {ratio}");
        if name == "as bounds" {
            assert!(darkest > 0.97, "as bounds, the rug should render at the clip: {darkest}");
        } else {
            assert!(darkest < 0.8, "left out, the rug keeps its dark albedo: {darkest}");
        }
    }
}
