//! Advisory locks on a file that several processes change (a project, a store being imported):
//! `flock` on a lock file beside it, `.<name>.lock`, so that a read, a change and the atomic
//! write that follows happen as one step with respect to every other Terrafuse process. The
//! kernel releases a lock when its holder closes the file or dies (a `kill -9` included), so a
//! lock can never be left behind; the lock file itself stays, empty of data, and is reused.
//!
//! The holder writes who it is into the lock file (`terrafuse brush, pid 1234`), so that a
//! process that waits can say what it waits for. Locks are advisory: they order Terrafuse's own
//! writers (commands, the workstation, imports), not other programs.

use std::io::{Read, Seek, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often a waiting process tries again.
const POLL: Duration = Duration::from_millis(25);

/// A lock that could not be taken.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// The lock file could not be opened or locked.
    #[error("{}: cannot lock it through {}", target.display(), lock.display())]
    Io {
        /// The file to be changed.
        target: PathBuf,
        /// Its lock file.
        lock: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Another process held the lock for longer than the wait.
    #[error(
        "{}: {holder} is changing it; gave up after waiting {waited_s:.0} s, and nothing was changed",
        target.display()
    )]
    Busy {
        /// The file to be changed.
        target: PathBuf,
        /// Who holds it, as it wrote itself into the lock file (`terrafuse brush, pid 1234`).
        holder: String,
        /// How long this process waited, seconds.
        waited_s: f64,
    },
}

/// The lock file of `target`: `.<name>.lock` in the same folder.
pub fn lock_path(target: &Path) -> PathBuf {
    let name = target.file_name().map_or_else(|| "file".into(), |n| n.to_string_lossy().into_owned());
    super::folder_of(target).join(format!(".{name}.lock"))
}

/// A held lock; dropping it releases the lock.
#[derive(Debug)]
pub struct Lock {
    file: std::fs::File,
    target: PathBuf,
}

impl Lock {
    /// Takes the lock on `target` for `holder` (a few words naming the process, e.g.
    /// `terrafuse brush`; the process id is added). While another process holds it, calls
    /// `waiting` once with the holder's words and tries again until `wait` has passed; then
    /// [`LockError::Busy`]. A zero `wait` tries once.
    pub fn acquire(
        target: &Path,
        holder: &str,
        wait: Duration,
        waiting: &mut dyn FnMut(&str),
    ) -> Result<Lock, LockError> {
        let lock = lock_path(target);
        let io = |source| LockError::Io { target: target.to_path_buf(), lock: lock.clone(), source };
        let mut file =
            std::fs::OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&lock).map_err(io)?;
        let start = Instant::now();
        let mut told = false;
        loop {
            if try_flock(&file).map_err(io)? {
                // Who holds it now, for whoever waits next.
                let me = format!("{holder}, pid {}", std::process::id());
                file.set_len(0)
                    .and_then(|()| file.rewind())
                    .and_then(|()| file.write_all(me.as_bytes()))
                    .map_err(io)?;
                return Ok(Lock { file, target: target.to_path_buf() });
            }
            let who = holder_of(&mut file);
            if start.elapsed() >= wait {
                return Err(LockError::Busy {
                    target: target.to_path_buf(),
                    holder: who,
                    waited_s: start.elapsed().as_secs_f64(),
                });
            }
            if !told {
                waiting(&who);
                told = true;
            }
            std::thread::sleep(POLL.min(wait.saturating_sub(start.elapsed())).max(Duration::from_millis(1)));
        }
    }

    /// The file the lock guards.
    pub fn target(&self) -> &Path {
        &self.target
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Closing the file releases the lock; emptying it first says nobody holds it.
        let _ = self.file.set_len(0);
    }
}

/// Who holds the lock, as the holder wrote itself (`another process` when it has not yet).
fn holder_of(file: &mut std::fs::File) -> String {
    let mut text = String::new();
    let read = file.rewind().and_then(|()| file.take(512).read_to_string(&mut text));
    match read {
        Ok(_) if !text.trim().is_empty() => text.trim().to_string(),
        _ => "another process".into(),
    }
}

/// `flock(LOCK_EX | LOCK_NB)`: true when taken, false when another open file holds it.
fn try_flock(file: &std::fs::File) -> std::io::Result<bool> {
    loop {
        // SAFETY: flock on a file descriptor this process owns; it touches no memory.
        let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
        if r == 0 {
            return Ok(true);
        }
        let e = std::io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EWOULDBLOCK) => return Ok(false),
            Some(libc::EINTR) => continue,
            _ => return Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("terrafuse-lock-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_second_taker_waits_names_the_holder_and_gives_up() {
        let dir = folder("busy");
        let target = dir.join("p.json");
        let held = Lock::acquire(&target, "terrafuse brush", Duration::ZERO, &mut |_| {}).unwrap();
        assert_eq!(held.target(), target);
        // Each open of the lock file is its own lock: a second one in this process is refused.
        let mut said = Vec::new();
        let e = Lock::acquire(&target, "terrafuse erode", Duration::from_millis(80), &mut |w| said.push(w.to_string()))
            .unwrap_err();
        let me = format!("terrafuse brush, pid {}", std::process::id());
        assert_eq!(said, vec![me.clone()], "one waiting line, naming the holder");
        match &e {
            LockError::Busy { holder, waited_s, .. } => {
                assert_eq!(holder, &me);
                assert!(*waited_s >= 0.08);
            }
            other => panic!("{other}"),
        }
        assert!(e.to_string().contains("nothing was changed"), "{e}");
        drop(held);
        // Released: taken at once.
        let again = Lock::acquire(&target, "terrafuse erode", Duration::ZERO, &mut |_| panic!("no wait")).unwrap();
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_waiter_gets_the_lock_when_the_holder_lets_go() {
        let dir = folder("handover");
        let target = dir.join("p.json");
        let held = Lock::acquire(&target, "first", Duration::ZERO, &mut |_| {}).unwrap();
        let releaser = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            drop(held);
        });
        let mut waited = false;
        let got = Lock::acquire(&target, "second", Duration::from_secs(20), &mut |_| waited = true);
        releaser.join().unwrap();
        assert!(got.is_ok() && waited);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_folder_is_an_error_that_names_the_lock_file() {
        let e =
            Lock::acquire(Path::new("/nonexistent-terrafuse/p.json"), "x", Duration::ZERO, &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains(".p.json.lock"), "{e}");
    }
}
