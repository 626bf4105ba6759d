//! Progress reporting without a terminal: long operations (renders, light grids, mesh loading,
//! bakes, fits) report stages, totals and increments to a [`Progress`] their caller passes in;
//! only the command line draws (bars on a terminal, lines in a log).
//!
//! Implementations are called from worker threads (`Sync`), must be cheap (an atomic add per
//! call is the expected cost) and must never affect results.

/// Receives the progress of long operations.
pub trait Progress: Sync {
    /// A stage begins: `stage` names it ("render", "light grid", "loading mesh"), `total` is its
    /// amount of work in `unit`s ("samples", "cells", "bytes"), or None when unknown.
    fn start(&self, _stage: &str, _total: Option<u64>, _unit: &str) {}
    /// `n` more units of the current stage are done (from any thread).
    fn advance(&self, _n: u64) {}
    /// The current stage is done.
    fn finish(&self) {}
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// Runs `f` as the stage `stage` of `progress` (start, then finish even on early return).
pub fn stage<T>(progress: &dyn Progress, stage: &str, total: Option<u64>, unit: &str, f: impl FnOnce() -> T) -> T {
    struct Finish<'a>(&'a dyn Progress);
    impl Drop for Finish<'_> {
        fn drop(&mut self) {
            self.0.finish();
        }
    }
    progress.start(stage, total, unit);
    let _finish = Finish(progress);
    f()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Mutex;

    #[derive(Default)]
    struct Log {
        events: Mutex<Vec<String>>,
        done: AtomicU64,
    }

    impl Progress for Log {
        fn start(&self, stage: &str, total: Option<u64>, unit: &str) {
            self.events.lock().unwrap().push(format!("start {stage} {total:?} {unit}"));
        }
        fn advance(&self, n: u64) {
            self.done.fetch_add(n, Ordering::Relaxed);
        }
        fn finish(&self) {
            self.events.lock().unwrap().push("finish".into());
        }
    }

    #[test]
    fn a_stage_finishes_even_on_early_return() {
        let log = Log::default();
        let r: Result<(), &str> = stage(&log, "load", Some(10), "bytes", || {
            log.advance(4);
            Err("bad")
        });
        assert!(r.is_err());
        assert_eq!(*log.events.lock().unwrap(), ["start load Some(10) bytes", "finish"]);
        assert_eq!(log.done.load(Ordering::Relaxed), 4);
        NoProgress.advance(3); // a no-op
    }
}
