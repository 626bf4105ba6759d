//! `psc compile <files or folders>`: check every graph and report what it compiled to.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::ValueEnum;
use psc_compiler::ParamKind;
use psc_compiler::{compile_files, Adjoint, CompiledGraph, Options};
use serde_json::json;

use crate::Failure;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Emit {
    /// The parsed syntax tree of each file.
    Ast,
    /// The optimised forward IR of each graph.
    Ir,
    /// The fused forward + adjoint IR of each graph.
    Adjoint,
}

#[derive(clap::Args)]
pub struct Args {
    /// .psg files, or folders searched recursively for them.
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Print a compilation stage instead of the summary.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    /// Machine-readable output on stdout (diagnostics included).
    #[arg(long)]
    pub json: bool,
    /// Library root for `import` (default: the nearest ancestor folder with `std/`).
    #[arg(long)]
    pub lib: Option<PathBuf>,
}

/// Every .psg file under the given paths, sorted, each once.
pub fn collect_sources(paths: &[PathBuf]) -> Result<Vec<PathBuf>, Failure> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let found = psc_compiler::find_sources(p)
                .map_err(|e| Failure(format!("cannot read folder {}: {e}", p.display())))?;
            out.extend(found);
        } else if p.exists() {
            out.push(p.clone());
        } else {
            return Err(Failure(format!("no such file or folder: {}", p.display())));
        }
    }
    out.sort();
    out.dedup();
    Ok(out)
}

pub fn run(args: Args) -> Result<ExitCode, Failure> {
    let files = collect_sources(&args.paths)?;
    if files.is_empty() {
        return Err(Failure("no .psg files found".into()));
    }
    if args.emit == Some(Emit::Ast) {
        return emit_ast(&files);
    }
    let started = Instant::now();
    let output = compile_files(&files, &Options { lib_root: args.lib.clone() });
    let front_end = started.elapsed();
    let adjoint_started = Instant::now();
    let adjoints: Vec<_> = output
        .graphs
        .iter()
        .map(|g| {
            let t = Instant::now();
            let adj = g.adjoint();
            (adj, t.elapsed())
        })
        .collect();
    let total = front_end + adjoint_started.elapsed();

    if args.json {
        print_json(&output, &adjoints, total);
    } else {
        let stderr = std::io::stderr();
        if stderr.is_terminal() {
            let mut stream = codespan_reporting_stream();
            for d in &output.diagnostics {
                d.emit_colored(&output.sources, &mut stream);
            }
        } else {
            eprint!("{}", output.render_diagnostics());
        }
        match args.emit {
            Some(Emit::Ir) => {
                for g in &output.graphs {
                    println!("{}", g.ir_dump());
                }
            }
            Some(Emit::Adjoint) => {
                for (g, (adj, _)) in output.graphs.iter().zip(&adjoints) {
                    println!("{}", g.adjoint_dump(adj));
                }
            }
            _ => print_summary(&output, &adjoints, files.len(), total),
        }
    }
    Ok(if output.has_errors() { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn codespan_reporting_stream() -> codespan_reporting::term::termcolor::StandardStream {
    codespan_reporting::term::termcolor::StandardStream::stderr(codespan_reporting::term::termcolor::ColorChoice::Auto)
}

fn emit_ast(files: &[PathBuf]) -> Result<ExitCode, Failure> {
    let mut ok = true;
    for f in files {
        let text = std::fs::read_to_string(f).map_err(|e| Failure(format!("cannot read {}: {e}", f.display())))?;
        match psc_grammar::parse(&text) {
            Ok(ast) => println!("// {}\n{ast:#?}", f.display()),
            Err(errors) => {
                ok = false;
                for e in errors {
                    let (line, col) = e.line_col(&text);
                    eprintln!("error: {}:{line}:{col}: {}", f.display(), e.message);
                }
            }
        }
    }
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(1) })
}

fn param_summary(g: &CompiledGraph) -> (usize, usize, usize) {
    let count = |pred: fn(&ParamKind) -> bool| g.info.params.iter().filter(|p| pred(&p.kind)).count();
    (
        count(|k| matches!(k, ParamKind::Continuous { .. })),
        count(|k| matches!(k, ParamKind::Color)),
        count(|k| matches!(k, ParamKind::Discrete { .. })),
    )
}

fn print_summary(
    output: &psc_compiler::CompileOutput,
    adjoints: &[(Adjoint, Duration)],
    files: usize,
    total: Duration,
) {
    for (g, (adj, adj_time)) in output.graphs.iter().zip(adjoints) {
        let (cont, colors, discrete) = param_summary(g);
        println!("graph {} ({}, {})", g.info.name, g.info.category, g.info.file.display());
        println!(
            "  params     {cont} continuous, {colors} colour, {discrete} discrete ({} slots, {} differentiable)",
            g.info.num_slots(),
            g.info.continuous_slots().len()
        );
        for p in &g.info.params {
            let range = match p.kind {
                ParamKind::Continuous { min, max } => format!("float in [{min}, {max}]"),
                ParamKind::Discrete { min, max } => format!("int in [{min}, {max}]"),
                ParamKind::Color => "colour".into(),
            };
            println!("    {:<18} {:<24} default {:?}", p.name, range, p.default);
        }
        println!(
            "  IR         {} nodes requested -> {} after CSE/folding -> {} ops after DCE ({} lowering steps of {})",
            g.stats.requested_nodes,
            g.stats.nodes_before_dce,
            g.stats.forward_ops,
            g.stats.lowering_work,
            psc_compiler::lower::MAX_LOWERING_WORK
        );
        println!("  ops        forward {}, forward+adjoint {}", g.forward.op_count(), adj.program.op_count());
        println!(
            "  time       lower {:.2} ms, adjoint {:.2} ms",
            g.stats.lower_time.as_secs_f64() * 1e3,
            adj_time.as_secs_f64() * 1e3
        );
    }
    let errors = output.diagnostics.iter().filter(|d| d.is_error()).count();
    let warnings = output.diagnostics.len() - errors;
    println!(
        "{} graph{} from {files} file{} in {:.1} ms; {errors} error{}, {warnings} warning{}",
        output.graphs.len(),
        plural(output.graphs.len()),
        plural(files),
        total.as_secs_f64() * 1e3,
        plural(errors),
        plural(warnings)
    );
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

fn print_json(output: &psc_compiler::CompileOutput, adjoints: &[(Adjoint, Duration)], total: Duration) {
    let graphs: Vec<_> = output
        .graphs
        .iter()
        .zip(adjoints)
        .map(|(g, (adj, adj_time))| {
            let params: Vec<_> = g
                .info
                .params
                .iter()
                .map(|p| {
                    let (kind, min, max) = match p.kind {
                        ParamKind::Continuous { min, max } => ("continuous", min as f64, max as f64),
                        ParamKind::Discrete { min, max } => ("discrete", min as f64, max as f64),
                        ParamKind::Color => ("color", 0.0, 1.0),
                    };
                    json!({"name": p.name, "kind": kind, "min": min, "max": max, "default": p.default, "slot": p.slot, "doc": p.doc})
                })
                .collect();
            json!({
                "name": g.info.name,
                "category": g.info.category,
                "description": g.info.description,
                "file": g.info.file,
                "params": params,
                "ir": {
                    "requested_nodes": g.stats.requested_nodes,
                    "lowering_work": g.stats.lowering_work,
                    "nodes_before_dce": g.stats.nodes_before_dce,
                    "forward_ops": g.forward.op_count(),
                    "adjoint_ops": adj.program.op_count(),
                },
                "lower_ms": g.stats.lower_time.as_secs_f64() * 1e3,
                "adjoint_ms": adj_time.as_secs_f64() * 1e3,
            })
        })
        .collect();
    let diagnostics: Vec<_> = output
        .diagnostics
        .iter()
        .map(|d| {
            let (line, col) = output.sources.line_col(d.file, d.span.start);
            json!({
                "severity": if d.is_error() { "error" } else { "warning" },
                "file": output.sources.name(d.file),
                "line": line,
                "column": col,
                "span": [d.span.start, d.span.end],
                "message": d.message,
                "hint": d.hint,
                "rendered": d.render(&output.sources),
            })
        })
        .collect();
    let files: Vec<_> = output.files.iter().map(|(p, ok)| json!({"path": p, "ok": ok})).collect();
    let doc =
        json!({"graphs": graphs, "diagnostics": diagnostics, "files": files, "total_ms": total.as_secs_f64() * 1e3});
    println!("{}", serde_json::to_string_pretty(&doc).unwrap_or_default());
}
