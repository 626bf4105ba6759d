//! The shading layer's exact adjoint against central finite differences, for every graph of
//! the library: parameters, the UV transform (θ, log-scale, offset), the albedo scale and the
//! roughness, through supersampling, normal mapping, the light grid, the view's per-channel
//! exposure and the sRGB encoding.
//!
//! A probe whose difference quotients at h and h/2 disagree crossed a kink or a jump of the
//! graph (floor, hash, comparisons) and is skipped rather than compared loosely; a floor on the
//! number of comparisons per graph keeps the test from passing vacuously.

use glam::Vec3;
use psc_base::SplitMix64;
use psc_fit::layer::{FitPixel, Gradient, MaterialState, PartView, Sampling, Workspace};
use psc_fit::shading::{irradiance_reference, LightSample, BINS};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library, Material};

fn random_light(rng: &mut SplitMix64) -> LightSample {
    let mut bins = [[0.0f32; 3]; BINS];
    // A bright "lamp" bin plus a smooth ambient term, like a room's grid.
    let lamp = rng.below(BINS);
    for (b, l) in bins.iter_mut().enumerate() {
        let base = 0.2 + 0.3 * rng.next_f32();
        *l = [base, base * (0.8 + 0.4 * rng.next_f32()), base * 0.9];
        if b == lamp {
            *l = l.map(|x| x + 20.0);
        }
    }
    let wo = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.3 + rng.next_f32()).normalize();
    LightSample::new(&bins, wo)
}

/// A 9×7 crop with 40 fit pixels at random uv with footprints that give 1–3 samples per axis.
fn synthetic_view(rng: &mut SplitMix64) -> PartView {
    let (width, height) = (9, 7);
    let mut weight = vec![0.0; width * height];
    let mut pixels = Vec::new();
    for (c, w) in weight.iter_mut().enumerate() {
        if rng.next_f32() < 0.35 {
            continue;
        }
        *w = 1.0;
        let f = 0.002 + 0.012 * rng.next_f32();
        let wo = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.4 + rng.next_f32()).normalize();
        pixels.push(FitPixel {
            crop_index: c as u32,
            uv: [rng.next_f32() * 3.0 - 1.0, rng.next_f32() * 3.0 - 1.0],
            duv_dx: [f, 0.3 * f],
            duv_dy: [-0.2 * f, f],
            bitangent_sign: if rng.next_f32() < 0.3 { -1.0 } else { 1.0 },
            wo_local: wo,
            light: random_light(rng),
        });
    }
    PartView {
        width,
        height,
        origin: [0, 0],
        factor: 1,
        pixels,
        weight,
        target: vec![[0.5; 3]; width * height],
        target_linear: vec![[0.2; 3]; width * height],
        // Per channel, so that the adjoint of the RGB exposure is checked.
        exposure: [0.35, 0.45, 0.28],
        noise: [0.0; 4],
        noise_scale: 1.0,
        faces: Vec::new(),
    }
}

struct Probe<'a> {
    view: &'a PartView,
    material: &'a Material,
    sampling: Sampling,
    seed: Vec<[f32; 3]>,
}

impl Probe<'_> {
    /// L = Σ seed · image.
    fn loss(&self, state: &MaterialState, ws: &mut Workspace) -> f64 {
        self.view.render(self.material, state, self.sampling, ws).unwrap();
        ws.image.iter().zip(&self.seed).map(|(p, s)| (0..3).map(|c| f64::from(p[c] * s[c])).sum::<f64>()).sum()
    }

    fn gradient(&self, state: &MaterialState, ws: &mut Workspace) -> Gradient {
        self.view.render(self.material, state, self.sampling, ws).unwrap();
        self.view.backward(self.material, state, ws, &self.seed).unwrap()
    }
}

struct Tally {
    /// Relative tolerance of a comparison (plus 2e-3 absolute).
    tolerance: f64,
    compared: usize,
    non_zero: usize,
    skipped: usize,
    skipped_what: Vec<String>,
    failures: Vec<String>,
}

/// Compares `analytic` with central differences of `probe` along `set` at steps h and h/2.
impl Tally {
    fn new(tolerance: f64) -> Tally {
        Tally { tolerance, compared: 0, non_zero: 0, skipped: 0, skipped_what: Vec::new(), failures: Vec::new() }
    }
}

fn compare(tally: &mut Tally, what: &str, analytic: f64, h: f32, mut eval: impl FnMut(f32) -> f64) {
    let d1 = (eval(h) - eval(-h)) / (2.0 * f64::from(h));
    let d2 = (eval(h / 2.0) - eval(-h / 2.0)) / f64::from(h);
    // The two quotients disagree when a jump or a feature narrower than h lies between the
    // probe points; that probe says nothing about the adjoint.
    if (d1 - d2).abs() > 0.01 * d1.abs().max(d2.abs()) + 1e-3 {
        tally.skipped += 1;
        tally.skipped_what.push(format!("{what}: {d1:.6} at h, {d2:.6} at h/2, adjoint {analytic:.6}"));
        return;
    }
    let scale = d1.abs().max(d2.abs()).max(analytic.abs());
    if (analytic - d2).abs() > tally.tolerance * scale + 2e-3 {
        // A kink (a slope change: clamp, min/max, the end of a bevel) close to the probe point
        // passes the test above when both central quotients average the two slopes alike,
        // while the adjoint takes the slope of one side. The one-sided quotients differ there
        // (by more than the comparison's tolerance; at a smooth point they agree): skip it.
        let f0 = eval(0.0);
        let right = (eval(h / 2.0) - f0) * 2.0 / f64::from(h);
        let left = (f0 - eval(-h / 2.0)) * 2.0 / f64::from(h);
        if (right - left).abs() > tally.tolerance * right.abs().max(left.abs()) + 2e-3 {
            tally.skipped += 1;
            tally
                .skipped_what
                .push(format!("{what}: on a kink, slopes {left:.6} and {right:.6}, adjoint {analytic:.6}"));
            return;
        }
        tally.failures.push(format!("{what}: adjoint {analytic:.6} vs finite difference {d2:.6} (h: {d1:.6})"));
    }
    tally.compared += 1;
    if analytic.abs() > 1e-3 {
        tally.non_zero += 1;
    }
}

/// One probe configuration: a random state and a loss on one random pixel (so that a finite
/// difference rarely straddles one of the graph's kinks), or on every pixel (`whole`).
fn check_graph(material: &Material, rng: &mut SplitMix64, tally: &mut Tally, whole: bool) {
    let view = synthetic_view(rng);
    let info = &material.graph.info;
    let mut params = info.default_params();
    // Move continuous parameters off their defaults, inside their ranges.
    for p in &info.params {
        if p.is_continuous() {
            let (lo, hi) = p.bounds();
            for x in &mut params[p.slot..p.slot + p.width()] {
                *x = lo + (hi - lo) * (0.2 + 0.6 * rng.next_f32());
            }
        }
    }
    let state = MaterialState {
        params,
        uv: UvTransform {
            rotation: rng.next_f32() * 6.0 - 3.0,
            log_scale: rng.next_f32() * 2.0 - 1.0,
            offset: [0.3, 0.7],
        },
        albedo_scale: [0.9, 1.1, 0.8],
        roughness: 0.33,
    };
    let picked = view.pixels[rng.below(view.pixels.len())].crop_index as usize;
    let seed: Vec<[f32; 3]> = (0..view.width * view.height)
        .map(|c| if whole || c == picked { [0, 1, 2].map(|_| rng.next_f32() - 0.5) } else { [0.0; 3] })
        .collect();
    let probe = Probe { view: &view, material, sampling: Sampling { density: 160.0, max_per_axis: 3 }, seed };
    let mut ws = Workspace::default();
    let g = probe.gradient(&state, &mut ws);
    let name = &info.name;
    for p in info.params.iter().filter(|p| p.is_continuous()) {
        let (lo, hi) = p.bounds();
        for s in p.slot..p.slot + p.width() {
            let h = 2e-4 * (hi - lo);
            compare(tally, &format!("{name}.{} slot {s}", p.name), g.params[s], h, |d| {
                let mut x = state.clone();
                x.params[s] += d;
                probe.loss(&x, &mut ws)
            });
        }
    }
    let uv_names = ["rotation", "log_scale", "offset.x", "offset.y"];
    for (k, what) in uv_names.iter().enumerate() {
        compare(tally, &format!("{name} uv {what}"), g.uv[k], 2e-4, |d| {
            let mut x = state.clone();
            match k {
                0 => x.uv.rotation += d,
                1 => x.uv.log_scale += d,
                _ => x.uv.offset[k - 2] += d,
            }
            probe.loss(&x, &mut ws)
        });
    }
    for c in 0..3 {
        compare(tally, &format!("{name} albedo_scale[{c}]"), g.albedo_scale[c], 1e-3, |d| {
            let mut x = state.clone();
            x.albedo_scale[c] += d;
            probe.loss(&x, &mut ws)
        });
    }
    compare(tally, &format!("{name} roughness"), g.roughness, 1e-3, |d| {
        let mut x = state.clone();
        x.roughness += d;
        probe.loss(&x, &mut ws)
    });
}

#[test]
fn layer_gradients_match_finite_differences_for_every_library_graph() {
    let library = Library::load(&default_library_root()).expect("library compiles");
    let mut report = String::new();
    let mut failures = Vec::new();
    let mut total = 0;
    for material in &library.materials {
        // Seeded by the graph's name, so that a graph added to the library leaves the others'
        // probes where they were.
        let mut rng = SplitMix64::new(psc_base::mix_name(1000, material.name()));
        // 5%: the graphs' kernels are checked against finite differences far more tightly by the
        // compiler's tests; features narrower than the step (thin mortar lines at high repeat
        // counts) blur the quotients of some probes by a few percent.
        let mut tally = Tally::new(0.05);
        for _ in 0..4 {
            check_graph(material, &mut rng, &mut tally, false);
        }
        let probes = tally.compared + tally.skipped;
        report.push_str(&format!(
            "{:<24} compared {:>3} ({:>3} non-zero), skipped {:>3} at a kink{}\n",
            material.name(),
            tally.compared,
            tally.non_zero,
            tally.skipped,
            if tally.failures.is_empty() { String::new() } else { format!("  FAILED {}", tally.failures.len()) }
        ));
        if tally.compared * 2 < probes {
            failures.push(format!("{}: only {} of {probes} probes were comparable", material.name(), tally.compared));
        }
        if tally.non_zero < 12 {
            failures.push(format!("{}: only {} compared derivatives are non-zero", material.name(), tally.non_zero));
        }
        total += tally.compared;
        failures.extend(tally.failures.into_iter().take(4));
    }
    eprintln!("{report}");
    assert!(total >= 500, "only {total} derivatives compared");
    assert!(failures.is_empty(), "{} problems:\n{}", failures.len(), failures.join("\n"));
}

/// A smooth graph (no kinks anywhere) with a height-derived normal: every derivative of a loss
/// over the whole crop is compared, with a tight tolerance.
#[test]
fn layer_gradients_of_a_smooth_graph_match_finite_differences_exactly() {
    let src = "graph smooth_probe {\n    category concrete\n    param a = 0.5 in [0, 1]\n    param f = 2.0 in [1, 4]\n    param tint = srgb(0.6, 0.5, 0.4)\n    output albedo = tint * (0.6 + 0.3 * sin(6.2831853 * f * uv.x + a) * cos(6.2831853 * uv.y))\n    output roughness = 0.5\n    output height = 0.03 * a * sin(6.2831853 * 2.0 * uv.x) * sin(6.2831853 * 3.0 * uv.y)\n}\n";
    let root = default_library_root();
    let out =
        psc_compiler::compile_text(&root.join("concrete/__smooth_probe.psg"), src, &psc_compiler::Options::default());
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    let material = Material::new(out.graphs.into_iter().next().unwrap()).unwrap();
    let mut tally = Tally::new(0.01);
    let mut rng = SplitMix64::new(77);
    for _ in 0..3 {
        check_graph(&material, &mut rng, &mut tally, true);
    }
    assert_eq!(tally.skipped, 0, "a smooth graph has no kinks: {:?}", tally.skipped_what);
    assert!(tally.compared >= 3 * 13, "{} compared", tally.compared);
    assert!(tally.failures.is_empty(), "{}", tally.failures.join("\n"));
}

#[test]
fn a_wrong_gradient_is_caught() {
    // The comparison is not vacuous: a roughness gradient off by 10% is flagged.
    let library = Library::load(&default_library_root()).unwrap();
    let material = library.get("plaster").unwrap();
    let mut rng = SplitMix64::new(5);
    let view = synthetic_view(&mut rng);
    let state = MaterialState {
        params: material.graph.info.default_params(),
        uv: UvTransform::default(),
        albedo_scale: [1.0; 3],
        roughness: 0.33,
    };
    let seed: Vec<[f32; 3]> = (0..view.width * view.height).map(|_| [1.0, 1.0, 1.0]).collect();
    let probe = Probe { view: &view, material, sampling: Sampling::default(), seed };
    let mut ws = Workspace::default();
    let g = probe.gradient(&state, &mut ws);
    let mut tally = Tally::new(0.05);
    compare(&mut tally, "roughness ×1.1", g.roughness * 1.1, 1e-3, |d| {
        let mut x = state.clone();
        x.roughness += d;
        probe.loss(&x, &mut ws)
    });
    assert_eq!(tally.compared, 1);
    assert_eq!(tally.failures.len(), 1, "a 10% error was not flagged");
}

/// First moments ∫_bin l dω of every grid bin by midpoint quadrature in f64 (independent of the
/// closed form the shading layer uses).
fn bin_moments_by_quadrature() -> Vec<[f64; 3]> {
    use std::f64::consts::PI;
    let (rows, cols, q) = (8, 16, 64);
    let (dt, dp) = (PI / 2.0 / rows as f64, 2.0 * PI / cols as f64);
    let mut out = vec![[0.0f64; 3]; rows * cols];
    for i in 0..rows {
        for j in 0..cols {
            let m = &mut out[i * cols + j];
            for a in 0..q {
                let t = (i as f64 + (a as f64 + 0.5) / q as f64) * dt;
                for b in 0..q {
                    let p = (j as f64 + (b as f64 + 0.5) / q as f64) * dp;
                    let w = t.sin() * (dt / q as f64) * (dp / q as f64);
                    m[0] += t.sin() * p.cos() * w;
                    m[1] += t.sin() * p.sin() * w;
                    m[2] += t.cos() * w;
                }
            }
        }
    }
    out
}

fn irradiance_f64(moments: &[[f64; 3]], bins: &[[f32; 3]; BINS], n: [f64; 3]) -> [f64; 3] {
    let mut e = [0.0f64; 3];
    for (m, l) in moments.iter().zip(bins) {
        let c = (n[0] * m[0] + n[1] * m[1] + n[2] * m[2]).max(0.0);
        for k in 0..3 {
            e[k] += c * f64::from(l[k]);
        }
    }
    e
}

#[test]
fn irradiance_fast_path_equals_the_sum_over_every_bin() {
    let moments = bin_moments_by_quadrature();
    let mut rng = SplitMix64::new(3);
    let mut compared = 0;
    for _ in 0..300 {
        let mut bins = [[0.0f32; 3]; BINS];
        for l in bins.iter_mut() {
            *l = [0, 1, 2].map(|_| rng.next_f32() * 2.0);
        }
        let light = LightSample::new(&bins, Vec3::Z);
        // Normals from untilted to 80° tilt.
        let tilt = rng.next_f32() * 1.4;
        let phi = rng.next_f32() * std::f32::consts::TAU;
        let n = Vec3::new(tilt.sin() * phi.cos(), tilt.sin() * phi.sin(), tilt.cos());
        let n64 = n.to_array().map(f64::from);
        let fast = light.irradiance(n);
        let exact = irradiance_f64(&moments, &bins, n64);
        let reference = irradiance_reference(&bins, n);
        for c in 0..3 {
            assert!(
                (f64::from(fast[c]) - exact[c]).abs() <= 1e-4 * exact[c].max(1.0),
                "{fast:?} vs {exact:?} at {n:?}"
            );
            assert!((f64::from(reference[c]) - exact[c]).abs() <= 1e-4 * exact[c].max(1.0));
        }
        // The adjoint against central differences in f64, away from the kinks where a bin's
        // moment crosses the perturbed normal's horizon.
        let near_kink = moments.iter().any(|m| (n64[0] * m[0] + n64[1] * m[1] + n64[2] * m[2]).abs() < 1e-4);
        if near_kink {
            continue;
        }
        let g = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let (_, d) = light.irradiance_grad(n, g);
        for axis in 0..3 {
            let h = 1e-7;
            let (mut p, mut m) = (n64, n64);
            p[axis] += h;
            m[axis] -= h;
            let (ep, em) = (irradiance_f64(&moments, &bins, p), irradiance_f64(&moments, &bins, m));
            let fd: f64 = (0..3).map(|c| f64::from(g[c]) * (ep[c] - em[c]) / (2.0 * h)).sum();
            compared += 1;
            assert!((fd - f64::from(d[axis])).abs() <= 1e-4 * fd.abs() + 1e-4, "axis {axis}: {} vs {fd}", d[axis]);
        }
    }
    assert!(compared >= 600, "only {compared} comparisons");
}

/// The fast path finds the arc of clipped bins from the column opposite the tilt, picked from
/// the tilt's quadrant and three slope comparisons: tilts whose opposite azimuth lies on a
/// column's edge or a quadrant's axis (where the pick may go either way) are still exact.
#[test]
fn irradiance_fast_path_is_exact_on_column_edges() {
    let moments = bin_moments_by_quadrature();
    let mut rng = SplitMix64::new(5);
    let mut bins = [[0.0f32; 3]; BINS];
    for l in bins.iter_mut() {
        *l = [0, 1, 2].map(|_| 0.1 + rng.next_f32());
    }
    let light = LightSample::new(&bins, Vec3::Z);
    for edge in 0..16 {
        for nudge in [-1e-5f32, 0.0, 1e-5] {
            for tilt_deg in [3.0f32, 30.0, 75.0] {
                let phi = edge as f32 * std::f32::consts::TAU / 16.0 + nudge;
                let tilt = tilt_deg.to_radians();
                let n = Vec3::new(tilt.sin() * phi.cos(), tilt.sin() * phi.sin(), tilt.cos());
                let exact = irradiance_f64(&moments, &bins, n.to_array().map(f64::from));
                let fast = light.irradiance(n);
                for c in 0..3 {
                    assert!(
                        (f64::from(fast[c]) - exact[c]).abs() <= 1e-4 * exact[c].max(1.0),
                        "edge {edge}, nudge {nudge}, tilt {tilt_deg}°: {fast:?} vs {exact:?}"
                    );
                }
            }
        }
    }
}
