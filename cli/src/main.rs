//! `psc`, the photoscene command line.
//!
//! Owns: argument parsing, progress display, exit codes. Must never: contain compiler,
//! rendering or kernel logic of its own — each command is a thin layer over the library crates.
//! Exit codes: 0 success, 1 a problem with the user's input (reported on stderr), 2 usage.

mod bake;
mod bench;
mod compile;
mod eval;
mod fit;
mod library;
mod render;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "psc", version, about = "photoscene: procedural materials and lighting fitted to photos")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check and compile .psg graphs; print parameters, IR sizes and compile times.
    Compile(compile::Args),
    /// Benchmark the JIT against the interpreter, forward and adjoint.
    Bench(bench::Args),
    /// Bake a graph's albedo, normal, roughness and height maps to image files.
    Bake(bake::Args),
    /// Compile the whole graph library; optionally write a contact sheet.
    Library(library::Args),
    /// Render a scene: path-traced images, G-buffers, per-pixel light grids.
    Render(render::Args),
    /// Fit a procedural material to every part of a scene from its photos.
    Fit(fit::Args),
    /// Evaluate a fit against a dev scene's ground truth, beside the baselines.
    Eval(eval::Args),
}

/// An error already worth showing to the user as is.
pub struct Failure(pub String);

impl<E: std::fmt::Display> From<E> for Failure {
    fn from(e: E) -> Self {
        Failure(e.to_string())
    }
}

/// Rust ignores SIGPIPE, so `psc library | head` would panic inside `println!` once the reader
/// goes away; a command-line tool should simply stop, as every Unix tool does.
#[cfg(unix)]
fn restore_default_sigpipe() {
    // SAFETY: called once at start-up, before any other thread exists; SIG_DFL is a valid handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn restore_default_sigpipe() {}

fn main() -> ExitCode {
    restore_default_sigpipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Compile(args) => compile::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Bake(args) => bake::run(args),
        Command::Library(args) => library::run(args),
        Command::Render(args) => render::run(args),
        Command::Fit(args) => fit::run(args),
        Command::Eval(args) => eval::run(args),
    };
    match result {
        Ok(code) => code,
        Err(Failure(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
    }
}
