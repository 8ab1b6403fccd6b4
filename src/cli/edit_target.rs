//! What `brush` and `erode` change: the layer `--layer` names (an edit or an erosion layer, made
//! on top of the stack only with `--create`, so that a typo never makes a layer), and the budget
//! a stroke or a run is held to before any of it is made (`--max-tiles`, else the project's
//! `detail.max_edit_tiles`).

use std::fmt::Write as _;

use super::{CliError, WaitArgs};
use crate::layers::LayerSpec;
use crate::project::Project;

/// The flags `brush` and `erode` share: the layer made when missing, the budget, the wait.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ChangeArgs {
    /// Make the layer (on top of the stack) when the project has none of that name; without it,
    /// an unknown --layer is refused, so a typo never makes a layer.
    #[arg(long)]
    pub create: bool,
    /// The most tiles the stroke or run may write at its level (default: the project's
    /// detail.max_edit_tiles, 2048); a larger one is refused before any of it is made.
    #[arg(long = "max-tiles", allow_negative_numbers = true)]
    pub max_tiles: Option<u64>,
    /// How long to wait for another process changing the project.
    #[command(flatten)]
    pub wait: WaitArgs,
}

/// What a command changes: an edit layer's strokes or an erosion layer's runs.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Holds {
    /// An edit layer (`brush`).
    Strokes,
    /// An erosion layer (`erode`).
    Runs,
}

impl Holds {
    /// Whether `spec` is such a layer.
    fn of(self, spec: &LayerSpec) -> bool {
        match self {
            Holds::Strokes => spec.as_edit().is_some(),
            Holds::Runs => spec.as_erosion().is_some(),
        }
    }

    /// A new, empty layer of this kind.
    fn layer(self, name: &str) -> LayerSpec {
        match self {
            Holds::Strokes => LayerSpec::edit(name),
            Holds::Runs => LayerSpec::erosion(name),
        }
    }

    /// `edit` or `erosion`, as its layers are named.
    fn kind_name(self) -> &'static str {
        self.layer("").kind().name()
    }
}

/// The index of the layer `name` of `project` that `holds` strokes or runs; with `create`, a new
/// one on top when there is none (a line in `out` says so). A missing layer without `create`, or
/// one of another kind, is refused with the project's layers and a close name.
pub fn target_layer(
    project: &mut Project,
    name: &str,
    holds: Holds,
    create: bool,
    out: &mut String,
) -> Result<usize, CliError> {
    let kind_name = holds.kind_name();
    match project.layers.iter().position(|l| l.name == name) {
        Some(i) if holds.of(&project.layers[i]) => {
            if create {
                let _ = writeln!(out, "layer '{name}' is already there: --create adds nothing");
            }
            Ok(i)
        }
        Some(i) => Err(format!(
            "--layer {name}: a {} layer, not an {kind_name} layer ({})",
            project.layers[i].kind().name(),
            layers_of(project, holds)
        )
        .into()),
        None if create => {
            project.layers.push(holds.layer(name));
            let _ = writeln!(out, "made {kind_name} layer '{name}' on top of the stack");
            Ok(project.layers.len() - 1)
        }
        None => {
            let names = project.layers.iter().map(|l| l.name.as_str());
            let hint = match crate::errors::closest(name, names) {
                Some(close) => format!("did you mean '{close}'? "),
                None => String::new(),
            };
            Err(format!(
                "--layer {name}: no such layer in {} ({}); {hint}add --create to make a new {kind_name} layer on top",
                project.base_dir.display(),
                layers_of(project, holds)
            )
            .into())
        }
    }
}

/// `its edit layers: a, b` or `it has no edit layer; its layers: x, y`.
fn layers_of(project: &Project, holds: Holds) -> String {
    let of_kind: Vec<&str> = project.layers.iter().filter(|l| holds.of(l)).map(|l| l.name.as_str()).collect();
    let all: Vec<&str> = project.layers.iter().map(|l| l.name.as_str()).collect();
    let kind_name = holds.kind_name();
    match (of_kind.is_empty(), all.is_empty()) {
        (false, _) => format!("its {kind_name} layers: {}", of_kind.join(", ")),
        (true, false) => format!("it has no {kind_name} layer; its layers: {}", all.join(", ")),
        (true, true) => "it has no layers".into(),
    }
}

/// The budget of one stroke or run, tiles, `(--max-tiles, the project's detail.max_edit_tiles)`:
/// a footprint of `tiles` over it is refused naming the budget, where it came from and the flag.
pub fn check_budget_of(budget: (Option<u64>, u64), tiles: f64, what: &str) -> Result<(), CliError> {
    let (flag, project) = budget;
    if flag == Some(0) {
        return Err("--max-tiles: give a number of tiles of at least 1".into());
    }
    let limit = flag.unwrap_or(project);
    if tiles > limit as f64 {
        let source = if flag.is_some() { "--max-tiles" } else { "the project's detail.max_edit_tiles" };
        let mib = tiles * 257.0 * 257.0 * 4.0 / f64::from(1u32 << 20);
        let size = if mib < 1024.0 { format!("{mib:.0} MiB") } else { format!("{:.1} GiB", mib / 1024.0) };
        return Err(format!(
            "{what} would write up to {tiles:.0} tiles ({size} of heights), over the budget of {limit} from {source}: make it smaller (a coarser --level, a shorter path, a smaller radius or box), or raise the budget with --max-tiles {}",
            (tiles.ceil() as u64).max(limit + 1)
        )
        .into());
    }
    Ok(())
}
