//! The IR invariants, on every library graph's forward and fused adjoint programs: they
//! validate (well-formed; hash-consed, commutative operands in canonical order; folded and
//! simplified; no dead code); compilation is deterministic; and common subexpressions written
//! twice in the source cost nothing extra.

mod support;

use psc_compiler::ir::{Op, Program};
use psc_compiler::{compile_text, Options};
use support::*;

/// Every invariant of one program (`Program::validate`: well-formed, hash-consed, folded and
/// simplified, no dead code); `Err` describes the first violation.
fn check_invariants(p: &Program) -> Result<(), String> {
    p.validate().map_err(|e| e.to_string())
}

#[test]
fn forward_and_adjoint_programs_of_every_graph_keep_the_ir_invariants() {
    let graphs = compile_library();
    let mut failures = Vec::new();
    let (mut forward_ops, mut adjoint_ops) = (0, 0);
    for g in &graphs {
        let adjoint = g.adjoint();
        adjoint.layout.check(&g.forward, &adjoint.program).unwrap_or_else(|e| panic!("{}: {e}", g.info.name));
        assert_eq!(adjoint.layout.wrt(), g.info.continuous_slots(), "{}", g.info.name);
        let adjoint = adjoint.program;
        for (kind, p) in [("forward", &g.forward), ("adjoint", &adjoint)] {
            if let Err(e) = check_invariants(p) {
                failures.push(format!("{} {kind}: {e}", g.info.name));
            }
        }
        assert_eq!(g.forward.num_seeds, 0);
        assert_eq!(adjoint.num_seeds, psc_compiler::Channel::COUNT, "{}: one seed per channel", g.info.name);
        assert_eq!(g.stats.forward_ops, g.forward.op_count(), "{}", g.info.name);
        assert!(g.stats.nodes_before_dce >= g.forward.nodes.len(), "{}", g.info.name);
        forward_ops += g.forward.op_count();
        adjoint_ops += adjoint.op_count();
    }
    eprintln!("{} graphs: {forward_ops} forward ops, {adjoint_ops} adjoint ops", graphs.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The checks above can fail: each catches a program built to break it (one per rule is in
/// `ir::validate`'s unit tests; these are the shapes a lowering bug would most likely make).
#[test]
fn the_invariant_checks_catch_violations() {
    use psc_compiler::ir::{InvalidProgram, NodeId, Output};
    let out = |node: u32| vec![Output { name: "x".into(), node: NodeId(node) }];
    let base = |nodes: Vec<Op>, o: u32| Program { nodes, outputs: out(o), num_params: 0, num_seeds: 0 };
    // add(u, v) and add(v, u): the second is not in canonical operand order.
    let dup = base(
        vec![Op::U, Op::V, Op::Add(NodeId(0), NodeId(1)), Op::Add(NodeId(1), NodeId(0)), Op::Mul(NodeId(2), NodeId(3))],
        4,
    );
    assert!(matches!(dup.validate(), Err(InvalidProgram::NotSimplified { node: NodeId(3), .. })));
    let c = f32::to_bits(2.0);
    let unfolded = base(vec![Op::Const(c), Op::Sin(NodeId(0))], 1);
    assert!(matches!(unfolded.validate(), Err(InvalidProgram::Unfolded { .. })));
    let dead = base(vec![Op::U, Op::V, Op::Sin(NodeId(0))], 2);
    assert!(check_invariants(&dead).unwrap_err().contains("reaches no output"));
    let fine = base(vec![Op::U, Op::Sin(NodeId(0))], 1);
    check_invariants(&fine).unwrap();
}

#[test]
fn compiling_a_graph_twice_gives_identical_programs() {
    for path in material_files() {
        let text = std::fs::read_to_string(&path).unwrap();
        let a = compile_text(&path, text.clone(), &Options::default());
        let b = compile_text(&path, text, &Options::default());
        assert!(!a.has_errors(), "{}", a.render_diagnostics());
        assert_eq!(a.graphs.len(), b.graphs.len());
        for (x, y) in a.graphs.iter().zip(&b.graphs) {
            assert_eq!(x.info, y.info, "{}", path.display());
            assert!(x.forward == y.forward, "{}: forward programs differ between two compilations", x.info.name);
            assert!(x.adjoint() == y.adjoint(), "{}: adjoint programs differ between two compilations", x.info.name);
        }
    }
}

fn compile_one(src: &str) -> psc_compiler::CompiledGraph {
    let out = compile_text(&graphs_dir().join("stone").join("__cse.psg"), src, &Options::default());
    assert!(!out.has_errors(), "{}\n{src}", out.render_diagnostics());
    assert_eq!(out.graphs.len(), 1);
    out.graphs.into_iter().next().unwrap()
}

fn graph_with(nodes: &str, height: &str) -> String {
    format!(
        "import std.noise;\nimport std.cells;\n\ngraph cse {{\n    param freq = 4.5 in [2, 8]\n    param k = 0.3 in [0, 1]\n{nodes}\n    output albedo = vec3(k)\n    output roughness = 0.5\n    output height = {height}\n}}\n"
    )
}

#[test]
fn a_subexpression_written_twice_costs_the_same_as_written_once() {
    let cases = [
        // A whole node library call, inline twice vs bound once.
        (
            graph_with("", "0.01 * sin(fbm(uv, freq)) * cos(fbm(uv, freq))"),
            graph_with("    node n = fbm(uv, freq)", "0.01 * sin(n) * cos(n)"),
        ),
        // Two nodes with the same definition vs one node used twice.
        (
            graph_with(
                "    node a = cells(uv * 2.0, 5.0, k).f1\n    node b = cells(uv * 2.0, 5.0, k).f1",
                "0.01 * a * exp(b)",
            ),
            graph_with("    node a = cells(uv * 2.0, 5.0, k).f1", "0.01 * a * exp(a)"),
        ),
        // Commuted operands of a commutative op, and the same value through a let.
        (
            graph_with("", "0.01 * (sin(uv.x * freq + k) * cos(k + freq * uv.x))"),
            graph_with("    node t = uv.x * freq + k", "0.01 * (sin(t) * cos(t))"),
        ),
        (
            graph_with("", "{ let a = perlin(uv, freq); let b = perlin(uv, freq); 0.01 * (a * k + b * b) }"),
            graph_with("", "{ let a = perlin(uv, freq); 0.01 * (a * k + a * a) }"),
        ),
    ];
    for (twice, once) in &cases {
        let (t, o) = (compile_one(twice), compile_one(once));
        assert_eq!(
            t.forward.op_count(),
            o.forward.op_count(),
            "writing a subexpression twice costs extra:\n{twice}\n{once}"
        );
        assert_eq!(
            t.adjoint().program.op_count(),
            o.adjoint().program.op_count(),
            "adjoints differ in size:\n{twice}\n{once}"
        );
        // And the repeated form did request more nodes: the sharing was the builder's work.
        assert!(t.stats.requested_nodes > o.stats.requested_nodes, "{twice}");
        check_invariants(&t.forward).unwrap();
    }
    // Control: a genuinely different second subexpression does cost more.
    let different = compile_one(&graph_with("", "0.01 * sin(fbm(uv, freq)) * cos(fbm(uv, freq + 1.0))"));
    let same = compile_one(&graph_with("", "0.01 * sin(fbm(uv, freq)) * cos(fbm(uv, freq))"));
    assert!(different.forward.op_count() > same.forward.op_count());
}
