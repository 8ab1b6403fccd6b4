//! Running one level of an import: quads computed in parallel by worker threads, written from
//! one thread in transactions of 32 quads or one second, skipping what an earlier run finished.

use std::collections::HashSet;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::super::StoreError;
use super::super::checkpoint::BackgroundCheckpoints;
use super::super::gpkg::Store;
use super::super::tile::{EncodedQuad, QuadGrid};
use super::super::watch::ImportWatch;
use crate::ecm::QuadId;

/// Runs the levels of one import: computes quads in parallel and writes them from this thread.
pub(in crate::store) struct LevelWriter<'a> {
    pub(in crate::store) store: &'a mut Store,
    pub(in crate::store) dataset: &'a str,
    pub(in crate::store) pool: &'a rayon::ThreadPool,
    /// Quads in flight between the workers and the writer.
    pub(in crate::store) queue: usize,
    pub(in crate::store) progress: bool,
    pub(in crate::store) watch: Option<&'a ImportWatch>,
}

impl<'a> LevelWriter<'a> {
    /// A writer for one dataset, with a queue between workers and writer sized by the threads
    /// and the memory budget (each quad in flight holds ≈ 600 KiB).
    pub(in crate::store) fn new(
        store: &'a mut Store,
        dataset: &'a str,
        pool: &'a rayon::ThreadPool,
        budget: u64,
        progress: bool,
        watch: Option<&'a ImportWatch>,
    ) -> LevelWriter<'a> {
        let threads = pool.current_num_threads();
        let queue = (2 * threads + 4).min((budget / 4 / (600 << 10)).max(4) as usize);
        LevelWriter { store, dataset, pool, queue, progress, watch }
    }

    /// Computes the candidates of a level that no earlier run finished, committing every 32 quads
    /// or every second. Returns the tiles with data written, the quads an earlier run had
    /// finished, and the quads computed now.
    pub(in crate::store) fn run<W, I, F>(
        &mut self,
        level: u8,
        candidates: HashSet<QuadId>,
        init: I,
        compute: F,
    ) -> Result<(u64, u64, usize), StoreError>
    where
        I: Fn() -> Result<W, StoreError> + Sync,
        F: Fn(&mut W, QuadId) -> Result<Option<QuadGrid>, StoreError> + Sync,
    {
        let finished = self.store.finished_quads(self.dataset, level)?;
        let mut todo: Vec<QuadId> = candidates.into_iter().filter(|q| !finished.contains(q)).collect();
        todo.sort();
        let written = self.write(&todo, &format!("level {level}"), init, compute)?;
        Ok((written, finished.len() as u64, todo.len()))
    }

    fn write<W, I, F>(&mut self, todo: &[QuadId], label: &str, init: I, compute: F) -> Result<u64, StoreError>
    where
        I: Fn() -> Result<W, StoreError> + Sync,
        F: Fn(&mut W, QuadId) -> Result<Option<QuadGrid>, StoreError> + Sync,
    {
        let (store, dataset, pool, queue, progress, watch) =
            (&mut *self.store, self.dataset, self.pool, self.queue, self.progress, self.watch);
        if todo.is_empty() {
            return Ok(0);
        }
        if let Some(w) = watch {
            w.start_phase(label, todo.len() as u64);
        }
        let bar = if progress { ProgressBar::new(todo.len() as u64) } else { ProgressBar::hidden() };
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>9} [{bar:32}] {pos}/{len} tiles  {per_sec}  {elapsed} elapsed, ~{eta} left",
            )
            .expect("a valid template")
            .progress_chars("=> "),
        );
        bar.set_prefix(label.to_owned());
        let stop = AtomicBool::new(false);
        store.set_auto_checkpoints(false)?;
        let checkpoints = BackgroundCheckpoints::start(store.path())?;
        let (tx, rx) = sync_channel::<Result<(QuadId, Option<EncodedQuad>), StoreError>>(queue);
        let mut written = 0u64;
        let mut failure = None;
        std::thread::scope(|s| {
            let stop = &stop;
            let init = &init;
            let compute = &compute;
            s.spawn(move || {
                pool.install(|| {
                    todo.par_iter().for_each_init(
                        || init().map_err(std::sync::Arc::new),
                        |worker, &q| {
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            let result = match worker {
                                Ok(w) => compute(w, q).map(|g| (q, g.map(|g| g.encode()))),
                                Err(e) => {
                                    Err(StoreError::caused(Path::new(dataset), "a worker could not start", e.clone()))
                                }
                            };
                            if tx.send(result).is_err() {
                                stop.store(true, Ordering::Relaxed);
                            }
                        },
                    );
                });
                drop(tx);
            });
            let mut batch = Vec::new();
            let mut last = Instant::now();
            let flush = |store: &mut Store, batch: &mut Vec<(QuadId, Option<EncodedQuad>)>| -> Result<(), StoreError> {
                store.write_quads(dataset, batch)?;
                batch.clear();
                Ok(())
            };
            for msg in rx.iter() {
                match msg {
                    Ok((q, g)) => {
                        written += u64::from(g.is_some());
                        batch.push((q, g));
                        bar.inc(1);
                        if let Some(w) = watch {
                            w.advance();
                            if w.is_cancelled() {
                                // What is committed stays; this batch is dropped like a crash's.
                                failure = Some(StoreError::new(store.path(), "cancelled"));
                                break;
                            }
                        }
                        if batch.len() >= 32 || last.elapsed().as_secs_f64() > 1.0 {
                            if let Err(e) = flush(store, &mut batch) {
                                failure = Some(e);
                                break;
                            }
                            last = Instant::now();
                        }
                    }
                    Err(e) => {
                        failure = Some(e);
                        break;
                    }
                }
            }
            if failure.is_some() {
                stop.store(true, Ordering::Relaxed);
                drop(rx);
            } else if let Err(e) = flush(store, &mut batch) {
                failure = Some(e);
            }
        });
        bar.finish_and_clear();
        drop(checkpoints);
        store.set_auto_checkpoints(true)?;
        match failure {
            Some(e) => Err(e),
            None => Ok(written),
        }
    }
}
