//! Outputs that appear whole or not at all: one atomic single-file write and one staged output
//! folder, used by every command that writes files (render, bake, library, fit).
//!
//! * [`write_atomic`] / [`write_atomic_with`]: the bytes go to a temporary file in the
//!   destination's folder, are synced to disk, and the temporary is renamed over the
//!   destination. A reader sees the old file or the new one, never half of one.
//! * [`StagedDir`]: a folder of outputs is built in a temporary sibling of the destination and
//!   renamed into place by [`StagedDir::commit`]. An existing destination is refused unless
//!   replacement was asked for ([`Replace::Yes`], `--force` on the command line); then the old
//!   folder is moved aside, the new one renamed in, and the old one removed, so the destination
//!   never holds a mix of old and new files.
//!
//! Temporaries never outlive the process that made them, except after SIGKILL:
//! * on error and on drop without commit they are removed;
//! * every live temporary is in a process-wide registry; SIGINT and SIGTERM run a handler (the
//!   `ctrlc` crate: it turns the signal into a call on its own thread, so the handler may take
//!   locks and remove folders, which a raw signal handler may not) that removes them and exits
//!   with status 130. psc-base owns the process's SIGINT/SIGTERM handler: a program that needs
//!   another must not install one with `ctrlc` itself;
//! * a program that ends on another signal calls [`stop_and_remove_temporaries`] first (psc does
//!   on SIGPIPE: a thread that writes to a closed pipe is held in the signal handler while another
//!   thread removes the temporaries, then the process ends by SIGPIPE);
//! * after SIGKILL nothing can run: temporaries have hidden names that say whose they are
//!   (`.psc-tmp-<pid>-<n>-<name>`), and the next [`StagedDir::new`] or atomic write to the same
//!   destination removes those whose process is gone (Linux: no `/proc/<pid>`).

use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, Once};

/// What a staged output does when its destination exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Replace {
    /// Refuse (the default of every command).
    No,
    /// Replace it whole (`--force`).
    Yes,
}

/// Why an output could not be written.
#[derive(Debug)]
pub enum OutputError {
    /// The destination exists and replacement was not asked for.
    Exists(PathBuf),
    /// The destination exists but is not a folder (or not a file) as the output would be.
    WrongKind { path: PathBuf, expected: &'static str },
    /// A folder on the way to the destination is a file (`--out notes.txt/out`).
    FileInPath { file: PathBuf, dest: PathBuf },
    /// An I/O error on `path`.
    Io { path: PathBuf, error: io::Error },
}

impl OutputError {
    fn io(path: &Path, error: io::Error) -> Self {
        OutputError::Io { path: path.to_path_buf(), error }
    }
}

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OutputError::Exists(p) => write!(
                f,
                "{}: already exists; refusing to overwrite it (ask for replacement, e.g. --force, or choose another path)",
                p.display()
            ),
            OutputError::WrongKind { path, expected } => {
                write!(f, "{}: exists and is not {expected}; refusing to replace it", path.display())
            }
            OutputError::FileInPath { file, dest } => write!(
                f,
                "{}: is a file, not a folder, so {} cannot be written inside it",
                file.display(),
                dest.display()
            ),
            OutputError::Io { path, error } => write!(f, "{}: {error}", path.display()),
        }
    }
}

impl std::error::Error for OutputError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            OutputError::Io { error, .. } => Some(error),
            _ => None,
        }
    }
}

impl From<OutputError> for io::Error {
    fn from(e: OutputError) -> io::Error {
        let kind = match &e {
            OutputError::Exists(_) | OutputError::WrongKind { .. } => io::ErrorKind::AlreadyExists,
            OutputError::FileInPath { .. } => io::ErrorKind::NotADirectory,
            OutputError::Io { error, .. } => error.kind(),
        };
        io::Error::new(kind, e.to_string())
    }
}

/// Prefix of every temporary name.
const TMP_PREFIX: &str = ".psc-tmp-";

/// Live temporaries of this process, by id.
static LIVE: Mutex<BTreeMap<u64, PathBuf>> = Mutex::new(BTreeMap::new());
static NEXT_ID: AtomicU64 = AtomicU64::new(0);
static HANDLER: Once = Once::new();
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit status after SIGINT or SIGTERM (128 + SIGINT, the shell convention).
pub const INTERRUPTED_EXIT_CODE: i32 = 130;

fn install_handler() {
    HANDLER.call_once(|| {
        // If another handler is already installed (a program that ignored the note in the
        // module docs), temporaries are still removed on error, on drop and by the next run.
        let _ = ctrlc::set_handler(|| {
            stop_and_remove_temporaries();
            std::process::exit(INTERRUPTED_EXIT_CODE);
        });
    });
}

/// True once SIGINT or SIGTERM has arrived (the process is about to exit with
/// [`INTERRUPTED_EXIT_CODE`]), or the program is ending on another signal
/// ([`stop_and_remove_temporaries`]): long loops may stop early.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// What the SIGINT/SIGTERM handler does before it exits, for a program that ends the process on
/// another signal itself (psc on SIGPIPE, when the reader of its output has gone): from now on
/// [`interrupted`] is true, so a writer whose temporary vanishes waits for the end instead of
/// racing it with an error of its own, and every registered temporary is removed. The caller
/// then ends the process, from a thread that may take locks (not a raw signal handler).
pub fn stop_and_remove_temporaries() {
    INTERRUPTED.store(true, Ordering::SeqCst);
    remove_live_temporaries();
}

/// Remove every registered temporary now (what the SIGINT/SIGTERM handler does). Writers still
/// running may recreate files meanwhile, so folders get a few attempts.
pub fn remove_live_temporaries() {
    let live = match LIVE.lock() {
        Ok(g) => g.clone(),
        Err(poisoned) => poisoned.into_inner().clone(),
    };
    for path in live.values() {
        remove_any(path);
    }
}

fn remove_any(path: &Path) {
    let Ok(meta) = std::fs::symlink_metadata(path) else { return };
    if !meta.is_dir() {
        let _ = std::fs::remove_file(path);
        return;
    }
    // A writer may still be creating files in the folder. Renaming it first makes its path
    // vanish at once (new files fail to be created), so the removal below cannot race with new
    // entries; the new name is a temporary name of the same destination, so if this process
    // dies now the next run still recognises it.
    let target = match (path.parent(), path.file_name().and_then(|n| n.to_str())) {
        (Some(dir), Some(name)) => {
            let tail = name.strip_prefix(TMP_PREFIX).and_then(|r| r.splitn(3, '-').nth(2)).unwrap_or(name);
            let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
            let dead = dir.join(format!("{TMP_PREFIX}{}-{id}-{tail}", std::process::id()));
            if std::fs::rename(path, &dead).is_ok() {
                dead
            } else {
                path.to_path_buf()
            }
        }
        _ => path.to_path_buf(),
    };
    for attempt in 0..50 {
        match std::fs::remove_dir_all(&target) {
            Ok(()) => return,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return,
            Err(_) => std::thread::sleep(std::time::Duration::from_millis(1 + attempt / 10)),
        }
    }
}

/// A registered temporary path: removed when dropped unless disarmed.
struct Temporary {
    id: u64,
    path: PathBuf,
    armed: bool,
}

impl Temporary {
    /// A fresh temporary name beside `dest` (same folder, so the final rename stays on one file
    /// system), registered for removal on interrupt. Also removes stale temporaries of `dest`
    /// left by killed processes.
    fn beside(dest: &Path) -> Result<Temporary, OutputError> {
        let (dir, name) = split(dest)?;
        remove_stale(&dir, &name);
        install_handler();
        let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!("{TMP_PREFIX}{}-{id}-{name}", std::process::id()));
        let mut live = LIVE.lock().unwrap_or_else(|p| p.into_inner());
        live.insert(id, path.clone());
        Ok(Temporary { id, path, armed: true })
    }

    /// Forget the temporary (it has been renamed into place).
    fn disarm(mut self) {
        self.armed = false;
        LIVE.lock().unwrap_or_else(|p| p.into_inner()).remove(&self.id);
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if self.armed && interrupted() {
            // The signal handler is removing the temporaries, so writers into them now fail;
            // a failing writer reaches this drop on its way out. Wait for the handler's exit
            // (status 130) instead of racing it to an exit of our own with a misleading error.
            loop {
                std::thread::park();
            }
        }
        if self.armed {
            remove_any(&self.path);
            LIVE.lock().unwrap_or_else(|p| p.into_inner()).remove(&self.id);
        }
    }
}

/// Refuse a destination inside a file: the nearest existing folder on the way to `dest` must
/// be a folder, not a file (else creating folders fails with "File exists" and files with "Not a
/// directory", naming neither the file nor why). Commands may call it before any work.
pub fn check_parents(dest: &Path) -> Result<(), OutputError> {
    for above in dest.ancestors().skip(1).filter(|a| !a.as_os_str().is_empty()) {
        // Paths below a file fail with "not a directory": go up to the first that exists.
        if let Ok(meta) = std::fs::metadata(above) {
            if meta.is_dir() {
                return Ok(());
            }
            return Err(OutputError::FileInPath { file: above.to_path_buf(), dest: dest.to_path_buf() });
        }
    }
    Ok(())
}

/// (folder, file name) of a destination path.
fn split(dest: &Path) -> Result<(PathBuf, String), OutputError> {
    let name =
        dest.file_name().and_then(|n| n.to_str()).filter(|n| !n.is_empty() && *n != "." && *n != "..").ok_or_else(
            || OutputError::io(dest, io::Error::new(io::ErrorKind::InvalidInput, "not a file or folder name")),
        )?;
    let dir = match dest.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Ok((dir, name.to_string()))
}

/// Whether process `pid` still runs (Linux: `/proc/<pid>`; elsewhere assume it does, so
/// nothing of another live process is ever removed).
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

/// Remove `dir/.psc-tmp-<pid>-<n>-<name>` entries whose process is gone.
fn remove_stale(dir: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let Some(s) = file_name.to_str() else { continue };
        let Some(rest) = s.strip_prefix(TMP_PREFIX) else { continue };
        let mut parts = rest.splitn(3, '-');
        let (Some(pid), Some(n), Some(tail)) = (parts.next(), parts.next(), parts.next()) else { continue };
        if tail != name || n.parse::<u64>().is_err() {
            continue;
        }
        if let Ok(pid) = pid.parse::<u32>() {
            if !process_alive(pid) {
                remove_any(&entry.path());
            }
        }
    }
}

fn sync_dir(dir: &Path) {
    // Makes the rename durable; not every platform can open a folder for syncing.
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Write `bytes` to `path` atomically (see the module docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic_with(path, |tmp| {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all(bytes)?;
        f.flush()
    })
}

/// Like [`write_atomic`], for writers that want a path: `write` creates the file at the
/// temporary path it is given (its name ends with the destination's name, so encoders that go
/// by the extension pick the right format). The file is then synced and renamed into place.
pub fn write_atomic_with(path: &Path, write: impl FnOnce(&Path) -> io::Result<()>) -> Result<(), OutputError> {
    if path.is_dir() {
        return Err(OutputError::WrongKind { path: path.to_path_buf(), expected: "a file" });
    }
    check_parents(path)?;
    let tmp = Temporary::beside(path)?;
    write(&tmp.path).map_err(|e| OutputError::io(path, e))?;
    let f = std::fs::File::open(&tmp.path).map_err(|e| OutputError::io(path, e))?;
    f.sync_all().map_err(|e| OutputError::io(path, e))?;
    drop(f);
    std::fs::rename(&tmp.path, path).map_err(|e| OutputError::io(path, e))?;
    tmp.disarm();
    if let Some(dir) = path.parent() {
        sync_dir(if dir.as_os_str().is_empty() { Path::new(".") } else { dir });
    }
    Ok(())
}

/// An output folder being built (see the module docs). Write into [`StagedDir::path`], then
/// [`StagedDir::commit`]; dropping it uncommitted removes everything written.
pub struct StagedDir {
    dest: PathBuf,
    tmp: Temporary,
    replace: Replace,
}

impl StagedDir {
    /// Start building the folder `dest`. Fails at once when `dest` exists and `replace` is
    /// [`Replace::No`] (or is not a folder), so no work is wasted on an output that would be
    /// refused. The parent folder is created if needed.
    pub fn new(dest: &Path, replace: Replace) -> Result<StagedDir, OutputError> {
        check_parents(dest)?;
        check_destination(dest, replace)?;
        let (dir, _) = split(dest)?;
        std::fs::create_dir_all(&dir).map_err(|e| OutputError::io(&dir, e))?;
        let tmp = Temporary::beside(dest)?;
        std::fs::create_dir(&tmp.path).map_err(|e| OutputError::io(dest, e))?;
        Ok(StagedDir { dest: dest.to_path_buf(), tmp, replace })
    }

    /// The folder to write into (a temporary until [`StagedDir::commit`]).
    pub fn path(&self) -> &Path {
        &self.tmp.path
    }

    /// Where the folder will be.
    pub fn destination(&self) -> &Path {
        &self.dest
    }

    /// Put the folder in place: every file written so far is synced, then the folder is renamed
    /// to the destination (replacing an existing one whole when asked for).
    pub fn commit(self) -> Result<PathBuf, OutputError> {
        let StagedDir { dest, tmp, replace } = self;
        sync_tree(&tmp.path).map_err(|e| OutputError::io(&dest, e))?;
        check_destination(&dest, replace)?;
        if std::fs::symlink_metadata(&dest).is_ok() {
            // Move the old folder aside under a temporary name (removed below, or by the next
            // run if this process is killed in between), then rename the new one in.
            let old = Temporary::beside(&dest)?;
            std::fs::rename(&dest, &old.path).map_err(|e| OutputError::io(&dest, e))?;
            if let Err(e) = std::fs::rename(&tmp.path, &dest) {
                // Put the old folder back: the destination keeps what it had.
                let _ = std::fs::rename(&old.path, &dest);
                old.disarm();
                return Err(OutputError::io(&dest, e));
            }
            drop(old); // removes the old folder
        } else {
            std::fs::rename(&tmp.path, &dest).map_err(|e| OutputError::io(&dest, e))?;
        }
        tmp.disarm();
        if let Some(dir) = dest.parent() {
            sync_dir(if dir.as_os_str().is_empty() { Path::new(".") } else { dir });
        }
        Ok(dest)
    }
}

/// Refuse an existing destination unless replacement was asked for, and then only a folder.
fn check_destination(dest: &Path, replace: Replace) -> Result<(), OutputError> {
    match std::fs::symlink_metadata(dest) {
        Err(_) => Ok(()),
        Ok(m) => match replace {
            Replace::No => Err(OutputError::Exists(dest.to_path_buf())),
            Replace::Yes if m.is_dir() => Ok(()),
            Replace::Yes => Err(OutputError::WrongKind { path: dest.to_path_buf(), expected: "a folder" }),
        },
    }
}

/// Sync every regular file under `dir`, and the folders themselves.
fn sync_tree(dir: &Path) -> io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let t = entry.file_type()?;
        if t.is_dir() {
            sync_tree(&entry.path())?;
        } else if t.is_file() {
            std::fs::File::open(entry.path())?.sync_all()?;
        }
    }
    sync_dir(dir);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_parse_back() {
        let tmp = tempfile::Builder::new().prefix("psc-base-names-").tempdir().unwrap();
        let dir = tmp.path();
        // A temporary of a process that cannot exist (pid above Linux's maximum) is stale; ours
        // and other names are not touched.
        let stale = dir.join(format!("{TMP_PREFIX}4194305-3-out"));
        let ours = dir.join(format!("{TMP_PREFIX}{}-3-out", std::process::id()));
        let other = dir.join(format!("{TMP_PREFIX}4194305-3-other"));
        for p in [&stale, &ours, &other] {
            std::fs::create_dir(p).unwrap();
        }
        remove_stale(dir, "out");
        if cfg!(target_os = "linux") {
            assert!(!stale.exists());
        }
        assert!(ours.exists() && other.exists());
        tmp.close().unwrap();
    }
}
