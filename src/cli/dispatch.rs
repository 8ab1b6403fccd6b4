//! Runs a parsed command line: each [`Command`] calls the library and writes what it reports to
//! the [`Console`] that `main.rs` gives (standard input, output and error, the environment's
//! settings), so that the library itself neither prints nor reads the environment. Returns the
//! exit status: 0, 1 when a check or a record failed, 3 for an incomplete merge.

use std::io::BufReader;

use super::args::{
    Analysis, Command, ExportArgs, GeoCommand, ImportArgs, ProjectCommand, RenderArgs, ShardsCommand, SlurmCommand,
    StoreCommand,
};
use super::console::Console;
use super::error::Context;
use super::feedback::watched;
use super::{CliError, GeoOperation};
use crate::ecm::CubeProjection;
use crate::geodesy::Ellipsoid;

/// Runs `command` (all but `view`, which needs the workstation: `main.rs` opens it).
pub fn run(command: Command, c: &mut Console) -> Result<u8, CliError> {
    match command {
        Command::Overview { landmarks } => {
            let text = std::fs::read_to_string(&landmarks)
                .with_context(|| format!("cannot read landmark file {}", landmarks.display()))?;
            c.print(super::overview(&text))?;
            c.print(format_args!("\n{}", super::tissot_report(600, 10).0))?;
        }
        Command::Geo { operation, body, projection, input } => return run_geo(operation, &body, &projection, input, c),
        Command::Analyze { analysis: Analysis::Tissot { samples, level } } => {
            c.print(super::tissot_report(samples, level).0)?;
        }
        Command::Analyze { analysis: Analysis::Cutoff { body, tolerance_m, limit_fraction, max_level, samples } } => {
            let ellipsoid: Ellipsoid = body.parse()?;
            if tolerance_m.is_nan() || tolerance_m <= 0.0 {
                return Err("--tolerance-m: the tolerance must be a positive number of metres".into());
            }
            if limit_fraction.is_nan() || limit_fraction < 0.0 {
                return Err("--limit-fraction: the limit fraction must be 0 or more".into());
            }
            let (table, _) =
                super::cutoff_report(&ellipsoid, tolerance_m, limit_fraction, max_level.min(30), samples.max(3));
            c.print(table)?;
        }
        Command::Render(args) => run_render(args, c)?,
        Command::Profile(request) => c.print(super::profile_command(&request)?)?,
        Command::Compare(request) => {
            let report = watched(c, !request.json, |fb| super::compare_command(&request, fb))?;
            c.print(report)?;
        }
        Command::Coregister(request) => {
            let started = std::time::Instant::now();
            let report = watched(c, !request.json, |fb| super::coregister_command(&request, fb))?;
            c.note(format!("terrafuse: co-registered in {:.1} s", started.elapsed().as_secs_f64()));
            c.print(report)?;
        }
        Command::Brush(request) => {
            let report = watched(c, true, |fb| super::brush_command(&request, fb))?;
            c.print(report)?;
        }
        Command::Erode(request) => {
            let report = watched(c, !request.json, |fb| super::erode_command(&request, fb))?;
            c.print(report)?;
        }
        Command::Replay(request) => {
            c.note_recovery(&request.project);
            let outcome = watched(c, !request.json, |fb| super::replay_command(&request, fb))?;
            c.print(&outcome.report)?;
            if !outcome.passed {
                c.note("terrafuse: replay: a check failed (see above)");
                return Ok(1);
            }
        }
        Command::Project { command } => match command {
            ProjectCommand::Check { project } => c.print(super::project_check(&project)?)?,
            ProjectCommand::Upgrade { project, out, wait } => {
                let report = watched(c, false, |fb| super::project_upgrade(&project, out.as_deref(), &wait, fb))?;
                c.print(report)?;
            }
            ProjectCommand::Schema { markdown: false } => c.print(crate::project::Project::schema())?,
            ProjectCommand::Schema { markdown: true } => c.print(crate::project::reference::markdown())?,
        },
        Command::Export(args) => run_export(args, c)?,
        Command::View { .. } => {
            return Err("the workstation is opened by the terrafuse program, not the library".into());
        }
        Command::Import { import } => run_import(&import, c)?,
        Command::Store { command } => return run_store(command, c),
        Command::Shard { plan, shard } => return super::sharded::shard_command(&plan, &shard, c),
        Command::Merge { plan, store } => return super::sharded::merge_command(&plan, store.as_deref(), c),
        Command::Shards { command: ShardsCommand::Run { plan, store, jobs } } => {
            return super::sharded::shards_run(&plan, store.as_deref(), jobs, c);
        }
        Command::Slurm { command: SlurmCommand::Submit(a) } => {
            let (Some(manifest), Some(parts), Some(store)) = (a.manifest, a.parts, a.store) else {
                let plan = a.plan.ok_or_else(|| CliError::Usage("give PLAN.json or --manifest".into()))?;
                let own_job = (c.var)("SLURM_JOB_ID");
                c.print(super::slurm::submit_plan(&super::slurm::PlanSubmit {
                    plan,
                    threads: a.threads,
                    memory_budget: a.memory_budget,
                    work_dir: a.work_dir,
                    sbatch_args: a.sbatch_arg,
                    terrafuse: a.terrafuse,
                    dry_run: a.dry_run,
                    own_job,
                })?)?;
                return Ok(0);
            };
            c.print(super::slurm_submit(&super::SubmitRequest {
                manifest,
                parts,
                store,
                threads: a.threads,
                memory_budget: a.memory_budget,
                work_dir: a.work_dir,
                sbatch_args: a.sbatch_arg,
                terrafuse: a.terrafuse,
                dry_run: a.dry_run,
            })?)?;
        }
        // The benchmarks live in the room above this one; `main` hands `bench` to them.
        Command::Bench { .. } => {
            return Err(CliError::Usage("`terrafuse bench` runs through terrafuse::bench::run".into()));
        }
    }
    Ok(0)
}

/// `terrafuse geo`: points converted record by record from a file or standard input; 1 when a
/// record was refused.
fn run_geo(
    operation: GeoCommand,
    body: &str,
    projection: &str,
    input: Option<std::path::PathBuf>,
    c: &mut Console,
) -> Result<u8, CliError> {
    let ellipsoid: Ellipsoid = body.parse()?;
    let projection: CubeProjection = projection.parse()?;
    let operation = match operation {
        GeoCommand::ToFace => GeoOperation::ToFace,
        GeoCommand::FromFace => GeoOperation::FromFace,
        GeoCommand::ToEcef => GeoOperation::ToEcef,
        GeoCommand::FromEcef => GeoOperation::FromEcef,
    };
    let report = match input {
        Some(path) => {
            let file =
                std::fs::File::open(&path).with_context(|| format!("cannot open input file {}", path.display()))?;
            super::run_batch(operation, &ellipsoid, projection, BufReader::new(file), &mut *c.out, &mut *c.err)
        }
        None => super::run_batch(operation, &ellipsoid, projection, &mut *c.input, &mut *c.out, &mut *c.err),
    }
    .context("cannot convert the records")?;
    if report.refused > 0 {
        c.note(format_args!("terrafuse: {} of {} records refused", report.refused, report.refused + report.converted));
        return Ok(1);
    }
    Ok(0)
}

/// `terrafuse render`: the colour maps listed, a flight's frames, or one frame.
fn run_render(args: RenderArgs, c: &mut Console) -> Result<(), CliError> {
    if args.list_colour_maps {
        for (name, what, _) in crate::colour::PRESETS {
            c.print(format_args!("{name:<14} {what}\n"))?;
        }
        c.print("(or visuals.colour_map.file: a gdaldem colour-relief file or a GMT .cpt, heights in metres)\n")?;
        return Ok(());
    }
    let RenderArgs { project, out, width, height, look, swipe, flight, frames, out_dir, no_geomorph, compose, .. } =
        args;
    let Some(project) = project else { return Err("render: give the project file".into()) };
    let Some(out) = out else {
        let request = super::FlightRequest {
            project: &project,
            flight: flight.as_deref().unwrap_or_default(),
            frames,
            out_dir: out_dir.as_deref().unwrap_or(std::path::Path::new(".")),
            width,
            height,
            lod_threshold: look.lod_threshold,
            pixel_error: look.pixel_error,
            compose_on: compose_on(compose.as_deref()),
            geomorph: !no_geomorph,
        };
        let err = &mut *c.err;
        let report = super::render_flight(&request, &mut |line| {
            let _ = writeln!(err, "{line}");
        })?;
        return c.print(report);
    };
    c.note_recovery(&project);
    let request = super::RenderRequest {
        project: &project,
        out: &out,
        geomorph: !no_geomorph,
        width,
        height,
        view: look.view.as_deref(),
        camera: look.camera.as_deref(),
        lod_threshold: look.lod_threshold,
        pixel_error: look.pixel_error,
        compose_on: compose_on(compose.as_deref()),
        swipe: swipe.as_deref(),
        trace: c.trace,
    };
    let err = &mut *c.err;
    let report = super::render(&request, &mut |line| {
        let _ = writeln!(err, "{line}");
    })?;
    c.print(report)
}

/// `terrafuse export`: the composed stack, a difference, a layer alone or a terrain attribute
/// written as a GeoTIFF on the asked grid.
fn run_export(args: ExportArgs, c: &mut Console) -> Result<(), CliError> {
    let ExportArgs { project, out, raster, level, compose, difference, attribute, layer, cog, plan, shards, parts } =
        args;
    let (crs, bounds, resolution) = raster.parse()?;
    let difference = match difference.as_deref().map(|d| d.split(',').map(str::trim).collect::<Vec<_>>()) {
        None => None,
        Some(v) if v.len() == 2 && v[0] != v[1] => Some((v[0].to_string(), v[1].to_string())),
        Some(v) => return Err(format!("--difference {}: give two different layers A,B", v.join(",")).into()),
    };
    let compose_on = compose_on(Some(&compose)).unwrap_or(super::ComposeOn::Gpu);
    let attribute = attribute
        .map(|name| {
            crate::attributes::Attribute::parse(&name).ok_or_else(|| {
                let names: Vec<&str> = crate::attributes::Attribute::ALL.iter().map(|a| a.name()).collect();
                format!("--attribute {name}: not an attribute ({})", names.join(", "))
            })
        })
        .transpose()?;
    let opts = crate::export::ComposedExport {
        project,
        out,
        crs,
        bounds,
        resolution,
        level,
        compose_on,
        difference,
        attribute,
        layer,
        cog,
    };
    if let (Some(plan), Some(shards)) = (plan, shards) {
        let made = crate::export::sharded::plan(&opts, shards, &plan, parts.as_deref())?;
        return c.print(format!(
            "planned {} ({}×{} pixels, level {}): its rows in {shards} shards → {} (parts in {})\n{}",
            made.out.display(),
            made.size[0],
            made.size[1],
            made.level,
            plan.display(),
            made.parts.display(),
            super::plans::next_steps(&plan, shards)
        ));
    }
    let started = std::time::Instant::now();
    let report = watched(c, true, |fb| crate::export::export_composed_watched(&opts, fb.watch))?;
    c.print(super::report::export_line(&opts.out, attribute, &report, started.elapsed()))
}

/// `terrafuse store …`: merge parts, describe, sample or export a store; 1 when a sampled line
/// was refused, 3 for an incomplete merge.
fn run_store(command: StoreCommand, c: &mut Console) -> Result<u8, CliError> {
    match command {
        StoreCommand::Merge { store, parts, threads, quiet } => {
            let opts = crate::store::merge::MergeOptions {
                store: store.clone(),
                parts,
                threads,
                progress: !quiet,
                watch: None,
            };
            let report = crate::store::merge::merge(&opts)?;
            c.print(super::merge_summary(&store, &report))?;
            if !report.complete {
                return Ok(3);
            }
        }
        StoreCommand::Info { store } => c.print(super::store_info(&store)?)?,
        StoreCommand::Sample { store, dataset, level } => {
            let s = crate::store::Store::open_read_only(&store)?;
            let mut reader = crate::store::GridReader::new(s, dataset.as_deref().unwrap_or(""))?;
            let finest = reader.finest_level();
            let level = level.unwrap_or(finest);
            if level > finest {
                let problem = format!("dataset {} has levels 0–{finest}, not {level}", reader.dataset());
                return Err(format!("{}: {problem}", store.display()).into());
            }
            let (_, refused) = super::sample_lines(&mut reader, level, &mut *c.input, &mut *c.out, &mut *c.err)?;
            if refused > 0 {
                c.note(format_args!("terrafuse: {refused} lines refused"));
                return Ok(1);
            }
        }
        StoreCommand::Export { store, out, raster, dataset, level } => {
            let (crs, bounds, resolution) = raster.parse()?;
            let opts = crate::store::export::ExportOptions { store, dataset, crs, bounds, resolution, level, out };
            let report = crate::store::export::export(&opts)?;
            c.print(format_args!(
                "wrote {} ({}×{} pixels, level {}, {} with data)\n",
                opts.out.display(),
                report.size.0,
                report.size.1,
                report.level,
                report.valid
            ))?;
        }
    }
    Ok(0)
}

/// `terrafuse import`: a plan, one shard of a plan, or a whole import.
fn run_import(import: &ImportArgs, c: &mut Console) -> Result<(), CliError> {
    match (&import.plan, &import.manifest) {
        (Some(plan), _) => {
            let opts = import_options(import)?;
            let report = crate::store::shard::plan(&opts, plan, import.shards.unwrap_or(0))?;
            c.print(super::plan_summary(plan, &report))
        }
        (None, Some(manifest)) => {
            let shard = super::shard::shard_index(import.shard.as_deref().unwrap_or_default(), c.var)?;
            let store = import.store.clone().unwrap_or_default();
            let opts = crate::store::shard::ShardOptions {
                manifest: manifest.clone(),
                shard,
                store: store.clone(),
                work_dir: import.work_dir.clone(),
                threads: import.threads,
                memory_budget: super::parse_bytes(&import.memory_budget)?,
                progress: !import.quiet,
                watch: None,
            };
            let report = crate::store::shard::import_shard(&opts)?;
            c.print(super::shard_summary(&store, shard, &report))
        }
        (None, None) => {
            let opts = import_options(import)?;
            let report = crate::store::import(&opts)?;
            c.print(super::import_summary(&opts.store, &report))
        }
    }
}

/// The import the flags ask for.
fn import_options(a: &ImportArgs) -> Result<crate::store::ImportOptions, CliError> {
    Ok(crate::store::ImportOptions {
        sources: a.sources.clone(),
        store: a.store.clone().or_else(|| a.plan.clone()).unwrap_or_default(),
        body: a.body.as_deref().unwrap_or_default().parse()?,
        name: a.name.clone(),
        level: a.max_level.parse()?,
        resampling: a.resampling.parse()?,
        transform: a.transform.parse()?,
        vertical: a.vertical_datum.parse()?,
        memory_budget: super::parse_bytes(&a.memory_budget)?,
        threads: a.threads,
        progress: !a.quiet,
        finest_only: false,
        watch: None,
    })
}

/// `--compose gpu|cpu` (clap has checked the value), or None for the default.
fn compose_on(compose: Option<&str>) -> Option<super::ComposeOn> {
    compose.map(|c| if c == "cpu" { super::ComposeOn::Cpu } else { super::ComposeOn::Gpu })
}
