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
