//! Terrain attributes (`terrafuse export --attribute`) against xDEM 0.2.3 (`xdem.terrain`, from
//! `.venv-ref`) and GDAL's `gdaldem` on the same heights: SRTM around Erzurum exported to a
//! transverse Mercator centred on the box (so the grid's metres are the ellipsoid's to 3·10⁻⁶ and
//! grid north is true north to 0.13°), two pixels in from the edges.

mod common;

use common::{repo_path, sample_project, terrafuse};

fn run(args: &[&str]) -> String {
    let out = terrafuse(args, "");
    assert!(out.status.success(), "terrafuse {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn every_attribute_agrees_with_xdem_and_gdaldem_on_the_same_heights() {
    let dir = common::out_path("attributes");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = sample_project("erzurum-compare", &dir);
    let grid = [
        "--crs",
        "+proj=tmerc +lon_0=40.42 +lat_0=39.6 +k=1 +ellps=WGS84 +units=m",
        "--bounds",
        "-15000,-12000,15000,12000",
        "--resolution",
        "90",
        "--compose",
        "cpu",
        "--layer",
        "srtm",
    ];
    let export = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec!["export", p.to_str().unwrap(), out.to_str().unwrap()];
        args.extend_from_slice(&grid);
        args.extend_from_slice(extra);
        run(&args)
    };
    let heights = dir.join("heights.tif");
    export(&heights, &[]);
    let names = [
        "slope",
        "aspect",
        "hillshade",
        "curvature",
        "planform_curvature",
        "profile_curvature",
        "tpi",
        "tri",
        "roughness",
    ];
    for name in names {
        let said = export(&dir.join(format!("{name}.tif")), &["--attribute", name]);
        assert!(said.contains(&format!(": {name} in ")), "{said}");
    }
    let mut args = vec![repo_path("tests/reference/terrain_attributes.py").to_string_lossy().into_owned()];
    args.push(heights.to_string_lossy().into_owned());
    args.push(dir.to_string_lossy().into_owned());
    args.extend(names.iter().map(|n| n.to_string()));
    let out = std::process::Command::new(repo_path(".venv-ref/bin/python")).args(&args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let x: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Tolerances: f32 heights (10⁻⁴ m) for the windowed indices; for the gradients the grid's
    // metres against the ellipsoid's (3·10⁻⁶) and f32; for aspect and hillshade grid north
    // against true north (≤ 0.13° at the box's corners), and gdaldem's rounding to a byte.
    for (name, reference, max) in [
        ("slope", "xdem", 1e-3),
        ("slope", "gdal", 1e-3),
        ("aspect", "xdem", 0.15),
        ("aspect", "gdal", 0.15),
        ("hillshade", "xdem", 1.0),
        ("hillshade", "gdal", 1.0),
        ("curvature", "xdem", 1e-4),
        ("planform_curvature", "xdem", 1e-3),
        ("profile_curvature", "xdem", 2e-5),
        ("tpi", "xdem", 1e-3),
        ("tpi", "gdal", 1e-3),
        ("tri", "xdem", 1e-3),
        ("tri", "gdal", 1e-3),
        ("roughness", "xdem", 1e-3),
        ("roughness", "gdal", 1e-3),
    ] {
        let r = &x[name][reference];
        let (worst, p99, n) = (r[0].as_f64().unwrap(), r[1].as_f64().unwrap(), r[2].as_u64().unwrap());
        println!("{name:>18} against {reference}: max |Δ| {worst:.3e}, 99th percentile {p99:.3e} over {n} pixels");
        assert!(n > 50_000, "{name}: {n} pixels compared");
        assert!(worst <= max, "{name} against {reference}: {worst} over {max}");
    }
}

#[test]
fn a_bad_attribute_is_refused_by_name() {
    let dir = common::out_path("attributes-bad");
    std::fs::create_dir_all(&dir).unwrap();
    let p = sample_project("erzurum-compare", &dir);
    let x = dir.join("x.tif");
    let export = |extra: [&str; 2]| {
        let mut args = vec!["export", p.to_str().unwrap(), x.to_str().unwrap(), "--crs", "EPSG:4326"];
        args.extend(["--bounds", "40.3,39.5,40.4,39.6", "--resolution", "0.001"]);
        args.extend(extra);
        let out = terrafuse(&args, "");
        (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (ok, err) = export(["--attribute", "slopes"]);
    assert!(!ok && err.contains("--attribute slopes: not an attribute (slope, aspect"), "{err}");
    let (ok, err) = export(["--layer", "nowhere"]);
    assert!(!ok && err.contains("'nowhere'"), "{err}");
}

#[test]
fn the_gpu_computes_every_attribute_as_the_cpu_reference() {
    // Hills of 300 m over 2 km and 40 m over 400 m on a 0.001° grid around 39.6°N, with a hole
    // of no data: the same heights and axes through both.
    use terrafuse::attributes::{Attribute, attribute_raster, pixel_axes};
    use terrafuse::geodesy::Ellipsoid;
    let (w, h) = (300usize, 200usize);
    let lat_lon: Vec<(f64, f64)> = (0..w * h)
        .map(|k| ((39.7 - (k / w) as f64 * 0.001).to_radians(), (40.3 + (k % w) as f64 * 0.001).to_radians()))
        .collect();
    let heights: Vec<f32> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64 * 85.0, (k / w) as f64 * 111.0);
            if (x - 12_000.0).hypot(y - 9_000.0) < 1_500.0 {
                return f32::NAN;
            }
            (2000.0
                + 300.0 * (x / 2000.0 * std::f64::consts::TAU).sin() * (y / 2600.0).cos()
                + 40.0 * (x / 400.0 + y / 310.0).sin()) as f32
        })
        .collect();
    let axes = pixel_axes(&Ellipsoid::WGS84, w, h, &lat_lon);
    let ctx = terrafuse::gpu::GpuContext::headless().expect("a GPU adapter (lavapipe in CI)");
    let slope = attribute_raster(Attribute::Slope, w, h, &heights, &axes);
    // f32 in the kernel against f64 here: heights to 1.2·10⁻⁴ m over 85 m steps move a gradient
    // by ≈ 2·10⁻⁶; aspect is compared where the slope passes 2° (it turns freely on the flat).
    for (attribute, tolerance) in [
        (Attribute::Slope, 1e-3),
        (Attribute::Aspect, 0.01),
        (Attribute::Hillshade, 1e-2),
        (Attribute::Curvature, 2e-5),
        (Attribute::PlanformCurvature, 1e-3),
        (Attribute::ProfileCurvature, 1e-5),
        (Attribute::Tpi, 1e-3),
        (Attribute::Tri, 1e-3),
        (Attribute::Roughness, 1e-3),
    ] {
        let cpu = attribute_raster(attribute, w, h, &heights, &axes);
        let gpu = terrafuse::gpu::attributes::attribute_raster(&ctx, attribute, w, h, &heights, &axes).unwrap();
        let (mut worst, mut compared) = (0f64, 0usize);
        for k in 0..w * h {
            assert_eq!(
                cpu[k].is_nan(),
                gpu[k].is_nan(),
                "{} at pixel {k}: CPU {}, GPU {}",
                attribute.name(),
                cpu[k],
                gpu[k]
            );
            if cpu[k].is_nan() || (attribute == Attribute::Aspect && slope[k] < 2.0) {
                continue;
            }
            let mut d = f64::from(gpu[k] - cpu[k]).abs();
            if attribute == Attribute::Aspect {
                d = d.min(360.0 - d);
            }
            worst = worst.max(d);
            compared += 1;
        }
        println!("{:>18}: GPU − CPU worst {worst:.2e} over {compared} pixels", attribute.name());
        assert!(compared > 40_000 && worst <= tolerance, "{}: {worst} over {tolerance}", attribute.name());
    }
}
