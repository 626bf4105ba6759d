//! Walking a folder tree for the files of one kind, safely on trees people assemble by hand.
//!
//! Symbolic links are followed (a library may link in a shared folder), but each real
//! directory is read once and each real file listed once, so a link back up the tree
//! (`a/up -> ..`) or a second name for a folder (`a/again -> ../a`) neither loops nor repeats
//! anything. "Real" means the same device and inode on Unix, the same canonical path
//! elsewhere. Where one file has several names, the one met first wins: a folder's own
//! entries before its subfolders', and within a folder real entries before links, each in
//! sorted order. So the choice is deterministic, and a file keeps its real name when that name
//! is met as early as a link to it. The result is sorted.

use std::collections::HashSet;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

/// Identity of a real file or directory, whatever the path that reached it.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum RealId {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg_attr(unix, allow(dead_code))]
    Canonical(PathBuf),
}

fn real_id(path: &Path, meta: &fs::Metadata) -> RealId {
    #[cfg(unix)]
    {
        let _ = path;
        use std::os::unix::fs::MetadataExt;
        RealId::Inode(meta.dev(), meta.ino())
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        RealId::Canonical(fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()))
    }
}

fn with_path(e: io::Error, path: &Path) -> io::Error {
    io::Error::new(e.kind(), format!("{}: {e}", path.display()))
}

/// Every file under `root` (recursively, following links) whose name ends in `.extension`,
/// each real file once, sorted. A link that leads nowhere but is named like a wanted file is
/// listed (reading it will then say what is wrong); any other entry that cannot be examined
/// is skipped. An unreadable folder is an error naming it.
pub fn files_with_extension(root: &Path, extension: &str) -> io::Result<Vec<PathBuf>> {
    let wanted = |p: &Path| p.extension().is_some_and(|e| e == extension);
    let root_meta = fs::metadata(root).map_err(|e| with_path(e, root))?;
    let mut seen: HashSet<RealId> = HashSet::from([real_id(root, &root_meta)]);
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let mut entries: Vec<(bool, PathBuf)> = fs::read_dir(&dir)
            .map_err(|e| with_path(e, &dir))?
            .map(|entry| {
                let path = entry?.path();
                let is_link = fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_symlink());
                Ok((is_link, path))
            })
            .collect::<io::Result<_>>()
            .map_err(|e| with_path(e, &dir))?;
        entries.sort();
        let mut subdirs = Vec::new();
        for (_, path) in entries {
            match fs::metadata(&path) {
                Ok(meta) => {
                    let new = seen.insert(real_id(&path, &meta));
                    if !new {
                        continue;
                    }
                    if meta.is_dir() {
                        subdirs.push(path);
                    } else if wanted(&path) {
                        out.push(path);
                    }
                }
                // A dangling link, or an entry that vanished: only a wanted name is reported.
                Err(_) if wanted(&path) => out.push(path),
                Err(_) => {}
            }
        }
        // Depth first, in sorted order: the stack pops the first subfolder next.
        stack.extend(subdirs.into_iter().rev());
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new().prefix(&format!("psc-walk-{name}-")).tempdir().unwrap()
    }

    #[test]
    fn lists_matching_files_recursively_and_sorted() {
        let tmp = scratch("plain");
        let dir = tmp.path();
        fs::create_dir_all(dir.join("b/c")).unwrap();
        for f in ["z.psg", "a.txt", "b/y.psg", "b/c/x.psg", "b/c/x.psg.bak"] {
            fs::write(dir.join(f), "").unwrap();
        }
        let got = files_with_extension(dir, "psg").unwrap();
        let want: Vec<PathBuf> = ["b/c/x.psg", "b/y.psg", "z.psg"].iter().map(|f| dir.join(f)).collect();
        assert_eq!(got, want);
        assert!(files_with_extension(&dir.join("missing"), "psg").unwrap_err().to_string().contains("missing"));
        tmp.close().unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn link_loops_and_second_names_are_walked_once() {
        use std::os::unix::fs::symlink;
        let tmp = scratch("loops");
        let dir = tmp.path();
        fs::create_dir_all(dir.join("a")).unwrap();
        fs::write(dir.join("a/x.psg"), "").unwrap();
        fs::write(dir.join("top.psg"), "").unwrap();
        symlink("..", dir.join("a/up")).unwrap();
        symlink("../a", dir.join("a/again")).unwrap();
        symlink("top.psg", dir.join("same.psg")).unwrap();
        symlink("nowhere.psg", dir.join("dangling.psg")).unwrap();
        let got = files_with_extension(dir, "psg").unwrap();
        // `same.psg` sorts before `top.psg` but is a link: the real name wins.
        let want: Vec<PathBuf> = ["a/x.psg", "dangling.psg", "top.psg"].iter().map(|f| dir.join(f)).collect();
        assert_eq!(got, want);
        tmp.close().unwrap();
    }
}
