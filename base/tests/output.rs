//! Outputs appear whole or not at all: failing writers, existing destinations, replacement, and
//! processes interrupted (SIGINT, SIGTERM) or killed (SIGKILL) in the middle of writing.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use psc_base::output::{write_atomic, write_atomic_with, OutputError, Replace, StagedDir};

fn temp_dir(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-base-output-{tag}-")).tempdir().unwrap()
}

/// Names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn atomic_write_replaces_whole_and_a_failing_writer_leaves_nothing() {
    let tmp = temp_dir("atomic");
    let dir = tmp.path();
    let p = dir.join("a.json");
    write_atomic(&p, b"first").unwrap();
    write_atomic(&p, b"second").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"second");
    let e = write_atomic_with(&p, |tmp| {
        std::fs::write(tmp, b"half")?;
        Err(std::io::Error::other("encoder failed"))
    })
    .unwrap_err();
    assert!(e.to_string().contains("encoder failed") && e.to_string().contains("a.json"), "{e}");
    assert_eq!(std::fs::read(&p).unwrap(), b"second", "the old file is untouched");
    assert_eq!(listing(dir), ["a.json"], "no temporary left");
    // The temporary keeps the destination's extension (encoders choose the format by it).
    write_atomic_with(&dir.join("b.png"), |tmp| {
        assert!(tmp.to_string_lossy().ends_with("b.png"), "{}", tmp.display());
        std::fs::write(tmp, b"png")
    })
    .unwrap();
    // A folder where a file should go is refused.
    std::fs::create_dir(dir.join("c.json")).unwrap();
    assert!(matches!(write_atomic(&dir.join("c.json"), b"x"), Err(OutputError::WrongKind { .. })));
}

#[test]
fn a_staged_folder_appears_only_on_commit_and_vanishes_on_drop() {
    let tmp = temp_dir("staged");
    let dir = tmp.path();
    let dest = dir.join("out");
    let staged = StagedDir::new(&dest, Replace::No).unwrap();
    std::fs::write(staged.path().join("a.exr"), b"a").unwrap();
    std::fs::create_dir(staged.path().join("sub")).unwrap();
    std::fs::write(staged.path().join("sub/b.json"), b"b").unwrap();
    assert!(!dest.exists(), "nothing at the destination before commit");
    staged.commit().unwrap();
    assert_eq!(listing(&dest), ["a.exr", "sub"]);
    assert_eq!(listing(dir), ["out"], "no temporary left");

    // A writer that fails half-way (the staged folder is dropped): nothing appears.
    let dest2 = dir.join("out2");
    let result: Result<(), String> = (|| {
        let staged = StagedDir::new(&dest2, Replace::No).map_err(|e| e.to_string())?;
        std::fs::write(staged.path().join("a.exr"), b"a").unwrap();
        Err("the second file failed".into())
    })();
    assert!(result.is_err());
    assert!(!dest2.exists());
    assert_eq!(listing(dir), ["out"], "the temporary was removed");
}

#[test]
fn an_existing_folder_is_refused_without_replace_and_replaced_whole_with_it() {
    let tmp = temp_dir("replace");
    let dir = tmp.path();
    let dest = dir.join("gbuf");
    std::fs::create_dir(&dest).unwrap();
    std::fs::write(dest.join("old_only.exr"), b"old").unwrap();
    std::fs::write(dest.join("shared.exr"), b"old").unwrap();

    let e = StagedDir::new(&dest, Replace::No).err().expect("refused");
    assert!(matches!(e, OutputError::Exists(_)));
    assert!(e.to_string().contains("already exists") && e.to_string().contains("--force"), "{e}");
    assert_eq!(listing(&dest), ["old_only.exr", "shared.exr"], "untouched");

    let staged = StagedDir::new(&dest, Replace::Yes).unwrap();
    std::fs::write(staged.path().join("shared.exr"), b"new").unwrap();
    std::fs::write(staged.path().join("new_only.exr"), b"new").unwrap();
    assert_eq!(listing(&dest), ["old_only.exr", "shared.exr"], "the old folder stays until commit");
    staged.commit().unwrap();
    assert_eq!(listing(&dest), ["new_only.exr", "shared.exr"], "no old file survives beside the new ones");
    assert_eq!(std::fs::read(dest.join("shared.exr")).unwrap(), b"new");
    assert_eq!(listing(dir), ["gbuf"]);

    // A file where the folder should go is not replaced even when asked.
    let file = dir.join("notes.txt");
    std::fs::write(&file, b"keep").unwrap();
    assert!(matches!(StagedDir::new(&file, Replace::Yes), Err(OutputError::WrongKind { .. })));
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
}

/// A destination below a file names the file and says it is not a folder (it said `f: File
/// exists (os error 17)`), and nothing is written, for a staged folder and an atomic file alike.
#[test]
fn a_file_on_the_way_to_the_destination_is_named() {
    let tmp = temp_dir("file-in-path");
    let dir = tmp.path();
    let file = dir.join("f");
    std::fs::write(&file, b"keep").unwrap();
    for dest in [file.join("out"), file.join("a/b/out")] {
        let e = StagedDir::new(&dest, Replace::No).err().expect("refused");
        assert!(matches!(&e, OutputError::FileInPath { file: f, .. } if *f == file), "{e}");
        let want = format!("{}: is a file, not a folder, so {} cannot", file.display(), dest.display());
        assert!(e.to_string().contains(&want), "{e}");
        let e = write_atomic(&dest.with_extension("png"), b"x").unwrap_err();
        assert!(e.to_string().contains(&format!("{}: is a file, not a folder", file.display())), "{e}");
    }
    assert_eq!(listing(dir), ["f"], "nothing written");
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    // A relative path whose first component is a file.
    let e = psc_base::output::check_parents(Path::new("Cargo.toml/out")).unwrap_err();
    assert_eq!(e.to_string(), "Cargo.toml: is a file, not a folder, so Cargo.toml/out cannot be written inside it");
}

/// Run in a child process by the tests below (ignored otherwise): stage a folder and an atomic
/// file write next to `PSC_OUTPUT_CHILD_DIR`, say "ready", then keep writing until killed.
#[test]
#[ignore = "run as a child process by the interruption tests"]
fn child_writes_until_killed() {
    let Some(dir) = std::env::var_os("PSC_OUTPUT_CHILD_DIR") else { return };
    let dir = PathBuf::from(dir);
    let staged = StagedDir::new(&dir.join("out"), Replace::No).unwrap();
    let mut i = 0u64;
    std::fs::write(staged.path().join("first.bin"), vec![1u8; 1 << 16]).unwrap();
    let _ = write_atomic_with(&dir.join("single.bin"), |tmp| {
        std::fs::write(tmp, vec![2u8; 1 << 16])?;
        println!("ready");
        loop {
            std::fs::write(staged.path().join(format!("f{}.bin", i % 8)), vec![3u8; 1 << 14])?;
            i += 1;
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    });
}

/// Start the child, wait for it to be mid-write, send `signal`, and return its exit status.
fn interrupt_child(dir: &Path, signal: &str) -> std::process::ExitStatus {
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_writes_until_killed", "--ignored", "--nocapture", "--test-threads", "1"])
        .env("PSC_OUTPUT_CHILD_DIR", dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    assert!(lines.any(|l| l.map(|l| l.contains("ready")).unwrap_or(false)), "the child never got ready");
    assert!(listing(dir).iter().any(|n| n.starts_with(".psc-tmp-")), "the child has temporaries: {:?}", listing(dir));
    let ok = Command::new("kill").args([signal, &child.id().to_string()]).status().unwrap();
    assert!(ok.success());
    child.wait().unwrap()
}

#[cfg(unix)]
#[test]
fn sigint_and_sigterm_remove_every_temporary() {
    use std::os::unix::process::ExitStatusExt;
    for signal in ["-INT", "-TERM"] {
        let tmp = temp_dir(&format!("signal{signal}"));
        let dir = tmp.path();
        let status = interrupt_child(dir, signal);
        assert_eq!(status.code(), Some(130), "{signal}: exit status {status:?} (signal {:?})", status.signal());
        assert_eq!(listing(dir), Vec::<String>::new(), "{signal}: nothing left behind");
    }
}

#[cfg(target_os = "linux")]
#[test]
fn temporaries_of_a_killed_process_are_removed_by_the_next_run() {
    let tmp = temp_dir("sigkill");
    let dir = tmp.path();
    let status = interrupt_child(dir, "-KILL");
    assert!(!status.success());
    let left = listing(dir);
    assert_eq!(left.len(), 2, "SIGKILL leaves the two temporaries: {left:?}");
    assert!(left.iter().all(|n| n.starts_with(".psc-tmp-")), "hidden, recognisable names: {left:?}");
    assert!(!dir.join("out").exists() && !dir.join("single.bin").exists(), "no partial output");
    // The next writer of the same outputs removes them.
    StagedDir::new(&dir.join("out"), Replace::No).unwrap().commit().unwrap();
    write_atomic(&dir.join("single.bin"), b"x").unwrap();
    assert_eq!(listing(dir), ["out", "single.bin"]);
}
