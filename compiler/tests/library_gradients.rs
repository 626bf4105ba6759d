//! Every library graph, end to end: the fused adjoint program's `d_u`, `d_v` and `d_param*`
//! against central finite differences of the seed-weighted forward channels (both by the
//! interpreter), at the defaults and at random parameter vectors; and tileability of every
//! channel over the unit tile.
//!
//! Probes that cross a kink or a jump are skipped, not compared with a looser tolerance: a probe
//! is compared only when every piecewise decision of the program (floor, hash, comparisons,
//! min/max, abs, …) is the same at all five probe points and the estimates at h and h/2 agree
//! (see `support::check_gradients` for the tolerance). A floor on the number of comparisons per
//! graph keeps the test from passing vacuously.
//!
//! `PSC_GRAPHS=a,b` restricts both tests to some graphs; `PSC_GRAD_POINTS` and
//! `PSC_TILE_POINTS` change the sample counts; `PSC_GRAD_DEBUG=1` prints every comparison with
//! the terms of its tolerance.

mod support;

use psc_compiler::Channel;
use support::*;

/// KNOWN FAILURES, reported to the library owner: graphs that do not tile. A graph listed here
/// is still checked and its mismatches reported, but it does not fail the test; remove it from
/// the list once the graph is fixed (the test prints a note when a listed graph tiles).
///
/// - `oak_grain`: its pores, `wood_pores(uv.x * 8.0, uv.y * float(lines) * 0.125, …)`, are value
///   noise with lattice period 4096 (std/wood.psg, meant for board-local coordinates) evaluated
///   over the whole tile, so they do not repeat at u + 1 or v + 1: every channel differs at
///   (0.80, 0.12) vs (1.80, 0.12) at the defaults.
/// - `granite` (odd `grain` only): `granite_grains` (std/stone.psg) samples its third layer
///   with `value_noise_lattice(p * f * 0.5, vec2(f, f) * 0.5, …)`, whose period f/2 is not an
///   integer for odd f; e.g. grain = 91 mismatches at most points.
const KNOWN_NOT_TILING: &[&str] = &[];

/// Graphs whose adjoint is known to disagree with finite differences (none).
const KNOWN_BAD_GRADIENTS: &[&str] = &[];

#[test]
fn adjoint_gradients_of_every_library_graph_match_finite_differences() {
    let graphs = compile_library();
    let filter = graph_filter();
    let points_per_vector = env_usize("PSC_GRAD_POINTS", 6);
    let mut total = GradCoverage::default();
    let mut failures = Vec::new();
    let mut report = String::new();
    for g in &graphs {
        if filter.as_ref().is_some_and(|f| !f.contains(&g.info.name)) {
            continue;
        }
        let adjoint = g.adjoint();
        adjoint.program.validate().unwrap_or_else(|e| panic!("{}: adjoint invalid: {e}", g.info.name));
        let slots = g.info.continuous_slots();
        let mut rng = Rng::for_name(&g.info.name, 1);
        let mut cov = GradCoverage::default();
        for params in param_vectors(&g.info, &mut rng, 2) {
            let (points, seeds) = random_points(&mut rng, points_per_vector);
            let c = check_gradients(&g.info.name, &g.forward, &adjoint, &params, &points, &seeds);
            cov.add(&c);
        }
        let vars = slots.len() + 2;
        report.push_str(&format!(
            "{:<22} {:>3} vars  compared {:>4} ({:>4} non-zero)  skipped {:>3} at a branch, {:>3} unresolved{}\n",
            g.info.name,
            vars,
            cov.compared,
            cov.non_zero,
            cov.skipped_branch,
            cov.skipped_unresolved,
            if cov.failures.is_empty() { String::new() } else { format!("  FAILED {}", cov.failures.len()) }
        ));
        // A floor per graph: at least a third of the probes compared, and some of them non-zero
        // (the homogeneous graph has no u/v dependence, so its derivatives in u, v are all 0).
        let probes = cov.compared + cov.skipped();
        if !KNOWN_BAD_GRADIENTS.contains(&g.info.name.as_str()) {
            if cov.compared * 3 < probes {
                failures.push(format!("{}: only {} of {probes} probes were comparable", g.info.name, cov.compared));
            }
            if cov.non_zero < vars.min(10) {
                failures.push(format!("{}: only {} compared derivatives are non-zero", g.info.name, cov.non_zero));
            }
            failures.extend(cov.failures.iter().take(5).cloned());
        }
        total.add(&cov);
    }
    eprintln!("{report}");
    eprintln!(
        "total: compared {} ({} non-zero), skipped {} at a branch, {} unresolved",
        total.compared, total.non_zero, total.skipped_branch, total.skipped_unresolved
    );
    if filter.is_none() {
        assert!(total.compared >= 3000, "only {} derivatives compared over the library", total.compared);
    }
    assert!(failures.is_empty(), "{} problems:\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn every_library_graph_tiles() {
    let graphs = compile_library();
    let filter = graph_filter();
    let n = env_usize("PSC_TILE_POINTS", 200);
    let mut failures = Vec::new();
    let mut report = String::new();
    let mut compared = 0;
    for g in &graphs {
        if filter.as_ref().is_some_and(|f| !f.contains(&g.info.name)) {
            continue;
        }
        let mut rng = Rng::for_name(&g.info.name, 2);
        let mut rep = TileReport::default();
        for params in param_vectors(&g.info, &mut rng, 2) {
            let r = check_tiling(&g.forward, &params, &mut rng, n);
            rep.compared += r.compared;
            rep.isolated += r.isolated;
            rep.failure_count += r.failure_count;
            if rep.failures.is_empty() && !r.failures.is_empty() {
                rep.failures = r.failures.iter().map(|f| format!("{f} (params {params:?})")).collect();
            }
        }
        compared += rep.compared;
        let known = KNOWN_NOT_TILING.contains(&g.info.name.as_str());
        if known && rep.failure_count == 0 && rep.isolated * 20 <= rep.compared {
            eprintln!("note: {} is listed as not tiling but tiles now: remove it from KNOWN_NOT_TILING", g.info.name);
        }
        report.push_str(&format!(
            "{:<22} compared {:>4}  isolated discontinuity hits {:>3}  mismatches {:>3}{}\n",
            g.info.name,
            rep.compared,
            rep.isolated,
            rep.failure_count,
            if known { "  (known not to tile)" } else { "" }
        ));
        // Isolated hits are expected near cell borders; many of them means the graph does not
        // tile at its borders after all.
        let too_many_isolated = rep.isolated * 20 > rep.compared;
        if !known && (rep.failure_count > 0 || too_many_isolated) {
            failures.push(format!(
                "{} does not tile: {} consistent mismatches, {} isolated of {} comparisons; e.g.\n  {}",
                g.info.name,
                rep.failure_count,
                rep.isolated,
                rep.compared,
                rep.failures.join("\n  ")
            ));
        }
    }
    eprintln!("{report}");
    eprintln!("channels compared: {:?}", Channel::ALL.map(Channel::name));
    assert!(compared > 0);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The gradient check is not vacuous: an adjoint whose derivative outputs are off by 2 % (plus
/// 0.01) is flagged at nearly every probe the check compares (at least 95 %).
#[test]
fn a_slightly_wrong_adjoint_is_caught() {
    use psc_compiler::ir::{Builder, Output};
    use psc_compiler::Adjoint;
    let graphs = compile_library();
    let (mut flagged, mut compared) = (0, 0);
    for name in ["red_brick", "plain_weave", "marble", "brushed_metal"] {
        let g = graphs.iter().find(|g| g.info.name == name).unwrap();
        let adjoint = g.adjoint();
        let mut b = Builder::from_program(&adjoint.program);
        // x + 0.02 |x| + 0.01: never cancels, ten times the REL floor of the tolerance.
        let (k, c) = (b.constant(0.02), b.constant(0.01));
        let mut outputs: Vec<Output> = adjoint.program.outputs.clone();
        for o in &mut outputs[adjoint.layout.d_u()..] {
            let a = b.abs(o.node);
            let scaled = b.mul(k, a);
            let err = b.add(scaled, c);
            o.node = b.add(o.node, err);
        }
        let wrong = Adjoint { program: b.finish(outputs), layout: adjoint.layout.clone() };
        let mut rng = Rng::for_name(name, 9);
        let params = random_params(&g.info, &mut rng);
        let (points, seeds) = random_points(&mut rng, 4);
        let good = check_gradients(name, &g.forward, &adjoint, &params, &points, &seeds);
        assert!(good.failures.is_empty(), "{:?}", good.failures);
        let bad = check_gradients(name, &g.forward, &wrong, &params, &points, &seeds);
        compared += good.compared;
        flagged += bad.failures.len();
    }
    eprintln!("an error of 2 % + 0.01 was flagged at {flagged} of {compared} compared probes");
    assert!(flagged * 20 >= compared * 19, "only {flagged} of {compared} wrong derivatives were flagged");
}

/// The tiling check is not vacuous: a graph with a slightly non-periodic height is flagged.
#[test]
fn a_graph_that_does_not_tile_is_caught() {
    let src = "graph seam {\n    param a = 0.5 in [0, 1]\n    output albedo = vec3(a)\n    output roughness = 0.5\n    output height = 0.05 * sin(6.0 * uv.x) + 0.01 * uv.y\n}\n";
    let out = psc_compiler::compile_text(&graphs_dir().join("wood/__seam.psg"), src, &psc_compiler::Options::default());
    assert!(!out.has_errors(), "{}", out.render_diagnostics());
    let g = &out.graphs[0];
    let rep = check_tiling(&g.forward, &g.info.default_params(), &mut Rng::new(5), 100);
    assert!(rep.failure_count >= 250, "only {} of {} mismatches flagged", rep.failure_count, rep.compared);
    // The same graph made periodic passes.
    let fixed =
        src.replace("sin(6.0 * uv.x) + 0.01 * uv.y", "sin(6.28318531 * 2.0 * uv.x) + 0.01 * cos(6.28318531 * uv.y)");
    let out =
        psc_compiler::compile_text(&graphs_dir().join("wood/__seam.psg"), fixed, &psc_compiler::Options::default());
    let g = &out.graphs[0];
    let rep = check_tiling(&g.forward, &g.info.default_params(), &mut Rng::new(5), 100);
    assert_eq!(rep.failure_count + rep.isolated, 0, "{:?}", rep.failures);
}
