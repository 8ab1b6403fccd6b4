//! The store file: a GeoPackage (SQLite) with, per dataset, one tiled gridded-coverage table per
//! cube face in that face's QSC CRS, plus Terrafuse's own tables (store header, datasets with
//! their provenance, tile rims, and the import journal that makes imports resumable).
//!
//! Every write is one SQLite transaction (WAL journal): a kill at any moment leaves the last
//! committed state, which opens and which a rerun of the import continues from.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags, OptionalExtension, params};
use serde::{Deserialize, Serialize};

use super::StoreError;
use super::tile::{EncodedQuad, QuadGrid};
use crate::ecm::grid::{TILE, intervals_per_face_edge};
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;

/// The GeoPackage application id ('GPKG') and version 1.2 (10200).
const APPLICATION_ID: i64 = 0x4750_4B47;
const USER_VERSION: i64 = 10_200;
/// The store's own format name and version, kept in `terrafuse_store`.
pub const FORMAT: &str = "terrafuse-store";
/// The store format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
const COVERAGE_EXTENSION: &str = "http://docs.opengeospatial.org/is/17-066r1/17-066r1.html";

/// How a dataset was made: everything that decides its samples. A rerun of an import with the
/// same settings continues it; with other settings it is refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetSettings {
    /// Source files, absolute paths, in priority order.
    pub sources: Vec<String>,
    /// Finest level stored.
    pub finest_level: u8,
    /// Resampling: bilinear, cubic or nearest.
    pub resampling: String,
    /// Sub-samples per axis averaged per sample at the finest level (1: point sampling).
    pub supersample: u32,
    /// How sample positions in the sources were computed: `lattice` (exact on a lattice,
    /// interpolated within 10⁻³ pixel, else exact) or `exact` (stores made before the lattice).
    #[serde(default = "exact_transform")]
    pub transform: String,
    /// The vertical datum of the stored heights, in words.
    pub vertical_datum: String,
    /// The geoid grid used to convert geoid heights to ellipsoidal ones, if any.
    pub geoid_grid: Option<String>,
}

fn exact_transform() -> String {
    "exact".into()
}

impl DatasetSettings {
    /// Whether two settings make the same samples: equal but for the transform (the lattice and
    /// the exact path agree to float rounding), so that a store made before the lattice, or with
    /// the other path, is resumed or found complete rather than refused.
    pub fn same_samples(&self, other: &DatasetSettings) -> bool {
        DatasetSettings { transform: String::new(), ..self.clone() }
            == DatasetSettings { transform: String::new(), ..other.clone() }
    }
}

/// What the store keeps about each source of a dataset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SourceProvenance {
    /// Absolute path.
    pub path: String,
    /// GDAL driver.
    pub driver: String,
    /// Raster size in pixels.
    pub size: (usize, usize),
    /// Sample type.
    pub data_type: String,
    /// The CRS as WKT.
    pub crs_wkt: String,
    /// The CRS in PROJ syntax, for reading.
    pub crs_proj: String,
    /// Declared nodata value.
    pub nodata: Option<f64>,
    /// Pixel-is-area or pixel-is-point.
    pub pixel_convention: String,
    /// Ground resolution at the raster's centre, metres.
    pub resolution_m: f64,
    /// Bounds: west, south, east, north, degrees.
    pub bounds_deg: [f64; 4],
    /// File size in bytes and modification time (Unix seconds), to notice a changed source.
    pub file_bytes: u64,
    /// Modification time, Unix seconds.
    pub modified_unix_s: u64,
}

/// A dataset as the store records it.
#[derive(Clone, Debug, PartialEq)]
pub struct DatasetRecord {
    /// Dataset name (also the prefix of its face tables).
    pub name: String,
    /// Settings.
    pub settings: DatasetSettings,
    /// Provenance of each source.
    pub sources: Vec<SourceProvenance>,
    /// When the import started (UTC, ISO 8601).
    pub created: String,
    /// When the import finished, if it did.
    pub completed: Option<String>,
}

/// Tiles of one dataset and level: how many per face.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelCount {
    /// Level.
    pub level: u8,
    /// Tiles per face, in [`Face::ALL`] order.
    pub per_face: [u64; 6],
}

/// An open store.
pub struct Store {
    path: PathBuf,
    conn: Connection,
    body: Ellipsoid,
}

fn sql_err(path: &Path, what: &str) -> impl Fn(rusqlite::Error) -> StoreError + use<> {
    let (path, what) = (path.to_owned(), what.to_owned());
    move |e| StoreError::caused(&path, what.as_str(), e)
}

/// The face table of a dataset: `<dataset>_<face>`.
pub fn face_table(dataset: &str, face: Face) -> String {
    format!("{dataset}_{}", face.name())
}

/// Checks a dataset name: letters, digits and underscores, starting with a letter, ≤ 48 chars.
pub fn check_dataset_name(name: &str) -> Result<(), crate::Invalid> {
    let ok = !name.is_empty()
        && name.len() <= 48
        && name.starts_with(|c: char| c.is_ascii_alphabetic())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "dataset name '{name}' is not usable as a table name: use letters, digits and '_', starting with a letter, at most 48 characters"
        ).into())
    }
}

/// The QSC CRS of one face on a body, as PROJ parameters.
pub fn face_proj(body: &Ellipsoid, face: Face) -> String {
    format!("+proj=qsc {} +a={} +b={} +units=m +no_defs", face.proj_center(), body.a_m(), body.b_m())
}

fn srs_id(face: Face) -> i64 {
    100_000 + face.index() as i64
}

/// The UTC time now, ISO 8601 with seconds.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

const SCHEMA: &str = r#"
CREATE TABLE gpkg_spatial_ref_sys (srs_name TEXT NOT NULL, srs_id INTEGER NOT NULL PRIMARY KEY,
  organization TEXT NOT NULL, organization_coordsys_id INTEGER NOT NULL, definition TEXT NOT NULL, description TEXT);
CREATE TABLE gpkg_contents (table_name TEXT NOT NULL PRIMARY KEY, data_type TEXT NOT NULL, identifier TEXT UNIQUE,
  description TEXT DEFAULT '', last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE, srs_id INTEGER,
  CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id));
CREATE TABLE gpkg_tile_matrix_set (table_name TEXT NOT NULL PRIMARY KEY, srs_id INTEGER NOT NULL,
  min_x DOUBLE NOT NULL, min_y DOUBLE NOT NULL, max_x DOUBLE NOT NULL, max_y DOUBLE NOT NULL,
  CONSTRAINT fk_gtms_table_name FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
  CONSTRAINT fk_gtms_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys (srs_id));
CREATE TABLE gpkg_tile_matrix (table_name TEXT NOT NULL, zoom_level INTEGER NOT NULL, matrix_width INTEGER NOT NULL,
  matrix_height INTEGER NOT NULL, tile_width INTEGER NOT NULL, tile_height INTEGER NOT NULL,
  pixel_x_size DOUBLE NOT NULL, pixel_y_size DOUBLE NOT NULL,
  CONSTRAINT pk_ttm PRIMARY KEY (table_name, zoom_level),
  CONSTRAINT fk_tmm_table_name FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name));
CREATE TABLE gpkg_extensions (table_name TEXT, column_name TEXT, extension_name TEXT NOT NULL,
  definition TEXT NOT NULL, scope TEXT NOT NULL, CONSTRAINT ge_tce UNIQUE (table_name, column_name, extension_name));
CREATE TABLE gpkg_2d_gridded_coverage_ancillary (id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
  tile_matrix_set_name TEXT NOT NULL UNIQUE, datatype TEXT NOT NULL DEFAULT 'integer', scale REAL NOT NULL DEFAULT 1.0,
  offset REAL NOT NULL DEFAULT 0.0, precision REAL DEFAULT 1.0, data_null REAL,
  grid_cell_encoding TEXT DEFAULT 'grid-value-is-center', uom TEXT, field_name TEXT DEFAULT 'Height',
  quantity_definition TEXT DEFAULT 'Height',
  CONSTRAINT fk_g2dgtct_name FOREIGN KEY(tile_matrix_set_name) REFERENCES gpkg_tile_matrix_set (table_name)
  CHECK (datatype in ('integer','float')));
CREATE TABLE gpkg_2d_gridded_tile_ancillary (id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, tpudt_name TEXT NOT NULL,
  tpudt_id INTEGER NOT NULL, scale REAL NOT NULL DEFAULT 1.0, offset REAL NOT NULL DEFAULT 0.0, min REAL DEFAULT NULL,
  max REAL DEFAULT NULL, mean REAL DEFAULT NULL, std_dev REAL DEFAULT NULL,
  CONSTRAINT fk_g2dgtat_name FOREIGN KEY (tpudt_name) REFERENCES gpkg_contents(table_name), UNIQUE (tpudt_name, tpudt_id));
INSERT INTO gpkg_spatial_ref_sys VALUES ('Undefined Cartesian SRS', -1, 'NONE', -1, 'undefined', 'undefined Cartesian coordinate reference system');
INSERT INTO gpkg_spatial_ref_sys VALUES ('Undefined geographic SRS', 0, 'NONE', 0, 'undefined', 'undefined geographic coordinate reference system');
INSERT INTO gpkg_spatial_ref_sys VALUES ('WGS 84 geodetic', 4326, 'EPSG', 4326, 'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]', 'longitude/latitude coordinates in decimal degrees on the WGS 84 spheroid');
CREATE TABLE terrafuse_store (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE terrafuse_datasets (name TEXT PRIMARY KEY, settings TEXT NOT NULL, sources TEXT NOT NULL,
  created TEXT NOT NULL, completed TEXT);
CREATE TABLE terrafuse_rims (dataset TEXT NOT NULL, level INTEGER NOT NULL, face INTEGER NOT NULL, x INTEGER NOT NULL,
  y INTEGER NOT NULL, rim BLOB NOT NULL, PRIMARY KEY (dataset, level, face, x, y)) WITHOUT ROWID;
CREATE TABLE terrafuse_journal (dataset TEXT NOT NULL, level INTEGER NOT NULL, face INTEGER NOT NULL, x INTEGER NOT NULL,
  y INTEGER NOT NULL, has_data INTEGER NOT NULL, PRIMARY KEY (dataset, level, face, x, y)) WITHOUT ROWID;
"#;

/// SQLite's page size for new stores, bytes (its largest). A tile is a blob of about 260 KB:
/// with 64 KiB pages it spans 5 pages instead of 65, so writing and reading it takes 13× fewer
/// page operations and system calls.
const PAGE_SIZE: u32 = 65_536;

impl Store {
    /// Creates a new, empty store for a body. The file appears complete or not at all: it is
    /// built beside the target and renamed into place. Refuses to overwrite an existing file.
    pub fn create(path: &Path, body: &Ellipsoid) -> Result<Store, StoreError> {
        if path.exists() {
            return Err(StoreError::new(path, "already exists; open it instead of creating it"));
        }
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.is_dir() {
            return Err(StoreError::new(path, format!("folder {} does not exist", dir.display())));
        }
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = dir.join(format!(".{name}.creating-{}", std::process::id()));
        let _ = std::fs::remove_file(&tmp);
        let result = (|| {
            let conn = Connection::open(&tmp).map_err(sql_err(path, "cannot create the store"))?;
            conn.execute_batch(&format!(
                "PRAGMA page_size = {PAGE_SIZE}; PRAGMA application_id = {APPLICATION_ID}; \
                 PRAGMA user_version = {USER_VERSION}; BEGIN; {SCHEMA} COMMIT;"
            ))
            .map_err(sql_err(path, "cannot write the store schema"))?;
            let header = [
                ("format", FORMAT.to_owned()),
                ("version", FORMAT_VERSION.to_string()),
                ("body", body.name().to_owned()),
                ("a_m", format!("{:?}", body.a_m())),
                ("b_m", format!("{:?}", body.b_m())),
                ("created", utc_now()),
            ];
            for (k, v) in header {
                conn.execute("INSERT INTO terrafuse_store VALUES (?1, ?2)", params![k, v])
                    .map_err(sql_err(path, "cannot write the store header"))?;
            }
            conn.close().map_err(|(_, e)| StoreError::caused(path, "cannot close the new store", e))?;
            std::fs::File::open(&tmp)
                .and_then(|f| f.sync_all())
                .map_err(|e| StoreError::caused(path, "cannot sync the new store", e))?;
            std::fs::rename(&tmp, path).map_err(|e| StoreError::caused(path, "cannot move the new store into place", e))
        })();
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result?;
        Store::open(path)
    }

    /// Opens an existing store for reading and writing. Refuses files that are not Terrafuse
    /// stores, or of a newer format.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        Store::open_with(path, OpenFlags::SQLITE_OPEN_READ_WRITE)
    }

    /// Opens an existing store read-only.
    pub fn open_read_only(path: &Path) -> Result<Store, StoreError> {
        Store::open_with(path, OpenFlags::SQLITE_OPEN_READ_ONLY)
    }

    fn open_with(path: &Path, flags: OpenFlags) -> Result<Store, StoreError> {
        if !path.is_file() {
            return Err(StoreError::new(path, "no such store file"));
        }
        let conn = Connection::open_with_flags(path, flags | OpenFlags::SQLITE_OPEN_NO_MUTEX)
            .map_err(sql_err(path, "cannot open the store"))?;
        conn.busy_timeout(std::time::Duration::from_secs(30)).map_err(sql_err(path, "cannot open the store"))?;
        let header = |key: &str| -> Result<Option<String>, rusqlite::Error> {
            conn.query_row("SELECT value FROM terrafuse_store WHERE key = ?1", [key], |r| r.get(0)).optional()
        };
        let format = header("format").map_err(|e| {
            StoreError::caused(path, "is not a Terrafuse store (not a GeoPackage made by `terrafuse import`)", e)
        })?;
        if format.as_deref() != Some(FORMAT) {
            return Err(StoreError::new(path, "is not a Terrafuse store (unknown format)"));
        }
        let version: u32 = header("version").ok().flatten().and_then(|v| v.parse().ok()).unwrap_or(0);
        if version == 0 || version > FORMAT_VERSION {
            return Err(StoreError::new(
                path,
                format!("store format version {version}; this terrafuse reads versions 1 to {FORMAT_VERSION}"),
            ));
        }
        let axis = |key: &str| header(key).ok().flatten().and_then(|v| v.parse::<f64>().ok());
        let name = header("body").ok().flatten().unwrap_or_default();
        let body = match (axis("a_m"), axis("b_m")) {
            (Some(a), Some(b)) => name.parse::<Ellipsoid>().ok().filter(|e| e.a_m() == a && e.b_m() == b).map_or_else(
                || Ellipsoid::from_axes(a, b).map_err(|e| StoreError::caused(path, "store body", e)),
                Ok,
            )?,
            _ => return Err(StoreError::new(path, "store header has no body axes")),
        };
        if flags.contains(OpenFlags::SQLITE_OPEN_READ_WRITE) {
            conn.execute_batch("PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL;")
                .map_err(sql_err(path, "cannot set the journal mode"))?;
        }
        Ok(Store { path: path.to_owned(), conn, body })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A value of the store's header (`terrafuse_store`).
    pub fn header(&self, key: &str) -> Result<Option<String>, StoreError> {
        self.conn
            .query_row("SELECT value FROM terrafuse_store WHERE key = ?1", [key], |r| r.get(0))
            .optional()
            .map_err(self.err("cannot read the store header"))
    }

    /// Sets a value of the store's header.
    pub fn set_header(&mut self, key: &str, value: &str) -> Result<(), StoreError> {
        self.conn
            .execute("INSERT OR REPLACE INTO terrafuse_store VALUES (?1, ?2)", params![key, value])
            .map(|_| ())
            .map_err(self.err("cannot write the store header"))
    }

    /// The SQLite connection, for the merge's attached statements.
    /// Turns the writer's automatic checkpoints of the log on (SQLite's default, every 1000
    /// pages) or off, while a [`super::checkpoint::BackgroundCheckpoints`] does them.
    pub fn set_auto_checkpoints(&self, on: bool) -> Result<(), StoreError> {
        self.conn
            .execute_batch(if on { "PRAGMA wal_autocheckpoint = 1000;" } else { "PRAGMA wal_autocheckpoint = 0;" })
            .map_err(self.err("cannot set the automatic checkpoints"))
    }

    pub(super) fn connection(&mut self) -> &mut Connection {
        &mut self.conn
    }

    /// The body every dataset of the store lies on.
    pub fn body(&self) -> &Ellipsoid {
        &self.body
    }

    fn err(&self, what: &str) -> impl Fn(rusqlite::Error) -> StoreError + use<> {
        sql_err(&self.path, what)
    }

    /// All datasets, by name.
    pub fn datasets(&self) -> Result<Vec<DatasetRecord>, StoreError> {
        let mut stmt = self
            .conn
            .prepare("SELECT name, settings, sources, created, completed FROM terrafuse_datasets ORDER BY name")
            .map_err(self.err("cannot list datasets"))?;
        let rows = stmt
            .query_map([], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?, r.get::<_, String>(2)?, r.get(3)?, r.get(4)?))
            })
            .map_err(self.err("cannot list datasets"))?;
        let mut out = Vec::new();
        for row in rows {
            let (name, settings, sources, created, completed) = row.map_err(self.err("cannot list datasets"))?;
            let bad =
                |e: serde_json::Error| StoreError::caused(&self.path, format!("dataset {name}: damaged record"), e);
            out.push(DatasetRecord {
                settings: serde_json::from_str(&settings).map_err(bad)?,
                sources: serde_json::from_str(&sources).map_err(bad)?,
                name,
                created,
                completed,
            });
        }
        Ok(out)
    }

    /// One dataset by name.
    pub fn dataset(&self, name: &str) -> Result<Option<DatasetRecord>, StoreError> {
        Ok(self.datasets()?.into_iter().find(|d| d.name == name))
    }

    /// The dataset a reader means: the named one, or the only one.
    pub fn resolve_dataset(&self, name: Option<&str>) -> Result<DatasetRecord, StoreError> {
        let all = self.datasets()?;
        let names = || all.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", ");
        match name {
            Some(n) => all
                .iter()
                .find(|d| d.name == n)
                .cloned()
                .ok_or_else(|| StoreError::new(&self.path, format!("has no dataset '{n}' (datasets: {})", names()))),
            None if all.len() == 1 => Ok(all[0].clone()),
            None if all.is_empty() => Err(StoreError::new(&self.path, "has no datasets")),
            None => {
                Err(StoreError::new(&self.path, format!("has several datasets; name one with --dataset ({})", names())))
            }
        }
    }

    /// Registers a dataset and creates its six face tables with tile matrices for levels
    /// 0 ..= finest, in one transaction.
    pub fn add_dataset(&mut self, record: &DatasetRecord, crs_wkt: &[String; 6]) -> Result<(), StoreError> {
        check_dataset_name(&record.name).map_err(|m| StoreError::new(&self.path, m))?;
        let a = self.body.a_m();
        let description = format!(
            "terrafuse dataset {}: {} source(s), first {}; heights: {}",
            record.name,
            record.sources.len(),
            record.settings.sources.first().map(String::as_str).unwrap_or("-"),
            record.settings.vertical_datum
        );
        let path = self.path.clone();
        let tx = self.conn.transaction().map_err(sql_err(&path, "cannot start a transaction"))?;
        let e = |what: &'static str| sql_err(&path, what);
        for face in Face::ALL {
            tx.execute(
                "INSERT OR IGNORE INTO gpkg_spatial_ref_sys VALUES (?1, ?2, 'NONE', ?2, ?3, ?4)",
                params![
                    format!("QSC {} face, {}", face.name(), self.body.name()),
                    srs_id(face),
                    crs_wkt[face.index()],
                    face_proj(&self.body, face)
                ],
            )
            .map_err(e("cannot write the face CRS"))?;
            let table = face_table(&record.name, face);
            tx.execute_batch(&format!(
                "CREATE TABLE \"{table}\" (id INTEGER PRIMARY KEY AUTOINCREMENT, zoom_level INTEGER NOT NULL,
                 tile_column INTEGER NOT NULL, tile_row INTEGER NOT NULL, tile_data BLOB NOT NULL,
                 UNIQUE (zoom_level, tile_column, tile_row));"
            ))
            .map_err(e("cannot create a face table"))?;
            tx.execute(
                "INSERT INTO gpkg_contents (table_name, data_type, identifier, description, min_x, min_y, max_x, max_y, srs_id)
                 VALUES (?1, '2d-gridded-coverage', ?1, ?2, ?3, ?3, ?4, ?4, ?5)",
                params![table, description, -a, a, srs_id(face)],
            )
            .map_err(e("cannot register a face table"))?;
            tx.execute(
                "INSERT INTO gpkg_tile_matrix_set VALUES (?1, ?2, ?3, ?3, ?4, ?4)",
                params![table, srs_id(face), -a, a],
            )
            .map_err(e("cannot write a tile matrix set"))?;
            for level in 0..=record.settings.finest_level {
                let n = 1i64 << level;
                let pixel = 2.0 * a / intervals_per_face_edge(level) as f64;
                tx.execute(
                    "INSERT INTO gpkg_tile_matrix VALUES (?1, ?2, ?3, ?3, ?4, ?4, ?5, ?5)",
                    params![table, level, n, TILE, pixel],
                )
                .map_err(e("cannot write a tile matrix"))?;
            }
            tx.execute(
                "INSERT INTO gpkg_2d_gridded_coverage_ancillary (tile_matrix_set_name, datatype, scale, offset, precision,
                 data_null, grid_cell_encoding, uom, field_name, quantity_definition)
                 VALUES (?1, 'float', 1.0, 0.0, 0.0, NULL, 'grid-value-is-corner', 'm', 'Height', 'Height')",
                [&table],
            )
            .map_err(e("cannot write the coverage description"))?;
            tx.execute(
                "INSERT INTO gpkg_extensions VALUES (?1, 'tile_data', 'gpkg_2d_gridded_coverage', ?2, 'read-write')",
                params![table, COVERAGE_EXTENSION],
            )
            .map_err(e("cannot register the coverage extension"))?;
        }
        for t in ["gpkg_2d_gridded_coverage_ancillary", "gpkg_2d_gridded_tile_ancillary"] {
            tx.execute(
                "INSERT OR IGNORE INTO gpkg_extensions VALUES (?1, NULL, 'gpkg_2d_gridded_coverage', ?2, 'read-write')",
                params![t, COVERAGE_EXTENSION],
            )
            .map_err(e("cannot register the coverage extension"))?;
        }
        let settings = serde_json::to_string(&record.settings).expect("settings serialise");
        let sources = serde_json::to_string(&record.sources).expect("provenance serialises");
        tx.execute(
            "INSERT INTO terrafuse_datasets VALUES (?1, ?2, ?3, ?4, NULL)",
            params![record.name, settings, sources, record.created],
        )
        .map_err(e("cannot register the dataset"))?;
        tx.commit().map_err(e("cannot commit the new dataset"))
    }

    /// Writes finished quads of one level in one transaction: tiles with data (GeoPackage tile,
    /// tile statistics, rim) and, for every quad, its journal entry, so that a resumed import
    /// skips it.
    pub fn write_quads(&mut self, dataset: &str, quads: &[(QuadId, Option<EncodedQuad>)]) -> Result<(), StoreError> {
        let path = self.path.clone();
        let e = |what: &'static str| sql_err(&path, what);
        let tx = self.conn.transaction().map_err(e("cannot start a transaction"))?;
        for (quad, grid) in quads {
            let face = quad.face.index() as i64;
            if let Some(grid) = grid {
                let table = face_table(dataset, quad.face);
                let row = (1i64 << quad.level) - 1 - i64::from(quad.y);
                tx.prepare_cached(&format!(
                    "INSERT OR REPLACE INTO \"{table}\" (zoom_level, tile_column, tile_row, tile_data) VALUES (?1, ?2, ?3, ?4)"
                ))
                .and_then(|mut st| st.execute(params![quad.level, quad.x, row, grid.tile]))
                .map_err(e("cannot write a tile"))?;
                let id = tx.last_insert_rowid();
                let s = &grid.stats;
                tx.prepare_cached(
                    "INSERT OR REPLACE INTO gpkg_2d_gridded_tile_ancillary (tpudt_name, tpudt_id, scale, offset, min, max, mean, std_dev)
                     VALUES (?1, ?2, 1.0, 0.0, ?3, ?4, ?5, ?6)",
                )
                .and_then(|mut st| st.execute(params![table, id, s.min, s.max, s.mean, s.std_dev]))
                .map_err(e("cannot write tile statistics"))?;
                tx.prepare_cached("INSERT OR REPLACE INTO terrafuse_rims VALUES (?1, ?2, ?3, ?4, ?5, ?6)")
                    .and_then(|mut st| st.execute(params![dataset, quad.level, face, quad.x, quad.y, grid.rim]))
                    .map_err(e("cannot write a tile rim"))?;
            }
            tx.prepare_cached("INSERT OR REPLACE INTO terrafuse_journal VALUES (?1, ?2, ?3, ?4, ?5, ?6)")
                .and_then(|mut st| st.execute(params![dataset, quad.level, face, quad.x, quad.y, grid.is_some()]))
                .map_err(e("cannot write the import journal"))?;
        }
        tx.commit().map_err(e("cannot commit tiles"))
    }

    /// Quads of a level that an import already finished (with or without data).
    pub fn finished_quads(&self, dataset: &str, level: u8) -> Result<HashSet<QuadId>, StoreError> {
        self.quad_query("SELECT face, x, y FROM terrafuse_journal WHERE dataset = ?1 AND level = ?2", dataset, level)
    }

    /// Quads of a level that have data.
    pub fn data_quads(&self, dataset: &str, level: u8) -> Result<HashSet<QuadId>, StoreError> {
        self.quad_query("SELECT face, x, y FROM terrafuse_rims WHERE dataset = ?1 AND level = ?2", dataset, level)
    }

    fn quad_query(&self, sql: &str, dataset: &str, level: u8) -> Result<HashSet<QuadId>, StoreError> {
        let mut stmt = self.conn.prepare_cached(sql).map_err(self.err("cannot read the journal"))?;
        let rows = stmt
            .query_map(params![dataset, level], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, u32>(1)?, r.get::<_, u32>(2)?)))
            .map_err(self.err("cannot read the journal"))?;
        let mut out = HashSet::new();
        for row in rows {
            let (f, x, y) = row.map_err(self.err("cannot read the journal"))?;
            let face = Face::from_index(f as usize)
                .ok_or_else(|| StoreError::new(&self.path, format!("journal names face {f}")))?;
            out.insert(QuadId { face, level, x, y });
        }
        Ok(out)
    }

    /// The 257² grid of a quad, or `None` where the dataset has no data.
    pub fn read_grid(&self, dataset: &str, quad: QuadId) -> Result<Option<QuadGrid>, StoreError> {
        let table = face_table(dataset, quad.face);
        let row = (1i64 << quad.level) - 1 - i64::from(quad.y);
        let tile: Option<Vec<u8>> = self
            .conn
            .prepare_cached(&format!(
                "SELECT tile_data FROM \"{table}\" WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3"
            ))
            .and_then(|mut s| s.query_row(params![quad.level, quad.x, row], |r| r.get(0)).optional())
            .map_err(self.err("cannot read a tile"))?;
        let Some(tile) = tile else { return Ok(None) };
        let rim: Vec<u8> = self
            .conn
            .prepare_cached(
                "SELECT rim FROM terrafuse_rims WHERE dataset = ?1 AND level = ?2 AND face = ?3 AND x = ?4 AND y = ?5",
            )
            .and_then(|mut s| {
                s.query_row(params![dataset, quad.level, quad.face.index() as i64, quad.x, quad.y], |r| r.get(0))
            })
            .map_err(self.err(&format!("tile {quad} has no rim")))?;
        QuadGrid::decode(&tile, &rim).map(Some).map_err(|e| StoreError::caused(&self.path, format!("tile {quad}"), e))
    }

    /// Tiles per level and face.
    pub fn level_counts(&self, dataset: &str) -> Result<Vec<LevelCount>, StoreError> {
        let mut stmt = self
            .conn
            .prepare("SELECT level, face, count(*) FROM terrafuse_rims WHERE dataset = ?1 GROUP BY level, face ORDER BY level")
            .map_err(self.err("cannot count tiles"))?;
        let rows = stmt
            .query_map([dataset], |r| {
                Ok((r.get::<_, u8>(0)?, r.get::<_, i64>(1)? as usize, r.get::<_, i64>(2)? as u64))
            })
            .map_err(self.err("cannot count tiles"))?;
        let mut out: Vec<LevelCount> = Vec::new();
        for row in rows {
            let (level, face, n) = row.map_err(self.err("cannot count tiles"))?;
            if out.last().is_none_or(|c| c.level != level) {
                out.push(LevelCount { level, per_face: [0; 6] });
            }
            if let Some(c) = out.last_mut() {
                c.per_face[face.min(5)] = n;
            }
        }
        Ok(out)
    }

    /// Height range of a dataset's tiles at a level (from the tile statistics).
    pub fn height_range(&self, dataset: &str, level: u8) -> Result<Option<(f64, f64)>, StoreError> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for face in Face::ALL {
            let table = face_table(dataset, face);
            let r: (Option<f64>, Option<f64>) = self
                .conn
                .query_row(
                    &format!(
                        "SELECT min(a.min), max(a.max) FROM gpkg_2d_gridded_tile_ancillary a JOIN \"{table}\" t
                         ON a.tpudt_name = ?1 AND a.tpudt_id = t.id WHERE t.zoom_level = ?2"
                    ),
                    params![table, level],
                    |r| Ok((r.get(0)?, r.get(1)?)),
                )
                .map_err(self.err("cannot read tile statistics"))?;
            if let (Some(a), Some(b)) = r {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        Ok((lo <= hi).then_some((lo, hi)))
    }

    /// Marks a dataset complete and folds the WAL journal into the file, so that the store is
    /// one self-contained file again.
    pub fn mark_complete(&mut self, dataset: &str) -> Result<(), StoreError> {
        self.conn
            .execute("UPDATE terrafuse_datasets SET completed = ?2 WHERE name = ?1", params![dataset, utc_now()])
            .map_err(self.err("cannot mark the dataset complete"))?;
        self.conn
            .execute_batch("PRAGMA wal_checkpoint(TRUNCATE); PRAGMA journal_mode = DELETE;")
            .map_err(self.err("cannot checkpoint the store"))
    }
}
