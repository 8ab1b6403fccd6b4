//! Checkpoints of a store's write-ahead log on a thread of their own while an import writes.
//!
//! In WAL mode SQLite copies the log into the database (a checkpoint) on the writing connection
//! once the log passes 1000 pages, and syncs both files to disk: the writer waits for the disk,
//! the workers' queue fills and the cores stand idle (about a fifth of an import's wall time on
//! this machine). Here the writer's automatic checkpoints are off and a second connection
//! checkpoints passively, which SQLite allows alongside a writer: the copies and syncs overlap
//! the computation. The durability is the same: every commit is in the log, and a checkpoint
//! syncs the log before it copies it.

use std::path::Path;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use rusqlite::Connection;

use super::StoreError;

/// How often the checkpointing thread looks for new log frames.
const INTERVAL: Duration = Duration::from_millis(25);

/// A thread that checkpoints a store's log until dropped.
pub struct BackgroundCheckpoints {
    stop: Arc<(Mutex<bool>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl BackgroundCheckpoints {
    /// Starts checkpointing the store at `path`; its writer turns its own automatic checkpoints
    /// off meanwhile ([`crate::store::Store::set_auto_checkpoints`]).
    pub fn start(path: &Path) -> Result<BackgroundCheckpoints, StoreError> {
        let conn = Connection::open(path)
            .map_err(|e| StoreError::caused(path, "cannot open a checkpointing connection", e))?;
        let stop = Arc::new((Mutex::new(false), Condvar::new()));
        let signal = stop.clone();
        let thread = std::thread::Builder::new()
            .name("checkpoints".into())
            .spawn(move || {
                let (lock, wake) = &*signal;
                let mut stopped = lock.lock().unwrap_or_else(|e| e.into_inner());
                while !*stopped {
                    drop(stopped);
                    // A busy or failed checkpoint is left to the next round and to the writer's
                    // final one: skipping one loses nothing.
                    let _ = conn.query_row("PRAGMA wal_checkpoint(PASSIVE)", [], |_| Ok(()));
                    stopped = lock.lock().unwrap_or_else(|e| e.into_inner());
                    if !*stopped {
                        stopped = wake.wait_timeout(stopped, INTERVAL).unwrap_or_else(|e| e.into_inner()).0;
                    }
                }
            })
            .map_err(|e| StoreError::caused(path, "cannot start the checkpointing thread", e))?;
        Ok(BackgroundCheckpoints { stop, thread: Some(thread) })
    }
}

impl Drop for BackgroundCheckpoints {
    fn drop(&mut self) {
        let (lock, wake) = &*self.stop;
        *lock.lock().unwrap_or_else(|e| e.into_inner()) = true;
        wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With the writer's own checkpoints off, the thread copies the log into the database while
    /// the writer goes on: the log's frames end up checkpointed without the writer doing it.
    #[test]
    fn the_thread_checkpoints_what_the_writer_commits() {
        let dir = std::env::temp_dir().join(format!("terrafuse-checkpoint-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.db");
        let writer = Connection::open(&path).unwrap();
        writer
            .execute_batch("PRAGMA journal_mode = WAL; PRAGMA wal_autocheckpoint = 0; CREATE TABLE t (b BLOB);")
            .unwrap();
        let checkpoints = BackgroundCheckpoints::start(&path).unwrap();
        for _ in 0..50 {
            writer.execute("INSERT INTO t VALUES (?1)", [vec![7u8; 100_000]]).unwrap();
        }
        // Asking SQLite would checkpoint from this connection; the database file's size tells
        // what the thread copied into it.
        let start = std::time::Instant::now();
        let db_bytes = || std::fs::metadata(&path).unwrap().len();
        while db_bytes() < 50 * 100_000 {
            assert!(start.elapsed() < Duration::from_secs(30), "nothing checkpointed in 30 s: {} bytes", db_bytes());
            std::thread::sleep(Duration::from_millis(10));
        }
        drop(checkpoints);
        let n: i64 = writer.query_row("SELECT count(*) FROM t", [], |r| r.get(0)).unwrap();
        assert_eq!(n, 50);
        drop(writer);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
