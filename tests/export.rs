//! `terrafuse export`: the composed elevation through GDAL. A single dataset exports exactly as
//! `store export` samples it (an independent path: the store's reader); the GPU and the CPU
//! reference agree; the GeoTIFF declares its CRS, NaN nodata and provenance; bad input is named.

mod common;

use std::path::PathBuf;

use common::{run_tool, terrafuse};

fn dir() -> PathBuf {
    let d = common::out_path("export");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn read_f32(path: &std::path::Path) -> Vec<f32> {
    // gdal_translate to raw float32 (ENVI), read back.
    let raw = path.with_extension("raw");
    run_tool("gdal_translate", &["-q", "-of", "ENVI", path.to_str().unwrap(), raw.to_str().unwrap()], "");
    let bytes = std::fs::read(&raw).unwrap();
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

#[test]
fn a_single_dataset_exports_as_the_store_does_and_gpu_matches_cpu() {
    let project = common::sample_project("erzurum", &dir());
    let store = terrafuse::project::Project::load(&project).unwrap().layers[0].as_dataset().unwrap().store.clone();
    let args = ["--crs", "EPSG:32637", "--bounds", "585000,4340000,650000,4420000", "--resolution", "250"];
    let composed = dir().join("composed.tif");
    let o =
        terrafuse(&[&["export", project.to_str().unwrap(), composed.to_str().unwrap()][..], &args[..]].concat(), "");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("composed on the GPU"), "{stdout}");
    let cpu = dir().join("composed-cpu.tif");
    let o = terrafuse(
        &[&["export", project.to_str().unwrap(), cpu.to_str().unwrap()][..], &args[..], &["--compose", "cpu"]].concat(),
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let single = dir().join("store.tif");
    let o = terrafuse(
        &[&["store", "export", store.to_str().unwrap(), single.to_str().unwrap()][..], &args[..]].concat(),
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let info = run_tool("gdalinfo", &[composed.to_str().unwrap()], "");
    assert!(info.contains("UTM zone 37N") && info.contains("NoData Value=nan"), "{info}");
    assert!(info.contains("TERRAFUSE_LAYERS=srtm") && info.contains("TERRAFUSE_LEVEL=8"), "{info}");
    let (g, c, s) = (read_f32(&composed), read_f32(&cpu), read_f32(&single));
    assert_eq!((g.len(), c.len()), (s.len(), s.len()));
    let (mut worst_store, mut worst_gpu, mut valid) = (0f32, 0f32, 0);
    for ((g, c), s) in g.iter().zip(&c).zip(&s) {
        assert_eq!(c.is_nan(), s.is_nan());
        assert_eq!(g.is_nan(), c.is_nan());
        if !c.is_nan() {
            valid += 1;
            worst_store = worst_store.max((c - s).abs());
            worst_gpu = worst_gpu.max((g - c).abs());
        }
    }
    assert!(valid > 50_000, "{valid} pixels with data");
    // One `over` layer at full coverage is its dataset exactly ((1 − 1)·h + 1·v = v); both
    // exports interpolate the same level's samples bilinearly (rounding to f32 in between: 1 ulp).
    assert!(worst_store <= 2.5e-4, "composed vs store export: {worst_store} m");
    // The GPU's composed samples equal the CPU's for a plain dataset (no arithmetic on them).
    assert!(worst_gpu <= 2.5e-4, "GPU vs CPU: {worst_gpu} m");
}

#[test]
fn an_export_made_band_by_band_equals_one_made_at_once_bit_for_bit() {
    use terrafuse::export::{ComposeOn, ComposedExport, export_composed_in_bands};
    let project = common::sample_project("erzurum", &dir());
    let export = |name: &str, attribute, band_pixels: usize| {
        let out = dir().join(name);
        let opts = ComposedExport {
            project: project.clone(),
            out: out.clone(),
            crs: "EPSG:32637".into(),
            bounds: [585000.0, 4340000.0, 650000.0, 4420000.0],
            resolution: (250.0, 250.0),
            level: None,
            compose_on: ComposeOn::Cpu,
            difference: None,
            attribute,
            layer: None,
            cog: false,
        };
        let report = export_composed_in_bands(&opts, &Default::default(), band_pixels).unwrap();
        (report, read_f32(&out))
    };
    for attribute in [None, Some(terrafuse::attributes::Attribute::Slope)] {
        let (whole, at_once) = export("at-once.tif", attribute, usize::MAX);
        // Bands of 7 rows of the 260: 38 of them, the last shorter, each with a row above and
        // below for the slope's window.
        let (banded, in_bands) = export("in-bands.tif", attribute, 7 * 260);
        assert_eq!(whole.size, (260, 320));
        assert_eq!((whole.quads, whole.valid), (banded.quads, banded.valid));
        assert!(whole.valid > 50_000, "{whole:?}");
        assert_eq!(at_once.len(), in_bands.len());
        let differing = at_once.iter().zip(&in_bands).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
        assert_eq!(differing, 0, "{attribute:?}: {differing} pixels differ");
    }
}

#[test]
fn bad_exports_are_refused_by_name() {
    let project = common::sample_project("erzurum", &dir());
    let p = project.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &[
                "export",
                "missing.json",
                "/tmp/x.tif",
                "--crs",
                "EPSG:4326",
                "--bounds",
                "0,0,1,1",
                "--resolution",
                "0.1",
            ],
            "missing.json: cannot read",
        ),
        (
            &["export", p, "/tmp/x.tif", "--crs", "EPSG:99999", "--bounds", "0,0,1,1", "--resolution", "0.1"],
            "unknown CRS 'EPSG:99999'",
        ),
        (
            &["export", p, "/tmp/x.tif", "--crs", "EPSG:4326", "--bounds", "1,0,0,1", "--resolution", "0.1"],
            "do not make a raster",
        ),
        (
            &[
                "export",
                p,
                "/no/such/folder/x.tif",
                "--crs",
                "EPSG:4326",
                "--bounds",
                "40,39,40.1,39.1",
                "--resolution",
                "0.01",
            ],
            "folder /no/such/folder does not exist",
        ),
    ];
    for (args, expected) in cases {
        let o = terrafuse(args, "");
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(expected), "{args:?}: {e}");
    }
}

#[test]
fn an_export_cut_into_shards_merges_to_the_single_export_pixel_for_pixel() {
    let dir = common::out_path("export-shards");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let project = common::sample_project("erzurum-compare", &dir);
    let p = project.to_str().unwrap();
    let grid = ["--crs", "EPSG:32637", "--bounds", "585000,4340000,650000,4420000", "--resolution", "250"];
    let run = |args: &[&str]| {
        let o = terrafuse(args, "");
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    for (what, extra) in [
        ("heights", &[][..]),
        ("slope", &["--attribute", "slope"][..]),
        ("difference", &["--difference", "blurred,srtm"][..]),
    ] {
        let single = dir.join(format!("{what}.tif"));
        run(&[&["export", p, single.to_str().unwrap()][..], &grid[..], extra, &["--compose", "cpu"]].concat());
        let one = read_f32(&single);
        for shards in [1, 3, 7] {
            let out = dir.join(format!("{what}-{shards}.tif"));
            let plan = dir.join(format!("{what}-{shards}.json"));
            let (out_s, plan_s, n) = (out.to_str().unwrap(), plan.to_str().unwrap(), shards.to_string());
            let cog: &[&str] = if shards == 3 { &["--cog"] } else { &[] };
            let planned = run(&[
                &["export", p, out_s][..],
                &grid[..],
                extra,
                cog,
                &["--compose", "cpu", "--plan", plan_s, "--shards", &n],
            ]
            .concat());
            assert!(planned.contains(&format!("in {shards} shards")) && !out.exists(), "{planned}");
            // Nothing made yet: the merge names every shard and exits 3, writing nothing.
            let waiting = terrafuse(&["merge", plan_s], "");
            let said = String::from_utf8_lossy(&waiting.stderr).into_owned();
            let all: Vec<String> = (0..shards).map(|i| i.to_string()).collect();
            assert_eq!(waiting.status.code(), Some(3), "{said}");
            assert!(said.contains(&format!("waits for shards {}", all.join(","))) && !out.exists(), "{said}");
            // A shard killed part-way leaves a temporary file and, at worst, data without their
            // JSON: the part counts as missing and the rerun makes it whole.
            let parts = dir.join(format!("{what}-{shards}.parts"));
            std::fs::write(parts.join(".shard-000000.f32.tmp-999999"), b"half").unwrap();
            std::fs::write(parts.join("shard-000000.f32"), b"half a shard").unwrap();
            assert!(run(&["shard", plan_s, "0"]).contains("wrote its rows"));
            assert!(run(&["shard", plan_s, "0"]).contains("there already"));
            let merged = run(&["shards", "run", plan_s, "--jobs", "2"]);
            assert!(merged.contains("wrote") && merged.contains("320 pixels"), "{merged}");
            let sharded = read_f32(&out);
            assert_eq!(sharded.len(), one.len());
            let differing = one.iter().zip(&sharded).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
            assert_eq!(differing, 0, "{what}, {shards} shards: {differing} pixels differ");
            assert!(one.iter().filter(|v| !v.is_nan()).count() > 50_000, "{what}");
            if shards == 3 {
                let info = run_tool("gdalinfo", &[out_s], "");
                assert!(info.contains("LAYOUT=COG") && info.contains("TERRAFUSE_LEVEL=8"), "{info}");
            }
        }
    }
    // Damaged data (same size, one byte changed) are refused by the part's SHA-256, the output
    // left as it was; a part of another plan is refused by name; so is a changed project.
    let (plan, out) = (dir.join("heights-3.json"), dir.join("heights-3.tif"));
    let before = std::fs::read(&out).unwrap();
    let data = dir.join("heights-3.parts/shard-000001.f32");
    let mut bytes = std::fs::read(&data).unwrap();
    bytes[1000] ^= 0x40;
    std::fs::write(&data, &bytes).unwrap();
    let refused = terrafuse(&["merge", plan.to_str().unwrap()], "");
    let said = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert!(!refused.status.success() && said.contains("shard-000001.f32") && said.contains("SHA-256"), "{said}");
    assert_eq!(std::fs::read(&out).unwrap(), before, "the output is untouched");
    std::fs::copy(dir.join("slope-3.parts/shard-000002.json"), dir.join("heights-3.parts/shard-000002.json")).unwrap();
    let refused = terrafuse(&["merge", plan.to_str().unwrap()], "");
    let said = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert!(said.contains("shard-000002.json") && said.contains("another plan"), "{said}");
    let text = std::fs::read_to_string(&project).unwrap();
    std::fs::write(&project, text + " ").unwrap();
    let refused = terrafuse(&["shard", dir.join("heights-7.json").to_str().unwrap(), "1"], "");
    let said = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert!(said.contains("erzurum-compare.json") && said.contains("changed since the plan"), "{said}");
}
