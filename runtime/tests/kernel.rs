//! The runtime kernel layer: thread-count independence, grid convention, adjoint plumbing
//! and adjoint-vs-finite-difference agreement.

use psc_compiler::diff::reverse;
use psc_compiler::ir::{Builder, NodeId, Output, Program};
use psc_compiler::{Adjoint, AdjointLayout};
use psc_runtime::kernel::{grid_uv, Gradients, Kernel, KernelError, CHUNK};

fn pool(k: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(k).build().expect("thread pool")
}

/// A smooth synthetic material-like program: 3 outputs, 4 parameters, every op smooth.
fn smooth_forward() -> Program {
    let mut b = Builder::new();
    let u = b.u();
    let v = b.v();
    let p: Vec<NodeId> = (0..4).map(|i| b.param(i)).collect();
    let fu = b.mul(p[0], u);
    let s = b.sin(fu);
    let vv = b.mul(v, v);
    let m = b.mul(p[1], vv);
    let r = b.add(s, m);
    let e = b.exp(r);
    let q = b.mul(p[2], v);
    let c = b.cos(q);
    let w = b.mul(c, e);
    let two = b.constant(2.0);
    let base = b.add(two, s);
    let pw = b.pow(base, p[3]);
    let at = b.atan2(c, base);
    let lg = {
        let t = b.add(two, vv);
        b.log(t)
    };
    let o2 = b.mul(at, lg);
    b.finish(vec![
        Output { name: "albedo.r".into(), node: w },
        Output { name: "height".into(), node: pw },
        Output { name: "rough".into(), node: o2 },
    ])
}

fn params() -> Vec<f32> {
    vec![3.1, -0.7, 2.3, 1.6]
}

fn points(n: usize) -> (Vec<f32>, Vec<f32>) {
    let u = (0..n).map(|k| ((k as f32) * 0.618_034).fract()).collect();
    let v = (0..n).map(|k| ((k as f32) * 0.414_213_5 + 0.1).fract()).collect();
    (u, v)
}

fn seeds(n: usize, outputs: usize) -> Vec<Vec<f32>> {
    (0..outputs).map(|o| (0..n).map(|k| (((k * 7 + o * 13) % 17) as f32 - 8.0) / 8.0).collect()).collect()
}

fn bits(cols: &[Vec<f32>]) -> Vec<Vec<u32>> {
    cols.iter().map(|c| c.iter().map(|x| x.to_bits()).collect()).collect()
}

#[test]
fn eval_and_adjoint_are_bit_identical_for_1_and_n_threads() {
    let fwd = smooth_forward();
    let adj = reverse::adjoint(&fwd, &[0, 1, 2, 3]);
    let k = Kernel::with_adjoint(fwd, adj).unwrap();
    let n = 5 * CHUNK + 37;
    let (u, v) = points(n);
    let s = seeds(n, 3);
    let s_refs: Vec<&[f32]> = s.iter().map(|c| &c[..]).collect();
    let p = params();
    let one = pool(1).install(|| (k.eval(&p, &u, &v).unwrap(), k.adjoint(&p, &u, &v, &s_refs).unwrap()));
    for threads in [2, 3, 8] {
        let many = pool(threads).install(|| (k.eval(&p, &u, &v).unwrap(), k.adjoint(&p, &u, &v, &s_refs).unwrap()));
        assert_eq!(bits(&one.0), bits(&many.0), "eval differs with {threads} threads");
        assert_eq!(bits(&one.1.values), bits(&many.1.values));
        assert_eq!(bits(&[one.1.d_u.clone(), one.1.d_v.clone()]), bits(&[many.1.d_u.clone(), many.1.d_v.clone()]));
        let a: Vec<u64> = one.1.d_params.iter().map(|x| x.to_bits()).collect();
        let b: Vec<u64> = many.1.d_params.iter().map(|x| x.to_bits()).collect();
        assert_eq!(a, b, "summed d_params differ with {threads} threads");
    }
    // The adjoint's forward values are the forward kernel's values.
    assert_eq!(bits(&one.0), bits(&one.1.values));
}

/// Reused buffers of any previous shape give the same bits as fresh ones.
#[test]
fn eval_into_and_adjoint_into_reuse_buffers_of_any_shape() {
    let fwd = smooth_forward();
    let adj = reverse::adjoint(&fwd, &[0, 1, 2, 3]);
    let k = Kernel::with_adjoint(fwd, adj).unwrap();
    let p = params();
    let (mut values, mut gradients) = (vec![vec![f32::NAN; 3]; 7], Gradients::default());
    for n in [2 * CHUNK + 5, 17, 0, 3 * CHUNK] {
        let (u, v) = points(n);
        let s = seeds(n, 3);
        let s_refs: Vec<&[f32]> = s.iter().map(|c| &c[..]).collect();
        k.eval_into(&p, &u, &v, &mut values).unwrap();
        assert_eq!(bits(&values), bits(&k.eval(&p, &u, &v).unwrap()), "eval_into at n = {n}");
        k.adjoint_into(&p, &u, &v, &s_refs, &mut gradients).unwrap();
        let fresh = k.adjoint(&p, &u, &v, &s_refs).unwrap();
        assert_eq!(bits(&gradients.values), bits(&fresh.values), "adjoint_into at n = {n}");
        assert_eq!(bits(&[gradients.d_u.clone(), gradients.d_v.clone()]), bits(&[fresh.d_u, fresh.d_v]));
        assert_eq!(gradients.d_params, fresh.d_params);
    }
}

#[test]
fn adjoint_matches_central_differences_of_the_jit_forward() {
    let fwd = smooth_forward();
    let adj = reverse::adjoint(&fwd, &[0, 1, 2, 3]);
    let k = Kernel::with_adjoint(fwd, adj).unwrap();
    let n = 3000;
    let (u, v) = points(n);
    let s = seeds(n, 3);
    let s_refs: Vec<&[f32]> = s.iter().map(|c| &c[..]).collect();
    let p = params();
    let g = k.adjoint(&p, &u, &v, &s_refs).unwrap();
    // The implied loss: L(p) = sum_k sum_o seed[o][k] * f_o(p; u_k, v_k), in f64.
    let loss = |p: &[f32], u: &[f32], v: &[f32]| -> f64 {
        let out = k.eval(p, u, v).unwrap();
        out.iter()
            .zip(&s)
            .map(|(col, sc)| col.iter().zip(sc).map(|(&f, &w)| f64::from(f) * f64::from(w)).sum::<f64>())
            .sum()
    };
    for slot in 0..4 {
        let h = 1e-2f32;
        let (mut hi, mut lo) = (p.clone(), p.clone());
        hi[slot] += h;
        lo[slot] -= h;
        let fd = (loss(&hi, &u, &v) - loss(&lo, &u, &v)) / f64::from(hi[slot] - lo[slot]);
        let ad = g.d_params[slot];
        let scale = fd.abs().max(ad.abs()).max(1.0);
        assert!((fd - ad).abs() <= 2e-3 * scale, "d_param{slot}: adjoint {ad} vs central difference {fd}");
    }
    // Per-point d_u, d_v at a few points.
    for &i in &[0usize, 17, 1234, 2999] {
        let sp: Vec<f32> = s.iter().map(|c| c[i]).collect();
        let point_loss = |uu: f32, vv: f32| -> f64 {
            let out = k.eval(&p, &[uu], &[vv]).unwrap();
            out.iter().zip(&sp).map(|(c, &w)| f64::from(c[0]) * f64::from(w)).sum()
        };
        let h = 1e-3f32;
        let du = (point_loss(u[i] + h, v[i]) - point_loss(u[i] - h, v[i])) / f64::from(2.0 * h);
        let dv = (point_loss(u[i], v[i] + h) - point_loss(u[i], v[i] - h)) / f64::from(2.0 * h);
        let tol = |x: f64| 2e-2 * x.abs().max(1.0);
        assert!((du - f64::from(g.d_u[i])).abs() <= tol(du), "d_u at {i}: {} vs {du}", g.d_u[i]);
        assert!((dv - f64::from(g.d_v[i])).abs() <= tol(dv), "d_v at {i}: {} vs {dv}", g.d_v[i]);
    }
}

/// A hand-written adjoint of f0 = p0 sin(u) + p1 v², f1 = p1 u, checking the plumbing
/// (seed routing, the layout's output order and slot mapping, per-chunk sums) independently of
/// diff::reverse.
#[test]
fn hand_made_adjoint_plumbing() {
    let mut b = Builder::new();
    let (u, v, p0, p1) = (b.u(), b.v(), b.param(0), b.param(1));
    let su = b.sin(u);
    let t0 = b.mul(p0, su);
    let vv = b.mul(v, v);
    let t1 = b.mul(p1, vv);
    let f0 = b.add(t0, t1);
    let f1 = b.mul(p1, u);
    b.reserve_params(3);
    let fwd = b.clone().finish(vec![Output { name: "f0".into(), node: f0 }, Output { name: "f1".into(), node: f1 }]);
    let (s0, s1) = (b.seed(0), b.seed(1));
    let cu = b.cos(u);
    let a = b.mul(p0, cu);
    let a = b.mul(s0, a);
    let c = b.mul(s1, p1);
    let du = b.add(a, c);
    let two = b.constant(2.0);
    let tv = b.mul(two, v);
    let tv = b.mul(p1, tv);
    let dv = b.mul(s0, tv);
    let dp1a = b.mul(s0, vv);
    let dp1b = b.mul(s1, u);
    let dp1 = b.add(dp1a, dp1b);
    let dp0 = b.mul(s0, su);
    // The names of the gradient outputs are for dumps only: the layout says what they are.
    let program = b.finish(vec![
        Output { name: "f0".into(), node: f0 },
        Output { name: "f1".into(), node: f1 },
        Output { name: "grad u".into(), node: du },
        Output { name: "grad v".into(), node: dv },
        Output { name: "grad p1".into(), node: dp1 },
        Output { name: "grad p0".into(), node: dp0 },
    ]);
    let adj = Adjoint { program, layout: AdjointLayout::new(2, vec![1, 0]) };
    let wrong_slots = Adjoint { layout: AdjointLayout::new(2, vec![1]), ..adj.clone() };
    assert!(matches!(Kernel::with_adjoint(fwd.clone(), wrong_slots), Err(KernelError::BadAdjoint(_))));
    let k = Kernel::with_adjoint(fwd, adj).unwrap();
    assert_eq!(k.wrt_params(), &[1, 0]);
    let n = 2 * CHUNK + 5;
    let (uu, vv) = points(n);
    let ones = vec![1.0f32; n];
    let zeros = vec![0.0f32; n];
    let p = [0.5, 2.0, 9.0];
    // Seed only f1: d_param1 = sum u, d_param0 = 0, d_u = p1, d_v = 0.
    let g = k.adjoint(&p, &uu, &vv, &[&zeros, &ones]).unwrap();
    let sum_u: f64 = uu.iter().map(|&x| f64::from(x)).sum();
    assert!((g.d_params[1] - sum_u).abs() < 1e-9 * sum_u.abs().max(1.0), "{} vs {sum_u}", g.d_params[1]);
    assert_eq!(g.d_params[0], 0.0);
    assert_eq!(g.d_params[2], 0.0, "slots outside wrt stay zero");
    assert!(g.d_u.iter().all(|&x| x == 2.0) && g.d_v.iter().all(|&x| x == 0.0));
    assert_eq!(g.values.len(), 2);
    assert_eq!(g.values[1][7], 2.0 * uu[7]);
}

#[test]
fn shapes_are_checked_not_panicked() {
    let fwd = smooth_forward();
    let k = Kernel::new(fwd.clone()).unwrap();
    let p = params();
    assert!(matches!(k.eval(&p, &[0.5; 3], &[0.5; 2]), Err(KernelError::Shape(_))));
    assert!(matches!(k.eval(&p[..2], &[0.5; 3], &[0.5; 3]), Err(KernelError::Jit(_))));
    assert!(matches!(k.adjoint(&p, &[0.5], &[0.5], &[]), Err(KernelError::NoAdjoint)));
    let bad = reverse::adjoint(&fwd, &[1]);
    let mut renamed = bad.clone();
    renamed.program.outputs[0].name = "other".into();
    assert!(matches!(Kernel::with_adjoint(fwd.clone(), renamed), Err(KernelError::BadAdjoint(_))));
    let k = Kernel::with_adjoint(fwd, bad).unwrap();
    assert!(matches!(k.adjoint(&p, &[0.5], &[0.5], &[&[1.0], &[1.0]]), Err(KernelError::Shape(_))));
    assert!(k.eval(&p, &[], &[]).unwrap().iter().all(|c| c.is_empty()));
}

#[test]
fn grid_row_zero_is_the_top_of_the_image() {
    let mut b = Builder::new();
    let (u, v) = (b.u(), b.v());
    let prog = b.finish(vec![Output { name: "u".into(), node: u }, Output { name: "v".into(), node: v }]);
    let k = Kernel::new(prog).unwrap();
    let (w, h) = (5, 4);
    let out = k.eval_grid(&[], w, h).unwrap();
    assert_eq!(out[0][..5], [0.1, 0.3, 0.5, 0.7, 0.9]);
    assert_eq!(out[1][0], 1.0 - 0.5 / 4.0, "row 0 is v near 1");
    assert_eq!(out[1][w * (h - 1)], 0.5 / 4.0, "last row is v near 0");
    let (gu, gv) = grid_uv(w, h).unwrap();
    assert_eq!((out[0].clone(), out[1].clone()), (gu, gv));
}

/// The chunking helpers the kernel uses are the ones benchmarks get: contiguous fixed chunks,
/// and `run_chunked` of the adjoint kernel gives the columns `Kernel::adjoint` reports.
#[test]
fn chunk_helpers_cover_the_batch_and_match_the_kernel() {
    use psc_runtime::kernel::{chunk_ranges, run_chunked};
    use rayon::prelude::*;
    for n in [0, 1, CHUNK, CHUNK + 1, 3 * CHUNK + 17] {
        let ranges: Vec<_> = chunk_ranges(n).collect();
        assert_eq!(ranges.len(), n.div_ceil(CHUNK));
        let mut next = 0;
        for r in &ranges {
            assert_eq!(r.start, next);
            assert!(r.len() == CHUNK || r.end == n, "{r:?} of {n}");
            next = r.end;
        }
        assert_eq!(next, n);
    }
    let fwd = smooth_forward();
    let k = Kernel::with_adjoint(fwd.clone(), reverse::adjoint(&fwd, &[0, 2])).unwrap();
    let n = 2 * CHUNK + 3;
    let (u, v) = points(n);
    let s = seeds(n, 3);
    let s_refs: Vec<&[f32]> = s.iter().map(|c| &c[..]).collect();
    let p = params();
    let mut cols = Vec::new();
    run_chunked(k.adjoint_jit().unwrap(), &p, &u, &v, &s_refs, &mut cols).unwrap();
    let g = k.adjoint(&p, &u, &v, &s_refs).unwrap();
    let layout = k.adjoint_layout().unwrap();
    assert_eq!(bits(&cols[..3]), bits(&g.values));
    assert_eq!(bits(std::slice::from_ref(&cols[layout.d_u()])), bits(std::slice::from_ref(&g.d_u)));
    let summed: f64 = cols[layout.d_param(1)].iter().map(|&x| f64::from(x)).sum();
    assert!((summed - g.d_params[2]).abs() <= 1e-6 * summed.abs().max(1.0));
    assert!(
        run_chunked(k.adjoint_jit().unwrap(), &p, &u, &v, &s_refs[..2], &mut cols).is_err(),
        "a missing seed column"
    );
}
