//! Maximum error of each inline transcendental, measured on the compiled kernel itself over
//! dense sweeps, against f64 `std`. The bounds asserted here are the ones stated in
//! `psc_jit::approx`.

mod common;

use common::run_jit;
use psc_compiler::ir::{Builder, Output, Program};
use psc_jit::compile;

fn unary(f: fn(&mut Builder, psc_compiler::ir::NodeId) -> psc_compiler::ir::NodeId) -> Program {
    let mut b = Builder::new();
    let u = b.u();
    let y = f(&mut b, u);
    b.finish(vec![Output { name: "y".into(), node: y }])
}

fn binary(
    f: fn(&mut Builder, psc_compiler::ir::NodeId, psc_compiler::ir::NodeId) -> psc_compiler::ir::NodeId,
) -> Program {
    let mut b = Builder::new();
    let u = b.u();
    let v = b.v();
    let y = f(&mut b, u, v);
    b.finish(vec![Output { name: "y".into(), node: y }])
}

fn eval_unary(p: &Program, xs: &[f32]) -> Vec<f32> {
    let k = compile(p).unwrap();
    run_jit(&k, &[], xs, &vec![0.0; xs.len()], &[]).remove(0)
}

/// `n` points evenly spread over [lo, hi].
fn sweep(lo: f64, hi: f64, n: usize) -> Vec<f32> {
    (0..n).map(|i| (lo + (hi - lo) * i as f64 / (n - 1) as f64) as f32).collect()
}

/// `n` points log-spaced over [lo, hi] (both > 0).
fn log_sweep(lo: f64, hi: f64, n: usize) -> Vec<f32> {
    let (a, b) = (lo.ln(), hi.ln());
    (0..n)
        .map(|i| (a + (b - a) * i as f64 / (n - 1) as f64).exp() as f32)
        .filter(|x| *x > 0.0 && x.is_finite())
        .collect()
}

fn max_abs_err(xs: &[f32], got: &[f32], f: impl Fn(f64) -> f64) -> (f64, f32) {
    let mut worst = (0.0, 0.0);
    for (&x, &y) in xs.iter().zip(got) {
        let e = (y as f64 - f(x as f64)).abs();
        if e > worst.0 || e.is_nan() {
            worst = (e, x);
        }
    }
    worst
}

fn max_rel_err(xs: &[f32], got: &[f32], f: impl Fn(f64) -> f64) -> (f64, f32) {
    let mut worst = (0.0, 0.0);
    for (&x, &y) in xs.iter().zip(got) {
        let want = f(x as f64);
        let e = ((y as f64 - want) / want).abs();
        if e > worst.0 || e.is_nan() {
            worst = (e, x);
        }
    }
    worst
}

#[test]
fn sin_and_cos_abs_error_below_2e_6_up_to_1e4() {
    let mut xs = sweep(-1e4, 1e4, 2_000_001);
    xs.extend(sweep(-10.0, 10.0, 200_001));
    let s = eval_unary(&unary(|b, u| b.sin(u)), &xs);
    let c = eval_unary(&unary(|b, u| b.cos(u)), &xs);
    let (es, xs_at) = max_abs_err(&xs, &s, f64::sin);
    let (ec, xc_at) = max_abs_err(&xs, &c, f64::cos);
    println!("sin max abs err {es:e} at {xs_at}; cos max abs err {ec:e} at {xc_at}");
    assert!(es < 2e-6, "sin error {es:e} at {xs_at}");
    assert!(ec < 2e-6, "cos error {ec:e} at {xc_at}");
    // Beyond the accurate range: bounded, and NaN for non-finite input.
    let wild = [1e6f32, -3e7, 1e20, f32::MAX, f32::INFINITY, f32::NAN];
    let s = eval_unary(&unary(|b, u| b.sin(u)), &wild);
    for (x, y) in wild.iter().zip(&s) {
        if x.is_finite() {
            assert!(y.abs() <= 1.5, "sin({x}) = {y}");
        } else {
            assert!(y.is_nan(), "sin({x}) = {y}");
        }
    }
}

#[test]
fn exp_rel_error_below_1e_6() {
    let xs = sweep(-87.0, 88.7, 2_000_001);
    let y = eval_unary(&unary(|b, u| b.exp(u)), &xs);
    let (e, at) = max_rel_err(&xs, &y, f64::exp);
    println!("exp max rel err {e:e} at {at}");
    assert!(e < 1e-6, "exp error {e:e} at {at}");
    let edge = [89.0f32, 1000.0, f32::INFINITY, -104.0, -1000.0, f32::NEG_INFINITY, f32::NAN, 0.0];
    let y = eval_unary(&unary(|b, u| b.exp(u)), &edge);
    assert_eq!(&y[..6], &[f32::INFINITY, f32::INFINITY, f32::INFINITY, 0.0, 0.0, 0.0]);
    assert!(y[6].is_nan());
    assert_eq!(y[7], 1.0);
}

#[test]
fn log_rel_error_below_1e_6() {
    let mut xs = log_sweep(f32::MIN_POSITIVE as f64, 3e38, 2_000_001);
    // Near 1, where ln x → 0, relative error is hardest.
    xs.extend(sweep(0.5, 2.0, 1_000_001).into_iter().filter(|&x| x != 1.0));
    let y = eval_unary(&unary(|b, u| b.log(u)), &xs);
    let (e, at) = max_rel_err(&xs, &y, f64::ln);
    println!("log max rel err {e:e} at {at}");
    assert!(e < 1e-6, "log error {e:e} at {at}");
    // The guard: ln(max(x, MIN_POSITIVE)).
    let edge = [0.0f32, -5.0, f32::NAN, f32::INFINITY, 1.0];
    let y = eval_unary(&unary(|b, u| b.log(u)), &edge);
    let floor = f32::MIN_POSITIVE.ln();
    assert!((y[0] - floor).abs() < 1e-5 && (y[1] - floor).abs() < 1e-5 && (y[2] - floor).abs() < 1e-5, "{y:?}");
    assert_eq!(y[3], f32::INFINITY);
    assert_eq!(y[4], 0.0);
}

#[test]
fn atan2_abs_error_below_1e_6() {
    let k = compile(&binary(|b, y, x| b.atan2(y, x))).unwrap();
    let mut ys = Vec::new();
    let mut xs = Vec::new();
    let ang = sweep(-std::f64::consts::PI, std::f64::consts::PI, 200_001);
    for (i, a) in ang.iter().enumerate() {
        let r = [1e-30, 1e-3, 1.0, 7.5, 1e5, 1e30][i % 6];
        ys.push((r * (*a as f64).sin()) as f32);
        xs.push((r * (*a as f64).cos()) as f32);
    }
    for i in -300..=300 {
        for j in -30..=30 {
            ys.push(i as f32 * 0.37);
            xs.push(j as f32 * 1.9);
        }
    }
    let got = run_jit(&k, &[], &ys, &xs, &[]).remove(0);
    let mut worst = (0.0f64, 0.0f32, 0.0f32);
    for i in 0..ys.len() {
        let want = if ys[i] == 0.0 && xs[i] == 0.0 { 0.0 } else { (ys[i] as f64).atan2(xs[i] as f64) };
        let e = (got[i] as f64 - want).abs();
        if e > worst.0 {
            worst = (e, ys[i], xs[i]);
        }
    }
    println!("atan2 max abs err {:e} at y={} x={}", worst.0, worst.1, worst.2);
    assert!(worst.0 < 1e-6, "atan2 error {:e} at y={} x={}", worst.0, worst.1, worst.2);
    let special =
        run_jit(&k, &[], &[0.0, -0.0, f32::INFINITY, f32::NAN, 1.0], &[0.0, 0.0, f32::INFINITY, 1.0, f32::NAN], &[])
            .remove(0);
    assert_eq!(special[0], 0.0);
    assert_eq!(special[1], 0.0);
    assert!((special[2] - std::f32::consts::FRAC_PI_4).abs() < 1e-7);
    assert!(special[3].is_nan() && special[4].is_nan());
}

#[test]
fn pow_rel_error_within_stated_bound() {
    let k = compile(&binary(|b, a, e| b.pow(a, e))).unwrap();
    let mut a = Vec::new();
    let mut e = Vec::new();
    for (i, x) in log_sweep(1e-3, 1e4, 3001).into_iter().enumerate() {
        for j in 0..301 {
            let b = -12.0 + 24.0 * j as f32 / 300.0 + (i % 7) as f32 * 1e-3;
            a.push(x);
            e.push(b);
        }
    }
    let got = run_jit(&k, &[], &a, &e, &[]).remove(0);
    let mut worst = (0.0f64, 0.0f32, 0.0f32);
    for i in 0..a.len() {
        let t = e[i] as f64 * (a[i] as f64).ln();
        let want = t.exp();
        if t.abs() > 80.0 {
            continue;
        }
        let err = ((got[i] as f64 - want) / want).abs();
        let bound = 2e-6 + 2e-7 * t.abs();
        let ratio = err / bound;
        if ratio > worst.0 {
            worst = (ratio, a[i], e[i]);
        }
    }
    println!("pow worst error / bound = {:.3} at a={} b={}", worst.0, worst.1, worst.2);
    assert!(worst.0 < 1.0, "pow error exceeds 2e-6 + 2e-7|b ln a| by {:.3}x at a={} b={}", worst.0, worst.1, worst.2);
    let special = run_jit(
        &k,
        &[],
        &[-2.0, 0.0, f32::NAN, 1.0, 5.0, f32::INFINITY, f32::INFINITY, 0.5],
        &[2.0, 3.0, 0.0, f32::NAN, 0.0, 2.0, -2.0, f32::INFINITY],
        &[],
    )
    .remove(0);
    assert_eq!(special, vec![0.0, 0.0, 0.0, 1.0, 1.0, f32::INFINITY, 0.0, 0.0]);
    // Subnormal bases take the scaled path of the log.
    let sub = run_jit(&k, &[], &[1e-40, 3e-44], &[0.5, 0.25], &[]).remove(0);
    for (got, want) in sub.iter().zip([(1e-40f32 as f64).sqrt(), (3e-44f32 as f64).powf(0.25)]) {
        assert!(((*got as f64 - want) / want).abs() < 1e-5, "{got} vs {want}");
    }
}
