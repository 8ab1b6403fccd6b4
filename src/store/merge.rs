//! `terrafuse store merge STORE PART…`: partial stores of one plan put into a store, one
//! SQLite transaction per shard (the part ATTACHed, its tiles, tile statistics re-keyed to the
//! new tile rows, rims and journal copied, and the shard recorded with the plan's hash, so that
//! merging it again skips it); when every shard of the plan is in, the pyramid is built once
//! and the dataset marked complete.
//!
//! Parts are checked before anything is written: each must be a finished shard of the same
//! plan, on the store's body; a part that is not is refused by name.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use gdal::spatial_ref::SpatialRef;
use rusqlite::{OptionalExtension, params};

use super::StoreError;
use super::checkpoint::BackgroundCheckpoints;
use super::gpkg::{DatasetRecord, Store, face_proj, face_table};
use super::import::{LevelWriter, check_body, peak_rss_bytes, pyramid, worker_pool};
use super::shard::{PartInfo, part_info};
use super::watch::ImportWatch;
use crate::ecm::Face;
use crate::geodesy::Ellipsoid;

/// How a merge runs.
#[derive(Clone, Debug)]
pub struct MergeOptions {
    /// The store (created if missing).
    pub store: PathBuf,
    /// Partial stores, in any order.
    pub parts: Vec<PathBuf>,
    /// Worker threads for the pyramid (default: all cores).
    pub threads: Option<usize>,
    /// Draw a progress bar for the pyramid.
    pub progress: bool,
    /// Progress and cancel from another thread.
    pub watch: Option<std::sync::Arc<ImportWatch>>,
}

/// What a merge did.
#[derive(Clone, Debug, Default)]
pub struct MergeReport {
    /// The dataset.
    pub dataset: String,
    /// The plan's hash.
    pub manifest: String,
    /// The plan's number of shards.
    pub shards: usize,
    /// Shards merged now, with their tiles.
    pub merged: Vec<(usize, u64)>,
    /// Shards a part gave that an earlier merge had already put in.
    pub skipped: Vec<usize>,
    /// Shards of the plan not in the store yet.
    pub missing: Vec<usize>,
    /// Per coarser level: tiles written, and those an earlier run had finished.
    pub levels: Vec<(u8, u64, u64)>,
    /// Seconds merging, and building the pyramid.
    pub seconds_merge: f64,
    /// Seconds building the pyramid.
    pub seconds_pyramid: f64,
    /// The dataset is complete (every shard in, the pyramid built).
    pub complete: bool,
    /// Peak resident memory, bytes.
    pub peak_rss_bytes: u64,
}

const MERGES_TABLE: &str = "CREATE TABLE IF NOT EXISTS terrafuse_merges (dataset TEXT NOT NULL, manifest TEXT NOT NULL,
  shard INTEGER NOT NULL, shards INTEGER NOT NULL, tiles INTEGER NOT NULL, merged TEXT NOT NULL,
  PRIMARY KEY (dataset, shard))";

/// A part, checked.
struct Part {
    path: PathBuf,
    body: Ellipsoid,
    info: PartInfo,
    record: DatasetRecord,
}

/// Opens and checks every part: a finished shard, all of one plan and body.
fn check_parts(paths: &[PathBuf]) -> Result<Vec<Part>, StoreError> {
    let mut parts: Vec<Part> = Vec::new();
    for path in paths {
        let store = Store::open_read_only(path)?;
        let info = part_info(&store)?.ok_or_else(|| {
            StoreError::new(path, "is not a shard's partial store (made by `terrafuse import --manifest M --shard I`)")
        })?;
        if !info.complete {
            return Err(StoreError::new(
                path,
                format!("shard {} is not finished: run it again to finish it", info.shard),
            ));
        }
        let mut datasets = store.datasets()?;
        if datasets.len() != 1 {
            return Err(StoreError::new(path, format!("holds {} datasets; a shard's store holds one", datasets.len())));
        }
        let record = datasets.remove(0);
        if let Some(first) = parts.first() {
            check_body(path, store.body(), &first.body)?;
            if info.manifest != first.info.manifest {
                return Err(StoreError::new(
                    path,
                    format!(
                        "belongs to plan {} (dataset {}), not to plan {} of {}: merge the parts of one plan",
                        short(&info.manifest),
                        record.name,
                        short(&first.info.manifest),
                        first.path.display()
                    ),
                ));
            }
            if let Some(twin) = parts.iter().find(|p| p.info.shard == info.shard) {
                return Err(StoreError::new(
                    path,
                    format!("is shard {} again (also {}): give each shard once", info.shard, twin.path.display()),
                ));
            }
        }
        if info.shard >= info.shards {
            return Err(StoreError::new(path, format!("damaged header: shard {} of {}", info.shard, info.shards)));
        }
        parts.push(Part { path: path.clone(), body: *store.body(), info, record });
    }
    parts.sort_by_key(|p| p.info.shard);
    Ok(parts)
}

fn short(hash: &str) -> &str {
    &hash[..12.min(hash.len())]
}

/// Merges partial stores into a store and, when every shard of the plan is in, builds the
/// pyramid and marks the dataset complete. See the module documentation.
pub fn merge(opts: &MergeOptions) -> Result<MergeReport, StoreError> {
    if opts.parts.is_empty() {
        return Err(StoreError::new(&opts.store, "no partial stores given"));
    }
    let parts = check_parts(&opts.parts)?;
    let first = &parts[0];
    let body = first.body;
    let (manifest, shards, dataset) = (first.info.manifest.clone(), first.info.shards, first.record.name.clone());
    let mut store = if opts.store.exists() { Store::open(&opts.store)? } else { Store::create(&opts.store, &body)? };
    check_body(&opts.store, store.body(), &body)?;
    let path = opts.store.clone();
    let sql = |what: &'static str| {
        let path = path.clone();
        move |e: rusqlite::Error| StoreError::caused(&path, what, e)
    };
    store.connection().execute_batch(MERGES_TABLE).map_err(sql("cannot record merges"))?;
    let recorded = recorded_merges(&mut store, &dataset)?;
    match (store.dataset(&dataset)?, recorded.values().next()) {
        (Some(_), Some((m, _))) if *m != manifest => {
            return Err(StoreError::new(
                &first.path,
                format!(
                    "belongs to plan {}, but {} holds dataset {dataset} from plan {}: merge into another store",
                    short(&manifest),
                    opts.store.display(),
                    short(m)
                ),
            ));
        }
        (Some(_), None) => {
            return Err(StoreError::new(
                &opts.store,
                format!("already has a dataset '{dataset}' that no merge made: merge into another store"),
            ));
        }
        (Some(_), Some(_)) => {}
        (None, _) => {
            let wkt: Vec<String> = Face::ALL
                .iter()
                .map(|&f| {
                    SpatialRef::from_proj4(&face_proj(&body, f))
                        .and_then(|s| s.to_wkt())
                        .map_err(|e| StoreError::caused(&opts.store, "PROJ has no QSC CRS", e))
                })
                .collect::<Result<_, _>>()?;
            let wkt: [String; 6] = wkt.try_into().expect("six faces");
            store.add_dataset(&DatasetRecord { completed: None, ..first.record.clone() }, &wkt)?;
        }
    }
    let stored = store.dataset(&dataset)?.expect("registered above");
    let mut report = MergeReport { dataset: dataset.clone(), manifest: manifest.clone(), shards, ..Default::default() };
    let start = Instant::now();
    // The parts' tiles are copied in big transactions: the log is checkpointed on a thread of
    // its own meanwhile, as during an import, so the copying never waits for the disk.
    store.set_auto_checkpoints(false)?;
    let checkpoints = BackgroundCheckpoints::start(&opts.store)?;
    for part in &parts {
        if part.record.settings != stored.settings || part.record.sources != stored.sources {
            return Err(StoreError::new(
                &part.path,
                format!(
                    "dataset {}: its settings or sources differ from the store's: a damaged part?",
                    part.record.name
                ),
            ));
        }
        if recorded.contains_key(&part.info.shard) {
            report.skipped.push(part.info.shard);
            continue;
        }
        let tiles = merge_part(&mut store, part, &dataset)?;
        report.merged.push((part.info.shard, tiles));
    }
    drop(checkpoints);
    store.set_auto_checkpoints(true)?;
    report.seconds_merge = start.elapsed().as_secs_f64();
    let have: BTreeSet<usize> = recorded_merges(&mut store, &dataset)?.into_keys().collect();
    report.missing = (0..shards).filter(|s| !have.contains(s)).collect();
    if report.missing.is_empty() {
        let start = Instant::now();
        let finest = stored.settings.finest_level;
        let threads =
            opts.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get())).max(1);
        let pool = worker_pool(&opts.store, threads)?;
        let mut levels = LevelWriter::new(&mut store, &dataset, &pool, 2 << 30, opts.progress, opts.watch.as_deref());
        if stored.completed.is_none() {
            report.levels = pyramid(&mut levels, &opts.store, finest)?;
            store.mark_complete(&dataset)?;
        }
        report.complete = true;
        report.seconds_pyramid = start.elapsed().as_secs_f64();
    }
    report.peak_rss_bytes = peak_rss_bytes();
    Ok(report)
}

/// The shards recorded as merged: shard → (plan hash, tiles).
fn recorded_merges(store: &mut Store, dataset: &str) -> Result<BTreeMap<usize, (String, u64)>, StoreError> {
    let path = store.path().to_owned();
    let e = |e: rusqlite::Error| StoreError::caused(&path, "cannot read the merges", e);
    let conn = store.connection();
    let mut stmt = conn.prepare("SELECT shard, manifest, tiles FROM terrafuse_merges WHERE dataset = ?1").map_err(e)?;
    let rows = stmt
        .query_map([dataset], |r| {
            Ok((r.get::<_, i64>(0)? as usize, (r.get::<_, String>(1)?, r.get::<_, i64>(2)? as u64)))
        })
        .map_err(e)?;
    rows.collect::<Result<_, _>>().map_err(e)
}

/// Copies one part into the store in one transaction; returns its tiles with data.
fn merge_part(store: &mut Store, part: &Part, dataset: &str) -> Result<u64, StoreError> {
    let path = store.path().to_owned();
    let e = |what: &str| {
        let (path, what, part) = (path.clone(), what.to_owned(), part.path.display().to_string());
        move |err: rusqlite::Error| StoreError::caused(&path, format!("merging {part}: {what}"), err)
    };
    let conn = store.connection();
    conn.execute("ATTACH DATABASE ?1 AS part", [part.path.to_string_lossy()]).map_err(e("cannot attach it"))?;
    let result = (|| {
        let tx = conn.transaction().map_err(e("cannot start a transaction"))?;
        let src = &part.record.name;
        let mut tiles = 0u64;
        for face in Face::ALL {
            let (to, from) = (face_table(dataset, face), face_table(src, face));
            tiles += tx
                .execute(
                    &format!(
                        "INSERT INTO main.\"{to}\" (zoom_level, tile_column, tile_row, tile_data)
                         SELECT zoom_level, tile_column, tile_row, tile_data FROM part.\"{from}\" ORDER BY id"
                    ),
                    [],
                )
                .map_err(e("cannot copy tiles (a quad in two shards?)"))? as u64;
            // Tile statistics follow their tile to its new row id.
            tx.execute(
                &format!(
                    "INSERT INTO main.gpkg_2d_gridded_tile_ancillary (tpudt_name, tpudt_id, scale, offset, min, max, mean, std_dev)
                     SELECT ?1, m.id, a.scale, a.offset, a.min, a.max, a.mean, a.std_dev
                     FROM part.gpkg_2d_gridded_tile_ancillary a
                     JOIN part.\"{from}\" t ON a.tpudt_name = ?2 AND a.tpudt_id = t.id
                     JOIN main.\"{to}\" m ON m.zoom_level = t.zoom_level AND m.tile_column = t.tile_column AND m.tile_row = t.tile_row
                     ORDER BY m.id"
                ),
                params![to, from],
            )
            .map_err(e("cannot copy tile statistics"))?;
        }
        for table in ["terrafuse_rims", "terrafuse_journal"] {
            tx.execute(
                &format!(
                    "INSERT INTO main.{table} SELECT ?1, level, face, x, y, {} FROM part.{table} WHERE dataset = ?2",
                    if table == "terrafuse_rims" { "rim" } else { "has_data" }
                ),
                params![dataset, src],
            )
            .map_err(e("cannot copy rims and journal (a quad in two shards?)"))?;
        }
        tx.execute(
            "INSERT INTO terrafuse_merges VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![
                dataset,
                part.info.manifest,
                part.info.shard as i64,
                part.info.shards as i64,
                tiles as i64,
                super::gpkg::utc_now()
            ],
        )
        .map_err(e("cannot record the merge"))?;
        tx.commit().map_err(e("cannot commit"))?;
        Ok(tiles)
    })();
    let detached = conn.execute("DETACH DATABASE part", []).map_err(e("cannot detach it"));
    let tiles = result?;
    detached?;
    Ok(tiles)
}

/// The plan's shards a store has merged, for `terrafuse slurm submit` to skip: `None` when the
/// store has no merges of the dataset.
pub fn merged_shards(
    store: &Path,
    dataset: &str,
    manifest: &str,
) -> Result<Option<(BTreeSet<usize>, bool)>, StoreError> {
    if !store.exists() {
        return Ok(None);
    }
    let mut s = Store::open_read_only(store)?;
    let complete = s.dataset(dataset)?.is_some_and(|d| d.completed.is_some());
    let has_table: bool = s
        .connection()
        .query_row("SELECT count(*) FROM sqlite_master WHERE name = 'terrafuse_merges'", [], |r| r.get::<_, i64>(0))
        .map(|n| n > 0)
        .map_err(|e| StoreError::caused(store, "cannot read the merges", e))?;
    if !has_table {
        return Ok(None);
    }
    let merged = recorded_merges(&mut s, dataset)?;
    Ok(Some((merged.into_iter().filter(|(_, (m, _))| m == manifest).map(|(k, _)| k).collect(), complete)))
}

/// What `store info` says of a merged dataset: the plan's hash, its shards and those merged.
pub fn merge_record(store: &Path, dataset: &str) -> Result<Option<(String, usize, usize)>, StoreError> {
    let mut s = Store::open_read_only(store)?;
    let conn = s.connection();
    let has_table: bool = conn
        .query_row("SELECT count(*) FROM sqlite_master WHERE name = 'terrafuse_merges'", [], |r| r.get::<_, i64>(0))
        .map(|n| n > 0)
        .map_err(|e| StoreError::caused(store, "cannot read the merges", e))?;
    if !has_table {
        return Ok(None);
    }
    conn.query_row(
        "SELECT manifest, max(shards), count(*) FROM terrafuse_merges WHERE dataset = ?1 GROUP BY manifest",
        [dataset],
        |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)? as usize, r.get::<_, i64>(2)? as usize)),
    )
    .optional()
    .map_err(|e| StoreError::caused(store, "cannot read the merges", e))
}
