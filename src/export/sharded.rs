//! An export cut into shards, under the contract the comparison's has (docs/shards.md): a plan
//! that fixes the output's grid, level and layers and cuts its rows into N runs of equal size
//! ±1; shards that each make their rows (the same pixels, bit for bit, as one export makes them:
//! a row never depends on the band it was made in) into a part; and a merge that checks every
//! part and writes the GeoTIFF (or Cloud-Optimized GeoTIFF) once, atomically.
//!
//! Shard I's part is two files in the parts' folder: `shard-I.f32`, its rows' heights as
//! little-endian float32 from the north, written to a temporary file and renamed, then
//! `shard-I.json`, written atomically after it and naming the plan, the rows, the byte count and
//! the data's SHA-256: a part is complete when its JSON is there and its data match it.

use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::{BAND_PIXELS, ComposeOn, ComposedExport, ComposedReport, ExportError, Exporter};
use crate::attributes::Attribute;
use crate::plan::{PlanError, Stamp, file_error};
use crate::progress::Watch;
use crate::store::export::RasterSpec;

/// The plan's format name.
pub const PLAN_FORMAT: &str = "terrafuse-export-plan";
/// A part's format name.
pub const PART_FORMAT: &str = "terrafuse-export-part";
/// The version this build writes and reads.
pub const PLAN_VERSION: u32 = 1;
/// The most shards a plan may have.
pub const MAX_SHARDS: usize = 1 << 16;

/// A sharded export's plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportPlan {
    /// Always [`PLAN_FORMAT`].
    pub format: String,
    /// [`PLAN_VERSION`].
    pub version: u32,
    /// SHA-256 (hex) of the plan with this field empty: every part names it.
    pub hash: String,
    /// The project file, absolute.
    pub project: PathBuf,
    /// SHA-256 (hex) of the project file's bytes.
    pub project_sha256: String,
    /// The project's dataset stores.
    pub stores: Vec<Stamp>,
    /// The GeoTIFF the merge writes, absolute.
    pub out: PathBuf,
    /// Write it as a Cloud-Optimized GeoTIFF.
    pub cog: bool,
    /// The output CRS, as given.
    pub crs: String,
    /// xmin, ymin, xmax, ymax in the output CRS.
    pub bounds: [f64; 4],
    /// Pixel size in CRS units (x, y).
    pub resolution: [f64; 2],
    /// The level composed.
    pub level: u8,
    /// Where the shards compose: `gpu` or `cpu`.
    pub compose: String,
    /// A − B instead of the stack.
    pub difference: Option<[String; 2]>,
    /// A terrain attribute instead of the heights.
    pub attribute: Option<String>,
    /// One layer alone instead of the stack.
    pub layer: Option<String>,
    /// Width and height of the output, pixels.
    pub size: [usize; 2],
    /// The parts' folder, absolute.
    pub parts: PathBuf,
    /// Each shard's rows, `[first, end)`, from the north.
    pub shards: Vec<[usize; 2]>,
}

/// A shard's part: what its data file holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Part {
    format: String,
    plan: String,
    shard: usize,
    rows: [usize; 2],
    width: usize,
    bytes: u64,
    sha256: String,
    valid: u64,
    /// The quads composed, `[face, x, y]` at the plan's level.
    quads: Vec<[u32; 3]>,
    composer: String,
}

/// What a shard did.
pub enum Sharded {
    /// Wrote its part.
    Wrote,
    /// Its part was there already.
    Already,
}

/// What a merge did.
pub enum Merged {
    /// Wrote the output.
    Done(ComposedReport),
    /// These shards' parts are missing.
    Pending(Vec<usize>),
}

impl crate::plan::Plan for ExportPlan {
    const FORMAT: &'static str = PLAN_FORMAT;
    const VERSION: u32 = PLAN_VERSION;
    const WHAT: &'static str = "an export plan";
    fn header(&self) -> (&str, u32, &str) {
        (&self.format, self.version, &self.hash)
    }
    fn hash_mut(&mut self) -> &mut String {
        &mut self.hash
    }
}

impl ExportPlan {
    fn digest(&self) -> String {
        crate::plan::digest(self)
    }

    /// Reads a plan and checks its format, version and hash.
    pub fn load(path: &Path) -> Result<ExportPlan, PlanError> {
        crate::plan::load(path)
    }

    /// The export the plan fixes, composed on the planned side.
    fn export(&self) -> Result<ComposedExport, ExportError> {
        let attribute = match &self.attribute {
            None => None,
            Some(name) => Some(
                Attribute::parse(name)
                    .ok_or_else(|| file_error(&self.project, format!("attribute {name}: not one this build knows")))?,
            ),
        };
        Ok(ComposedExport {
            project: self.project.clone(),
            out: self.out.clone(),
            crs: self.crs.clone(),
            bounds: self.bounds,
            resolution: (self.resolution[0], self.resolution[1]),
            level: Some(self.level),
            compose_on: if self.compose == "cpu" { ComposeOn::Cpu } else { ComposeOn::Gpu },
            difference: self.difference.clone().map(|[a, b]| (a, b)),
            attribute,
            layer: self.layer.clone(),
            cog: self.cog,
        })
    }

    fn data_path(&self, shard: usize) -> PathBuf {
        self.parts.join(format!("shard-{shard:06}.f32"))
    }

    fn part_path(&self, shard: usize) -> PathBuf {
        self.parts.join(format!("shard-{shard:06}.json"))
    }

    /// Shard `shard`'s part if complete; Err for one of another plan or damaged.
    fn part(&self, shard: usize) -> Result<Option<Part>, PlanError> {
        let path = self.part_path(shard);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(file_error(&path, format!("cannot read the part: {e}"))),
        };
        let part: Part = serde_json::from_str(&text).map_err(|e| file_error(&path, format!("not a part: {e}")))?;
        let [first, end] = self.shards[shard];
        if part.format != PART_FORMAT || part.plan != self.hash || part.shard != shard {
            return Err(file_error(
                &path,
                format!("a part of another plan or shard (plan {}, shard {})", part.plan, part.shard),
            ));
        }
        let bytes = ((end - first) * self.size[0] * 4) as u64;
        if part.rows != [first, end] || part.width != self.size[0] || part.bytes != bytes {
            return Err(file_error(&path, format!("holds rows {:?} × {}, not the plan's", part.rows, part.width)));
        }
        let data = self.data_path(shard);
        let on_disk = std::fs::metadata(&data).map(|m| m.len()).unwrap_or(u64::MAX);
        if on_disk != bytes {
            return Err(file_error(&data, format!("{on_disk} bytes where the part says {bytes}: run the shard again")));
        }
        Ok(Some(part))
    }
}

/// Plans `opts` in `shards` shards: checks the project, the grid, the layers and the level as
/// `export` would, writes the plan to `plan_path` atomically (its parts to go to `parts`, default
/// `PLAN.parts` beside it) and exports nothing.
pub fn plan(
    opts: &ComposedExport,
    shards: usize,
    plan_path: &Path,
    parts: Option<&Path>,
) -> Result<ExportPlan, ExportError> {
    let absolute = |p: &Path| std::path::absolute(p).map_err(|e| file_error(p, e));
    let project = absolute(&opts.project)?;
    let out = absolute(&opts.out)?;
    // Checked as the export checks them, composing nothing (and needing no GPU).
    let checked = Exporter::new(&ComposedExport {
        project: project.clone(),
        out: out.clone(),
        compose_on: ComposeOn::Cpu,
        ..opts.clone()
    })?;
    let (w, h) = checked.raster.size;
    if !(1..=MAX_SHARDS.min(h)).contains(&shards) {
        return Err(file_error(
            plan_path,
            format!("--shards {shards}: give 1 … {} (the output has {h} rows)", MAX_SHARDS.min(h)),
        )
        .into());
    }
    let plan_path = absolute(plan_path)?;
    let parts = match parts {
        Some(p) => absolute(p)?,
        None => plan_path.with_extension("parts"),
    };
    let loaded = crate::project::Project::load(&project)?;
    let (project_sha256, stores) = crate::plan::inputs(&project, &loaded)?;
    let mut plan = ExportPlan {
        format: PLAN_FORMAT.into(),
        version: PLAN_VERSION,
        hash: String::new(),
        project,
        project_sha256,
        stores,
        out,
        cog: opts.cog,
        crs: opts.crs.clone(),
        bounds: opts.bounds,
        resolution: [opts.resolution.0, opts.resolution.1],
        level: checked.level,
        compose: if opts.compose_on == ComposeOn::Cpu { "cpu" } else { "gpu" }.into(),
        difference: opts.difference.clone().map(|(a, b)| [a, b]),
        attribute: opts.attribute.map(|a| a.name().to_owned()),
        layer: opts.layer.clone(),
        size: [w, h],
        parts,
        shards: crate::plan::runs(h, shards).into_iter().map(|(a, b)| [a, b]).collect(),
    };
    plan.hash = plan.digest();
    crate::plan::write(&plan_path, &plan.parts, &plan)?;
    Ok(plan)
}

/// Makes shard `shard`'s rows into its part (nothing where the part is there), after checking
/// that the project and its stores are as planned; the rows counted and cancelled on `watch`.
pub fn shard(plan_path: &Path, shard: usize, watch: &Watch) -> Result<Sharded, ExportError> {
    let plan = ExportPlan::load(plan_path)?;
    crate::plan::check_shard(plan_path, shard, plan.shards.len())?;
    crate::plan::check_inputs(&plan.project, &plan.project_sha256, &plan.stores)?;
    if plan.part(shard).ok().flatten().is_some() {
        return Ok(Sharded::Already);
    }
    let mut exporter = Exporter::new(&plan.export()?)?;
    let [first, end] = plan.shards[shard];
    let data = plan.data_path(shard);
    std::fs::create_dir_all(&plan.parts).map_err(|e| file_error(&plan.parts, format!("cannot create: {e}")))?;
    let tmp = plan.parts.join(format!(".shard-{shard:06}.f32.tmp-{}", std::process::id()));
    let written = (|| {
        let file = std::fs::File::create(&tmp).map_err(|e| file_error(&tmp, format!("cannot create: {e}")))?;
        let mut file = BufWriter::new(file);
        let mut hash = Sha256::new();
        let made = exporter.rows(first..end, BAND_PIXELS, watch, &mut |_, band| {
            let bytes: Vec<u8> = band.iter().flat_map(|v| v.to_le_bytes()).collect();
            hash.update(&bytes);
            file.write_all(&bytes).map_err(|e| file_error(&tmp, format!("cannot write: {e}")).into())
        })?;
        let file = file.into_inner().map_err(|e| file_error(&tmp, format!("cannot write: {}", e.error())))?;
        file.sync_all().map_err(|e| file_error(&tmp, format!("cannot write: {e}")))?;
        std::fs::rename(&tmp, &data).map_err(|e| file_error(&data, format!("cannot move into place: {e}")))?;
        Ok::<_, ExportError>((made, hash.finalize()))
    })();
    let (made, digest) = match written {
        Ok(w) => w,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    let part = Part {
        format: PART_FORMAT.into(),
        plan: plan.hash.clone(),
        shard,
        rows: [first, end],
        width: plan.size[0],
        bytes: ((end - first) * plan.size[0] * 4) as u64,
        sha256: digest.iter().map(|b| format!("{b:02x}")).collect(),
        valid: made.valid,
        quads: made.quads.iter().map(|q| [q.face as u32, q.x, q.y]).collect(),
        composer: exporter.composer().to_owned(),
    };
    let path = plan.part_path(shard);
    let text = serde_json::to_string(&part).map_err(|e| file_error(&path, e))?;
    crate::files::write_atomic(&path, text.as_bytes()).map_err(|e| file_error(&path, format!("cannot write: {e}")))?;
    Ok(Sharded::Wrote)
}

/// The shards whose parts are missing (every present part checked first: one of another plan,
/// or damaged, is refused by name).
pub fn missing(plan: &ExportPlan) -> Result<Vec<usize>, PlanError> {
    let mut missing = Vec::new();
    for shard in 0..plan.shards.len() {
        if plan.part(shard)?.is_none() {
            missing.push(shard);
        }
    }
    Ok(missing)
}

/// Checks every part and writes the output (atomically, the parts' data checked against their
/// digests on the way), or names the shards missing; counted and cancelled on `watch`.
pub fn merge(plan_path: &Path, watch: &Watch) -> Result<Merged, ExportError> {
    let plan = ExportPlan::load(plan_path)?;
    let project = crate::plan::check_inputs(&plan.project, &plan.project_sha256, &plan.stores)?;
    let missing = missing(&plan)?;
    if !missing.is_empty() {
        return Ok(Merged::Pending(missing));
    }
    let parts: Vec<Part> = (0..plan.shards.len()).filter_map(|i| plan.part(i).transpose()).collect::<Result<_, _>>()?;
    let mut composers: Vec<&str> = parts.iter().map(|p| p.composer.as_str()).collect();
    composers.dedup();
    let composer = composers.join("; ");
    let opts = plan.export()?;
    let raster = RasterSpec::new(&plan.crs, plan.bounds, (plan.resolution[0], plan.resolution[1]), &plan.out)?;
    let metadata = super::metadata(&opts, &project, plan.level, &composer);
    let mut writer = raster.create_as(&plan.out, &metadata, plan.cog)?;
    let w = plan.size[0];
    let band_rows = (BAND_PIXELS / w.max(1)).max(1);
    watch.start_phase("rows", plan.size[1] as u64);
    for (shard, part) in parts.iter().enumerate() {
        let path = plan.data_path(shard);
        let cannot = |e: std::io::Error| file_error(&path, format!("cannot read: {e}"));
        let mut file = std::io::BufReader::new(std::fs::File::open(&path).map_err(cannot)?);
        let mut hash = Sha256::new();
        let [first, end] = part.rows;
        for row in (first..end).step_by(band_rows) {
            watch.check().map_err(super::cancelled)?;
            let rows = band_rows.min(end - row);
            let mut bytes = vec![0u8; rows * w * 4];
            file.read_exact(&mut bytes).map_err(cannot)?;
            hash.update(&bytes);
            let band = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            writer.write_rows(row, band)?;
            watch.advance_by(rows as u64);
        }
        let digest: String = hash.finalize().iter().map(|b| format!("{b:02x}")).collect();
        if digest != part.sha256 {
            return Err(file_error(&path, "its data do not match the part's SHA-256: run the shard again").into());
        }
    }
    writer.finish()?;
    let quads: std::collections::BTreeSet<[u32; 3]> = parts.iter().flat_map(|p| p.quads.iter().copied()).collect();
    Ok(Merged::Done(ComposedReport {
        size: (plan.size[0], plan.size[1]),
        level: plan.level,
        quads: quads.len(),
        valid: parts.iter().map(|p| p.valid).sum(),
        composer,
    }))
}
