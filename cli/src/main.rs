//! `psc`, the photoscene command line.
//!
//! Owns: argument parsing, progress display, exit codes. Must never: contain compiler,
//! rendering or kernel logic of its own — each command is a thin layer over the library crates.
//! Exit codes: 0 success, 1 a problem with the user's input (reported on stderr), 2 usage.

mod bake;
mod bench;
mod checks;
mod compile;
mod eval;
mod export;
mod fit;
mod library;
mod progress;
mod render;
mod report;

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
    /// Export a scene with its materials and lights as glTF 2.0 and as a Mitsuba 3 scene.
    Export(export::Args),
    /// Write report.html: one self-contained page showing a fit output.
    Report(report::Args),
}

/// Bad input (a file, a scene, a graph): worth showing to the user as is; exit 1.
pub struct Failure(pub String);

impl<E: std::fmt::Display> From<E> for Failure {
    fn from(e: E) -> Self {
        Failure(e.to_string())
    }
}

/// A command line that makes no sense (an option's value, or options that exclude each other):
/// exit 2, as for clap's own parse errors. The message names the option, what was expected and
/// what was given.
pub struct Usage(pub String);

/// Either kind of error, for commands that can give both.
pub enum Error {
    Input(Failure),
    Usage(Usage),
}

impl<E: std::fmt::Display> From<E> for Error {
    fn from(e: E) -> Self {
        Error::Input(Failure(e.to_string()))
    }
}

impl From<Failure> for Error {
    fn from(f: Failure) -> Self {
        Error::Input(f)
    }
}

impl From<Usage> for Error {
    fn from(u: Usage) -> Self {
        Error::Usage(u)
    }
}

/// Rust ignores SIGPIPE, so `psc library | head` would panic inside `println!` once the reader
/// goes away; a command-line tool should simply stop, as every Unix tool does. Stopping at once
/// (the default action) would leave the staged output folders and temporaries of
/// `psc_base::output` behind (`psc fit ... 2>&1 | head`: the progress log is on stderr), so the
/// handler only holds the writing thread and wakes `sigpipe_thread`, which removes them and
/// then ends the process by SIGPIPE after all, with the status a shell expects (141).
#[cfg(unix)]
mod sigpipe {
    use std::io::Read;
    use std::os::fd::IntoRawFd;
    use std::os::unix::net::UnixStream;
    use std::sync::atomic::{AtomicI32, Ordering};

    /// The write end of the wake-up channel (set before the handler is installed).
    static WAKE: AtomicI32 = AtomicI32::new(-1);

    extern "C" fn on_sigpipe(_: libc::c_int) {
        let fd = WAKE.load(Ordering::SeqCst);
        // SAFETY: `write` and `pause` are async-signal-safe; `fd` is the write end of a socket
        // pair that stays open for the life of the process, and the buffer is a live byte. The
        // thread never returns from here: the process ends by SIGPIPE from `sigpipe_thread`
        // (returning would hand `println!` an EPIPE to panic on).
        unsafe {
            libc::write(fd, [1u8].as_ptr().cast(), 1);
            loop {
                libc::pause();
            }
        }
    }

    /// Waits for the handler's byte, removes the temporaries, then dies by SIGPIPE.
    fn sigpipe_thread(mut wake: UnixStream) {
        let mut byte = [0u8; 1];
        if wake.read_exact(&mut byte).is_err() {
            return;
        }
        psc_base::output::stop_and_remove_temporaries();
        // SAFETY: restoring the default action and raising the signal on this thread (which
        // does not block it) ends the process as SIGPIPE always did; both are plain libc calls.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
            libc::raise(libc::SIGPIPE);
        }
        std::process::exit(128 + libc::SIGPIPE);
    }

    /// Called once at start-up, before any other thread exists. If the channel or the thread
    /// cannot be made, SIGPIPE gets its default action (stop at once, temporaries left for the
    /// next run to remove).
    pub fn install() {
        let handler = match UnixStream::pair() {
            Ok((read, write)) => {
                WAKE.store(write.into_raw_fd(), Ordering::SeqCst);
                match std::thread::Builder::new().name("sigpipe".into()).spawn(move || sigpipe_thread(read)) {
                    Ok(_) => on_sigpipe as extern "C" fn(libc::c_int) as libc::sighandler_t,
                    Err(_) => libc::SIG_DFL,
                }
            }
            Err(_) => libc::SIG_DFL,
        };
        // SAFETY: called once at start-up, before any thread but `sigpipe_thread` exists (which
        // does not touch signal dispositions until the handler has run); the handler is an
        // `extern "C"` function that only makes async-signal-safe calls, or SIG_DFL.
        unsafe {
            libc::signal(libc::SIGPIPE, handler);
        }
    }
}

#[cfg(unix)]
fn handle_sigpipe() {
    sigpipe::install();
}

#[cfg(not(unix))]
fn handle_sigpipe() {}

fn main() -> ExitCode {
    handle_sigpipe();
    let cli = Cli::parse();
    let result: Result<ExitCode, Error> = match cli.command {
        Command::Compile(args) => compile::run(args).map_err(Error::from),
        Command::Bench(args) => bench::run(args),
        Command::Bake(args) => bake::run(args),
        Command::Library(args) => library::run(args),
        Command::Render(args) => render::run(args),
        Command::Fit(args) => fit::run(args),
        Command::Eval(args) => eval::run(args).map_err(Error::from),
        Command::Export(args) => export::run(args),
        Command::Report(args) => report::run(args).map_err(Error::from),
    };
    match result {
        Ok(code) => code,
        Err(Error::Input(Failure(message))) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
        Err(Error::Usage(Usage(message))) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}
