//! Writing files so that a crash, a kill or a power cut never leaves a half-written one.
//!
//! [`write_atomic`] is the sequence that survives all three on a POSIX file system: write into a
//! temporary file in the same folder (a rename across file systems is not atomic), flush it to
//! disk (`fsync`), rename it over the target (atomic: readers see the old file or the new one),
//! then `fsync` the folder so that the rename itself is on disk. A process killed part-way leaves
//! at most its temporary file, named `.<name>.tmp-<pid>-<n>`; the next save into that folder
//! removes the temporaries of processes that no longer run.

pub mod lock;

use sha2::{Digest, Sha256};

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Temporaries of this process, numbered so that two threads saving the same file never share
/// one.
static NEXT: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically (see the module's documentation). On an error the target
/// is untouched and the temporary removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = folder_of(path);
    let name = path.file_name().ok_or_else(|| std::io::Error::other("the path names no file"))?;
    let name = name.to_string_lossy();
    let tmp = dir.join(format!(".{name}.tmp-{}-{}", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed)));
    let result = (|| {
        let mut file = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)?;
        sync_folder(dir)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    } else {
        remove_orphans(dir, &name);
    }
    result
}

/// The folder a path is in (`.` for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Flushes a folder's entries (a rename into it) to disk.
fn sync_folder(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}

/// The temporaries of `name` in `dir` that processes no longer running left behind.
pub fn orphans(dir: &Path, name: &str) -> Vec<PathBuf> {
    orphans_of(dir, |file| file == name)
}

/// The temporaries in `dir` of every file whose name `of` accepts, left by processes that no
/// longer run.
pub fn orphans_of(dir: &Path, of: impl Fn(&str) -> bool) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .filter_map(Result::ok)
        .filter_map(|e| {
            let file = e.file_name().to_string_lossy().into_owned();
            let (name, tail) = file.strip_prefix('.')?.rsplit_once(".tmp-")?;
            let pid: i32 = tail.split('-').next()?.parse().ok()?;
            (of(name) && !process_runs(pid)).then(|| e.path())
        })
        .collect()
}

fn remove_orphans(dir: &Path, name: &str) {
    for path in orphans(dir, name) {
        let _ = std::fs::remove_file(path);
    }
}

/// Whether a process with this id runs (signal 0 checks without sending anything).
fn process_runs(pid: i32) -> bool {
    if pid <= 0 {
        return false;
    }
    // SAFETY: kill with signal 0 only checks that the process exists and may be signalled.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// The SHA-256 of `bytes`, as lower-case hex (how plans, manifests and parts name a digest).
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn replaces_the_file_and_leaves_no_temporary_behind() {
        let dir = std::env::temp_dir().join(format!("terrafuse-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.csv");
        super::write_atomic(&path, b"old").unwrap();
        super::write_atomic(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        assert!(super::write_atomic(&dir.join("missing/out.csv"), b"x").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn temporaries_of_dead_processes_are_removed_by_the_next_save() {
        let dir = std::env::temp_dir().join(format!("terrafuse-orphans-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // No process has id 2³¹ − 2 (Linux's pid_max is at most 2²²); this process runs.
        let dead = dir.join(".p.json.tmp-2147483646-0");
        let alive = dir.join(format!(".p.json.tmp-{}-999", std::process::id()));
        let other = dir.join(".q.json.tmp-2147483646-0");
        for f in [&dead, &alive, &other] {
            std::fs::write(f, b"half a proj").unwrap();
        }
        assert_eq!(super::orphans(&dir, "p.json"), std::slice::from_ref(&dead));
        super::write_atomic(&dir.join("p.json"), b"{}").unwrap();
        assert!(!dead.exists() && alive.exists() && other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
