//! The JIT against its oracles on random DAGs:
//! - all ops: bit-exact with the scalar mirror (`psc_jit::mirror_eval_point`), which is the
//!   same op definitions instantiated on `f32` — this checks the vector lowering of every
//!   primitive, the loop structure and the padded tail, for every n;
//! - no transcendentals: bit-exact with the reference interpreter (NaN payloads and the sign
//!   of a zero from `sqrt(max(-0, 0))` aside, see `common::same`);
//! - transcendentals on well-conditioned programs: within 1e-4 absolute of the interpreter
//!   (every node there stays in [-1, 1] with derivatives ≲ 1, so this is ~1000x the per-op polynomial error).

mod common;

use common::{random_program, run_jit, same, same_bits, OpSet, Rng};
use proptest::prelude::*;
use psc_compiler::interp;
use psc_compiler::ir::{Builder, NodeId, Output, Program};
use psc_jit::{compile_with, mirror_eval_point, CompiledKernel, OptLevel, Options};

fn points(
    seed: u64,
    n: usize,
    num_params: usize,
    num_seeds: usize,
    nasty: bool,
) -> (Vec<f32>, Vec<f32>, Vec<f32>, Vec<Vec<f32>>) {
    let mut r = Rng::new(seed);
    let draw = |r: &mut Rng| if nasty { r.nasty() } else { r.uniform(-1.0, 1.0) };
    let u = (0..n).map(|_| draw(&mut r)).collect();
    let v = (0..n).map(|_| draw(&mut r)).collect();
    let p = (0..num_params).map(|_| draw(&mut r)).collect();
    let s = (0..num_seeds).map(|_| (0..n).map(|_| draw(&mut r)).collect()).collect();
    (u, v, p, s)
}

fn options(k: u8) -> Options {
    let opt_level = if k & 1 == 0 { OptLevel::Speed } else { OptLevel::None };
    let schedule = [None, Some(2), Some(12)][(k as usize >> 3) % 3];
    let single_pass_above = if k & 32 == 0 { Options::default().single_pass_above } else { 0 };
    Options { opt_level, groups: [1, 2, 4][(k as usize >> 1) % 3], schedule, single_pass_above }
}

fn spec() -> impl Strategy<Value = Vec<(u8, u32, u32, u32)>> {
    prop::collection::vec((any::<u8>(), any::<u32>(), any::<u32>(), any::<u32>()), 1..40)
}

fn consts() -> impl Strategy<Value = Vec<f32>> {
    prop::collection::vec(
        prop::sample::select(vec![0.5f32, 2.0, -1.5, 3.7, 1e3, -1e-3, 0.0, 7.0, f32::NAN, f32::INFINITY, 1e20]),
        0..4,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn jit_matches_mirror_bit_exactly(spec in spec(), consts in consts(), seeds in 0u32..3,
                                      outs in prop::collection::vec(any::<u32>(), 0..4),
                                      n in prop::sample::select(vec![0usize, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 31, 33, 64, 67]),
                                      pts in any::<u64>(), opt in any::<u8>()) {
        let prog = random_program(&spec, &consts, seeds, &outs, OpSet::All);
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, s) = points(pts, n, prog.num_params, prog.num_seeds, true);
        let got = run_jit(&k, &p, &u, &v, &s);
        for i in 0..n {
            let seeds_i: Vec<f32> = s.iter().map(|c| c[i]).collect();
            let want = mirror_eval_point(&prog, k.uses_fma(), &p, u[i], v[i], &seeds_i);
            for (o, w) in want.iter().enumerate() {
                prop_assert!(same_bits(got[o][i], *w),
                    "point {i} of {n} output {o}: jit {:e} ({:#x}) mirror {:e} ({:#x}) at u={:e} v={:e}",
                    got[o][i], got[o][i].to_bits(), w, w.to_bits(), u[i], v[i]);
            }
        }
    }

    #[test]
    fn run_point_matches_the_mirror(spec in spec(), consts in consts(), outs in prop::collection::vec(any::<u32>(), 0..4),
                                    pts in any::<u64>(), opt in any::<u8>()) {
        let prog = random_program(&spec, &consts, 0, &outs, OpSet::All);
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, _) = points(pts, 9, prog.num_params, 0, true);
        let mut out = vec![0.0f32; k.num_outputs()];
        for i in 0..u.len() {
            k.run_point(&p, u[i], v[i], &mut out).unwrap();
            let want = mirror_eval_point(&prog, k.uses_fma(), &p, u[i], v[i], &[]);
            for (o, w) in want.iter().enumerate() {
                prop_assert!(same_bits(out[o], *w), "point {i} output {o}: run_point {:e} mirror {:e}", out[o], w);
            }
        }
        prop_assert!(k.run_point(&p, 0.5, 0.5, &mut vec![0.0; k.num_outputs() + 1]).is_err());
    }

    /// A packet of points, each in a lane of its own (the padding lanes repeat the last point):
    /// every point's values are the mirror's, whatever the points beside it.
    #[test]
    fn run_points_matches_the_mirror(spec in spec(), consts in consts(), outs in prop::collection::vec(any::<u32>(), 0..4),
                                     n in 1usize..=CompiledKernel::MAX_POINTS, pts in any::<u64>(), opt in any::<u8>()) {
        let prog = random_program(&spec, &consts, 0, &outs, OpSet::All);
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, _) = points(pts, n, prog.num_params, 0, true);
        let n_out = k.num_outputs();
        let mut out = vec![0.0f32; n * n_out];
        k.run_points(&p, &u, &v, &mut out).unwrap();
        for i in 0..n {
            let want = mirror_eval_point(&prog, k.uses_fma(), &p, u[i], v[i], &[]);
            for (o, w) in want.iter().enumerate() {
                prop_assert!(same_bits(out[i * n_out + o], *w),
                    "point {i} of {n} output {o}: run_points {:e} mirror {:e}", out[i * n_out + o], w);
            }
        }
        prop_assert!(k.run_points(&p, &u, &v, &mut vec![0.0; n * n_out + 1]).is_err());
        let many = vec![0.5f32; CompiledKernel::MAX_POINTS + 1];
        prop_assert!(k.run_points(&p, &many, &many, &mut vec![0.0; many.len() * n_out]).is_err());
        prop_assert!(k.run_points(&p, &[], &[], &mut []).is_err());
    }

    #[test]
    fn jit_matches_interpreter_without_transcendentals(spec in spec(), consts in consts(), seeds in 0u32..3,
                                      outs in prop::collection::vec(any::<u32>(), 0..4),
                                      n in 0usize..70, pts in any::<u64>(), opt in any::<u8>()) {
        let prog = random_program(&spec, &consts, seeds, &outs, OpSet::Exact);
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, s) = points(pts, n, prog.num_params, prog.num_seeds, true);
        let got = run_jit(&k, &p, &u, &v, &s);
        let seed_refs: Vec<&[f32]> = s.iter().map(|c| &c[..]).collect();
        let want = interp::eval(&prog, &p, &interp::Batch { u: &u, v: &v, seeds: &seed_refs });
        for (o, col) in want.iter().enumerate() {
            for i in 0..n {
                prop_assert!(same(got[o][i], col[i]), "output {o} point {i}: jit {:e} interp {:e}", got[o][i], col[i]);
            }
        }
    }

    #[test]
    fn jit_is_close_to_interpreter_with_transcendentals(choices in prop::collection::vec((0u8..12, any::<u32>(), any::<u32>()), 1..32),
                                      n in 0usize..40, pts in any::<u64>(), opt in any::<u8>()) {
        let prog = smooth_program(&choices);
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, _) = points(pts, n, prog.num_params, 0, false);
        let got = run_jit(&k, &p, &u, &v, &[]);
        let want = interp::eval(&prog, &p, &interp::Batch { u: &u, v: &v, seeds: &[] });
        for (o, col) in want.iter().enumerate() {
            for i in 0..n {
                prop_assert!((got[o][i] - col[i]).abs() <= 1e-4,
                    "output {o} point {i}: jit {} interp {} (diff {:e})", got[o][i], col[i], (got[o][i] - col[i]).abs());
            }
        }
    }
}

/// A random program every node of which stays in [-1, 1] for inputs in [-1, 1], built from
/// compositions with derivatives bounded by about 1 (no division by values near zero, logs
/// and pows of arguments bounded away from zero, atan2 away from the origin), so
/// approximation errors cannot be amplified much.
fn smooth_program(choices: &[(u8, u32, u32)]) -> Program {
    let mut b = Builder::new();
    let mut pool: Vec<NodeId> = vec![b.u(), b.v(), b.param(0), b.param(1)];
    for &(kind, x, y) in choices {
        let a = pool[x as usize % pool.len()];
        let c = pool[y as usize % pool.len()];
        let two = b.constant(2.0);
        let half = b.constant(0.5);
        let node = match kind {
            0 => b.sin(a),
            1 => b.cos(a),
            2 => {
                let e = b.exp(a);
                b.scale(0.36, e)
            }
            3 => {
                let aa = b.mul(a, a);
                let s = b.add(two, aa);
                let l = b.log(s);
                b.scale(0.9, l)
            }
            4 => {
                let x = b.add(two, c);
                let t = b.atan2(a, x);
                b.scale(0.9, t)
            }
            5 => {
                let base = b.add(two, a);
                let e = b.mul(half, c);
                let p = b.pow(base, e);
                b.mul(half, p)
            }
            6 => b.mul(a, c),
            7 => {
                let s = b.add(a, c);
                b.mul(half, s)
            }
            8 => {
                let s = b.sub(a, c);
                b.mul(half, s)
            }
            9 => b.min(a, c),
            10 => b.max(a, c),
            _ => {
                let t = b.add(two, a);
                let s = b.sqrt(t);
                b.mul(half, s)
            }
        };
        pool.push(node);
    }
    let outputs =
        pool.iter().rev().take(3).enumerate().map(|(k, &node)| Output { name: format!("o{k}"), node }).collect();
    b.finish(outputs)
}

/// `sin x` and `cos x` of one `x` share their reduction and polynomials in generated code
/// (in either order, several times, and beside a `sin` of another value); the scalar mirror
/// computes each separately, so this checks the sharing changes no bit.
#[test]
fn shared_sin_cos_match_the_mirror() {
    let mut b = Builder::new();
    let (u, v) = (b.u(), b.v());
    let p = b.param(0);
    let x = b.mul(u, p);
    let y = b.add(x, v);
    let c1 = b.cos(x);
    let s1 = b.sin(x);
    let s2 = b.sin(y);
    let c2 = b.cos(y);
    let t = b.mul(s1, c2);
    let w = b.add(c1, s2);
    let outputs = [("c1", c1), ("s1", s1), ("s2", s2), ("c2", c2), ("t", t), ("w", w)];
    let prog = b.finish(outputs.iter().map(|&(name, node)| Output { name: name.into(), node }).collect());
    for opt in 0..12u8 {
        let k = compile_with(&prog, &options(opt)).unwrap();
        let (u, v, p, _) = points(7 + u64::from(opt), 37, prog.num_params, 0, true);
        let got = run_jit(&k, &p, &u, &v, &[]);
        for i in 0..u.len() {
            let want = mirror_eval_point(&prog, k.uses_fma(), &p, u[i], v[i], &[]);
            for (o, w) in want.iter().enumerate() {
                assert!(
                    same_bits(got[o][i], *w),
                    "options {opt}, point {i}, output {}: {} vs {}",
                    outputs[o].0,
                    got[o][i],
                    w
                );
            }
        }
    }
}

/// More outputs than `run_point`'s and `run_points`' stack buffers hold: they fall back to the
/// general call.
#[test]
fn run_point_with_many_outputs_matches_run() {
    let mut b = Builder::new();
    let (u, v) = (b.u(), b.v());
    let mut outputs = Vec::new();
    let mut x = b.add(u, v);
    for k in 0..20 {
        let p = b.param(k % 3);
        x = b.mul(x, p);
        x = b.add(x, u);
        outputs.push(Output { name: format!("o{k}"), node: x });
    }
    let prog = b.finish(outputs);
    let k = psc_jit::compile(&prog).unwrap();
    let p = [0.5, -1.25, 0.75];
    let mut point = vec![0.0f32; k.num_outputs()];
    k.run_point(&p, 0.3, 0.7, &mut point).unwrap();
    let batch = run_jit(&k, &p, &[0.3], &[0.7], &[]);
    for (o, col) in batch.iter().enumerate() {
        assert!(same_bits(point[o], col[0]), "output {o}: {} vs {}", point[o], col[0]);
    }
    let (us, vs) = ([0.3, -2.0, 0.9, 7.5, 0.1], [0.7, 0.25, -0.4, 3.0, 0.6]);
    let mut packet = vec![0.0f32; us.len() * k.num_outputs()];
    k.run_points(&p, &us, &vs, &mut packet).unwrap();
    let batch = run_jit(&k, &p, &us, &vs, &[]);
    for (o, col) in batch.iter().enumerate() {
        for (i, &want) in col.iter().enumerate() {
            let got = packet[i * k.num_outputs() + o];
            assert!(same_bits(got, want), "point {i} output {o}: {got} vs {want}");
        }
    }
}

/// A program past `SINGLE_PASS_ABOVE` ops, compiled with the default options (so with the
/// single-pass register allocator), is bit-exact with the mirror on every output, and its
/// outputs are those of the same program under the backtracking allocator.
#[test]
fn programs_past_the_single_pass_threshold_match_the_mirror() {
    let mut r = Rng::new(11);
    // Each op's first operand is the op before it (the pool holds u, v, three parameters,
    // one seed and three constants, then the ops), so every op is live in the kernel, and
    // the others reach back anywhere, so thousands of values are live at once.
    let leaves = 9;
    let spec: Vec<(u8, u32, u32, u32)> = (0..psc_jit::SINGLE_PASS_ABOVE as u32 + 500)
        .map(|i| (r.next_u64() as u8, leaves + i - 1, r.next_u64() as u32, r.next_u64() as u32))
        .collect();
    let outs: Vec<u32> = (0..8).map(|_| r.next_u64() as u32).collect();
    let prog = random_program(&spec, &[0.5, -1.5, 3.7], 1, &outs, OpSet::All);
    assert!(prog.nodes.len() > psc_jit::SINGLE_PASS_ABOVE, "{} ops", prog.nodes.len());
    let single_pass = compile_with(&prog, &Options::default()).unwrap();
    let backtracking = compile_with(&prog, &Options { single_pass_above: usize::MAX, ..Options::default() }).unwrap();
    let (u, v, p, s) = points(3, 37, prog.num_params, prog.num_seeds, true);
    let got = run_jit(&single_pass, &p, &u, &v, &s);
    let other = run_jit(&backtracking, &p, &u, &v, &s);
    for i in 0..u.len() {
        let seeds_i: Vec<f32> = s.iter().map(|c| c[i]).collect();
        let want = mirror_eval_point(&prog, single_pass.uses_fma(), &p, u[i], v[i], &seeds_i);
        for (o, w) in want.iter().enumerate() {
            assert!(same_bits(got[o][i], *w), "point {i} output {o}: jit {:e} mirror {:e}", got[o][i], w);
            assert!(same_bits(got[o][i], other[o][i]), "point {i} output {o}: the allocators disagree");
        }
    }
}
