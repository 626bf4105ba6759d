//! Unit tests of the parameter vector: round trips through JSON and the unit cube, the chain
//! rule factor against finite differences, projection, and hostile JSON.

use super::*;
use psc_compiler::{compile_text, Options};
use serde_json::json;

/// A graph with every kind of parameter: a float, an int and a colour, in that slot order.
fn space() -> ParamSpace {
    let src = r#"
graph probe {
    param gain = 0.5 in [0.1, 4]
    param rows = 6 in [2, 16] int
    param tint = srgb(0.8, 0.4, 0.2)
    param bias = -1.0 in [-3, 1]
    output albedo = clamp(tint * gain * 0.1 * rows + bias * 0.0, 0.0, 1.0)
    output roughness = 0.5
    output height = 0.0
}
"#;
    let out = compile_text(std::path::Path::new("probe.psg"), src, &Options::default());
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    ParamSpace::new(&out.graphs[0].info)
}

#[test]
fn slots_follow_declaration_order_with_their_ranges() {
    let s = space();
    assert_eq!(s.len(), 6);
    let kinds: Vec<SlotKind> = s.slots().iter().map(|k| k.kind).collect();
    use SlotKind::*;
    assert_eq!(kinds, [Continuous, Discrete, ColorChannel(0), ColorChannel(1), ColorChannel(2), Continuous]);
    assert_eq!((s.slots()[0].min, s.slots()[0].max), (0.1, 4.0));
    assert_eq!((s.slots()[1].min, s.slots()[1].max), (2.0, 16.0));
    assert_eq!((s.slots()[5].min, s.slots()[5].max), (-3.0, 1.0));
    assert!(s.check(&s.defaults()).is_ok());
}

#[test]
fn json_round_trips_bit_for_bit() {
    let s = space();
    let mut rng = SplitMix64::new(42);
    for _ in 0..200 {
        let p = s.random(&mut rng);
        s.check(&p).expect("random vectors are valid");
        let json = s.to_json(&p).unwrap();
        // Through text too, as a file would carry it.
        let text = serde_json::to_string(&json).unwrap();
        let back = s.from_json(&serde_json::from_str(&text).unwrap()).unwrap();
        assert_eq!(
            back.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            p.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
}

#[test]
fn json_fills_unnamed_parameters_with_defaults_and_reads_srgb() {
    let s = space();
    let p = s.from_json(&json!({"rows": 9, "tint": {"srgb": [1.0, 0.5, 0.0]}})).unwrap();
    let d = s.defaults();
    assert_eq!(p[0], d[0]);
    assert_eq!(p[1], 9.0);
    assert_eq!(p[2], 1.0);
    assert!((p[3] - 0.214_041).abs() < 1e-5, "sRGB 0.5 is linear 0.214, got {}", p[3]);
    assert_eq!(p[4], 0.0);
    assert_eq!(p[5], d[5]);
}

#[test]
fn random_variants_are_reproducible_and_in_range() {
    let s = space();
    let a: Vec<Vec<f32>> = (0..50).scan(SplitMix64::new(7), |r, _| Some(s.random(r))).collect();
    let b: Vec<Vec<f32>> = (0..50).scan(SplitMix64::new(7), |r, _| Some(s.random(r))).collect();
    assert_eq!(a, b);
    let c: Vec<Vec<f32>> = (0..50).scan(SplitMix64::new(8), |r, _| Some(s.random(r))).collect();
    assert_ne!(a, c);
    for p in &a {
        s.check(p).unwrap();
    }
    // Every integer value of `rows` is reachable.
    let mut rng = SplitMix64::new(1);
    let mut seen = [false; 17];
    for _ in 0..2000 {
        seen[s.random(&mut rng)[1] as usize] = true;
    }
    assert!(seen[2..=16].iter().all(|&x| x), "{seen:?}");
}

#[test]
fn unit_cube_round_trips_and_spans_the_ranges() {
    let s = space();
    let lo: Vec<f32> = s.slots().iter().map(|k| k.min).collect();
    let hi: Vec<f32> = s.slots().iter().map(|k| k.max).collect();
    assert!(s.to_unit(&lo).unwrap().iter().all(|&u| u == 0.0));
    assert!(s.to_unit(&hi).unwrap().iter().all(|&u| u == 1.0));
    let mut rng = SplitMix64::new(3);
    for _ in 0..100 {
        let p = s.random(&mut rng);
        let u = s.to_unit(&p).unwrap();
        assert!(u.iter().all(|x| (0.0..=1.0).contains(x)), "{u:?}");
        let back = s.from_unit(&u).unwrap();
        for (k, (a, b)) in p.iter().zip(&back).enumerate() {
            assert!((a - b).abs() <= 1e-6 * (1.0 + a.abs()), "slot {k}: {a} -> {b}");
        }
    }
}

/// The chain-rule factor, checked with central differences of a loss through `from_unit`.
#[test]
fn unit_gradient_matches_finite_differences() {
    let s = space();
    // A smooth loss of the natural-unit vector with a known gradient.
    let w = [0.3f64, -1.2, 0.7, 2.0, -0.4, 1.5];
    let loss = |x: &[f32]| -> f64 { x.iter().zip(&w).map(|(&x, w)| w * (x as f64) * (x as f64)).sum() };
    let grad = |x: &[f32]| -> Vec<f64> { x.iter().zip(&w).map(|(&x, w)| 2.0 * w * x as f64).collect() };
    let u0 = vec![0.3f32, 0.5, 0.2, 0.6, 0.9, 0.4];
    let x0 = s.from_unit(&u0).unwrap();
    let g_unit = s.unit_gradient(&grad(&x0)).unwrap();
    for k in 0..s.len() {
        if !s.slots()[k].is_differentiable() {
            assert_eq!(g_unit[k], 0.0, "integer slot {k} has no gradient");
            continue;
        }
        let h = 1e-3f32;
        let (mut up, mut dn) = (u0.clone(), u0.clone());
        up[k] += h;
        dn[k] -= h;
        let fd = (loss(&s.from_unit(&up).unwrap()) - loss(&s.from_unit(&dn).unwrap())) / (2.0 * h as f64);
        assert!((fd - g_unit[k]).abs() <= 1e-3 * (1.0 + fd.abs()), "slot {k}: analytic {} vs fd {fd}", g_unit[k]);
    }
}

#[test]
fn projection_clamps_and_rounds() {
    let s = space();
    let mut p = vec![9.0, 7.6, -0.5, 0.5, 3.0, f32::NEG_INFINITY];
    s.project(&mut p).unwrap();
    assert_eq!(p, [4.0, 8.0, 0.0, 0.5, 1.0, -3.0]);
    s.check(&p).unwrap();
    let mut p = vec![0.5, 99.4, 0.1, 0.1, 0.1, 0.0];
    s.project(&mut p).unwrap();
    assert_eq!(p[1], 16.0);
    // Projection is idempotent on valid vectors.
    let d = s.defaults();
    let mut e = d.clone();
    s.project(&mut e).unwrap();
    assert_eq!(d, e);
    let mut nan = s.defaults();
    nan[3] = f32::NAN;
    assert!(matches!(s.project(&mut nan), Err(ParamError::NotFinite { channel: Some(1), .. })));
}

#[test]
fn hostile_json_is_refused_with_the_parameter_named() {
    let s = space();
    let cases: Vec<(Value, &str)> = vec![
        (json!([1, 2]), "must be a JSON object"),
        (json!("gain"), "must be a JSON object"),
        (json!({"gian": 1.0}), "no parameter `gian` (it has: gain, rows, tint, bias)"),
        (json!({"gain": "bright"}), "`gain` must be a number in [0.1, 4], found a string \"bright\""),
        (json!({"gain": null}), "`gain` must be a number"),
        (json!({"gain": [1.0]}), "found an array of 1 element"),
        (json!({"gain": 4.5}), "`gain` = 4.5 is outside its range [0.1, 4]"),
        (json!({"gain": 1e39}), "`gain` is not a finite number"),
        (json!({"rows": 6.5}), "`rows` = 6.5 must be an integer"),
        (json!({"rows": 17}), "`rows` = 17 is outside its range [2, 16]"),
        (json!({"rows": true}), "`rows` must be an integer in [2, 16], found true"),
        (json!({"tint": [0.1, 0.2]}), "`tint` must be [r, g, b]"),
        (json!({"tint": [[0.1], [0.2], [0.3]]}), "`tint` must be a number in [0, 1], found an array"),
        (json!({"tint": [0.1, 1.2, 0.3]}), "`tint` channel 1 (g) = 1.2 is outside its range [0, 1]"),
        (json!({"tint": {"srgb": [0.1, 0.2, -0.3]}}), "`tint` channel 2 (b) = -0.3"),
        (json!({"tint": {"srgb": [0.1, 0.2, 0.3], "x": 1}}), "`tint` must be [r, g, b]"),
        (json!({"tint": {"linear": [0.1, 0.2, 0.3]}}), "`tint` must be [r, g, b]"),
    ];
    for (json, want) in cases {
        let err = s.from_json(&json).expect_err(&json.to_string());
        let msg = err.to_string();
        assert!(msg.contains(want), "{json}: {msg:?} lacks {want:?}");
    }
}

#[test]
fn vectors_of_the_wrong_shape_are_errors_not_panics() {
    let s = space();
    let short = vec![0.5; 5];
    for r in [
        s.check(&short).map(drop),
        s.to_json(&short).map(drop),
        s.to_unit(&short).map(drop),
        s.from_unit(&short).map(drop),
    ] {
        assert!(matches!(r, Err(ParamError::WrongLength { expected: 6, found: 5, .. })), "{r:?}");
    }
    assert!(s.unit_gradient(&[0.0; 7]).is_err());
    let mut bad = s.defaults();
    bad[0] = f32::NAN;
    assert!(s.check(&bad).unwrap_err().to_string().contains("`gain` is not a finite number"));
    bad[0] = 0.01;
    assert!(s.check(&bad).unwrap_err().to_string().contains("outside its range"));
    let mut frac = s.defaults();
    frac[1] = 3.5;
    assert!(matches!(s.check(&frac), Err(ParamError::NotAnInteger { .. })));
}
