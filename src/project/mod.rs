//! The project file: a versioned JSON scene (body, layer stack, visual settings, named views).
//!
//! ```json
//! { "format": "terrafuse-project", "version": 4, "body": "moon",
//!   "layers": [ { "name": "lola", "kind": "dataset", "store": "stores/moon.gpkg",
//!                 "source": { "files": ["data/moon.tif"] } } ],
//!   "visuals": { "colour_map": { "preset": "hypsometric" }, "isolines": { "interval_m": 500 } },
//!   "views": { "overview": { "lat": 0, "lon": 0, "alt": 4e6, "heading": 0, "pitch": -90 } } }
//! ```
//!
//! Every field past `format`, `version` and `body` has a default, unknown fields are refused (a
//! typo must not be silently ignored), and relative paths resolve against the file's folder. The
//! version is checked on load: a file of a newer version is refused by name, older ones are
//! migrated on load ([`Project::parse`]) and saved in the current version.
//!
//! Versions (each older one migrates one step at a time, see [`migrate`]): 1 had `datasets`
//! (first listed wins per sample); 2 has `layers`, bottom to top (a version-1 file's datasets
//! become `over` dataset layers, the first listed on top); 3 adds `checks`, the expected digests
//! a replay verifies ([`checks`]); 4 writes an erosion run's `region` as
//! `[west, south, east, north]` like every other box (it was `[lat_min, lon_min, lat_max,
//! lon_max]`).
//!
//! Loading is bounded: a file over [`MAX_FILE_BYTES`] is refused before it is read, the current
//! version is parsed straight into the typed project (no intermediate JSON tree), every error
//! names the field by its path (`layers[2].strokes[10].radius_m`), and every list an operation
//! log can grow has a limit ([`crate::layers::spec::MAX_STROKES`], `MAX_RUNS`).

mod camera;
pub mod checks;
pub mod editing;
pub mod migrate;
pub mod recovery;
pub mod reference;
mod settings;

use crate::errors::AtField;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use self::camera::CameraSpec;
pub use self::checks::CheckSpec;
pub use self::migrate::DatasetSpec;
pub use self::settings::{
    BadDetailOverride, ColourBy, ColourMapSpec, ComparisonSpec, DetailSpec, IsolineSpec, LightingSpec, ProfileLine,
    SwipeSpec, Visuals, check_detail_overrides,
};
use crate::geodesy::Ellipsoid;
use crate::layers::LayerSpec;
pub use crate::layers::SourceSpec;

/// The `format` value of every project file.
pub const FORMAT: &str = "terrafuse-project";
/// The version this build writes (and the newest it reads).
pub const VERSION: u32 = 4;
/// The largest project file read, bytes: ten times a log of 10⁵ strokes.
pub const MAX_FILE_BYTES: u64 = 512 << 20;
/// Most quads a frame may draw (`detail.max_quads`).
pub const MAX_QUADS: usize = 1 << 16;
/// The largest cache budget, MiB (`detail.cpu_cache_mib`, `gpu_cache_mib`).
pub const MAX_CACHE_MIB: u64 = 1 << 20;
/// The most tiles one stroke or run may be allowed to write (2²⁰, 270 GB of heights).
pub const MAX_EDIT_TILES: u64 = 1 << 20;
/// The widest isoline, pixels (`visuals.isolines.*width_px`).
pub const MAX_LINE_WIDTH_PX: f32 = 64.0;
/// The body's semi-major axis, metres: from 1 km (a small asteroid) to 10⁸ m (past Jupiter's).
pub const BODY_RADIUS_M: [f64; 2] = [1e3, 1e8];

/// A serde error with the path of the field it is about.
fn field_error(e: serde_path_to_error::Error<serde_json::Error>) -> String {
    let path = e.path().to_string();
    if path == "." { e.into_inner().to_string() } else { format!("{path}: {}", e.into_inner()) }
}

/// `path` made absolute against the working folder, `.` and `..` folded away where possible.
fn absolute(path: &Path) -> PathBuf {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            std::path::Component::ParentDir if out.parent().is_some() => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// The relative path from folder `dir` to `target` (both absolute).
fn relative_to(target: &Path, dir: &Path) -> PathBuf {
    let (t, d): (Vec<_>, Vec<_>) = (target.components().collect(), dir.components().collect());
    let common = t.iter().zip(&d).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return target.to_path_buf();
    }
    let mut out: PathBuf = d[common..].iter().map(|_| "..").collect();
    out.extend(&t[common..]);
    out
}

pub use crate::errors::Invalid;

/// A project file that could not be read or written, naming the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    /// The file could not be read.
    #[error("{}: cannot read", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is too large to be a project.
    #[error("{}: {size} bytes: a project file is at most {MAX_FILE_BYTES} bytes (is it a project?)", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size in bytes.
        size: u64,
    },
    /// The file's text or values are not a valid project.
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field and the problem.
        problem: Invalid,
    },
    /// The project in memory is not valid, so it was not written (it would not load again).
    #[error("{}: not saved: {problem}", path.display())]
    NotSaved {
        /// The file.
        path: PathBuf,
        /// The field and the problem.
        problem: Invalid,
    },
    /// The project could not be encoded as JSON.
    #[error("{}: cannot encode the project", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// The file could not be written.
    #[error("{}: cannot write", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Another process holds the project (it is changing it) for longer than the wait.
    #[error(transparent)]
    Lock(#[from] crate::files::lock::LockError),
    /// Another process changed the file since this one read or wrote it: not written over.
    #[error(
        "{}: not saved: another process changed the file since it was opened here (reload it, or save these changes as a copy)",
        path.display()
    )]
    ChangedOnDisk {
        /// The file.
        path: PathBuf,
    },
}

/// The project: what `terrafuse render` and the workstation open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Project {
    /// Always [`FORMAT`].
    pub format: String,
    /// The schema version, [`VERSION`] for files this build writes.
    pub version: u32,
    /// The body: `wgs84`, `moon`, `mars`.
    pub body: String,
    /// The layer stack, bottom to top.
    #[serde(default)]
    pub layers: Vec<LayerSpec>,
    /// How the terrain looks.
    #[serde(default)]
    pub visuals: Visuals,
    /// Level of detail and caches.
    #[serde(default)]
    pub detail: DetailSpec,
    /// Named views.
    #[serde(default)]
    pub views: BTreeMap<String, CameraSpec>,
    /// The view shown when none is asked for (default: the first by name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_view: Option<String>,
    /// Saved swipes and profile lines.
    #[serde(default, skip_serializing_if = "ComparisonSpec::is_empty")]
    pub comparison: ComparisonSpec,
    /// Expected digests a replay checks, by name (see [`checks`]).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub checks: BTreeMap<String, CheckSpec>,
    /// The folder relative paths resolve against (not saved).
    #[serde(skip)]
    pub base_dir: PathBuf,
}

impl Project {
    /// An empty project on a body.
    pub fn new(body: &str) -> Project {
        Project {
            format: FORMAT.into(),
            version: VERSION,
            body: body.into(),
            layers: Vec::new(),
            visuals: Visuals::default(),
            detail: DetailSpec::default(),
            views: BTreeMap::new(),
            default_view: None,
            comparison: ComparisonSpec::default(),
            checks: BTreeMap::new(),
            base_dir: PathBuf::from("."),
        }
    }

    /// Reads and checks a project file (bounded: see the module's documentation).
    pub fn load(path: &Path) -> Result<Project, ProjectError> {
        Ok(Project::load_seen(path)?.0)
    }

    /// [`Project::load`], with what the file held as it was read (the workstation saves only
    /// while the file still holds that: see [`editing`]).
    pub fn load_seen(path: &Path) -> Result<(Project, editing::OnDisk), ProjectError> {
        let read = |source| ProjectError::Read { path: path.into(), source };
        let size = std::fs::metadata(path).map_err(read)?.len();
        if size > MAX_FILE_BYTES {
            return Err(ProjectError::TooLarge { path: path.into(), size });
        }
        let text = std::fs::read_to_string(path).map_err(read)?;
        let seen = editing::OnDisk::of(text.as_bytes());
        let mut project =
            Project::parse(&text).map_err(|problem| ProjectError::Invalid { path: path.into(), problem })?;
        project.base_dir = path.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        if project.base_dir.as_os_str().is_empty() {
            project.base_dir = PathBuf::from(".");
        }
        Ok((project, seen))
    }

    /// Parses and checks a project from JSON text (paths stay relative); an older version is
    /// migrated to [`VERSION`]. Errors name the field by its path.
    pub fn parse(text: &str) -> Result<Project, Invalid> {
        let version = migrate::header(text)?;
        let project: Project = if version == VERSION {
            let mut de = serde_json::Deserializer::from_str(text);
            let project = serde_path_to_error::deserialize(&mut de).map_err(field_error)?;
            de.end().at_field("after the project")?;
            project
        } else {
            let value = migrate::to_current(text, version)?;
            serde_path_to_error::deserialize(value).map_err(field_error)?
        };
        project.check()?;
        Ok(project)
    }

    /// The checks serde cannot express.
    pub fn check(&self) -> Result<(), Invalid> {
        let a = self.ellipsoid()?.a_m();
        if !(BODY_RADIUS_M[0]..=BODY_RADIUS_M[1]).contains(&a) {
            return Err(format!(
                "body: a semi-major axis of {a:?} m is outside {:?} … {:?} m (a body this tool can draw)",
                BODY_RADIUS_M[0], BODY_RADIUS_M[1]
            )
            .into());
        }
        for (name, view) in &self.views {
            view.check().at_field(format_args!("view '{name}'"))?;
        }
        if let Some(v) = &self.default_view
            && !self.views.contains_key(v)
        {
            return Err(format!("default_view '{v}' is not one of the views").into());
        }
        let mut names = std::collections::HashSet::new();
        let radius_m = self.ellipsoid()?.a_m();
        for (k, layer) in self.layers.iter().enumerate() {
            if !names.insert(&layer.name) {
                return Err(format!("layers[{k}]: layer '{}' is listed twice", layer.name).into());
            }
            layer.check(radius_m).at_field(format_args!("layers[{k}]"))?;
        }
        // Difference operands name layers with heights (the stack's own check, with the index).
        crate::layers::Stack::new(self.ellipsoid()?, &self.layers).map_err(|e| {
            let k = self.layers.iter().position(|l| l.name == e.layer).unwrap_or(0);
            format!("layers[{k}]: {e}")
        })?;
        for (name, s) in &self.comparison.swipes {
            let at = format!("comparison.swipes.{name}");
            for layer in [&s.a, &s.b] {
                if !names.contains(layer) {
                    return Err(format!("{at}: layer '{layer}' is not in the project").into());
                }
            }
            if s.a == s.b {
                return Err(format!("{at}: a and b are the same layer").into());
            }
            if !(0.0..=1.0).contains(&s.position) {
                return Err(format!("{at}.position: {} must lie within 0–1 of the width", s.position).into());
            }
            if let Some(v) = &s.view
                && !self.views.contains_key(v)
            {
                return Err(format!("{at}.view: '{v}' is not one of the views").into());
            }
        }
        for (name, line) in &self.comparison.profiles {
            for (end, [lat, lon]) in [("from", line.from), ("to", line.to)] {
                if !(lat.abs() <= 90.0 && lon.abs() <= 180.0) {
                    return Err(format!(
                        "comparison.profiles.{name}.{end}: [{lat}, {lon}] is not [lat, lon] in degrees"
                    )
                    .into());
                }
            }
        }
        let kinds = |name: &str| self.layers.iter().find(|l| l.name == name).map(|l| l.holds_deltas());
        for (name, check) in &self.checks {
            let target = check.target(&kinds).map_err(|e| e.under(format_args!("checks.{name}")))?;
            if let checks::CheckTarget::View { view, .. } = target
                && !self.views.contains_key(view)
            {
                return Err(format!("checks.{name}.view: '{view}' is not one of the views").into());
            }
        }
        self.visuals.check()?;
        self.detail.check()
    }

    /// The body's ellipsoid.
    pub fn ellipsoid(&self) -> Result<Ellipsoid, Invalid> {
        self.body.parse::<Ellipsoid>().map_err(|e| Invalid(format!("body: {e}")))
    }

    /// The dataset layers, bottom to top.
    pub fn dataset_layers(&self) -> impl Iterator<Item = &LayerSpec> {
        self.layers.iter().filter(|l| l.is_data())
    }

    /// A path of the project, resolved against the project file's folder.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() { path.to_path_buf() } else { self.base_dir.join(path) }
    }

    /// The camera a command asks for: an explicit `lat,lon,alt,heading,pitch[,fov]` (`--camera`),
    /// else a named view, else the default view.
    pub fn camera(&self, view: Option<&str>, camera: Option<&str>) -> Result<CameraSpec, Invalid> {
        match camera {
            Some(c) => CameraSpec::parse(c).map_err(|e| e.at("--camera")),
            None => self.view(view),
        }
    }

    /// A named view, or the default view when `name` is `None`.
    pub fn view(&self, name: Option<&str>) -> Result<CameraSpec, Invalid> {
        let name = match name {
            Some(n) => n.to_string(),
            None => match (&self.default_view, self.views.keys().next()) {
                (Some(v), _) => v.clone(),
                (None, Some(first)) => first.clone(),
                (None, None) => return Err("the project has no views: pass --camera lat,lon,alt,heading,pitch".into()),
            },
        };
        self.views.get(&name).copied().ok_or_else(|| {
            let known: Vec<&str> = self.views.keys().map(String::as_str).collect();
            Invalid(format!("no view '{name}'; the project has: {}", known.join(", ")))
        })
    }

    /// The JSON Schema of the project file, generated from these types (committed as
    /// `docs/project.schema.json` and checked by a test to match).
    pub fn schema() -> String {
        let mut text = serde_json::to_string_pretty(&schemars::schema_for!(Project)).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Moves the project's folder to `dir` (save as): every relative path is rewritten to point
    /// at the same file from there (absolute where no relative path reaches it).
    pub fn rebase(&mut self, dir: &Path) {
        let old = self.base_dir.clone();
        let moved = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = relative_to(&absolute(&old.join(&*p)), &absolute(dir));
            }
        };
        for data in self.layers.iter_mut().filter_map(LayerSpec::as_dataset_mut) {
            moved(&mut data.store);
            if let Some(source) = &mut data.source {
                source.files.iter_mut().for_each(moved);
            }
        }
        if let Some(file) = &mut self.visuals.colour_map.file {
            moved(file);
        }
        self.base_dir = dir.to_path_buf();
    }

    /// Writes the project atomically (paths as they are, relative ones stay relative).
    pub fn save(&self, path: &Path) -> Result<(), ProjectError> {
        // Never write a file that would not load again.
        self.check().map_err(|problem| ProjectError::NotSaved { path: path.into(), problem })?;
        let mut text =
            serde_json::to_string_pretty(self).map_err(|source| ProjectError::Encode { path: path.into(), source })?;
        text.push('\n');
        crate::files::write_atomic(path, text.as_bytes())
            .map_err(|source| ProjectError::Write { path: path.into(), source })
    }
}

#[cfg(test)]
mod tests;
