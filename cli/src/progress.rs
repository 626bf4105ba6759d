//! The command line's progress drawer: the libraries report stages and increments through
//! `psc_base::progress::Progress`; this draws them on stderr.
//!
//! - On a terminal: an indicatif bar per stage (a spinner when the total is unknown), cleared
//!   when the stage ends.
//! - Otherwise (a log file, CI, a pipe): plain lines, one when a stage starts, one when it ends,
//!   and between them one each time it passes another 10% of its total (every 5 s when the
//!   total is unknown), but not within a second of the previous line (`PSC_PROGRESS_SECONDS`
//!   sets that interval), each with the time since the command started. A log shows that long
//!   work goes on without flooding it with the steps of quick stages.
//! - `--quiet`: nothing.
//!
//! Calls come from worker threads: `advance` costs an atomic add, plus a lock only when a line
//! is due.

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use psc_base::progress::Progress;

/// A line every this fraction of a stage's total, in the line log.
const LOG_STEPS: u64 = 10;
/// A line at most this often for stages of unknown length, in the line log.
const LOG_SECONDS_UNKNOWN: f64 = 5.0;
/// Progress lines of a stage at least this far apart, in seconds, unless `PSC_PROGRESS_SECONDS`
/// says otherwise.
const LOG_SECONDS_BETWEEN: f64 = 1.0;

enum Mode {
    Quiet,
    Bar(Mutex<Option<ProgressBar>>),
    Log(Mutex<LogStage>),
}

#[derive(Default)]
struct LogStage {
    name: String,
    unit: String,
    total: Option<u64>,
    started: Option<Instant>,
    /// The last progress line's step (tenths of the total) or time (unknown totals).
    last_step: u64,
    last_line: f64,
}

/// Draws progress on stderr (see the module docs).
pub struct Drawer {
    mode: Mode,
    /// Least time between two progress lines of the line log.
    between: f64,
    started: Instant,
    done: AtomicU64,
    /// The next count at which a log line is due (`u64::MAX`: none until the time check).
    next_line_at: AtomicU64,
}

impl Drawer {
    /// Bars on a terminal, lines otherwise, nothing when `quiet`.
    pub fn new(quiet: bool) -> Drawer {
        let mode = if quiet {
            Mode::Quiet
        } else if std::io::stderr().is_terminal() {
            Mode::Bar(Mutex::new(None))
        } else {
            Mode::Log(Mutex::new(LogStage::default()))
        };
        Drawer::with_mode(mode)
    }

    fn with_mode(mode: Mode) -> Drawer {
        let between = std::env::var("PSC_PROGRESS_SECONDS")
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .filter(|x| x.is_finite() && *x >= 0.0)
            .unwrap_or(LOG_SECONDS_BETWEEN);
        Drawer {
            mode,
            between,
            started: Instant::now(),
            done: AtomicU64::new(0),
            next_line_at: AtomicU64::new(u64::MAX),
        }
    }

    fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// A line of the log, or above the bar on a terminal (for notes such as "fitted part x").
    pub fn line(&self, text: &str) {
        match &self.mode {
            Mode::Quiet => {}
            Mode::Bar(bar) => match lock(bar).as_ref() {
                Some(b) => b.println(text),
                None => eprintln!("{text}"),
            },
            Mode::Log(_) => self.log(text),
        }
    }

    fn log(&self, text: &str) {
        let _ = writeln!(std::io::stderr(), "[{:>7.1} s] {text}", self.elapsed());
    }

    /// The count at which the next log line of a stage with `total` is due, after `step` tenths.
    fn due_at(total: u64, step: u64) -> u64 {
        if step >= LOG_STEPS {
            u64::MAX
        } else {
            (total as u128 * (step + 1) as u128).div_ceil(LOG_STEPS as u128).min(u64::MAX as u128) as u64
        }
    }

    fn log_progress(&self, done: u64) {
        let Mode::Log(stage) = &self.mode else { return };
        let mut s = lock(stage);
        let Some(started) = s.started else { return };
        let seconds = started.elapsed().as_secs_f64();
        match s.total {
            Some(total) if total > 0 => {
                let step = (done.min(total) as u128 * LOG_STEPS as u128 / total as u128) as u64;
                if step > s.last_step && step < LOG_STEPS && seconds - s.last_line >= self.between {
                    s.last_step = step;
                    s.last_line = seconds;
                    let text =
                        format!("{}: {}% ({done}/{total} {}, {seconds:.1} s)", s.name, step * 100 / LOG_STEPS, s.unit);
                    self.next_line_at.store(Self::due_at(total, step), Ordering::Relaxed);
                    drop(s);
                    self.log(&text);
                }
            }
            _ => {
                if seconds - s.last_line >= LOG_SECONDS_UNKNOWN {
                    s.last_line = seconds;
                    let text = format!("{}: {done} {} ({seconds:.1} s)", s.name, s.unit);
                    drop(s);
                    self.log(&text);
                }
            }
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Progress for Drawer {
    fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
        self.done.store(0, Ordering::Relaxed);
        match &self.mode {
            Mode::Quiet => {}
            Mode::Bar(bar) => {
                let b = ProgressBar::with_draw_target(total, ProgressDrawTarget::stderr());
                let template = match total {
                    Some(_) => {
                        format!("{{msg}} [{{bar:40}}] {{human_pos}}/{{human_len}} {unit} ({{elapsed}}, eta {{eta}})")
                    }
                    None => format!("{{spinner}} {{msg}} {{human_pos}} {unit} ({{elapsed}})"),
                };
                if let Ok(style) = ProgressStyle::with_template(&template) {
                    b.set_style(style.progress_chars("=> "));
                }
                b.set_message(stage.to_string());
                if total.is_none() {
                    b.enable_steady_tick(std::time::Duration::from_millis(200));
                }
                if let Some(old) = lock(bar).replace(b) {
                    old.finish_and_clear();
                }
            }
            Mode::Log(log) => {
                let mut s = lock(log);
                *s = LogStage {
                    name: stage.to_string(),
                    unit: unit.to_string(),
                    total,
                    started: Some(Instant::now()),
                    last_step: 0,
                    last_line: 0.0,
                };
                let due = match total {
                    Some(t) if t > 0 => Self::due_at(t, 0),
                    Some(_) => u64::MAX,
                    None => 0, // every call checks the time
                };
                self.next_line_at.store(due, Ordering::Relaxed);
                drop(s);
                match total {
                    Some(t) => self.log(&format!("{stage}: started ({t} {unit})")),
                    None => self.log(&format!("{stage}: started {unit}")),
                }
            }
        }
    }

    fn advance(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        match &self.mode {
            Mode::Quiet => {}
            Mode::Bar(bar) => {
                if let Some(b) = lock(bar).as_ref() {
                    b.inc(n);
                }
            }
            Mode::Log(_) => {
                if done >= self.next_line_at.load(Ordering::Relaxed) {
                    self.log_progress(done);
                }
            }
        }
    }

    fn finish(&self) {
        match &self.mode {
            Mode::Quiet => {}
            Mode::Bar(bar) => {
                if let Some(b) = lock(bar).take() {
                    b.finish_and_clear();
                }
            }
            Mode::Log(log) => {
                let mut s = lock(log);
                let Some(started) = s.started.take() else { return };
                let text = format!("{}: done in {:.1} s", s.name, started.elapsed().as_secs_f64());
                self.next_line_at.store(u64::MAX, Ordering::Relaxed);
                drop(s);
                self.log(&text);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_lines_fall_due_every_tenth() {
        assert_eq!(Drawer::due_at(100, 0), 10);
        assert_eq!(Drawer::due_at(100, 9), 100);
        assert_eq!(Drawer::due_at(100, 10), u64::MAX);
        assert_eq!(Drawer::due_at(7, 0), 1, "small totals still get their lines");
        assert_eq!(Drawer::due_at(u64::MAX, 5), (u64::MAX as u128 * 6).div_ceil(10) as u64);
    }

    #[test]
    fn a_quiet_drawer_takes_any_sequence_of_calls() {
        let d = Drawer::new(true);
        d.advance(5);
        d.finish();
        d.start("x", None, "units");
        d.advance(1);
        d.line("text");
        d.finish();
        d.finish();
    }
}
