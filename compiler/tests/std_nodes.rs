//! Every node of the standard library (`graphs/std/*.psg`), one at a time: each `fn` is called
//! from a generated wrapper graph whose continuous parameters feed its arguments (position
//! arguments as `uv * 3.0 + vec2(q0, q1)`, image-like arguments as periodic fields of `uv`
//! plus a parameter, scalars as parameters), and whose height and albedo are a scalar reduction
//! of the result (records: the sum of their numeric fields). The wrapper is compiled with
//! `compile_text`, its adjoint checked against finite differences (as for the library graphs),
//! and, for fns that are periodic by design, its tiling checked.
//!
//! `PSC_STD_FNS=a,b` restricts the test to some fns; `PSC_STD_VERBOSE=1` prints each wrapper.

mod support;

use std::collections::BTreeMap;

use psc_compiler::{compile_text, Options};
use psc_grammar::ast::{FnDef, Item, TypeExpr};
use support::*;

/// Fns that are not periodic over the unit tile by design, with the reason. Their gradients are
/// still checked; their tiling is reported but not asserted.
const NOT_PERIODIC_BY_DESIGN: &[(&str, &str)] = &[
    ("fade", "a polynomial of its argument"),
    ("lattice_rand", "expects already wrapped integer lattice coordinates"),
    ("lattice_rand2", "expects already wrapped integer lattice coordinates"),
    ("grad_dot", "expects already wrapped integer lattice coordinates"),
    ("rehash", "a hash of a continuous value: the rounding at u + 1 changes it"),
    ("quarter_turn", "returns a position: periodic patterns of it stay periodic"),
    ("transform2d", "documented: periodic only for quarter turns and integer scales"),
    ("wood_grain", "takes board-local coordinates"),
    ("wood_pores", "takes board-local coordinates (lattice period 4096)"),
    ("knot", "takes board-local coordinates"),
    ("ray_flecks", "takes board-local coordinates (lattice period 4096)"),
    ("flower", "takes motif-local coordinates"),
    ("leaf", "takes motif-local coordinates"),
    ("damask", "takes motif-local coordinates"),
];

/// Fns whose tiling fails although they are meant to tile: reported to the library owner.
/// KNOWN FAILURES: listed ones are checked and reported but do not fail the test.
const KNOWN_NOT_TILING: &[(&str, &str)] = &[];

struct StdFn {
    module: String,
    def: FnDef,
    src: String,
}

fn std_fns() -> Vec<StdFn> {
    let mut out = Vec::new();
    for path in std_files() {
        let src = std::fs::read_to_string(&path).unwrap();
        let module = path.file_stem().unwrap().to_string_lossy().into_owned();
        let file = psc_grammar::parse(&src).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
        for item in file.items {
            if let Item::Fn(def) = item {
                out.push(StdFn { module: module.clone(), def, src: src.clone() });
            }
        }
    }
    out
}

fn type_name(t: &TypeExpr) -> Option<&str> {
    match t {
        TypeExpr::Named(i) => Some(i.name.as_str()),
        TypeExpr::Record(..) => None,
    }
}

/// A scalar reduction of a value of type `t` named by the expression `e`.
fn reduce(e: &str, t: &TypeExpr) -> Result<String, String> {
    match t {
        TypeExpr::Named(i) => match i.name.as_str() {
            "float" | "int" => Ok(format!("({e})")),
            "vec2" => Ok(format!("({e}.x + {e}.y)")),
            "vec3" | "color" => Ok(format!("({e}.x + {e}.y + {e}.z)")),
            other => Err(format!("returns `{other}`")),
        },
        TypeExpr::Record(fields, _) => {
            let parts: Result<Vec<String>, String> =
                fields.iter().map(|(n, t)| reduce(&format!("{e}.{}", n.name), t)).collect();
            Ok(format!("({})", parts?.join(" + ")))
        }
    }
}

/// Names of scalar arguments that are counts or frequencies (floored inside the fn).
const FREQ_LIKE: &[&str] = &[
    "per", "freq", "count", "res", "cols", "rows", "threads", "lines", "sides", "ratio", "stretch", "tiling", "quarter",
];
/// Names of arguments that are images (fields over the tile) rather than settings.
const IMAGE_LIKE: &[&str] =
    &["e", "h", "mask", "slope", "intensity", "x", "t", "fg", "bg", "base", "detail", "c", "v", "o", "a", "b", "r2"];

struct Wrapper {
    text: String,
    /// Whether the position argument (if any) is `uv` scaled by an integer.
    uses_uv: bool,
}

/// A wrapper graph calling `f`; `Err` with the reason when `f` cannot be wrapped.
fn wrapper(f: &StdFn) -> Result<Wrapper, String> {
    let d = &f.def;
    let mut params: Vec<String> = Vec::new();
    let mut q = 0usize;
    let mut new_param = |lo: f32, hi: f32, def: f32| -> String {
        let name = format!("q{q}");
        q += 1;
        let def = def.clamp(lo, hi);
        params.push(format!("    param {name} = {def:?} in [{lo:?}, {hi:?}]"));
        name
    };
    let mut args = Vec::new();
    let mut seen_vec2 = false;
    let has_vec2 = d.params.iter().any(|p| type_name(&p.ty) == Some("vec2"));
    let mut seen_float = false;
    let mut field = 0usize;
    let mut uses_uv = false;
    let lattice = d.name.name.ends_with("_lattice");
    for p in &d.params {
        let name = p.name.name.as_str();
        let default_text = p.default.as_ref().map(|e| f.src[e.span.start..e.span.end].to_string());
        let default_num: Option<f32> = default_text.as_ref().and_then(|t| t.parse().ok());
        let ty = type_name(&p.ty).ok_or_else(|| format!("parameter `{name}` has a record type"))?;
        if p.is_const {
            if default_text.is_none() {
                args.push(format!("{name}: 3"));
            }
            continue;
        }
        let arg = match ty {
            "int" => "3".to_string(),
            "bool" => return Err(format!("parameter `{name}` is a bool")),
            "vec2" if !seen_vec2 && !IMAGE_LIKE.contains(&name) || name == "p" || name == "c" && !seen_vec2 => {
                seen_vec2 = true;
                uses_uv = true;
                let (a, b) = (new_param(-0.5, 0.5, 0.1), new_param(-0.5, 0.5, 0.2));
                format!("uv * 3.0 + vec2({a}, {b})")
            }
            "vec2" if name == "per" && lattice => "vec2(3.0, 3.0)".to_string(),
            "vec2" if FREQ_LIKE.contains(&name) => {
                let (a, b) = (new_param(2.2, 5.8, 3.5), new_param(2.2, 5.8, 4.5));
                format!("vec2({a}, {b})")
            }
            "vec2" if IMAGE_LIKE.contains(&name) => {
                field += 1;
                let (a, b) = (new_param(0.2, 0.8, 0.5), new_param(0.2, 0.8, 0.5));
                uses_uv = true;
                format!("vec2({a} + 0.2 * sin(6.28318531 * (uv.x + {field}.0 * uv.y)), {b} + 0.2 * cos(6.28318531 * ({field}.0 * uv.x - uv.y)))")
            }
            "vec2" => {
                let (a, b) = (new_param(-0.2, 0.2, 0.05), new_param(-0.2, 0.2, -0.05));
                format!("vec2({a}, {b})")
            }
            "vec3" | "color"
                if IMAGE_LIKE.contains(&name)
                    || !d
                        .params
                        .iter()
                        .take_while(|x| x.name.name != name)
                        .any(|x| matches!(type_name(&x.ty), Some("vec3" | "color"))) =>
            {
                field += 1;
                uses_uv = true;
                let (a, b, c) = (new_param(0.2, 0.8, 0.4), new_param(0.2, 0.8, 0.5), new_param(0.2, 0.8, 0.6));
                format!(
                    "vec3({a} + 0.2 * sin(6.28318531 * (uv.x + {field}.0 * uv.y)), {b} + 0.2 * cos(6.28318531 * ({field}.0 * uv.x - uv.y)), {c} + 0.15 * sin(6.28318531 * (2.0 * uv.x + uv.y)))"
                )
            }
            "vec3" | "color" => {
                let (a, b, c) = (new_param(0.1, 0.9, 0.3), new_param(0.1, 0.9, 0.5), new_param(0.1, 0.9, 0.7));
                format!("vec3({a}, {b}, {c})")
            }
            "float" if IMAGE_LIKE.contains(&name) || !has_vec2 && !seen_float => {
                seen_float = true;
                field += 1;
                uses_uv = true;
                let a = new_param(0.2, 0.8, 0.45);
                format!("({a} + 0.3 * sin(6.28318531 * (uv.x + {field}.0 * uv.y)) * cos(6.28318531 * ({field}.0 * uv.x - 2.0 * uv.y)))")
            }
            "float" => {
                seen_float = true;
                let (lo, hi, def) = if name == "seed" || name == "salt" {
                    (0.1, 0.9, 0.5)
                } else if FREQ_LIKE.contains(&name) || name == "size" && default_num.is_none_or(|x| x >= 1.0) {
                    match default_num {
                        Some(x) if x >= 1.0 => ((0.6 * x).max(1.2), 1.4 * x + 0.3, x + 0.37),
                        _ => (2.2, 5.8, 3.6),
                    }
                } else if let Some(x) = default_num {
                    let w = 0.25 * (x.abs() + 0.2);
                    (x - w, x + w, x)
                } else if ["r", "w", "len", "k"].contains(&name) {
                    (0.01, 0.06, 0.03)
                } else {
                    (0.2, 0.8, 0.5)
                };
                new_param(lo, hi, def)
            }
            other => return Err(format!("parameter `{name}` has type `{other}`")),
        };
        args.push(format!("{name}: {arg}"));
    }
    let reduction = reduce("r", &d.ret)?;
    let text = format!(
        "import std.{module};\n\ngraph wrap_{fname} {{\n{params}\n    node r = {fname}({args})\n    node s = {reduction}\n    output albedo = vec3(s)\n    output roughness = 0.5\n    output height = 0.02 * s\n}}\n",
        module = f.module,
        fname = d.name.name,
        params = params.join("\n"),
        args = args.join(", "),
    );
    Ok(Wrapper { text, uses_uv })
}

#[test]
fn every_std_fn_compiles_differentiates_and_tiles() {
    let fns = std_fns();
    assert!(fns.len() >= 60, "only {} std fns found", fns.len());
    let filter: Option<Vec<String>> =
        std::env::var("PSC_STD_FNS").ok().map(|s| s.split(',').map(str::to_string).collect());
    let verbose = std::env::var("PSC_STD_VERBOSE").is_ok();
    let path = graphs_dir().join("wood").join("__std_wrapper.psg");
    let mut not_covered: BTreeMap<String, String> = BTreeMap::new();
    let mut failures = Vec::new();
    let mut report = String::new();
    let mut total = GradCoverage::default();
    let (mut covered, mut tiled, mut tile_exempt) = (0, 0, 0);
    for f in &fns {
        let fname = &f.def.name.name;
        if filter.as_ref().is_some_and(|x| !x.contains(fname)) {
            continue;
        }
        let w = match wrapper(f) {
            Ok(w) => w,
            Err(why) => {
                not_covered.insert(format!("{}.{fname}", f.module), why);
                continue;
            }
        };
        if verbose {
            eprintln!("{}", w.text);
        }
        let out = compile_text(&path, w.text.clone(), &Options::default());
        if out.has_errors() || out.graphs.len() != 1 {
            failures.push(format!("{fname}: the wrapper does not compile:\n{}\n{}", w.text, out.render_diagnostics()));
            continue;
        }
        let g = &out.graphs[0];
        let adjoint = g.adjoint();
        if let Err(e) = g.forward.validate().and(adjoint.program.validate()) {
            failures.push(format!("{fname}: invalid program: {e}"));
            continue;
        }
        covered += 1;
        let mut rng = Rng::for_name(fname, 3);
        let mut cov = GradCoverage::default();
        for params in param_vectors(&g.info, &mut rng, 2) {
            let (points, seeds) = random_points(&mut rng, 4);
            cov.add(&check_gradients(fname, &g.forward, &adjoint, &params, &points, &seeds));
        }
        total.add(&cov);
        let probes = cov.compared + cov.skipped();
        if !cov.failures.is_empty() {
            failures.push(format!(
                "{fname}: gradients disagree:\n{}\n{}",
                cov.failures[..cov.failures.len().min(3)].join("\n"),
                w.text
            ));
        }
        // Every wrapper gets some comparisons; piecewise-constant fns (hashes, checker) have
        // only zero derivatives, which are still compared.
        if cov.compared * 4 < probes {
            failures.push(format!("{fname}: only {} of {probes} probes were comparable\n{}", cov.compared, w.text));
        }

        let exempt = NOT_PERIODIC_BY_DESIGN.iter().find(|(n, _)| n == fname);
        let known = KNOWN_NOT_TILING.iter().any(|(n, _)| n == fname);
        let mut tile = TileReport::default();
        if w.uses_uv {
            for params in param_vectors(&g.info, &mut rng, 1) {
                let r = check_tiling(&g.forward, &params, &mut rng, 100);
                tile.compared += r.compared;
                tile.isolated += r.isolated;
                tile.failure_count += r.failure_count;
                tile.failures.extend(r.failures);
            }
            let tiles = tile.failure_count == 0 && tile.isolated * 20 <= tile.compared;
            if known && tiles {
                eprintln!("note: {fname} is listed as not tiling but tiles now: remove it from KNOWN_NOT_TILING");
            }
            if exempt.is_some() || known {
                tile_exempt += 1;
            } else {
                tiled += 1;
                if !tiles {
                    failures.push(format!(
                        "{fname} does not tile: {} consistent mismatches, {} isolated of {}; e.g.\n  {}\n{}",
                        tile.failure_count,
                        tile.isolated,
                        tile.compared,
                        tile.failures.join("\n  "),
                        w.text
                    ));
                }
            }
        }
        report.push_str(&format!(
            "{:<10} {:<20} {:>2} slots {:>5} ops  grad compared {:>3} ({:>3} non-zero) skipped {:>3}  tiling: {}\n",
            f.module,
            fname,
            adjoint.layout.wrt().len(),
            g.forward.op_count(),
            cov.compared,
            cov.non_zero,
            cov.skipped(),
            if !w.uses_uv {
                "n/a (constant in uv)".to_string()
            } else if let Some((_, why)) = exempt.or(KNOWN_NOT_TILING.iter().find(|(n, _)| n == fname)) {
                format!("not asserted ({why}); mismatches {}", tile.failure_count)
            } else {
                format!("{} compared, {} isolated, {} mismatches", tile.compared, tile.isolated, tile.failure_count)
            }
        ));
    }
    eprintln!("{report}");
    eprintln!(
        "{covered} std fns covered ({tiled} tiling-checked, {tile_exempt} exempt from tiling), {} not covered:",
        not_covered.len()
    );
    for (name, why) in &not_covered {
        eprintln!("  {name}: {why}");
    }
    eprintln!(
        "gradients: compared {} ({} non-zero), skipped {} at a branch, {} unresolved",
        total.compared, total.non_zero, total.skipped_branch, total.skipped_unresolved
    );
    if filter.is_none() {
        assert!(covered >= 60, "only {covered} std fns covered");
        assert!(total.non_zero >= 1000, "only {} non-zero derivatives compared", total.non_zero);
    }
    assert!(failures.is_empty(), "{} problems:\n{}", failures.len(), failures.join("\n\n"));
}
