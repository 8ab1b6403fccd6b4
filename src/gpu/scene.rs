//! A project opened for rendering: the body, the datasets' coverage (importing a dataset from its
//! listed sources when its store lacks it), the colour ramp, and the settings.

use std::sync::Arc;

use super::data::DatasetInfo;
use crate::colour::Ramp;
use crate::ecm::QuadId;
use crate::geodesy::Ellipsoid;
use crate::project::{ColourMapSpec, DetailSpec, Project, Visuals};
use crate::store::{ImportOptions, LevelChoice, Resampling, Store, VerticalDatum};

/// Everything the renderer needs from a project.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The body.
    pub ellipsoid: Ellipsoid,
    /// The datasets, in priority order.
    pub datasets: Arc<Vec<DatasetInfo>>,
    /// How the terrain looks.
    pub visuals: Visuals,
    /// Level of detail and caches.
    pub detail: DetailSpec,
    /// The colour ramp, resolved against the data's height range.
    pub ramp: Ramp,
    /// Height range over all datasets, metres (0, 0 without data).
    pub range_m: (f64, f64),
}

/// What opening a scene did besides opening (imports), for the command line to report.
#[derive(Clone, Debug, Default)]
pub struct OpenReport {
    /// One line per dataset imported from its sources.
    pub imported: Vec<String>,
}

impl Scene {
    /// Whether any dataset has heights at `quad` (its own tile or upsampled from its finest level).
    pub fn has_data(&self, quad: QuadId) -> bool {
        self.datasets.iter().any(|d| d.covers(quad))
    }

    /// The finest level of the datasets with heights at `quad`, if any has.
    pub fn finest_level_at(&self, quad: QuadId) -> Option<u8> {
        self.datasets.iter().filter(|d| d.covers(quad)).map(|d| d.finest_level).max()
    }

    /// Opens a project's datasets, importing those whose store lacks them and that list sources.
    pub fn open(project: &Project) -> Result<(Scene, OpenReport), String> {
        let ellipsoid = project.ellipsoid()?;
        let mut report = OpenReport::default();
        let mut datasets = Vec::new();
        for d in &project.datasets {
            let store_path = project.resolve(&d.store);
            let name = d.store_dataset();
            let has = store_path.exists()
                && Store::open_read_only(&store_path)
                    .map_err(|e| e.to_string())?
                    .dataset(name)
                    .map_err(|e| e.to_string())?
                    .is_some_and(|r| r.completed.is_some());
            if !has {
                let Some(source) = &d.source else {
                    return Err(format!(
                        "dataset '{}': {} has no complete dataset '{name}' and the project lists no source to import it from",
                        d.name,
                        store_path.display()
                    ));
                };
                if let Some(dir) = store_path.parent() {
                    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
                }
                let vertical = match &source.vertical_datum {
                    Some(v) => v.parse::<VerticalDatum>().map_err(|e| format!("dataset '{}': {e}", d.name))?,
                    None => VerticalDatum::Ellipsoidal,
                };
                let opts = ImportOptions {
                    sources: source.files.iter().map(|f| project.resolve(f)).collect(),
                    store: store_path.clone(),
                    body: ellipsoid,
                    name: Some(name.to_string()),
                    level: source.max_level.map_or(LevelChoice::Auto, LevelChoice::Level),
                    resampling: Resampling::Bilinear,
                    vertical,
                    memory_budget: 1 << 30,
                    threads: None,
                    progress: false,
                    finest_only: false,
                };
                let r = crate::store::import(&opts).map_err(|e| e.to_string())?;
                report.imported.push(format!(
                    "imported {} into {} (levels 0–{}, {:.1} s)",
                    source.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", "),
                    store_path.display(),
                    r.finest_level,
                    r.seconds_finest + r.seconds_pyramid
                ));
            }
            let info = DatasetInfo::open(&store_path, name).map_err(|e| format!("dataset '{}': {e}", d.name))?;
            let store_body = info.body;
            if store_body.a_m() != ellipsoid.a_m() || store_body.b_m() != ellipsoid.b_m() {
                return Err(format!(
                    "dataset '{}': {} is on {}, the project on {}",
                    d.name,
                    store_path.display(),
                    store_body.name(),
                    ellipsoid.name()
                ));
            }
            datasets.push(info);
        }
        let range_m =
            datasets.iter().map(|d| d.range_m).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1))).unwrap_or((0.0, 0.0));
        let visuals = project.visuals.clone();
        let ramp = resolve_ramp(project, &visuals.colour_map, range_m)?;
        Ok((
            Scene { ellipsoid, datasets: Arc::new(datasets), visuals, detail: project.detail.clone(), ramp, range_m },
            report,
        ))
    }
}

/// The colour ramp a colour-map setting names: a user's file (relative to the project) or a
/// preset, over its range or, without one, the data's height range.
pub fn resolve_ramp(project: &Project, cm: &ColourMapSpec, data_range_m: (f64, f64)) -> Result<Ramp, String> {
    let range = if data_range_m.1 > data_range_m.0 { data_range_m } else { (0.0, 1.0) };
    let range = cm.range_m.map_or(range, |[a, b]| (a, b));
    match &cm.file {
        Some(file) => Ramp::from_file(&project.resolve(file), range, cm.nodata_colour),
        None => Ramp::preset(&cm.preset, range, cm.nodata_colour),
    }
}
