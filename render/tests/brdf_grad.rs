//! The BRDF's derivatives against central finite differences (in f64, where the differences
//! are accurate), near grazing angles and at small roughness too; the gradient functions' values
//! against the value functions and the path tracer's per-hit form, bit for bit.

use glam::Vec3;
use psc_render::brdf::{
    f_cos_grad, specular, specular_cos_grad, specular_grad, Cosines, Karis, SpecularGrad, MIN_ROUGHNESS,
};
use psc_render::rng::Rng;

/// Random cosines and a roughness: a third of the cases grazing (n·v or n·l tiny), a third with
/// the smallest roughnesses, a third anywhere.
fn cases() -> Vec<(Cosines<f64>, f64)> {
    let mut rng = Rng::new(11, 12, 13);
    let mut u = || rng.next_f32() as f64;
    let mut out = Vec::new();
    for i in 0..3000 {
        let mut c = Cosines { n_v: 0.02 + 0.98 * u(), n_l: 0.02 + 0.98 * u(), n_h: u(), v_h: u() };
        let mut r = MIN_ROUGHNESS as f64 + (1.0 - MIN_ROUGHNESS as f64) * u();
        match i % 3 {
            0 => {
                c.n_v = 1e-4 + 1e-2 * u();
                if u() < 0.5 {
                    c.n_l = 1e-4 + 1e-2 * u();
                }
            }
            1 => {
                r = MIN_ROUGHNESS as f64 + 0.05 * u();
                // Put n·h near the peak of D, where it is steepest.
                c.n_h = 1.0 - 1e-3 * u();
            }
            _ => {}
        }
        out.push((c, r));
    }
    out
}

/// Central difference of `f` at `x` with step `h`.
fn central(mut f: impl FnMut(f64) -> f64, x: f64, h: f64) -> f64 {
    (f(x + h) - f(x - h)) / (2.0 * h)
}

/// Agreement up to the finite difference's own error: truncation (relative) and rounding
/// (about 1e-16 |f| / h = 1e-7 |f| for h = 1e-9).
fn close(analytic: f64, numeric: f64, scale: f64) -> bool {
    (analytic - numeric).abs() <= 1e-5 * analytic.abs().max(numeric.abs()) + 1e-6 * scale
}

/// Check every partial of `grad` against `value` by central differences.
fn check(name: &str, value: impl Fn(Cosines<f64>, f64) -> f64, grad: impl Fn(Cosines<f64>, f64) -> SpecularGrad<f64>) {
    let mut worst = 0.0f64;
    for (c, r) in cases() {
        let g = grad(c, r);
        assert_eq!(g.value.to_bits(), value(c, r).to_bits(), "{name}: value differs from the value function");
        // Steps small against each variable's feature size (D's peak has width d =
        // (n·h)²(α²−1) + 1 in n·h and in r), large against f64 rounding; the value's rounding
        // error grows like ε/d through the cancellation in d, which `slack` allows for.
        let a2 = r.powi(4);
        let dd = c.n_h * c.n_h * (a2 - 1.0) + 1.0;
        let (h_r, h_c, h_nh) = (1e-7 * r * dd.min(1.0), 1e-7, 1e-4 * dd);
        let slack = |h: f64| 4e-16 / dd * g.value.abs() / h;
        let partials = [
            ("roughness", g.d_roughness, central(|x| value(c, x), r, h_r), slack(h_r)),
            ("n_v", g.d_n_v, central(|x| value(Cosines { n_v: x, ..c }, r), c.n_v, h_c * c.n_v), slack(h_c * c.n_v)),
            ("n_l", g.d_n_l, central(|x| value(Cosines { n_l: x, ..c }, r), c.n_l, h_c * c.n_l), slack(h_c * c.n_l)),
            ("n_h", g.d_n_h, central(|x| value(Cosines { n_h: x, ..c }, r), c.n_h, h_nh), slack(h_nh)),
            ("v_h", g.d_v_h, central(|x| value(Cosines { v_h: x, ..c }, r), c.v_h, h_c), slack(h_c)),
        ];
        for (what, a, n, slack) in partials {
            assert!(
                (a - n).abs() <= 1e-6 * a.abs().max(n.abs()) + slack,
                "{name}: ∂/∂{what} = {a}, finite difference {n} at {c:?}, r = {r}"
            );
            worst = worst.max((a - n).abs() / (1e-6 * a.abs().max(n.abs()) + slack));
        }
    }
    eprintln!("{name}: largest gradient error {worst:.3} of the tolerance");
}

#[test]
fn specular_gradient_matches_finite_differences() {
    check("specular", specular, specular_grad);
}

#[test]
fn specular_cos_gradient_matches_finite_differences() {
    check("specular·cos", |c, r| specular(c, r) * c.n_l, specular_cos_grad);
}

#[test]
fn gradients_vanish_below_the_surface() {
    let c = Cosines { n_v: -0.2, n_l: 0.5, n_h: 0.9, v_h: 0.8 };
    assert_eq!(specular_grad(c, 0.5), specular_grad(Cosines { n_v: 0.0, ..c }, 0.5));
    assert_eq!(specular_grad(c, 0.5).value, 0.0);
    assert_eq!(specular_cos_grad(Cosines { n_l: -0.1, n_v: 0.3, ..c }, 0.5).d_roughness, 0.0);
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

fn random_dir(rng: &mut Rng, min_z: f64) -> [f64; 3] {
    loop {
        let v = [rng.next_f32() as f64 * 2.0 - 1.0, rng.next_f32() as f64 * 2.0 - 1.0, rng.next_f32() as f64];
        let v = unit(v);
        if v[2] > min_z {
            return v;
        }
    }
}

#[test]
fn f_cos_gradient_matches_finite_differences_in_normal_roughness_and_albedo() {
    let mut rng = Rng::new(21, 22, 23);
    for i in 0..2000 {
        // The normal is tilted off z; v and l above the z plane, some of them grazing.
        let n = unit([0.2 * (rng.next_f32() as f64 - 0.5), 0.2 * (rng.next_f32() as f64 - 0.5), 1.0]);
        let min_z = if i % 4 == 0 { 0.0 } else { 0.15 };
        let (v, l) = (random_dir(&mut rng, min_z), random_dir(&mut rng, min_z));
        let albedo = [rng.next_f32() as f64, rng.next_f32() as f64, rng.next_f32() as f64];
        let r = if i % 3 == 0 { 0.02 + 0.05 * rng.next_f32() as f64 } else { 0.02 + 0.98 * rng.next_f32() as f64 };
        let g = f_cos_grad(n, v, l, albedo, r);
        if g.d_albedo == 0.0 {
            continue; // n·v or n·l ≤ 0 after the tilt
        }
        let h = 1e-9;
        for ch in 0..3 {
            let val = |n: [f64; 3], a: [f64; 3], r: f64| f_cos_grad(n, v, l, a, r).value[ch];
            let scale = g.value[ch].abs() + 1.0;
            let dr = central(|x| val(n, albedo, x), r, h);
            assert!(close(g.d_roughness, dr, scale), "∂/∂r {} vs {dr}", g.d_roughness);
            let mut a2 = albedo;
            let da = central(
                |x| {
                    a2[ch] = x;
                    val(n, a2, r)
                },
                albedo[ch],
                h,
            );
            assert!(close(g.d_albedo, da, scale), "∂/∂albedo {} vs {da}", g.d_albedo);
            for k in 0..3 {
                let dn = central(
                    |x| {
                        let mut m = n;
                        m[k] = x;
                        val(m, albedo, r)
                    },
                    n[k],
                    h,
                );
                assert!(
                    close(g.d_normal[ch][k], dn, scale),
                    "∂/∂n{k} channel {ch}: {} vs {dn} (n {n:?}, v {v:?}, l {l:?}, r {r})",
                    g.d_normal[ch][k]
                );
            }
        }
    }
}

#[test]
fn f32_gradients_follow_the_f64_ones() {
    for (c, r) in cases() {
        let g64 = specular_cos_grad(c, r);
        let c32 = Cosines { n_v: c.n_v as f32, n_l: c.n_l as f32, n_h: c.n_h as f32, v_h: c.v_h as f32 };
        let g32 = specular_cos_grad(c32, r as f32);
        // The f32 evaluation of the same inputs rounded to f32: compare at those inputs.
        let c_r = Cosines { n_v: c32.n_v as f64, n_l: c32.n_l as f64, n_h: c32.n_h as f64, v_h: c32.v_h as f64 };
        let g64 = if c_r == c { g64 } else { specular_cos_grad(c_r, (r as f32) as f64) };
        for (a, b) in [
            (g32.value, g64.value),
            (g32.d_roughness, g64.d_roughness),
            (g32.d_n_v, g64.d_n_v),
            (g32.d_n_l, g64.d_n_l),
            (g32.d_n_h, g64.d_n_h),
            (g32.d_v_h, g64.d_v_h),
        ] {
            // f32 cancellation in d = (n·h)²(α²−1) + 1 near the peak limits the agreement.
            assert!(((a as f64) - b).abs() <= 2e-2 * b.abs() + 1e-6, "f32 {a} vs f64 {b} at {c:?}, r {r}");
        }
    }
}

#[test]
fn one_brdf_bit_for_bit() {
    // The value functions, the Karis evaluation and the path tracer's per-hit form agree exactly.
    let mut rng = Rng::new(31, 32, 33);
    for _ in 0..5000 {
        let b = Karis::new(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()), rng.next_f32());
        let d = |rng: &mut Rng| {
            let v = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32()).normalize();
            if v.z > 0.0 {
                v
            } else {
                Vec3::Z
            }
        };
        let (wo, wi) = (d(&mut rng), d(&mut rng));
        let h = (wo + wi).normalize();
        let c = Cosines { n_v: wo.z, n_l: wi.z, n_h: h.z, v_h: wo.dot(h).max(0.0) };
        let s = specular(c, b.roughness);
        assert_eq!(b.specular(wo, wi).to_bits(), s.to_bits());
        assert_eq!(specular_grad(c, b.roughness).value.to_bits(), s.to_bits());
        let (f, _) = b.at(wo).eval_pdf(wi);
        assert_eq!(f, b.eval(wo, wi), "KarisWo::eval_pdf and Karis::eval");
        let (cc, _) = Cosines::new(Vec3::Z.to_array(), wo.to_array(), wi.to_array());
        assert_eq!(cc, c, "Cosines::new in the local frame");
    }
}
