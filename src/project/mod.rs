//! The project file: a versioned JSON scene (body, layer stack, visual settings, named views).
//!
//! ```json
//! { "format": "terrafuse-project", "version": 2, "body": "moon",
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
//! Versions: 1 had `datasets` (first listed wins per sample); 2 has `layers`, bottom to top
//! (a version-1 file's datasets become `over` dataset layers, the first listed on top).

mod camera;
mod migrate;
mod settings;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use self::camera::CameraSpec;
pub use self::migrate::DatasetSpec;
use self::migrate::migrate_v1;
pub use self::settings::{
    ColourMapSpec, ComparisonSpec, DetailSpec, IsolineSpec, LightingSpec, ProfileLine, SwipeSpec, Visuals,
};
use crate::geodesy::Ellipsoid;
pub use crate::layers::SourceSpec;
use crate::layers::{LayerKind, LayerSpec};

/// The `format` value of every project file.
pub const FORMAT: &str = "terrafuse-project";
/// The version this build writes (and the newest it reads).
pub const VERSION: u32 = 2;

/// A project file that could not be used, naming the file and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct ProjectError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: String,
}

impl ProjectError {
    fn new(path: &Path, problem: impl Into<String>) -> ProjectError {
        ProjectError { path: path.to_path_buf(), problem: problem.into() }
    }
}

/// The project: what `terrafuse render` and the workstation open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
            base_dir: PathBuf::from("."),
        }
    }

    /// Reads and checks a project file.
    pub fn load(path: &Path) -> Result<Project, ProjectError> {
        let text = std::fs::read_to_string(path).map_err(|e| ProjectError::new(path, format!("cannot read: {e}")))?;
        let mut project = Project::parse(&text).map_err(|problem| ProjectError::new(path, problem))?;
        project.base_dir = path.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        if project.base_dir.as_os_str().is_empty() {
            project.base_dir = PathBuf::from(".");
        }
        Ok(project)
    }

    /// Parses and checks a project from JSON text (paths stay relative).
    pub fn parse(text: &str) -> Result<Project, String> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("not valid JSON: {e}"))?;
        match value.get("format").and_then(|f| f.as_str()) {
            Some(FORMAT) => {}
            Some(other) => return Err(format!("format is '{other}', not '{FORMAT}'")),
            None => return Err(format!("no \"format\": \"{FORMAT}\" field: not a Terrafuse project")),
        }
        let version = value.get("version").and_then(|v| v.as_u64()).ok_or("no numeric \"version\" field")?;
        if version > u64::from(VERSION) || version == 0 {
            return Err(format!(
                "version {version} is not supported: this build reads versions 1 to {VERSION}; a newer Terrafuse wrote it?"
            ));
        }
        let mut value = value;
        if version == 1 {
            migrate_v1(&mut value)?;
        }
        // serde_json's errors from a value have no position: name the layer a bad one is in.
        if let Some(layers) = value.get("layers").and_then(|l| l.as_array()) {
            for (k, layer) in layers.iter().enumerate() {
                if let Err(e) = serde_json::from_value::<crate::layers::LayerSpec>(layer.clone()) {
                    let name = layer.get("name").and_then(|n| n.as_str()).unwrap_or("?");
                    return Err(format!("layers[{k}]: layer '{name}': {e}"));
                }
            }
        }
        let project: Project = serde_json::from_value(value).map_err(|e| format!("{e}"))?;
        project.check()?;
        Ok(project)
    }

    /// The checks serde cannot express.
    pub fn check(&self) -> Result<(), String> {
        self.ellipsoid()?;
        for (name, view) in &self.views {
            view.check().map_err(|e| format!("view '{name}': {e}"))?;
        }
        if let Some(v) = &self.default_view
            && !self.views.contains_key(v)
        {
            return Err(format!("default_view '{v}' is not one of the views"));
        }
        let mut names = std::collections::HashSet::new();
        let radius_m = self.ellipsoid()?.a_m();
        for (k, layer) in self.layers.iter().enumerate() {
            if !names.insert(&layer.name) {
                return Err(format!("layers[{k}]: layer '{}' is listed twice", layer.name));
            }
            layer.check(radius_m).map_err(|e| format!("layers[{k}]: {e}"))?;
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
                    return Err(format!("{at}: layer '{layer}' is not in the project"));
                }
            }
            if s.a == s.b {
                return Err(format!("{at}: a and b are the same layer"));
            }
            if !(0.0..=1.0).contains(&s.position) {
                return Err(format!("{at}.position: {} must lie within 0–1 of the width", s.position));
            }
            if let Some(v) = &s.view
                && !self.views.contains_key(v)
            {
                return Err(format!("{at}.view: '{v}' is not one of the views"));
            }
        }
        for (name, line) in &self.comparison.profiles {
            for (end, [lat, lon]) in [("from", line.from), ("to", line.to)] {
                if !(lat.abs() <= 90.0 && lon.abs() <= 180.0) {
                    return Err(format!(
                        "comparison.profiles.{name}.{end}: [{lat}, {lon}] is not [lat, lon] in degrees"
                    ));
                }
            }
        }
        let v = &self.visuals;
        if !(v.exaggeration.is_finite() && v.exaggeration > 0.0) {
            return Err(format!("visuals.exaggeration {} must be a positive number", v.exaggeration));
        }
        let iso = &v.isolines;
        if !(iso.interval_m.is_finite() && iso.interval_m > 0.0) {
            return Err(format!("visuals.isolines.interval_m {} must be positive", iso.interval_m));
        }
        if !(iso.width_px >= 0.0 && iso.major_width_px >= 0.0 && iso.min_width_px >= 0.0) {
            return Err("visuals.isolines widths must not be negative".into());
        }
        if let Some([lo, hi]) = v.colour_map.range_m
            && !(lo.is_finite() && hi.is_finite() && lo < hi)
        {
            return Err(format!("visuals.colour_map.range_m [{lo}, {hi}] must be increasing"));
        }
        if !(v.lighting.strength >= 0.0 && v.lighting.strength <= 1.0) {
            return Err(format!("visuals.lighting.strength {} must lie in [0, 1]", v.lighting.strength));
        }
        let d = &self.detail;
        if !(d.lod_threshold_px.is_finite() && d.lod_threshold_px > 0.0) {
            return Err(format!("detail.lod_threshold_px {} must be positive", d.lod_threshold_px));
        }
        if d.max_quads < 6 {
            return Err(format!("detail.max_quads {} must be at least 6 (the cube's faces)", d.max_quads));
        }
        Ok(())
    }

    /// The body's ellipsoid.
    pub fn ellipsoid(&self) -> Result<Ellipsoid, String> {
        self.body.parse::<Ellipsoid>().map_err(|e| format!("body: {e}"))
    }

    /// The dataset layers, bottom to top.
    pub fn dataset_layers(&self) -> impl Iterator<Item = &LayerSpec> {
        self.layers.iter().filter(|l| l.kind == LayerKind::Dataset)
    }

    /// A path of the project, resolved against the project file's folder.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() { path.to_path_buf() } else { self.base_dir.join(path) }
    }

    /// The camera a command asks for: an explicit `lat,lon,alt,heading,pitch[,fov]` (`--camera`),
    /// else a named view, else the default view.
    pub fn camera(&self, view: Option<&str>, camera: Option<&str>) -> Result<CameraSpec, String> {
        match camera {
            Some(c) => CameraSpec::parse(c).map_err(|e| format!("--camera: {e}")),
            None => self.view(view),
        }
    }

    /// A named view, or the default view when `name` is `None`.
    pub fn view(&self, name: Option<&str>) -> Result<CameraSpec, String> {
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
            format!("no view '{name}'; the project has: {}", known.join(", "))
        })
    }

    /// Writes the project atomically (paths as they are, relative ones stay relative).
    pub fn save(&self, path: &Path) -> Result<(), ProjectError> {
        // Never write a file that would not load again.
        self.check().map_err(|e| ProjectError::new(path, format!("not saved: {e}")))?;
        let mut text = serde_json::to_string_pretty(self).map_err(|e| ProjectError::new(path, e.to_string()))?;
        text.push('\n');
        crate::files::write_atomic(path, text.as_bytes())
            .map_err(|e| ProjectError::new(path, format!("cannot write: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"{"format": "terrafuse-project", "version": 1, "body": "moon"}"#;

    #[test]
    fn a_minimal_project_gets_the_defaults() {
        let p = Project::parse(MINIMAL).unwrap();
        assert_eq!(p.body, "moon");
        assert_eq!(p.detail.lod_threshold_px, 1.5);
        assert!(p.visuals.lighting.enabled);
        assert!(p.view(None).unwrap_err().contains("no views"));
    }

    #[test]
    fn save_and_load_round_trip_and_paths_resolve_against_the_file() {
        let dir = std::env::temp_dir().join(format!("terrafuse-project-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut p = Project::new("wgs84");
        p.layers.push(LayerSpec::dataset("srtm", "s/e.gpkg"));
        p.views.insert("near".into(), CameraSpec::parse("39.9,41.3,2000,30,-20").unwrap());
        let path = dir.join("p.json");
        p.save(&path).unwrap();
        let q = Project::load(&path).unwrap();
        assert_eq!(q.layers, p.layers);
        assert_eq!(q.views, p.views);
        assert_eq!(q.resolve(q.layers[0].store.as_ref().unwrap()), dir.join("s/e.gpkg"));
        assert_eq!(q.view(None).unwrap().heading, 30.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_projects_are_refused_with_the_reason() {
        let cases = [
            ("{", "not valid JSON"),
            (r#"{"format": "x", "version": 1, "body": "moon"}"#, "format is 'x'"),
            (r#"{"format": "terrafuse-project", "version": 9, "body": "moon"}"#, "version 9 is not supported"),
            (r#"{"format": "terrafuse-project", "version": 1, "body": "pluto"}"#, "body"),
            (r#"{"format": "terrafuse-project", "version": 1, "body": "moon", "colour": 1}"#, "unknown field"),
            (
                r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
                    "views": {"v": {"lat": 95, "lon": 0, "alt": 1}}}"#,
                "view 'v': camera latitude 95",
            ),
            (
                r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
                    "visuals": {"isolines": {"interval_m": 0}}}"#,
                "interval_m 0 must be positive",
            ),
        ];
        for (text, expected) in cases {
            let e = Project::parse(text).unwrap_err();
            assert!(e.contains(expected), "{text}: {e}");
        }
        let e = Project::load(Path::new("/nonexistent/p.json")).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/p.json: cannot read"), "{e}");
    }

    #[test]
    fn version_1_files_migrate_to_layers_first_listed_on_top() {
        let v1 = r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
            "datasets": [{"name": "north", "store": "s.gpkg", "source": {"files": ["n.tif"]}},
                         {"name": "global", "store": "s.gpkg", "dataset": "lola"}]}"#;
        let p = Project::parse(v1).unwrap();
        assert_eq!(p.version, VERSION);
        let names: Vec<&str> = p.layers.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["global", "north"], "bottom to top: the first listed ends on top");
        assert!(p.layers.iter().all(|l| l.kind == LayerKind::Dataset && l.blend == crate::layers::BlendMode::Over));
        assert_eq!(p.layers[0].store_dataset(), "lola");
        assert_eq!(p.layers[1].source.as_ref().unwrap().files, [PathBuf::from("n.tif")]);
        let text = serde_json::to_string(&p).unwrap();
        assert!(text.contains("\"version\":2") && text.contains("\"layers\"") && !text.contains("\"datasets\""));
        // A version-2 file with datasets is refused (the field is gone), naming it.
        let e = Project::parse(r#"{"format": "terrafuse-project", "version": 2, "body": "moon", "datasets": []}"#);
        assert!(e.unwrap_err().contains("unknown field `datasets`"));
    }

    #[test]
    fn layers_are_checked_with_their_index_and_name() {
        let bad = r#"{"format": "terrafuse-project", "version": 2, "body": "moon",
            "layers": [{"name": "sea", "kind": "constant", "height_m": 0},
                       {"name": "n", "kind": "procedural", "noise": {"amplitude_m": 5, "wavelength_m": -1}}]}"#;
        let e = Project::parse(bad).unwrap_err();
        assert!(e.contains("layers[1]: layer 'n': noise.wavelength_m: -1 must be a positive length"), "{e}");
        let bad = r#"{"format": "terrafuse-project", "version": 2, "body": "moon",
            "layers": [{"name": "sea", "kind": "constant", "height_m": 0, "blend": "screen"}]}"#;
        assert!(Project::parse(bad).unwrap_err().contains("unknown variant `screen`"));
    }

    #[test]
    fn cameras_parse_from_the_command_line() {
        let c = CameraSpec::parse("39.9, 41.27, 30000, 45, -30").unwrap();
        assert_eq!((c.lat, c.lon, c.alt, c.heading, c.pitch, c.fov), (39.9, 41.27, 30000.0, 45.0, -30.0, 45.0));
        assert!(CameraSpec::parse("1,2,3").unwrap_err().contains("got 3 values"));
        assert!(CameraSpec::parse("1,2,x,4,5").unwrap_err().contains("'x' is not a number"));
        assert!(CameraSpec::parse("0,0,100,0,-100").unwrap_err().contains("pitch"));
    }
}
