//! The graph library (`graphs/`): every graph compiles and JIT-compiles; outputs stay finite
//! and in range for random parameters; every graph tiles; no continuous parameter is dead;
//! random variants differ visibly. Bake time at 2048² is a benchmark, not a test:
//! `psc library --bench 2048` prints every graph's time.

use std::sync::OnceLock;

use psc_base::SplitMix64 as Rng;
use psc_compiler::ParamKind;
use psc_runtime::library::{default_library_root, Library, Material};

fn library() -> &'static Library {
    static LIB: OnceLock<Library> = OnceLock::new();
    LIB.get_or_init(|| Library::load(&default_library_root()).unwrap_or_else(|e| panic!("{e}")))
}

/// Uniformly random parameters over every parameter's full range.
fn random_params(m: &Material, rng: &mut Rng) -> Vec<f32> {
    let info = &m.graph.info;
    let mut p = info.default_params();
    for q in &info.params {
        match q.kind {
            ParamKind::Continuous { min, max } => p[q.slot] = min + (max - min) * rng.next_f32(),
            ParamKind::Discrete { min, max } => {
                p[q.slot] = (min + (rng.next_u64() % (max - min + 1) as u64) as i64) as f32
            }
            ParamKind::Color => (0..3).for_each(|c| p[q.slot + c] = rng.next_f32()),
        }
    }
    p
}

fn random_points(n: usize, rng: &mut Rng) -> (Vec<f32>, Vec<f32>) {
    (0..n).map(|_| (rng.next_f32(), rng.next_f32())).unzip()
}

/// The families a fit's report groups by (docs/materials.md): a graph's `category` is one of
/// these and names the folder it lives in.
const FAMILIES: [&str; 12] = [
    "wood",
    "tiles",
    "stone",
    "concrete",
    "wallpaper",
    "brick",
    "carpet",
    "fabric",
    "leather",
    "metal",
    "plastic",
    "homogeneous",
];

#[test]
fn library_covers_the_families_of_indoor_rooms() {
    let lib = library();
    let count = |cat: &str| lib.materials.iter().filter(|m| m.graph.info.category == cat).count();
    assert!(lib.materials.len() >= 72, "{} graphs", lib.materials.len());
    // Floors per family: what issue 12 asked the library to cover.
    for (family, at_least) in [
        ("wood", 15),
        ("tiles", 6),
        ("stone", 8),
        ("concrete", 6),
        ("wallpaper", 5),
        ("brick", 4),
        ("carpet", 6),
        ("fabric", 12),
        ("leather", 3),
        ("metal", 5),
        ("plastic", 6),
    ] {
        assert!(count(family) >= at_least, "{family}: {} graphs", count(family));
    }
    assert!(lib.get("homogeneous").is_some());
    for m in &lib.materials {
        let info = &m.graph.info;
        assert!(FAMILIES.contains(&info.category.as_str()), "{}: unknown category {}", info.name, info.category);
        // graphs/<category>/name.psg; the homogeneous material sits at the root, graphs/.
        let folder = info.file.parent().and_then(|d| d.file_name()).map(|d| d.to_string_lossy().into_owned());
        let expected = if info.category == "homogeneous" { "graphs" } else { info.category.as_str() };
        assert_eq!(folder.as_deref(), Some(expected), "{} lives in the wrong folder", info.name);
        assert!(!info.description.is_empty(), "{} has no description", info.name);
        assert!(info.has_height, "{} should derive its normal from a height", info.name);
        // Keep kernels a reasonable size: a few hundred to a few thousand scalar ops.
        assert!(m.graph.forward.op_count() < 4000, "{}: {} ops", info.name, m.graph.forward.op_count());
    }
}

/// For 100 random parameter vectors (and the defaults), at 256 random points each: every
/// output is finite, albedo and roughness lie in [0, 1] (roughness in [0.02, 1]), metallic in
/// [0, 1], and normals are unit length with z > 0.
#[test]
fn outputs_are_finite_and_in_range_for_random_parameters() {
    let mut failures = Vec::new();
    for m in &library().materials {
        let mut rng = Rng(0x5EED ^ m.graph.info.name.len() as u64);
        for trial in 0..=100 {
            let params = if trial == 0 { m.graph.info.default_params() } else { random_params(m, &mut rng) };
            let (u, v) = random_points(256, &mut rng);
            let out = m.kernel.eval(&params, &u, &v).unwrap();
            for k in 0..u.len() {
                let px: Vec<f32> = out.iter().map(|c| c[k]).collect();
                let n_len = (px[4] * px[4] + px[5] * px[5] + px[6] * px[6]).sqrt();
                let ok = px.iter().all(|x| x.is_finite())
                    && px[0..3].iter().all(|x| (0.0..=1.0).contains(x))
                    && (0.02..=1.0).contains(&px[3])
                    && (n_len - 1.0).abs() < 1e-3
                    && px[6] > 0.0
                    && (0.0..=1.0).contains(&px[8]);
                if !ok {
                    failures.push(format!("{} trial {trial} at ({}, {}): {px:?}", m.graph.info.name, u[k], v[k]));
                    break;
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
}

/// Tiling: the value at uv equals the value at uv + (1, 0) and uv + (0, 1). Points are dyadic
/// (k/4096 + 1/8192), so uv + 1 is exact and lattice coordinates match bit for bit; what can
/// differ is transcendental rounding. Tolerance: every channel within 2e-3 (height within
/// 1e-5 + 1e-3 |h|) at ≥ 99% of the points (the rest may sit on a step edge, where one
/// rounding flips a floor).
#[test]
fn every_graph_tiles() {
    let mut failures = Vec::new();
    for m in &library().materials {
        let mut rng = Rng(77);
        for trial in 0..4 {
            let params = if trial == 0 { m.graph.info.default_params() } else { random_params(m, &mut rng) };
            let n = 512;
            let u: Vec<f32> = (0..n).map(|_| (rng.next_u64() % 4096) as f32 / 4096.0 + 1.0 / 8192.0).collect();
            let v: Vec<f32> = (0..n).map(|_| (rng.next_u64() % 4096) as f32 / 4096.0 + 1.0 / 8192.0).collect();
            let base = m.kernel.eval(&params, &u, &v).unwrap();
            for (du, dv) in [(1.0f32, 0.0f32), (0.0, 1.0)] {
                let u2: Vec<f32> = u.iter().map(|x| x + du).collect();
                let v2: Vec<f32> = v.iter().map(|x| x + dv).collect();
                let shifted = m.kernel.eval(&params, &u2, &v2).unwrap();
                let mut bad = 0;
                for k in 0..n {
                    let differs = (0..9).any(|c| {
                        let (a, b) = (base[c][k], shifted[c][k]);
                        let tol = if c == 7 { 1e-5 + 1e-3 * a.abs() } else { 2e-3 };
                        (a - b).abs() > tol
                    });
                    bad += differs as usize;
                }
                if bad * 100 > n {
                    failures.push(format!(
                        "{} trial {trial} shift ({du}, {dv}): {bad}/{n} points differ",
                        m.graph.info.name
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// No dead parameters: each continuous parameter slot (colour channels included) has a
/// non-zero gradient of some output for the defaults or one of a few random parameter
/// vectors. The loss is a random ±1-weighted sum of all outputs over 2048 random points.
#[test]
fn every_continuous_parameter_has_a_gradient() {
    let mut failures = Vec::new();
    for m in &library().materials {
        let info = &m.graph.info;
        let slots = info.continuous_slots();
        let mut live = vec![false; info.num_slots()];
        let mut rng = Rng(4242);
        for trial in 0..6 {
            let params = if trial == 0 { info.default_params() } else { random_params(m, &mut rng) };
            let (u, v) = random_points(2048, &mut rng);
            let seeds: Vec<Vec<f32>> =
                (0..9).map(|_| (0..u.len()).map(|_| rng.next_f32() * 2.0 - 1.0).collect()).collect();
            let seed_refs: Vec<&[f32]> = seeds.iter().map(|s| &s[..]).collect();
            let g = m.gradient_kernel().unwrap().adjoint(&params, &u, &v, &seed_refs).unwrap();
            for &s in &slots {
                let d = g.d_params[s as usize];
                assert!(d.is_finite(), "{}: non-finite gradient for slot {s}", info.name);
                if d != 0.0 {
                    live[s as usize] = true;
                }
            }
            if slots.iter().all(|&s| live[s as usize]) {
                break;
            }
        }
        for p in &info.params {
            if p.is_continuous() && !(p.slot..p.slot + p.width()).any(|s| live[s]) {
                failures.push(format!("{}.{}", info.name, p.name));
            }
        }
    }
    assert!(failures.is_empty(), "dead parameters: {}", failures.join(", "));
}

/// Random variants differ visibly: over a 48² grid, the mean absolute difference of the
/// sRGB-ish albedo (x^(1/2.2)) plus the normal between any two of four random variants is at
/// least 0.01 (a floor on image distance, not a fixed picture).
#[test]
fn random_variants_differ_visibly() {
    let mut failures = Vec::new();
    for m in &library().materials {
        let mut rng = Rng(99);
        let images: Vec<Vec<Vec<f32>>> = (0..4)
            .map(|_| {
                let p = random_params(m, &mut rng);
                m.kernel.eval_grid(&p, 48, 48).unwrap()
            })
            .collect();
        for a in 0..4 {
            for b in a + 1..4 {
                let n = images[a][0].len();
                let gamma = |x: f32| x.max(0.0).powf(1.0 / 2.2);
                let mut d = 0.0f64;
                // Albedo channels compared in a perceptual (gamma) space, normals as they are.
                for (ca, cb) in images[a][0..3].iter().zip(&images[b][0..3]) {
                    d += ca.iter().zip(cb).map(|(&x, &y)| (gamma(x) - gamma(y)).abs() as f64).sum::<f64>();
                }
                for (ca, cb) in images[a][4..7].iter().zip(&images[b][4..7]) {
                    d += ca.iter().zip(cb).map(|(&x, &y)| (x - y).abs() as f64).sum::<f64>();
                }
                let mean = d / (n * 6) as f64;
                if mean < 0.01 {
                    failures.push(format!("{} variants {a} and {b}: mean difference {mean:.4}", m.graph.info.name));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
