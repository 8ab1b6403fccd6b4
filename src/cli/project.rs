//! `terrafuse project check|upgrade`: a project file checked the way opening it would, without
//! opening a window or importing anything; and rewritten in the current version.

use super::{CliError, Within};
use crate::scene::SceneError;
use std::fmt::Write as _;
use std::path::Path;

use crate::layers::LayerPayload;
use crate::project::{Project, recovery};

/// `terrafuse project check`: every field, the files it names (a store there, or the sources to
/// import it from; a store on the project's body), and a recovery file left by the workstation.
pub fn project_check(path: &Path) -> Result<String, CliError> {
    let project = Project::load(path)?;
    let text = std::fs::read_to_string(path).map_err(CliError::file(path, "cannot read"))?;
    let version = crate::project::migrate::header(&text).unwrap_or(crate::project::VERSION);
    let mut out = String::new();
    let _ = writeln!(out, "{}: a Terrafuse project, version {version}, body {}", path.display(), project.body);
    if version < crate::project::VERSION {
        let _ = writeln!(
            out,
            "  an older version: it is read as version {} (terrafuse project upgrade rewrites it)",
            crate::project::VERSION
        );
    }
    for (k, layer) in project.layers.iter().enumerate() {
        let field = |f: &str| format!("{}: layers[{k}].{f}", path.display());
        let mut line = format!("  layer '{}' ({}", layer.name, layer.kind().name());
        if !layer.visible {
            line += ", hidden";
        }
        line += ")";
        match &layer.payload {
            LayerPayload::Dataset(data) => {
                let store = project.resolve(&data.store);
                if store.exists() {
                    match crate::scene::open_dataset(&project, layer) {
                        Ok(_) => {}
                        // An incomplete dataset is imported again from its sources.
                        Err(e) if data.source.is_some() && !matches!(e, SceneError::OtherBody { .. }) => {}
                        Err(e) => return Err(format!("{}: {}", field("store"), crate::errors::chain(&e)).into()),
                    }
                    let _ = write!(line, ": store {}", store.display());
                } else {
                    let source = data.source.as_ref().ok_or_else(|| {
                        format!("{}: {} does not exist and the layer lists no source", field("store"), store.display())
                    })?;
                    for (j, f) in source.files.iter().enumerate() {
                        let file = project.resolve(f);
                        if !file.is_file() {
                            return Err(format!(
                                "{}: {} does not exist",
                                field(&format!("source.files[{j}]")),
                                file.display()
                            )
                            .into());
                        }
                    }
                    let _ = write!(
                        line,
                        ": imported into {} on first open from {} files",
                        store.display(),
                        source.files.len()
                    );
                }
            }
            LayerPayload::Edit(edit) => {
                let _ = write!(line, ": {} of {} strokes applied", edit.in_effect().len(), edit.strokes.len());
            }
            LayerPayload::Erosion(erosion) => {
                // Each run's region placed as a replay places it (a box too large for one region, or
                // one reaching the opposite face, is refused there).
                let ellipsoid = project.ellipsoid()?;
                for (j, run) in erosion.runs.iter().enumerate() {
                    crate::erosion::region::Region::from_box(&ellipsoid, run.region, run.level)
                        .within(field(&format!("runs[{j}].region")))?;
                }
                let _ = write!(line, ": {} of {} runs applied", erosion.in_effect().len(), erosion.runs.len());
            }
            _ => {}
        }
        out += &line;
        out.push('\n');
    }
    if let Some(file) = &project.visuals.colour_map.file {
        let f = project.resolve(file);
        if !f.is_file() {
            return Err(format!("{}: visuals.colour_map.file: {} does not exist", path.display(), f.display()).into());
        }
    }
    let _ = writeln!(
        out,
        "  {} views, {} checks ({} recorded)",
        project.views.len(),
        project.checks.len(),
        project.checks.values().filter(|c| c.digest.is_some()).count()
    );
    if let Some(r) = recovery::find(path) {
        let _ = writeln!(out, "  {}", r.notice());
    }
    Ok(out)
}

/// `terrafuse project upgrade`: the project rewritten in the current version, over itself or at
/// `out` (relative paths rewritten to reach the same files from there).
pub fn project_upgrade(
    path: &Path,
    out: Option<&Path>,
    wait: &super::WaitArgs,
    fb: &mut super::Feedback,
) -> Result<String, CliError> {
    let target = out.unwrap_or(path);
    // The file written is held from before the project is read until it is written.
    let lock = crate::files::lock::Lock::acquire(target, "terrafuse project upgrade", wait.duration()?, &mut |who| {
        (fb.note)(&format!("terrafuse: waiting for {who} to finish changing {}", target.display()))
    })
    .map_err(super::feedback::lock_error)?;
    let text = std::fs::read_to_string(path).map_err(CliError::file(path, "cannot read"))?;
    let from = crate::project::migrate::header(&text).within(path.display())?;
    let mut project = Project::load(path)?;
    if let Some(out) = out {
        let dir = crate::files::folder_of(out);
        project.rebase(dir);
    }
    project.save(target)?;
    drop(lock);
    Ok(format!("{}: version {from} → {}, written to {}\n", path.display(), crate::project::VERSION, target.display()))
}
