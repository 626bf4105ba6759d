//! The whole material library through the JIT: it compiles, and its native kernels agree with
//! the reference interpreter on random parameters and points, forward and adjoint.

use psc_compiler::interp::{self, Batch};
use std::sync::OnceLock;

use psc_base::SplitMix64 as Rng;
use psc_runtime::library::{default_library_root, Library};
use psc_runtime::params::ParamSpace;

/// Compiled once for all tests of this file: JIT-compiling 31 graphs twice is wasted time.
fn library() -> &'static Library {
    static LIBRARY: OnceLock<Library> = OnceLock::new();
    LIBRARY.get_or_init(|| Library::load(&default_library_root()).unwrap_or_else(|e| panic!("{e}")))
}

/// Within `tol` absolutely or relatively.
fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn jit_matches_the_interpreter_on_every_library_graph() {
    let lib = library();
    assert!(lib.materials.len() >= 30, "the library has {} graphs", lib.materials.len());
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let n = 512;
    for m in &lib.materials {
        for trial in 0..3 {
            let params = if trial == 0 {
                m.graph.info.default_params()
            } else {
                ParamSpace::new(&m.graph.info).random(&mut rng)
            };
            // Points inside and outside the unit tile.
            let u: Vec<f32> = (0..n).map(|_| rng.next_f32() * 3.0 - 1.0).collect();
            let v: Vec<f32> = (0..n).map(|_| rng.next_f32() * 3.0 - 1.0).collect();
            let jit = m.kernel.eval(&params, &u, &v).unwrap();
            let reference = interp::eval(&m.graph.forward, &params, &Batch { u: &u, v: &v, seeds: &[] });
            // Polynomial sin/cos/exp/log differ from libm by ~1e-6 relative; a difference that
            // small can move a value across a floor() or cell boundary and change a texel a lot.
            // So: almost every value must agree tightly, and boundary flips must stay rare.
            let mut total = 0usize;
            let mut off = 0usize;
            for (c, (a, b)) in jit.iter().zip(&reference).enumerate() {
                for k in 0..n {
                    total += 1;
                    assert!(a[k].is_finite(), "{} channel {c} not finite at ({}, {})", m.name(), u[k], v[k]);
                    if !close(a[k], b[k], 2e-3) {
                        off += 1;
                    }
                }
            }
            let fraction = off as f64 / total as f64;
            assert!(fraction <= 0.01, "{}: {off} of {total} values differ from the interpreter", m.name());
        }
    }
}

#[test]
fn jit_adjoint_matches_the_interpreter_adjoint() {
    let lib = library();
    let mut rng = Rng(12345);
    let n = 256;
    for m in &lib.materials {
        let params = ParamSpace::new(&m.graph.info).random(&mut rng);
        let u: Vec<f32> = (0..n).map(|_| rng.next_f32()).collect();
        let v: Vec<f32> = (0..n).map(|_| rng.next_f32()).collect();
        let seeds: Vec<Vec<f32>> = (0..9).map(|_| (0..n).map(|_| rng.next_f32() - 0.5).collect()).collect();
        let seed_refs: Vec<&[f32]> = seeds.iter().map(|s| &s[..]).collect();
        let kernel = m.gradient_kernel().unwrap();
        let grads = kernel.adjoint(&params, &u, &v, &seed_refs).unwrap();
        let adjoint = kernel.adjoint_program().expect("gradient kernels carry adjoints");
        let reference = interp::eval(adjoint, &params, &Batch { u: &u, v: &v, seeds: &seed_refs });
        // Per-point d_u agreement, as a fraction (see the forward test for why not all points).
        let du_ref = &reference[9];
        let agree = (0..n).filter(|&k| close(grads.d_u[k], du_ref[k], 5e-3)).count();
        assert!(agree as f64 >= 0.97 * n as f64, "{}: d_u agrees at only {agree} of {n} points", m.name());
        assert!(grads.d_params.iter().all(|g| g.is_finite()), "{}: non-finite parameter gradient", m.name());
    }
}

/// The renderer shades the hits of a packet that share a part in one batch: for every library
/// graph, a batch (longer than the packet entry's 16 points, so it is cut in chunks) gives each
/// point exactly what evaluating it alone gives.
#[test]
fn a_batch_of_hits_shades_as_the_hits_one_at_a_time() {
    use psc_render::SurfaceMaterial;
    use psc_runtime::material::ProceduralMaterial;
    let mut rng = Rng(0x5EED_BA7C);
    for m in &library().materials {
        let params = ParamSpace::new(&m.graph.info).random(&mut rng);
        let material = ProceduralMaterial::new(std::sync::Arc::clone(m), params).unwrap();
        let uvs: Vec<[f32; 2]> = (0..37).map(|_| [rng.next_f32() * 3.0 - 1.0, rng.next_f32() * 3.0 - 1.0]).collect();
        let mut batch = vec![psc_render::SurfaceSample::default(); uvs.len()];
        material.eval_batch(&uvs, &mut batch);
        for (k, (uv, got)) in uvs.iter().zip(&batch).enumerate() {
            let alone = material.eval(*uv);
            let bits = |s: &psc_render::SurfaceSample| {
                s.albedo.iter().chain(&s.normal).chain([&s.roughness]).map(|x| x.to_bits()).collect::<Vec<_>>()
            };
            assert_eq!(bits(got), bits(&alone), "{}: point {k} at {uv:?}", m.name());
        }
    }
}
