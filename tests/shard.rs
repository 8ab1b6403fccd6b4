//! The sharded import: a plan run shard by shard with plain processes, and on a real single-node
//! Slurm cluster (started here, a shard killed with scancel, the missing ones resubmitted), gives
//! the same store as one process, tile for tile; bad plans, parts and stores are refused by name.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use common::{repo_path, terrafuse};
use terrafuse::store::Store;

const BIN: &str = env!("CARGO_BIN_EXE_terrafuse");
const SRTM: &str = "projects/data/earth_srtm3_demcompare_N39E040.tif";
const LOLA: &str = "projects/data/moon_lola_ldem_4ppd_global.tif";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn ok(args: &[&str]) -> String {
    let o = terrafuse(args, "");
    assert!(o.status.success(), "terrafuse {args:?} failed: {}", text(&o));
    text(&o)
}

/// A refusal: exit 1, a message that names `file` and says `problem`.
fn refused(args: &[&str], file: &Path, problem: &str) {
    let o = terrafuse(args, "");
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "terrafuse {args:?} should be refused: {t}");
    let name = file.file_name().unwrap().to_string_lossy();
    assert!(t.contains(name.as_ref()), "the message names {name}: {t}");
    assert!(t.contains(problem), "the message says '{problem}': {t}");
    assert!(!t.contains("panicked"), "{t}");
}

/// Every tile of a store's only dataset: (level, face, x, y) → a hash of its 257² samples.
fn tiles(path: &Path) -> BTreeMap<(u8, usize, u32, u32), u64> {
    let store = Store::open_read_only(path).unwrap();
    let d = store.resolve_dataset(None).unwrap();
    assert!(d.completed.is_some(), "{}: dataset {} is not complete", path.display(), d.name);
    let mut out = BTreeMap::new();
    for level in 0..=d.settings.finest_level {
        for q in store.data_quads(&d.name, level).unwrap() {
            let g = store.read_grid(&d.name, q).unwrap().expect("a tile with data");
            let mut h = 0xcbf2_9ce4_8422_2325u64;
            for v in &g.values {
                for b in v.to_bits().to_le_bytes() {
                    h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
                }
            }
            out.insert((level, q.face.index(), q.x, q.y), h);
        }
    }
    out
}

fn assert_same_store(merged: &Path, single: &Path) {
    let (a, b) = (tiles(merged), tiles(single));
    assert!(a.len() > 100, "{} tiles", a.len());
    let differ: Vec<_> = a.keys().chain(b.keys()).filter(|k| a.get(k) != b.get(k)).take(5).collect();
    assert!(
        differ.is_empty(),
        "{} and {} differ at (level, face, x, y) {differ:?}",
        merged.display(),
        single.display()
    );
    let (x, y) = (Store::open_read_only(merged).unwrap(), Store::open_read_only(single).unwrap());
    assert_eq!(x.resolve_dataset(None).unwrap().settings, y.resolve_dataset(None).unwrap().settings);
}

/// One process's import of the Erzurum SRTM at level 11: the reference.
fn single_import(dir: &Path) -> PathBuf {
    let store = dir.join("single.gpkg");
    let src = repo_path(SRTM);
    ok(&["import", s(&src), "--body", "wgs84", "--max-level", "11", "--store", s(&store), "--quiet"]);
    store
}

fn plan(dir: &Path, name: &str, source: &str, body: &str, level: &str, shards: usize) -> PathBuf {
    let manifest = dir.join(name);
    let src = repo_path(source);
    let n = shards.to_string();
    let out = ok(&["import", s(&src), "--body", body, "--max-level", level, "--plan", s(&manifest), "--shards", &n]);
    assert!(out.contains(&format!("in {shards} shards")), "{out}");
    manifest
}

fn shard(manifest: &Path, i: usize, part: &Path, extra: &[&str]) -> String {
    ok(&[&["import", "--manifest", s(manifest), "--shard", &i.to_string(), "--store", s(part), "--quiet"], extra]
        .concat())
}

#[test]
fn shards_run_as_plain_processes_merge_into_the_single_process_store() {
    let dir = common::scratch("shard/plain");
    let single = single_import(&dir);
    let manifest = plan(&dir, "plan.json", SRTM, "wgs84", "11", 3);
    let part = |i: usize| dir.join(format!("part-{i}.gpkg"));

    // Shard 1 killed mid-import: nothing is published, and a rerun resumes from its journal.
    let work = dir.join(".part-1.gpkg.importing");
    let mut child = Command::new(BIN)
        .args(["import", "--manifest", s(&manifest), "--shard", "1", "--store", s(&part(1)), "--threads", "1"])
        .args(["--quiet"])
        .spawn()
        .unwrap();
    let start = Instant::now();
    // Killed once its first transaction is in (the journal names quads). The shard is stopped
    // (SIGSTOP) while the test looks, so that however fast the machine it cannot run to the end
    // between a look and the kill.
    let pid = child.id().to_string();
    let signal = |sig: &str| {
        let o = Command::new("kill").args([sig, &pid]).output().unwrap();
        assert!(o.status.success(), "kill {sig}: {}", text(&o));
    };
    loop {
        std::thread::sleep(Duration::from_millis(10));
        signal("-STOP");
        let committed = Store::open_read_only(&work)
            .ok()
            .and_then(|st| st.resolve_dataset(None).ok().map(|d| (st, d)))
            .is_some_and(|(st, d)| st.finished_quads(&d.name, 11).is_ok_and(|q| !q.is_empty()));
        if committed {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "shard 1 committed nothing in 120 s");
        assert!(child.try_wait().unwrap().is_none(), "shard 1 ended before it could be killed");
        signal("-CONT");
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!part(1).exists(), "a killed shard publishes nothing");
    let resumed = shard(&manifest, 1, &part(1), &[]);
    assert!(resumed.contains("finished by an earlier run"), "{resumed}");
    assert!(!work.exists(), "the working file is gone once published");

    // The others, one through the scheduler's index variable; a finished shard again does nothing.
    shard(&manifest, 0, &part(0), &[]);
    let o = Command::new(BIN)
        .args(["import", "--manifest", s(&manifest), "--shard", "env", "--store", s(&part(2)), "--quiet"])
        .env("SLURM_ARRAY_TASK_ID", "2")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(shard(&manifest, 2, &part(2), &[]).contains("already complete: nothing to do"));

    // Merged in two goes: incomplete (exit 3, the missing shard named, no pyramid), then complete.
    let merged = dir.join("merged.gpkg");
    let o = terrafuse(&["store", "merge", s(&merged), s(&part(2)), s(&part(0)), "--quiet"], "");
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("INCOMPLETE: 1 of 3 shards missing (1)"), "{}", text(&o));
    let info = ok(&["store", "info", s(&merged)]);
    assert!(info.contains("INCOMPLETE") && info.contains(": 2 of 3 shards"), "{info}");
    let out = ok(&["store", "merge", s(&merged), s(&part(0)), s(&part(1)), s(&part(2)), "--quiet"]);
    assert!(out.contains("merged 1 shards (1)") && out.contains("already merged, skipped: 0,2"), "{out}");
    assert!(out.contains("complete: all 3 shards in"), "{out}");
    assert_same_store(&merged, &single);
    // Merging again changes nothing.
    let before = tiles(&merged);
    let out = ok(&["store", "merge", s(&merged), s(&part(1)), "--quiet"]);
    assert!(out.contains("merged 0 shards"), "{out}");
    assert_eq!(tiles(&merged), before);
}

#[test]
fn an_import_plan_runs_under_the_contract_every_command_shares() {
    // `terrafuse shard PLAN I`, `merge PLAN` and `shards run PLAN`, as for a comparison or an
    // export: the parts in PLAN.parts, the store PLAN.gpkg.
    let dir = common::scratch("shard/contract");
    let single = single_import(&dir);
    let manifest = plan(&dir, "srtm.json", SRTM, "wgs84", "11", 3);
    let waiting = terrafuse(&["merge", s(&manifest)], "");
    assert_eq!(waiting.status.code(), Some(3), "{}", text(&waiting));
    assert!(text(&waiting).contains("waits for shards 0,1,2"), "{}", text(&waiting));
    assert!(ok(&["shard", s(&manifest), "1"]).contains("srtm.parts/part-0001.gpkg"));
    assert!(ok(&["shard", s(&manifest), "1"]).contains("already complete: nothing to do"));
    let out = ok(&["shards", "run", s(&manifest), "--jobs", "2"]);
    assert!(out.contains("complete: all 3 shards in"), "{out}");
    assert_same_store(&dir.join("srtm.gpkg"), &single);
    let dry = ok(&["slurm", "submit", s(&manifest), "--dry-run"]);
    assert!(dry.contains("is complete: nothing to submit"), "{dry}");
}

#[test]
fn bad_plans_parts_and_stores_are_refused_by_name() {
    let dir = common::scratch("shard/bad");
    let a = plan(&dir, "a.json", SRTM, "wgs84", "9", 2);
    let b = plan(&dir, "b.json", SRTM, "wgs84", "9", 3);
    let moon = plan(&dir, "moon.json", LOLA, "moon", "1", 2);
    let (a0, a1, b0, m0) = (dir.join("a0.gpkg"), dir.join("a1.gpkg"), dir.join("b0.gpkg"), dir.join("m0.gpkg"));
    shard(&a, 0, &a0, &[]);
    shard(&a, 1, &a1, &[]);
    shard(&b, 0, &b0, &[]);
    shard(&moon, 0, &m0, &[]);
    let store = dir.join("store.gpkg");

    // A part of another plan, or of another body: refused by name, the store not even made.
    refused(&["store", "merge", s(&store), s(&a0), s(&b0)], &b0, "belongs to plan");
    refused(&["store", "merge", s(&store), s(&a0), s(&m0)], &m0, "is a store of body");
    assert!(!store.exists());
    // A shard given twice, a store that is not a part.
    refused(&["store", "merge", s(&store), s(&a0), s(&a0)], &a0, "again");
    ok(&["store", "merge", s(&store), s(&a0), s(&a1), "--quiet"]);
    refused(&["store", "merge", s(&dir.join("x.gpkg")), s(&store)], &store, "is not a shard's partial store");
    // Parts of another plan into a store merged from plan a, and a Moon part into an Earth store.
    let b1 = dir.join("b1.gpkg");
    shard(&b, 1, &b1, &[]);
    refused(&["store", "merge", s(&store), s(&b0)], &b0, "from plan");
    refused(&["store", "merge", s(&store), s(&m0)], &store, "is a store of body");

    // Shards: out of range, an existing file that is not the shard, a bad index.
    refused(&["import", "--manifest", s(&a), "--shard", "5", "--store", s(&dir.join("p.gpkg"))], &a, "not 5");
    refused(&["import", "--manifest", s(&a), "--shard", "1", "--store", s(&a0)], &a0, "is not shard 1");
    let o = terrafuse(&["import", "--manifest", s(&a), "--shard", "x", "--store", s(&dir.join("p.gpkg"))], "");
    assert!(o.status.code() == Some(1) && text(&o).contains("--shard x"), "{}", text(&o));

    // An edited manifest, a damaged one, one of another format.
    let edited = dir.join("edited.json");
    let t = std::fs::read_to_string(&a).unwrap();
    let first_quad = t.find("\"quads\":[[").unwrap() + 10;
    let mut e = t.clone();
    e.replace_range(first_quad..first_quad + 1, if &t[first_quad..first_quad + 1] == "1" { "2" } else { "1" });
    std::fs::write(&edited, e).unwrap();
    refused(&["import", "--manifest", s(&edited), "--shard", "0", "--store", s(&dir.join("p.gpkg"))], &edited, "hash");
    std::fs::write(&edited, &t[..t.len() / 2]).unwrap();
    refused(&["import", "--manifest", s(&edited), "--shard", "0", "--store", s(&dir.join("p.gpkg"))], &edited, "JSON");
    std::fs::write(&edited, r#"{"format": "terrafuse-project", "version": 3}"#).unwrap();
    refused(
        &["import", "--manifest", s(&edited), "--shard", "0", "--store", s(&dir.join("p.gpkg"))],
        &edited,
        "format",
    );

    // A source changed since the plan.
    let copy = dir.join("srtm.tif");
    std::fs::copy(repo_path(SRTM), &copy).unwrap();
    let c = dir.join("c.json");
    ok(&["import", s(&copy), "--body", "wgs84", "--max-level", "8", "--plan", s(&c), "--shards", "1"]);
    let f = std::fs::File::options().write(true).open(&copy).unwrap();
    f.set_modified(std::time::SystemTime::now() + Duration::from_secs(3600)).unwrap();
    drop(f);
    refused(
        &["import", "--manifest", s(&c), "--shard", "0", "--store", s(&dir.join("c0.gpkg"))],
        &copy,
        "changed since the plan",
    );

    // Plans of no shards, or of more shards than quads.
    let src = repo_path(SRTM);
    let p = dir.join("p.json");
    let o =
        terrafuse(&["import", s(&src), "--body", "wgs84", "--max-level", "9", "--plan", s(&p), "--shards", "0"], "");
    assert!(o.status.code() == Some(1) && text(&o).contains("--shards 0"), "{}", text(&o));
    refused(
        &["import", s(&src), "--body", "wgs84", "--max-level", "9", "--plan", s(&p), "--shards", "100000"],
        &p,
        "only",
    );
    assert!(!p.exists(), "a refused plan writes nothing");
}

/// A single-node Slurm cluster in a folder, stopped when dropped.
struct Cluster {
    dir: PathBuf,
    conf: String,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let o = Command::new(repo_path("scripts/slurm-local"))
            .args(["start", s(dir), "2"])
            .output()
            .expect("scripts/slurm-local runs");
        assert!(
            o.status.success(),
            "Slurm could not start on this machine (scripts/install-deps installs slurmctld, slurmd, slurm-client and munge): {}",
            text(&o)
        );
        let out = String::from_utf8_lossy(&o.stdout);
        let conf = out.trim().strip_prefix("export SLURM_CONF=").expect("the script prints SLURM_CONF").to_owned();
        Cluster { dir: dir.to_owned(), conf }
    }

    fn run(&self, program: &str, args: &[&str]) -> Output {
        Command::new(program).args(args).env("SLURM_CONF", &self.conf).output().unwrap()
    }

    fn terrafuse(&self, args: &[&str]) -> String {
        let o = self.run(BIN, args);
        assert!(o.status.success(), "terrafuse {args:?}: {}", text(&o));
        text(&o)
    }

    /// Lines of `squeue` for these job names: "jobid state".
    fn queue(&self, names: &str) -> Vec<String> {
        let o = self.run("squeue", &["-h", "-r", "-n", names, "-o", "%i %T"]);
        assert!(o.status.success(), "squeue: {}", text(&o));
        String::from_utf8_lossy(&o.stdout).lines().map(str::to_owned).collect()
    }

    fn wait_empty(&self, names: &str) {
        let start = Instant::now();
        while !self.queue(names).is_empty() {
            assert!(
                start.elapsed() < Duration::from_secs(300),
                "jobs still queued after 300 s: {:?}",
                self.queue(names)
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(repo_path("scripts/slurm-local")).args(["stop", s(&self.dir)]).output();
    }
}

#[test]
fn a_job_array_on_slurm_with_a_shard_cancelled_and_resubmitted_gives_the_single_process_store() {
    let dir = common::scratch("shard/slurm");
    let cluster = Cluster::start(&dir.join("cluster"));
    let single = single_import(&dir);
    let manifest = plan(&dir, "plan.json", SRTM, "wgs84", "11", 6);
    let (parts, store) = (dir.join("parts"), dir.join("merged.gpkg"));
    let local = dir.join("node-local");
    // Shard 1's first run is paused (SIGSTOP) once its working file exists, so that the test
    // cancels it mid-import however fast the machine: without the pause it could finish first.
    // Until then it runs in slices of 5 ms, so it cannot get far past that point either.
    let (task, paused) = (1usize, dir.join("shard-1-paused"));
    let wrapper = dir.join("terrafuse-pausing-shard-1");
    let working = format!("'{}/terrafuse-*/.part-{task:04}.gpkg.importing'", s(&local));
    std::fs::write(
        &wrapper,
        format!(
            r#"#!/bin/bash
if [ "${{SLURM_ARRAY_TASK_ID:-}}" = {task} ] && [ "$1" = import ] && [ ! -e {paused} ]; then
  {bin} "$@" &
  pid=$!
  kill -STOP $pid
  until compgen -G {working} >/dev/null; do
    kill -0 $pid 2>/dev/null || exit 1
    kill -CONT $pid; sleep 0.005; kill -STOP $pid
  done
  touch {paused}
  wait $pid
  exit $?
fi
exec {bin} "$@"
"#,
            paused = s(&paused),
            bin = BIN,
        ),
    )
    .unwrap();
    std::fs::set_permissions(&wrapper, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let submit = |cluster: &Cluster| {
        cluster.terrafuse(&[
            "slurm",
            "submit",
            "--manifest",
            s(&manifest),
            "--parts",
            s(&parts),
            "--store",
            s(&store),
            "--threads",
            "1",
            "--work-dir",
            s(&local),
            "--terrafuse",
            s(&wrapper),
        ])
    };
    let out = submit(&cluster);
    assert!(out.contains("6 shards, 6 to run (0-5)"), "{out}");
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&manifest).unwrap()).unwrap();
    let name = format!("tf-{}", &m["hash"].as_str().unwrap()[..12]);
    let names = format!("{name},{name}-merge");

    // Cancel shard 1 while it is paused mid-import.
    let start = Instant::now();
    while !paused.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "shard {task} did not start importing within 120 s: {:?}",
            cluster.queue(&names)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let id = cluster.queue(&name).into_iter().find_map(|l| {
        let id = l.split(' ').next()?;
        (id.rsplit('_').next() == Some(&task.to_string())).then(|| id.to_owned())
    });
    let cancelled = id.unwrap_or_else(|| panic!("shard {task} is not in the queue: {:?}", cluster.queue(&names)));
    let o = cluster.run("scancel", &[&cancelled]);
    assert!(o.status.success(), "scancel {cancelled}: {}", text(&o));
    cluster.wait_empty(&names);
    let part = parts.join(format!("part-{task:04}.gpkg"));
    assert!(!part.exists(), "the cancelled shard {task} published nothing");
    assert!(!store.exists(), "the merge never ran (its dependency failed)");
    let done = (0..6).filter(|i| parts.join(format!("part-{i:04}.gpkg")).exists()).count();
    assert_eq!(done, 5, "the other shards finished");

    // Resubmitted: only the cancelled shard runs, then the merge.
    let out = submit(&cluster);
    assert!(out.contains(&format!("6 shards, 1 to run ({task})")), "{out}");
    cluster.wait_empty(&names);
    let log = std::fs::read_to_string(parts.join("slurm/merge.log")).unwrap_or_default();
    assert!(log.contains("complete: all 6 shards in"), "merge log: {log}");
    assert_same_store(&store, &single);
    // Once complete, there is nothing to submit.
    assert!(submit(&cluster).contains("nothing to submit"));
}

#[test]
fn a_comparison_and_an_export_planned_in_shards_run_on_slurm_round_after_round_as_one_process() {
    let dir = common::scratch("shard/slurm-plans");
    let cluster = Cluster::start(&dir.join("cluster"));
    let project = common::sample_project("erzurum-compare", &dir);
    let p = s(&project);
    let args = ["blurred", "srtm", "--json", "--level", "9"];
    let o = terrafuse(&[&["compare", p][..], &args[..]].concat(), "");
    assert!(o.status.success(), "{}", text(&o));
    let one: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let plan = dir.join("compare.json");
    ok(&[&["compare", p][..], &args[..], &["--plan", s(&plan), "--shards", "3"]].concat());
    let dry = cluster.terrafuse(&["slurm", "submit", s(&plan), "--dry-run"]);
    assert!(dry.contains("round 0: 3 shards to run (0-2)") && dry.contains("--array=0-2"), "{dry}");
    let out = cluster.terrafuse(&["slurm", "submit", s(&plan), "--threads", "1"]);
    assert!(out.contains("submitted job array") && out.contains("submitted merge job"), "{out}");
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&plan).unwrap()).unwrap();
    let name = format!("tf-{}", &m["hash"].as_str().unwrap()[..12]);
    // Each round's merge (exit 3) submits the next round and its merge before it ends, so the
    // queue is empty only once the last merge wrote the result.
    cluster.wait_empty(&format!("{name},{name}-merge"));
    let parts = dir.join("compare.parts");
    let log = std::fs::read_to_string(parts.join("slurm/merge.log")).unwrap_or_default();
    let result = std::fs::read_to_string(parts.join("slurm/result.json"))
        .unwrap_or_else(|e| panic!("no result ({e}); merge log:\n{log}"));
    let merged: serde_json::Value = serde_json::from_str(&result).unwrap();
    for field in ["count", "nodata_count", "median_m", "nmad_m", "le90_m", "p90_abs_m", "min_m", "max_m", "level"] {
        assert_eq!(merged[field], one[field], "{field}");
    }
    let rounds = std::fs::read_dir(&parts)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("round-"))
        .count();
    assert!(rounds > 2 && log.matches("round").count() >= rounds - 1, "{rounds} rounds; merge log:\n{log}");
    assert!(cluster.terrafuse(&["slurm", "submit", s(&plan)]).contains("nothing to submit"));

    // An export in 2 shards: the merge job writes the GeoTIFF, pixel for pixel the single one's.
    let grid = ["--crs", "EPSG:32637", "--bounds", "585000,4340000,650000,4420000", "--resolution", "500"];
    let (single, sharded, eplan) = (dir.join("single.tif"), dir.join("sharded.tif"), dir.join("export.json"));
    ok(&[&["export", p, s(&single)][..], &grid[..], &["--compose", "cpu"]].concat());
    ok(&[&["export", p, s(&sharded)][..], &grid[..], &["--compose", "cpu", "--plan", s(&eplan), "--shards", "2"]]
        .concat());
    cluster.terrafuse(&["slurm", "submit", s(&eplan), "--threads", "1"]);
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&eplan).unwrap()).unwrap();
    let name = format!("tf-{}", &m["hash"].as_str().unwrap()[..12]);
    cluster.wait_empty(&format!("{name},{name}-merge"));
    let said = std::fs::read_to_string(dir.join("export.parts/slurm/result.txt")).unwrap_or_default();
    assert!(said.contains("wrote") && sharded.exists(), "{said}");
    let raw = |tif: &Path| {
        let out = tif.with_extension("raw");
        common::run_tool("gdal_translate", &["-q", "-of", "ENVI", s(tif), s(&out)], "");
        std::fs::read(out).unwrap()
    };
    assert_eq!(raw(&single), raw(&sharded), "the Slurm export equals the single one byte for byte");
}
