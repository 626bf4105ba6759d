//! Symbolic differentiation against finite differences (random programs), forward against
//! reverse mode, the rules at kinks, golden adjoint dumps and the "no work for unused
//! parameters" invariant.

use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use psc_compiler::diff::{adjoint, derivative, derivative_program, ForwardDiff, Wrt};
use psc_compiler::interp::eval_point;
use psc_compiler::ir::{Builder, NodeId, Op, Output, Program};

#[path = "gradients/random_programs.rs"]
mod random_programs;
use random_programs::*;
const ALL_WRT: [Wrt; 5] = [Wrt::U, Wrt::V, Wrt::Param(0), Wrt::Param(1), Wrt::Param(2)];

// ---------------------------------------------------------------------------------------------
// Finite differences

/// Outcome of comparing one derivative with finite differences.
#[derive(Debug, PartialEq)]
enum Probe {
    /// Agreed; `true` when the derivative is clearly non-zero.
    Agreed(bool),
    /// The probe interval crosses a kink, or the function is not resolvable at this step.
    Skipped,
}

/// Central difference of output `k` of `program` along `wrt` at `at`, compared with `exact`.
///
/// The step is h = 1e-3 · max(1, |x|), evaluated in f32 by the interpreter. Samples are skipped
/// (not compared) when any node changes branch anywhere on the five probe points x-h…x+h, when a
/// value is non-finite or above 1e5, when some node is not close to linear over the probe, or
/// when the estimates at h and h/2 differ by more than 5 % (1 + |D|): a derivative the step
/// cannot resolve. Otherwise the tolerance is
///   1e-3 · (1 + |exact|)            (mixed absolute/relative floor)
/// + 2 · |D(h) - D(h/2)|             (estimated truncation + rounding error of the probe)
/// + 16 · eps · max|node| / h        (f32 rounding of the evaluated values, amplified by 1/h).
fn check_against_finite_differences(
    program: &Program,
    k: usize,
    wrt: Wrt,
    at: Point,
    exact: f32,
) -> Result<Probe, String> {
    let x = at.get(wrt);
    let h = 1e-3 * x.abs().max(1.0);
    let offsets = [-h, -h / 2.0, 0.0, h / 2.0, h];
    let points: Vec<Point> = offsets.iter().map(|&dx| at.with(wrt, x + dx)).collect();
    let mut largest = 0.0f32;
    let mut signatures = Vec::new();
    let mut values_at = Vec::new();
    for p in &points {
        let values = node_values(program, p, &[]);
        match max_magnitude(&values) {
            Some(m) => largest = largest.max(m),
            None => return Ok(Probe::Skipped),
        }
        signatures.push(branch_signature(program, &values));
        values_at.push(values);
    }
    if signatures.windows(2).any(|w| w[0] != w[1]) || !exact.is_finite() || !resolved_by_step(&values_at) {
        return Ok(Probe::Skipped);
    }
    let f: Vec<f32> = points.iter().map(|p| p.eval(program, &[])[k]).collect();
    // Divide by the steps actually taken (x ± h rounds in f32).
    let xs: Vec<f32> = points.iter().map(|p| p.get(wrt)).collect();
    let central_h = (f[4] - f[0]) / (xs[4] - xs[0]);
    let central_half = (f[3] - f[1]) / (xs[3] - xs[1]);
    let disagreement = (central_h - central_half).abs();
    if disagreement > 0.05 * (1.0 + central_h.abs()) {
        return Ok(Probe::Skipped);
    }
    let tolerance = 1e-3 * (1.0 + exact.abs()) + 2.0 * disagreement + 16.0 * f32::EPSILON * largest / h;
    if (exact - central_h).abs() <= tolerance {
        Ok(Probe::Agreed(exact != 0.0))
    } else {
        Err(format!(
            "d(o{k})/d{wrt} at {at:?}: symbolic {exact}, central differences {central_h} (h/2: {central_half}), \
             tolerance {tolerance}\n{program}"
        ))
    }
}

#[derive(Debug, Default)]
struct Coverage {
    agreed: usize,
    agreed_non_zero: usize,
    skipped: usize,
}

/// Forward mode against finite differences, then reverse mode against forward mode, for every
/// output and every variable, at each point.
fn check_program(program: &Program, points: &[(Point, [f32; 3])]) -> Result<Coverage, String> {
    program.validate().map_err(|e| e.to_string())?;
    let forward_derivatives: Vec<Program> = ALL_WRT.iter().map(|&w| derivative_program(program, w)).collect();
    let fused = adjoint(program, &[0, 1, 2]);
    fused.program.validate().map_err(|e| e.to_string())?;
    fused.layout.check(program, &fused.program)?;
    let (layout, fused) = (fused.layout, fused.program);
    let outputs = program.outputs.len();
    let mut coverage = Coverage::default();
    for (at, seeds) in points {
        let seeds = &seeds[..outputs];
        let values = at.eval(program, &[]);
        let gradients: Vec<Vec<f32>> = forward_derivatives.iter().map(|d| at.eval(d, &[])).collect();
        for (w, &wrt) in ALL_WRT.iter().enumerate() {
            for (k, &exact) in gradients[w].iter().enumerate() {
                match check_against_finite_differences(program, k, wrt, *at, exact)? {
                    Probe::Agreed(non_zero) => {
                        coverage.agreed += 1;
                        coverage.agreed_non_zero += non_zero as usize;
                    }
                    Probe::Skipped => coverage.skipped += 1,
                }
            }
        }
        // Reverse mode: the fused outputs are the forward values, then the seed-weighted sums of
        // the forward-mode derivatives. Both sides are exact, so they differ only by f32
        // rounding: tolerance 1e-4 relative to the sum of the magnitudes of the terms, plus
        // 1e-5 (about 80 ulps) of the largest tangent or adjoint intermediate, for results that
        // cancel down from much larger intermediates (d/du of u / sin(u) near u = 0).
        let reverse = at.eval(&fused, seeds);
        let same_values =
            values.iter().zip(&reverse).all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        if !same_values {
            return Err(format!("fused forward values {:?} differ from {values:?}", &reverse[..outputs]));
        }
        // A non-finite forward intermediate (even in a branch a select discards) is an error the
        // runtime reports; reverse mode turns it into NaN (0 · inf) where forward mode may not.
        if node_values(program, at, &[]).iter().any(|x| !x.is_finite()) {
            continue;
        }
        // Likewise a derivative intermediate beyond f32's range (pow(0.36, -88.3) ≈ 9e38 for the
        // slope of a finite pow(0.36, -87.3)): the derivative is not representable there, and a
        // discarded branch's zero adjoint times it is NaN.
        if forward_derivatives.iter().any(|d| node_values(d, at, &[]).iter().any(|x| x.is_infinite())) {
            continue;
        }
        let adjoint_scale =
            largest_dependent_value(&fused, &node_values(&fused, at, seeds), |op| matches!(op, Op::Seed(_)));
        for (w, &wrt) in ALL_WRT.iter().enumerate() {
            let terms: Vec<f32> = seeds.iter().zip(&gradients[w]).map(|(s, g)| s * g).collect();
            if terms.iter().any(|t| !t.is_finite()) {
                continue;
            }
            let expected: f32 = terms.iter().sum();
            let scale: f32 = terms.iter().map(|t| t.abs()).sum();
            let d = &forward_derivatives[w];
            let tangent_scale = largest_dependent_value(d, &node_values(d, at, &[]), |op| is_variable(op, wrt));
            let tolerance = 1e-4 * (1.0 + scale) + 1e-5 * (tangent_scale + adjoint_scale);
            let got = reverse[match wrt {
                Wrt::U => layout.d_u(),
                Wrt::V => layout.d_v(),
                Wrt::Param(p) => layout.d_param_of_slot(p).expect("every parameter is differentiated"),
            }];
            let agrees = (got - expected).abs() <= tolerance; // false for NaN, on purpose
            if !agrees {
                return Err(format!(
                    "reverse d/d{wrt} = {got}, forward gives {expected} (tolerance {tolerance}) at {at:?}, \
                     seeds {seeds:?}\n{program}"
                ));
            }
        }
    }
    Ok(coverage)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn derivatives_match_finite_differences_and_reverse_matches_forward(
        program in program(),
        points in prop::collection::vec(point(), 4),
    ) {
        check_program(&program, &points).map_err(TestCaseError::fail)?;
    }

    /// Second derivatives: differentiating a derivative program is checked the same way.
    #[test]
    fn second_derivatives_match_finite_differences(
        program in program(),
        points in prop::collection::vec(point(), 2),
    ) {
        for wrt in [Wrt::U, Wrt::V] {
            let first = derivative_program(&program, wrt);
            check_program(&first, &points).map_err(TestCaseError::fail)?;
        }
    }

    /// Mixed partials are symmetric: d/du d/dv f = d/dv d/du f (both symbolic, so tight).
    #[test]
    fn mixed_second_derivatives_commute(program in program(), (at, _) in point()) {
        let mut b = Builder::from_program(&program);
        let (mut ddu, mut ddv) = (ForwardDiff::new(Wrt::U), ForwardDiff::new(Wrt::V));
        let mut outputs = Vec::new();
        for o in &program.outputs {
            let (du, dv) = (ddu.derivative(&mut b, o.node), ddv.derivative(&mut b, o.node));
            let (dvdu, dudv) = (ddv.derivative(&mut b, du), ddu.derivative(&mut b, dv));
            outputs.push(Output { name: "dvdu".into(), node: dvdu });
            outputs.push(Output { name: "dudv".into(), node: dudv });
        }
        let mut mixed = b.finish(outputs);
        mixed.eliminate_dead_code();
        mixed.validate().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let values = at.eval(&mixed, &[]);
        for pair in values.chunks(2) {
            let (a, c) = (pair[0], pair[1]);
            if a.is_finite() && c.is_finite() {
                prop_assert!((a - c).abs() <= 1e-3 * (1.0 + a.abs().max(c.abs())), "{a} vs {c}\n{mixed}");
            }
        }
    }
}

/// The property tests above skip samples near kinks; this makes sure they still compare a
/// healthy share of derivatives and that the compared programs use every op kind.
#[test]
fn random_programs_are_mostly_comparable_and_use_every_op() {
    let mut runner = TestRunner::deterministic();
    let cases = (program(), prop::collection::vec(point(), 4));
    let (mut agreed, mut agreed_non_zero, mut skipped) = (0, 0, 0);
    let mut kinds_seen = std::collections::BTreeSet::new();
    for _ in 0..200 {
        let (program, points) = cases.new_tree(&mut runner).unwrap().current();
        let coverage = check_program(&program, &points).unwrap();
        agreed += coverage.agreed;
        agreed_non_zero += coverage.agreed_non_zero;
        skipped += coverage.skipped;
        if coverage.agreed > 0 {
            kinds_seen.extend(program.nodes.iter().filter(|op| !op.is_leaf()).map(|op| op.mnemonic()));
        }
    }
    let share = agreed as f64 / (agreed + skipped) as f64;
    eprintln!("compared {agreed} ({agreed_non_zero} non-zero), skipped {skipped}");
    assert!(share > 0.5, "only {agreed} of {} derivatives were comparable", agreed + skipped);
    assert!(agreed_non_zero > 1000, "only {agreed_non_zero} of {agreed} compared derivatives are non-zero");
    for kind in OP_KINDS.iter() {
        assert!(kinds_seen.contains(kind), "no compared program used `{kind}`");
    }
}

/// The cheap-gradient principle: the fused program costs a bounded multiple of the forward one
/// (the worst single rule, atan2, adds about ten ops), never an expression swell.
#[test]
fn adjoint_cost_is_a_bounded_multiple_of_the_forward_cost() {
    let mut runner = TestRunner::deterministic();
    let (mut forward_total, mut adjoint_total, mut forward_mode_total) = (0, 0, 0);
    for _ in 0..200 {
        let program = program().new_tree(&mut runner).unwrap().current();
        let fused = adjoint(&program, &[0, 1, 2]).program;
        let (forward_ops, fused_ops) = (program.op_count(), fused.op_count());
        assert!(fused_ops <= 12 * forward_ops + 4, "{forward_ops} forward ops became {fused_ops}\n{program}\n{fused}");
        forward_total += forward_ops;
        adjoint_total += fused_ops;
        forward_mode_total += ALL_WRT.iter().map(|&w| derivative_program(&program, w).op_count()).sum::<usize>();
    }
    eprintln!(
        "200 random programs: {forward_total} forward ops, {adjoint_total} in the fused adjoints, \
         {forward_mode_total} in five forward-mode derivative programs (each including the forward ops)"
    );
}

// ---------------------------------------------------------------------------------------------
// Rules at kinks, by hand

/// A one-output program `f(u, v, p0)`.
fn single(f: impl FnOnce(&mut Builder, NodeId, NodeId, NodeId) -> NodeId) -> Program {
    let mut b = Builder::new();
    let (u, v, p0) = (b.u(), b.v(), b.param(0));
    let node = f(&mut b, u, v, p0);
    b.finish(vec![Output { name: "f".into(), node }])
}

/// `[df/du, df/dv, df/dp0]` by forward mode, after checking that reverse mode agrees.
fn gradient(program: &Program, u: f32, v: f32, p0: f32) -> [f32; 3] {
    let forward =
        [Wrt::U, Wrt::V, Wrt::Param(0)].map(|w| eval_point(&derivative_program(program, w), &[p0], u, v, &[])[0]);
    let fused = adjoint(program, &[0]);
    fused.program.validate().unwrap();
    let l = &fused.layout;
    let all = eval_point(&fused.program, &[p0], u, v, &[1.0]);
    let reverse = [all[l.d_u()], all[l.d_v()], all[l.d_param(0)]];
    for (f, r) in forward.iter().zip(&reverse) {
        assert!((f - r).abs() <= 1e-6 * (1.0 + f.abs()), "forward {forward:?}, reverse {reverse:?}");
    }
    forward
}

fn assert_gradient(program: &Program, (u, v, p0): (f32, f32, f32), expected: [f32; 3]) {
    let got = gradient(program, u, v, p0);
    for (g, e) in got.iter().zip(expected) {
        assert!(
            (g - e).abs() <= 1e-5 * (1.0 + e.abs()),
            "at {:?}: got {got:?}, expected {expected:?}\n{program}",
            (u, v, p0)
        );
    }
}

#[test]
fn min_and_max_route_to_the_active_branch() {
    let min = single(|b, u, v, _| b.min(u, v));
    assert_gradient(&min, (0.2, 0.7, 0.0), [1.0, 0.0, 0.0]);
    assert_gradient(&min, (0.7, 0.2, 0.0), [0.0, 1.0, 0.0]);
    let max = single(|b, u, v, _| b.max(u, v));
    assert_gradient(&max, (0.2, 0.7, 0.0), [0.0, 1.0, 0.0]);
    assert_gradient(&max, (0.7, 0.2, 0.0), [1.0, 0.0, 0.0]);
    let select = single(|b, u, v, _| {
        let (c, s, vv) = (b.lt(u, v), b.sin(u), b.mul(v, v));
        b.select(c, s, vv)
    });
    assert_gradient(&select, (0.2, 0.7, 0.0), [0.2f32.cos(), 0.0, 0.0]);
    assert_gradient(&select, (0.7, 0.2, 0.0), [0.0, 0.4, 0.0]);
}

#[test]
fn piecewise_constant_ops_have_zero_derivative_and_emit_nothing() {
    let programs = [
        single(|b, u, _, _| b.scale(4.0, u)), // control: not piecewise constant
        single(|b, u, _, _| {
            let x = b.scale(4.0, u);
            b.floor(x)
        }),
        single(|b, u, v, _| {
            let (x, y) = (b.scale(10.0, u), b.scale(10.0, v));
            b.hash(x, y)
        }),
        single(|b, u, v, _| b.lt(u, v)),
        single(|b, u, v, _| b.le(u, v)),
        single(|b, u, v, _| b.eq(u, v)),
    ];
    assert_gradient(&programs[0], (0.3, 0.6, 0.0), [4.0, 0.0, 0.0]);
    for program in &programs[1..] {
        assert_gradient(program, (0.3, 0.6, 0.0), [0.0; 3]);
        for wrt in [Wrt::U, Wrt::V] {
            let d = derivative_program(program, wrt);
            assert_eq!(d.op_count(), 0, "derivative of a piecewise-constant op emitted code:\n{d}");
        }
    }
    let fract = single(|b, u, _, _| {
        let x = b.scale(3.0, u);
        b.fract(x)
    });
    assert_gradient(&fract, (0.5, 0.0, 0.0), [3.0, 0.0, 0.0]);
    assert_gradient(&fract, (0.9, 0.0, 0.0), [3.0, 0.0, 0.0]);
}

#[test]
fn sqrt_and_log_are_guarded_at_the_edge_of_their_domain() {
    let sqrt = single(|b, u, _, _| b.sqrt(u));
    assert_gradient(&sqrt, (0.0, 0.0, 0.0), [0.0; 3]); // 0, not inf or NaN
    assert_gradient(&sqrt, (0.25, 0.0, 0.0), [1.0, 0.0, 0.0]);
    let sqrt_shifted = single(|b, u, _, _| {
        let half = b.constant(0.5);
        let x = b.sub(u, half);
        b.sqrt(x)
    });
    assert_gradient(&sqrt_shifted, (0.2, 0.0, 0.0), [0.0; 3]);
    let log = single(|b, u, _, _| b.log(u));
    assert_gradient(&log, (0.0, 0.0, 0.0), [0.0; 3]);
    assert_gradient(&log, (0.5, 0.0, 0.0), [2.0, 0.0, 0.0]);
}

#[test]
fn pow_has_zero_derivative_where_the_base_is_not_positive() {
    let pow = single(|b, u, _, p0| {
        let half = b.constant(0.5);
        let base = b.sub(u, half);
        b.pow(base, p0)
    });
    assert_gradient(&pow, (0.2, 0.0, 2.0), [0.0; 3]); // base < 0
    assert_gradient(&pow, (0.5, 0.0, 2.0), [0.0; 3]); // base = 0
    assert_gradient(&pow, (0.5, 0.0, 0.5), [0.0; 3]); // base = 0, exponent < 1: no inf
    assert_gradient(&pow, (1.5, 0.0, 2.0), [2.0, 0.0, 0.0]); // 2·1, 1·ln 1
    assert_gradient(&pow, (2.5, 0.0, 3.0), [12.0, 0.0, 8.0 * 2f32.ln()]);
}

#[test]
fn abs_atan2_and_div_follow_their_stated_rules() {
    let abs = single(|b, u, _, _| {
        let half = b.constant(0.5);
        let x = b.sub(u, half);
        b.abs(x)
    });
    assert_gradient(&abs, (0.2, 0.0, 0.0), [-1.0, 0.0, 0.0]);
    assert_gradient(&abs, (0.7, 0.0, 0.0), [1.0, 0.0, 0.0]);
    assert_gradient(&abs, (0.5, 0.0, 0.0), [1.0, 0.0, 0.0]); // the kink takes the `a >= 0` side
    let atan2 = single(|b, u, v, _| {
        let half = b.constant(0.5);
        let (x, y) = (b.sub(u, half), b.sub(v, half));
        b.atan2(y, x)
    });
    assert_gradient(&atan2, (0.5, 0.5, 0.0), [0.0; 3]); // origin: 0, not NaN
    assert_gradient(&atan2, (1.5, 0.5, 0.0), [0.0, 1.0, 0.0]);
    assert_gradient(&atan2, (0.5, 2.5, 0.0), [-0.5, 0.0, 0.0]);
    let div = single(|b, u, v, _| b.div(u, v));
    assert_gradient(&div, (0.3, 0.5, 0.0), [2.0, -1.2, 0.0]);
}

// ---------------------------------------------------------------------------------------------
// Adjoint invariants and golden dumps

#[test]
fn parameters_the_outputs_do_not_depend_on_get_no_adjoint_code() {
    // p1 is read only through floor and hash (zero derivative); p2 is not read at all.
    let mut b = Builder::new();
    let (u, v, p0, p1) = (b.u(), b.v(), b.param(0), b.param(1));
    b.reserve_params(3);
    let up = b.mul(u, p0);
    let wave = b.sin(up);
    let step = b.floor(p1);
    let stepped = b.mul(step, v);
    let noise = b.hash(p1, u);
    let sum = b.add(wave, stepped);
    let f = b.add(sum, noise);
    let program = b.finish(vec![Output { name: "f".into(), node: f }]);

    let only_p0 = adjoint(&program, &[0]);
    let all = adjoint(&program, &[0, 1, 2]);
    for fused in [&only_p0, &all] {
        fused.program.validate().unwrap();
    }
    let (only_p0, layout, all) = (only_p0.program, all.layout, all.program);
    for slot in [1, 2] {
        let node = all.outputs[layout.d_param_of_slot(slot).unwrap()].node;
        assert_eq!(all.op(node).as_const(), Some(0.0), "d/d param{slot} should be the constant 0:\n{all}");
    }
    assert_eq!(all.op_count(), only_p0.op_count(), "asking for p1, p2 added work:\n{all}");
    assert_eq!(derivative_program(&program, Wrt::Param(1)).op_count(), 0);
}

#[test]
fn adjoint_of_sin_u_times_p0() {
    let program = single(|b, u, _, p0| {
        let x = b.mul(u, p0);
        b.sin(x)
    });
    insta::assert_snapshot!(adjoint(&program, &[0]).program.to_string());
}

#[test]
fn adjoint_of_min_u_v_times_sqrt_p0() {
    let program = single(|b, u, v, p0| {
        let (m, s) = (b.min(u, v), b.sqrt(p0));
        b.mul(m, s)
    });
    insta::assert_snapshot!(adjoint(&program, &[0]).program.to_string());
}

#[test]
fn adjoint_of_two_outputs_sharing_a_subexpression() {
    let mut b = Builder::new();
    let (u, p0, p1) = (b.u(), b.param(0), b.param(1));
    let up = b.mul(u, p0);
    let e = b.exp(up);
    let scaled = b.mul(e, p1);
    let program = b.finish(vec![Output { name: "a".into(), node: up }, Output { name: "b".into(), node: scaled }]);
    insta::assert_snapshot!(adjoint(&program, &[0, 1]).program.to_string());
}

#[test]
fn forward_derivatives_of_a_height_for_its_normal() {
    // The lowering's normal from height: d/du and d/dv of one height node, sharing work.
    let mut b = Builder::new();
    let (u, v, p0) = (b.u(), b.v(), b.param(0));
    let up = b.mul(u, p0);
    let (s, c) = (b.sin(up), b.cos(v));
    let height = b.mul(s, c);
    let du = derivative(&mut b, height, Wrt::U);
    let dv = derivative(&mut b, height, Wrt::V);
    let program = b.finish(vec![
        Output { name: "h".into(), node: height },
        Output { name: "dh_du".into(), node: du },
        Output { name: "dh_dv".into(), node: dv },
    ]);
    insta::assert_snapshot!(program.to_string());
}
