//! Sharded imports: a plan (the manifest) that cuts an import's finest-level quads into N
//! contiguous runs along a Hilbert curve per face, and the import of one shard into a partial
//! store of its own, resumable through its journal and published complete or not at all.
//!
//! The contract with a scheduler is an index: shard `I` of the manifest, for any `I` in
//! `0..N`, in any order, on any machine that sees the sources and the manifest. A shard's
//! partial store holds the finest level only; [`super::merge`] puts them together and builds
//! the pyramid once.

use crate::errors::AtField;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::files::sha256_hex;
use serde::{Deserialize, Serialize};

use super::StoreError;
use super::gpkg::{DatasetSettings, SourceProvenance, Store};
use super::import::{
    ImportOptions, ImportReport, LevelChoice, LevelWriter, Prepared, Resampling, VerticalDatum, candidates,
    finest_level, open_dataset, peak_rss_bytes, prepare, same_files, worker_pool,
};
use super::watch::ImportWatch;
use crate::Invalid;
use crate::ecm::grid::GRID;
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;

/// The manifest's format name.
pub const MANIFEST_FORMAT: &str = "terrafuse-import-manifest";
/// The manifest version this build writes and reads.
pub const MANIFEST_VERSION: u32 = 1;
/// The most shards a plan may have.
pub const MAX_SHARDS: usize = 1 << 20;
/// Keys of a partial store's header that name its manifest and shard.
pub const HEADER_MANIFEST: &str = "manifest";
/// The shard's index.
pub const HEADER_SHARD: &str = "shard";
/// The plan's number of shards.
pub const HEADER_SHARDS: &str = "shards";

/// How the import is run: what `terrafuse import` was given, with the sources made absolute.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestImport {
    /// Source rasters, absolute paths, in priority order.
    pub sources: Vec<String>,
    /// Dataset name.
    pub dataset: String,
    /// The finest level.
    pub level: u8,
    /// bilinear, cubic or nearest.
    pub resampling: String,
    /// lattice or exact.
    pub transform: String,
    /// The vertical datum as `--vertical-datum` takes it.
    pub vertical_datum: String,
}

/// One shard: its quads of the finest level, as `[face, x, y]` (face in 0..6, `Face::ALL`
/// order), contiguous along the curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardSpec {
    /// The quads.
    pub quads: Vec<[u32; 3]>,
}

/// A sharded import's plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`MANIFEST_FORMAT`].
    pub format: String,
    /// [`MANIFEST_VERSION`].
    pub version: u32,
    /// SHA-256 (hex) of the manifest with this field empty: names the plan in every partial
    /// store, and notices an edited or damaged manifest.
    pub hash: String,
    /// SHA-256 (hex) of the body, the import, the settings and the sources' provenance alone.
    pub inputs_hash: String,
    /// The body: `wgs84`, `moon`, `mars` or `a=A,b=B`.
    pub body: String,
    /// The body's semi-axes, metres.
    pub body_axes_m: [f64; 2],
    /// What to import.
    pub import: ManifestImport,
    /// The dataset settings the import records (what decides its samples).
    pub settings: DatasetSettings,
    /// The sources as planned: a shard refuses to run on sources that changed since.
    pub provenance: Vec<SourceProvenance>,
    /// How quads are ordered before they are cut: `hilbert` (per face, faces in order).
    pub order: String,
    /// When the plan was made (UTC).
    pub created: String,
    /// The shards.
    pub shards: Vec<ShardSpec>,
}

/// What `terrafuse import … --plan` made.
#[derive(Clone, Debug)]
pub struct PlanReport {
    /// The plan.
    pub manifest: Manifest,
    /// Seconds spent checking sources and listing quads.
    pub seconds: f64,
}

/// How the manifest names a body.
pub fn body_text(body: &Ellipsoid) -> String {
    match body.name() {
        n @ ("wgs84" | "moon" | "mars") => n.to_owned(),
        _ => format!("a={:?},b={:?}", body.a_m(), body.b_m()),
    }
}

/// The `--vertical-datum` text that gives back this datum.
pub fn vertical_text(v: &VerticalDatum) -> String {
    match v {
        VerticalDatum::Unspecified => "unspecified".into(),
        VerticalDatum::Ellipsoidal => "ellipsoidal".into(),
        VerticalDatum::Geoid { grid, .. } if grid == "egm96_15.gtx" => "egm96".into(),
        VerticalDatum::Geoid { grid, .. } if grid == "egm08_25.gtx" => "egm2008".into(),
        VerticalDatum::Geoid { grid, .. } => format!("geoid:{grid}"),
    }
}

/// The Hilbert curve index of (x, y) on a 2^order square (x, y < 2^order).
pub fn hilbert_index(order: u8, x: u32, y: u32) -> u64 {
    let (mut x, mut y) = (u64::from(x), u64::from(y));
    let n = 1u64 << order;
    let mut d = 0u64;
    let mut s = n / 2;
    while s > 0 {
        let rx = u64::from(x & s > 0);
        let ry = u64::from(y & s > 0);
        d += s * s * ((3 * rx) ^ ry);
        // Rotate the quadrant so that the curve continues.
        if ry == 0 {
            if rx == 1 {
                x = n - 1 - x;
                y = n - 1 - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s /= 2;
    }
    d
}

/// Orders quads face by face, along the Hilbert curve within a face, and cuts them into
/// `shards` contiguous runs whose lengths differ by at most one.
pub fn cut(mut quads: Vec<QuadId>, shards: usize) -> Vec<Vec<QuadId>> {
    quads.sort_by_key(|q| (q.face.index(), hilbert_index(q.level, q.x, q.y)));
    let n = quads.len();
    (0..shards).map(|k| quads[k * n / shards..(k + 1) * n / shards].to_vec()).collect()
}

impl Manifest {
    fn with_hash(mut self) -> Manifest {
        #[derive(Serialize)]
        struct Inputs<'a> {
            body: &'a str,
            body_axes_m: [f64; 2],
            import: &'a ManifestImport,
            settings: &'a DatasetSettings,
            provenance: &'a [SourceProvenance],
        }
        let inputs = Inputs {
            body: &self.body,
            body_axes_m: self.body_axes_m,
            import: &self.import,
            settings: &self.settings,
            provenance: &self.provenance,
        };
        self.inputs_hash = sha256_hex(&serde_json::to_vec(&inputs).expect("the inputs serialise"));
        self.hash = self.own_hash();
        self
    }

    fn own_hash(&self) -> String {
        let blank = Manifest { hash: String::new(), ..self.clone() };
        sha256_hex(&serde_json::to_vec(&blank).expect("a manifest serialises"))
    }

    /// The first 12 characters of the hash, for names (job names, messages).
    pub fn short_hash(&self) -> &str {
        &self.hash[..12.min(self.hash.len())]
    }

    /// The body.
    pub fn ellipsoid(&self) -> Result<Ellipsoid, Invalid> {
        let body: Ellipsoid = self.body.parse().at_field("body")?;
        if body.a_m() != self.body_axes_m[0] || body.b_m() != self.body_axes_m[1] {
            return Err(format!("body_axes_m: {:?} are not the axes of {}", self.body_axes_m, self.body).into());
        }
        Ok(body)
    }

    /// The quads of shard `i`.
    pub fn shard_quads(&self, i: usize) -> Result<HashSet<QuadId>, Invalid> {
        let shard = self
            .shards
            .get(i)
            .ok_or_else(|| format!("has shards 0–{}, not {i}", self.shards.len().saturating_sub(1)))?;
        shard
            .quads
            .iter()
            .enumerate()
            .map(|(k, &[f, x, y])| {
                let face = Face::from_index(f as usize)
                    .ok_or_else(|| Invalid(format!("shards[{i}].quads[{k}]: face {f} is not 0–5")))?;
                QuadId::new(face, self.import.level, x, y).map_err(|e| {
                    Invalid(format!("shards[{i}].quads[{k}]: [{f}, {x}, {y}] at level {}: {e}", self.import.level))
                })
            })
            .collect()
    }

    /// The import options that rebuild this plan's dataset, with a shard's threads and memory.
    pub fn import_options(
        &self,
        store: &Path,
        threads: Option<usize>,
        memory_budget: u64,
    ) -> Result<ImportOptions, Invalid> {
        Ok(ImportOptions {
            sources: self.import.sources.iter().map(PathBuf::from).collect(),
            store: store.to_owned(),
            body: self.ellipsoid()?,
            name: Some(self.import.dataset.clone()),
            level: LevelChoice::Level(self.import.level),
            resampling: self.import.resampling.parse::<Resampling>().at_field("import.resampling")?,
            transform: self.import.transform.parse().at_field("import.transform")?,
            vertical: self.import.vertical_datum.parse().at_field("import.vertical_datum")?,
            memory_budget,
            threads,
            progress: false,
            watch: None,
            finest_only: true,
        })
    }

    /// Reads and checks a manifest: format, version, hash, body and every shard's quads.
    pub fn load(path: &Path) -> Result<Manifest, StoreError> {
        let err = |m: String| StoreError::new(path, m);
        let meta = std::fs::metadata(path).map_err(|e| StoreError::caused(path, "cannot read the manifest", e))?;
        if meta.len() > 4 << 30 {
            return Err(err(format!("is {} bytes: not a manifest (at most 4 GiB)", meta.len())));
        }
        let text = std::fs::read(path).map_err(|e| StoreError::caused(path, "cannot read the manifest", e))?;
        let head: serde_json::Value = match serde_json::from_slice::<serde_json::Value>(&text) {
            Ok(serde_json::Value::Object(mut m)) => {
                m.retain(|k, _| k == "format" || k == "version");
                serde_json::Value::Object(m)
            }
            Ok(_) => return Err(err("is not a Terrafuse import manifest (not a JSON object)".into())),
            Err(e) => return Err(StoreError::caused(path, "is not valid JSON", e)),
        };
        if head["format"] != MANIFEST_FORMAT {
            return Err(err(format!("format: {} is not {MANIFEST_FORMAT}", head["format"])));
        }
        if head["version"].as_u64() != Some(u64::from(MANIFEST_VERSION)) {
            return Err(err(format!("version: {}; this terrafuse reads version {MANIFEST_VERSION}", head["version"])));
        }
        let mut de = serde_json::Deserializer::from_slice(&text);
        let m: Manifest =
            serde_path_to_error::deserialize(&mut de).map_err(|e| err(format!("{}: {}", e.path(), e.inner())))?;
        if m.own_hash() != m.hash {
            return Err(err("hash: does not match the manifest's contents (edited or damaged): plan again".into()));
        }
        m.ellipsoid().map_err(|e| err(e.0))?;
        if m.shards.is_empty() || m.shards.len() > MAX_SHARDS {
            return Err(err(format!("shards: {} shards; a plan has 1 to {MAX_SHARDS}", m.shards.len())));
        }
        let mut seen = HashSet::new();
        for i in 0..m.shards.len() {
            for q in m.shard_quads(i).map_err(|e| err(e.0))? {
                if !seen.insert(q) {
                    return Err(err(format!("shards[{i}]: quad {q} is in two shards")));
                }
            }
        }
        Ok(m)
    }
}

/// `terrafuse import … --plan MANIFEST --shards N`: checks the sources, lists the finest-level
/// quads (the import's footprint step), cuts them into `shards` runs and writes the manifest
/// atomically.
pub fn plan(opts: &ImportOptions, manifest: &Path, shards: usize) -> Result<PlanReport, StoreError> {
    let start = Instant::now();
    if shards == 0 || shards > MAX_SHARDS {
        return Err(StoreError::new(manifest, format!("--shards {shards}: give 1 to {MAX_SHARDS} shards")));
    }
    let prepared = prepare(opts)?;
    let quads: Vec<QuadId> = candidates(&prepared, &opts.body)?.into_iter().collect();
    if shards > quads.len() {
        return Err(StoreError::new(
            manifest,
            format!(
                "--shards {shards}: the import has only {} quads at level {}; give at most that many shards",
                quads.len(),
                prepared.level
            ),
        ));
    }
    let m = Manifest {
        format: MANIFEST_FORMAT.into(),
        version: MANIFEST_VERSION,
        hash: String::new(),
        inputs_hash: String::new(),
        body: body_text(&opts.body),
        body_axes_m: [opts.body.a_m(), opts.body.b_m()],
        import: ManifestImport {
            sources: prepared.settings.sources.clone(),
            dataset: prepared.name.clone(),
            level: prepared.level,
            resampling: opts.resampling.name().into(),
            transform: opts.transform.name().into(),
            vertical_datum: vertical_text(&opts.vertical),
        },
        settings: prepared.settings.clone(),
        provenance: prepared.provenance.clone(),
        order: "hilbert".into(),
        created: super::gpkg::utc_now(),
        shards: cut(quads, shards)
            .into_iter()
            .map(|s| ShardSpec { quads: s.iter().map(|q| [q.face.index() as u32, q.x, q.y]).collect() })
            .collect(),
    }
    .with_hash();
    let text = serde_json::to_vec(&m).expect("a manifest serialises");
    crate::files::write_atomic(manifest, &text)
        .map_err(|e| StoreError::caused(manifest, "cannot write the manifest", e))?;
    Ok(PlanReport { manifest: m, seconds: start.elapsed().as_secs_f64() })
}

/// How one shard is run.
#[derive(Clone, Debug)]
pub struct ShardOptions {
    /// The manifest.
    pub manifest: PathBuf,
    /// The shard's index.
    pub shard: usize,
    /// Where the finished partial store is published.
    pub store: PathBuf,
    /// Where it is built (node-local disk), if not beside `store`; copied over when complete.
    pub work_dir: Option<PathBuf>,
    /// Worker threads (default: all cores).
    pub threads: Option<usize>,
    /// Memory budget, bytes.
    pub memory_budget: u64,
    /// Draw a progress bar.
    pub progress: bool,
    /// Progress and cancel from another thread.
    pub watch: Option<std::sync::Arc<ImportWatch>>,
}

/// What a partial store says about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct PartInfo {
    /// The manifest's hash.
    pub manifest: String,
    /// The shard.
    pub shard: usize,
    /// The plan's shards.
    pub shards: usize,
    /// Whether the shard's import finished.
    pub complete: bool,
}

/// Reads a partial store's header: `None` for a store that is not a shard's.
pub fn part_info(store: &Store) -> Result<Option<PartInfo>, StoreError> {
    let (Some(manifest), Some(shard), Some(shards)) =
        (store.header(HEADER_MANIFEST)?, store.header(HEADER_SHARD)?, store.header(HEADER_SHARDS)?)
    else {
        return Ok(None);
    };
    let bad = |k: &str| StoreError::new(store.path(), format!("damaged partial-store header: {k}"));
    let complete = store.datasets()?.iter().all(|d| d.completed.is_some());
    Ok(Some(PartInfo {
        manifest,
        shard: shard.parse().map_err(|_| bad(HEADER_SHARD))?,
        shards: shards.parse().map_err(|_| bad(HEADER_SHARDS))?,
        complete,
    }))
}

/// Whether `path` holds shard `shard` of manifest `m`, complete.
pub fn part_is_done(path: &Path, m: &Manifest, shard: usize) -> bool {
    Store::open_read_only(path)
        .ok()
        .and_then(|s| part_info(&s).ok().flatten())
        .is_some_and(|p| p.manifest == m.hash && p.shard == shard && p.complete)
}

/// `terrafuse import --manifest M --shard I --store PART`: imports shard I alone into a
/// partial store (the finest level only). The store is built in a working file (beside the
/// target, or in `work_dir`) whose journal a rerun resumes from, and published by a rename,
/// or by a copy and a rename from another disk, only when complete. Rerunning a finished
/// shard does nothing.
pub fn import_shard(opts: &ShardOptions) -> Result<ImportReport, StoreError> {
    let m = Manifest::load(&opts.manifest)?;
    let quads = m.shard_quads(opts.shard).map_err(|e| StoreError::new(&opts.manifest, format!("--shard: {e}")))?;
    let import = m
        .import_options(&opts.store, opts.threads, opts.memory_budget)
        .map_err(|e| StoreError::new(&opts.manifest, e))?;
    let done = ImportReport {
        dataset: m.import.dataset.clone(),
        finest_level: m.import.level,
        vertical_datum: m.settings.vertical_datum.clone(),
        already_complete: true,
        peak_rss_bytes: peak_rss_bytes(),
        ..Default::default()
    };
    if opts.store.exists() {
        let existing = Store::open_read_only(&opts.store)?;
        match part_info(&existing)? {
            Some(p) if p.manifest == m.hash && p.shard == opts.shard && p.complete => return Ok(done),
            _ => {
                return Err(StoreError::new(
                    &opts.store,
                    format!(
                        "exists and is not shard {} of plan {}: remove it or choose another --store",
                        opts.shard,
                        m.short_hash()
                    ),
                ));
            }
        }
    }
    let prepared = prepare(&import)?;
    check_unchanged(&m, &prepared)?;
    let work = working_file(&opts.store, opts.work_dir.as_deref())?;
    // A working file of another plan or shard (a reused name) is ours to drop.
    if work.exists() {
        let keep = Store::open_read_only(&work)
            .ok()
            .and_then(|s| part_info(&s).ok().flatten())
            .is_some_and(|p| p.manifest == m.hash && p.shard == opts.shard);
        if !keep {
            remove_store_files(&work);
        }
    }
    let mut store = open_dataset(&work, &import.body, &prepared)?;
    store.set_header(HEADER_MANIFEST, &m.hash)?;
    store.set_header(HEADER_SHARD, &opts.shard.to_string())?;
    store.set_header(HEADER_SHARDS, &m.shards.len().to_string())?;
    let body = *store.body();
    let pool = worker_pool(&opts.store, prepared.threads)?;
    let mut levels =
        LevelWriter::new(&mut store, &prepared.name, &pool, prepared.budget, opts.progress, opts.watch.as_deref());
    let start = Instant::now();
    let (written, finished, computed) = finest_level(&mut levels, &prepared, &body, quads)?;
    let seconds_finest = start.elapsed().as_secs_f64();
    store.mark_complete(&prepared.name)?;
    drop(store);
    publish(&work, &opts.store)?;
    Ok(ImportReport {
        levels: vec![(prepared.level, written, finished)],
        finest_samples: computed as u64 * u64::from(GRID * GRID),
        seconds_finest,
        lattice: prepared.plan.lattice.summary(),
        already_complete: false,
        peak_rss_bytes: peak_rss_bytes(),
        ..done
    })
}

/// Refuses to run a shard on sources that are not those of the plan.
fn check_unchanged(m: &Manifest, p: &Prepared) -> Result<(), StoreError> {
    if p.settings != m.settings || !same_files(&p.provenance, &m.provenance) {
        let changed = m
            .provenance
            .iter()
            .zip(&p.provenance)
            .find(|(a, b)| a.file_bytes != b.file_bytes || a.modified_unix_s != b.modified_unix_s)
            .map(|(a, _)| PathBuf::from(&a.path));
        return Err(match changed {
            Some(path) => {
                StoreError::new(&path, "changed since the plan was made (size or modification time): plan again")
            }
            None => StoreError::new(
                Path::new(&m.import.sources[0]),
                "the import's settings here differ from the plan's (another terrafuse or PROJ grid?): plan again",
            ),
        });
    }
    Ok(())
}

/// The working file of a partial store: `.NAME.importing` beside it or in `work_dir`.
fn working_file(store: &Path, work_dir: Option<&Path>) -> Result<PathBuf, StoreError> {
    let name = store
        .file_name()
        .ok_or_else(|| StoreError::new(store, "--store names no file"))?
        .to_string_lossy()
        .into_owned();
    let dir = match work_dir {
        Some(d) => {
            std::fs::create_dir_all(d).map_err(|e| StoreError::caused(d, "cannot make the work folder", e))?;
            d.to_owned()
        }
        None => crate::files::folder_of(store).to_owned(),
    };
    Ok(dir.join(format!(".{name}.importing")))
}

fn remove_store_files(path: &Path) {
    let _ = std::fs::remove_file(path);
    for suffix in ["-wal", "-shm", "-journal"] {
        let mut p = path.as_os_str().to_owned();
        p.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(p));
    }
}

/// Moves a finished working file to its place: a rename on the same file system, else a copy
/// to a temporary beside the target, fsync, and a rename; the folder is synced after.
fn publish(work: &Path, target: &Path) -> Result<(), StoreError> {
    let err = |what: &str, e: std::io::Error| StoreError::caused(target, what, e);
    std::fs::File::open(work).and_then(|f| f.sync_all()).map_err(|e| err("cannot sync the shard's store", e))?;
    let dir = crate::files::folder_of(target);
    if std::fs::rename(work, target).is_err() {
        let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = dir.join(format!(".{name}.copying-{}", std::process::id()));
        let copied = std::fs::copy(work, &tmp)
            .and_then(|_| std::fs::File::open(&tmp)?.sync_all())
            .and_then(|_| std::fs::rename(&tmp, target));
        if let Err(e) = copied {
            let _ = std::fs::remove_file(&tmp);
            return Err(err("cannot copy the shard's store into place", e));
        }
        remove_store_files(work);
    }
    std::fs::File::open(dir).and_then(|f| f.sync_all()).map_err(|e| err("cannot sync the folder", e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hilbert_index_visits_every_cell_once_through_neighbours() {
        for order in 1..=5u8 {
            let n = 1u32 << order;
            let mut cells: Vec<(u64, u32, u32)> =
                (0..n).flat_map(|x| (0..n).map(move |y| (hilbert_index(order, x, y), x, y))).collect();
            cells.sort();
            for (k, w) in cells.windows(2).enumerate() {
                assert_eq!(w[0].0 + 1, w[1].0, "order {order}: indices are 0..n² once each");
                let step = w[0].1.abs_diff(w[1].1) + w[0].2.abs_diff(w[1].2);
                assert_eq!(step, 1, "order {order}, step {k}: {:?} → {:?} is not a neighbour", w[0], w[1]);
            }
            assert_eq!(cells[0].0, 0);
        }
    }

    #[test]
    fn shards_are_contiguous_and_even_and_cover_every_quad_once() {
        let quads: Vec<QuadId> = Face::ALL
            .iter()
            .flat_map(|&f| (0..8u32).flat_map(move |x| (0..8u32).map(move |y| QuadId::new(f, 3, x, y).unwrap())))
            .filter(|q| !(q.x + q.y + q.face.index() as u32).is_multiple_of(3))
            .collect();
        for shards in [1, 2, 5, 7, quads.len()] {
            let cut = cut(quads.clone(), shards);
            let sizes: Vec<usize> = cut.iter().map(Vec::len).collect();
            assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "{sizes:?}");
            let all: HashSet<QuadId> = cut.iter().flatten().copied().collect();
            assert_eq!(all.len(), quads.len());
            assert_eq!(sizes.iter().sum::<usize>(), quads.len());
        }
    }
}
