//! `psc bench`: JIT against interpreter, forward and forward+adjoint, on a size×size grid.
//!
//! Benchmarks the graphs of the given files at their defaults or, without any, a seeded
//! synthetic material-like program of about `--synthetic` ops. Timings are the best of
//! `--runs` runs (a shared machine is noisy); both the JIT and the interpreter run on all rayon
//! threads over the same chunks.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use psc_compiler::diff::reverse;
use psc_compiler::interp;
use psc_compiler::ir::{random, Program};
use psc_compiler::Adjoint;
use psc_jit::{CompiledKernel, OptLevel, Options};
use psc_runtime::kernel::{chunk_ranges, grid_uv, run_chunked, Gradients, Kernel};
use rayon::prelude::*;

use crate::Failure;

#[derive(clap::Args)]
pub struct Args {
    /// .psg files or folders to benchmark (each graph at its defaults); without any, a
    /// synthetic program is benchmarked.
    pub paths: Vec<std::path::PathBuf>,
    /// Grid side: size×size texels per evaluation.
    #[arg(long, default_value_t = 512, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub size: usize,
    /// Ops in the synthetic workload (at most 65 536).
    #[arg(long, default_value_t = 300, value_parser = parse_synthetic)]
    pub synthetic: usize,
    /// Seed of the synthetic workload generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Timed runs per measurement; the best is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub runs: usize,
    /// Also compare code generation variants (cranelift opt level × vectors per iteration ×
    /// instruction scheduling).
    #[arg(long)]
    pub variants: bool,
}

/// One benchmarked program.
#[derive(Clone, Debug)]
pub struct BenchRow {
    pub name: String,
    pub ops: usize,
    pub adjoint_ops: Option<usize>,
    pub compile: Duration,
    pub adjoint_compile: Option<Duration>,
    /// Best times for one size×size evaluation.
    pub jit_forward: Duration,
    pub interp_forward: Duration,
    pub jit_adjoint: Option<Duration>,
    pub interp_adjoint: Option<Duration>,
    pub texels: usize,
    /// Floating-point operations per texel of the forward kernel (FMA = 2).
    pub flops_per_texel: usize,
}

impl BenchRow {
    fn mtexels(&self, t: Duration) -> f64 {
        self.texels as f64 / t.as_secs_f64() / 1e6
    }
    pub fn forward_gflops(&self) -> f64 {
        (self.flops_per_texel * self.texels) as f64 / self.jit_forward.as_secs_f64() / 1e9
    }
}

pub fn run(args: Args) -> Result<ExitCode, crate::Error> {
    // Interpreter and JIT both hold size² texels of every channel: the bake's limit applies.
    crate::checks::bake_size("--size", args.size)?;
    if !args.paths.is_empty() {
        return Ok(bench_graphs(&args)?);
    }
    let forward = random::material_like(args.synthetic, args.seed);
    let wrt: Vec<u32> = (0..forward.num_params as u32).collect();
    let adjoint = reverse::adjoint(&forward, &wrt);
    let name = format!("synthetic-{}#{}", args.synthetic, args.seed);
    let params = bench_params(forward.num_params);
    let row = bench_program_runs(&name, &forward, Some(&adjoint), &params, args.size, args.runs)?;
    print_table(&[row], args.size);
    if args.variants {
        print_variants("forward", &forward, args.size, args.runs)?;
        print_variants("forward+adjoint", &adjoint.program, args.size, args.runs)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Every graph of the given files at its default parameters, adjoint over its continuous ones.
fn bench_graphs(args: &Args) -> Result<ExitCode, Failure> {
    let files = crate::compile::collect_sources(&args.paths)?;
    let output = psc_compiler::compile_files(&files, &psc_compiler::Options::default());
    if output.has_errors() {
        eprint!("{}", output.render_diagnostics());
        return Ok(ExitCode::from(1));
    }
    let mut rows = Vec::new();
    for g in &output.graphs {
        let adjoint = g.adjoint();
        let params = g.info.default_params();
        rows.push(bench_program_runs(&g.info.name, &g.forward, Some(&adjoint), &params, args.size, args.runs)?);
        if args.variants {
            print_variants(&format!("{} forward", g.info.name), &g.forward, args.size, args.runs)?;
            print_variants(&format!("{} forward+adjoint", g.info.name), &adjoint.program, args.size, args.runs)?;
        }
        eprintln!("benchmarked {}", g.info.name);
    }
    print_table(&rows, args.size);
    Ok(ExitCode::SUCCESS)
}

fn bench_program_runs(
    name: &str,
    forward: &Program,
    adjoint: Option<&Adjoint>,
    params: &[f32],
    size: usize,
    runs: usize,
) -> Result<BenchRow, Failure> {
    let kernel = match adjoint {
        Some(a) => Kernel::with_adjoint(forward.clone(), a.clone())?,
        None => Kernel::new(forward.clone())?,
    };
    let (u, v) = grid_uv(size, size)?;
    let n = u.len();

    let seeds: Vec<Vec<f32>> = match adjoint {
        Some(_) => (0..forward.outputs.len()).map(|o| vec![1.0 / (o + 1) as f32; n]).collect(),
        None => Vec::new(),
    };
    let seed_refs: Vec<&[f32]> = seeds.iter().map(|s| &s[..]).collect();
    // The four measurements take turns within each run, so a burst of load from elsewhere on
    // a shared machine hits JIT and interpreter alike instead of skewing their ratio.
    // Output columns are reused across runs (`eval_into`, `adjoint_into`), as a caller
    // evaluating repeatedly would: fresh columns cost a page fault per 4 KiB on first write,
    // which for cheap graphs takes as long as the kernel itself.
    let (mut values, mut gradients) = (Vec::new(), Gradients::default());
    kernel.eval_into(params, &u, &v, &mut values)?;
    if adjoint.is_some() {
        kernel.adjoint_into(params, &u, &v, &seed_refs, &mut gradients)?;
    }
    let mut best = [Duration::MAX; 4];
    for _ in 0..runs.max(1) {
        best[0] = best[0].min(time(|| kernel.eval_into(params, &u, &v, &mut values))?);
        best[1] = best[1].min(time(|| {
            interp_chunked(forward, params, &u, &v, &[]);
            Ok::<_, Failure>(())
        })?);
        if let Some(adj) = adjoint {
            best[2] = best[2].min(time(|| kernel.adjoint_into(params, &u, &v, &seed_refs, &mut gradients))?);
            best[3] = best[3].min(time(|| {
                interp_chunked(&adj.program, params, &u, &v, &seed_refs);
                Ok::<_, Failure>(())
            })?);
        }
    }
    let [jit_forward, interp_forward, jit_adjoint, interp_adjoint] = best;
    let (jit_adjoint, interp_adjoint) = match adjoint {
        Some(_) => (Some(jit_adjoint), Some(interp_adjoint)),
        None => (None, None),
    };
    Ok(BenchRow {
        name: name.to_string(),
        ops: forward.op_count(),
        adjoint_ops: adjoint.map(|a| a.program.op_count()),
        compile: kernel.forward_jit().compile_time(),
        adjoint_compile: kernel.adjoint_jit().map(CompiledKernel::compile_time),
        jit_forward,
        interp_forward,
        jit_adjoint,
        interp_adjoint,
        texels: n,
        flops_per_texel: kernel.forward_jit().flops_per_point(),
    })
}

/// Deterministic, unremarkable parameter values.
fn bench_params(n: usize) -> Vec<f32> {
    (0..n).map(|i| 0.3 + 0.37 * ((i * 7) % 11) as f32 / 11.0).collect()
}

fn time<E>(f: impl FnOnce() -> Result<(), E>) -> Result<Duration, E> {
    let t = Instant::now();
    f()?;
    Ok(t.elapsed())
}

fn best_of<E>(runs: usize, mut f: impl FnMut() -> Result<(), E>) -> Result<Duration, E> {
    let mut best = Duration::MAX;
    for _ in 0..runs {
        let t = Instant::now();
        f()?;
        best = best.min(t.elapsed());
    }
    Ok(best)
}

/// The interpreter over the same parallel chunks as the kernel layer; results discarded.
fn interp_chunked(program: &Program, params: &[f32], u: &[f32], v: &[f32], seeds: &[&[f32]]) {
    chunk_ranges(u.len()).for_each(|r| {
        let s: Vec<&[f32]> = seeds.iter().map(|col| &col[r.clone()]).collect();
        let out = interp::eval(program, params, &interp::Batch { u: &u[r.clone()], v: &v[r], seeds: &s });
        std::hint::black_box(out);
    });
}

/// Nominal peak: cores × 4 lanes × 2 flops per FMA × 1 FMA issued per cycle × clock.
fn nominal_peak() -> Option<(f64, usize, f64)> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let mhz: f64 = info.lines().find(|l| l.starts_with("cpu MHz"))?.split(':').nth(1)?.trim().parse().ok()?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    Some((cores as f64 * 4.0 * 2.0 * mhz / 1e3, cores, mhz / 1e3))
}

fn ms(t: Duration) -> String {
    format!("{:.1}", t.as_secs_f64() * 1e3)
}

pub fn print_table(rows: &[BenchRow], size: usize) {
    let threads = rayon::current_num_threads();
    println!(
        "psc bench: {size}x{size} texels, best of several runs, {threads} rayon threads for JIT and interpreter alike"
    );
    println!(
        "{:<20} {:>6} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>7} {:>8} {:>9} {:>7}",
        "program",
        "ops",
        "adj ops",
        "compile",
        "JIT fwd",
        "interp",
        "JIT/int",
        "JIT f+a",
        "interp",
        "JIT/int",
        "f+a/fwd",
        "flop/tex",
        "GFLOP/s"
    );
    println!(
        "{:<20} {:>6} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>7} {:>8} {:>9} {:>7}",
        "", "", "", "ms f/a", "Mtex/s", "Mtex/s", "fwd", "Mtex/s", "Mtex/s", "f+a", "time", "", ""
    );
    for r in rows {
        let (jf, inf) = (r.mtexels(r.jit_forward), r.mtexels(r.interp_forward));
        let compile = match r.adjoint_compile {
            Some(a) => format!("{}/{}", ms(r.compile), ms(a)),
            None => ms(r.compile),
        };
        let (ja, ia, ra, fa) = match (r.jit_adjoint, r.interp_adjoint) {
            (Some(j), Some(i)) => (
                format!("{:.1}", r.mtexels(j)),
                format!("{:.2}", r.mtexels(i)),
                format!("{:.1}x", i.as_secs_f64() / j.as_secs_f64()),
                format!("{:.2}x", j.as_secs_f64() / r.jit_forward.as_secs_f64()),
            ),
            _ => ("-".into(), "-".into(), "-".into(), "-".into()),
        };
        println!(
            "{:<20} {:>6} {:>7} {:>9} {:>9.1} {:>9.2} {:>8.1}x {:>9} {:>7} {:>7} {:>8} {:>9} {:>7.1}",
            r.name,
            r.ops,
            r.adjoint_ops.map_or("-".into(), |n| n.to_string()),
            compile,
            jf,
            inf,
            jf / inf,
            ja,
            ia,
            ra,
            fa,
            r.flops_per_texel,
            r.forward_gflops()
        );
    }
    match nominal_peak() {
        Some((peak, cores, ghz)) => {
            let best = rows.iter().map(BenchRow::forward_gflops).fold(0.0, f64::max);
            println!(
                "nominal peak {peak:.1} GFLOP/s = {cores} cores x 4 lanes x 2 flops/FMA x {ghz:.2} GHz (nominal clock from /proc/cpuinfo); best forward reaches {:.0}% of it",
                100.0 * best / peak
            );
        }
        None => println!("nominal peak unknown (no cpu MHz in /proc/cpuinfo)"),
    }
}

/// Throughput of each code generation variant, on the same chunks as the kernel layer.
fn print_variants(what: &str, program: &Program, size: usize, runs: usize) -> Result<(), Failure> {
    let (u, v) = grid_uv(size, size)?;
    let params = bench_params(program.num_params);
    let seeds: Vec<Vec<f32>> = (0..program.num_seeds).map(|_| vec![0.5; u.len()]).collect();
    let seed_refs: Vec<&[f32]> = seeds.iter().map(|s| &s[..]).collect();
    println!("code generation variants ({what}, {} ops):", program.op_count());
    let scheduled = Options::default().schedule;
    let variants = [OptLevel::None, OptLevel::Speed]
        .into_iter()
        .flat_map(|opt_level| [1, 2, 4].map(move |groups| (opt_level, groups)))
        .flat_map(|(opt_level, groups)| {
            [None, scheduled].map(move |schedule| Options { opt_level, groups, schedule, ..Options::default() })
        });
    for options in variants {
        let Options { opt_level, groups, schedule, .. } = options;
        let k = psc_jit::compile_with(program, &options)?;
        let mut outs = Vec::new();
        let t = best_of(runs, || run_chunked(&k, &params, &u, &v, &seed_refs, &mut outs))?;
        println!(
            "  opt_level={:<5} vectors/iter={groups} scheduled={:<5}: {:>8.1} Mtexels/s  compile {:>7} ms",
            format!("{opt_level:?}").to_lowercase(),
            schedule.is_some(),
            u.len() as f64 / t.as_secs_f64() / 1e6,
            ms(k.compile_time())
        );
    }
    Ok(())
}

/// A synthetic workload's op count, bounded by memory: 65 536 ops compile and run in about
/// 6 s and 0.8 GB.
fn parse_synthetic(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n @ 1..=65536) => Ok(n),
        Ok(n) => Err(format!("expected 1 to 65536 ops, got {n}")),
        Err(e) => Err(format!("{e}")),
    }
}
