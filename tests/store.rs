//! The tile store against GDAL: every sample DEM imported and compared with gdalwarp into the
//! same QSC grid, seams across face edges, pixel conventions, vertical datum against PROJ's cct,
//! GDAL reading the GeoPackage, bad input, and an import killed and resumed.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{repo_path, run_tool, terrafuse};
use terrafuse::bench::{WarpMode, warp_comparison};
use terrafuse::ecm::grid::{self, fold_sample};
use terrafuse::ecm::{Face, QuadId};
use terrafuse::geodesy::Ellipsoid;
use terrafuse::store::{GridReader, ImportOptions, ImportWatch, LevelChoice, Resampling, Store, VerticalDatum, import};

const BIN: &str = env!("CARGO_BIN_EXE_terrafuse");

fn data(name: &str) -> PathBuf {
    repo_path(&format!("projects/data/{name}"))
}

fn options(sources: &[PathBuf], store: &Path, body: Ellipsoid, name: &str, level: LevelChoice) -> ImportOptions {
    ImportOptions {
        sources: sources.to_vec(),
        store: store.to_owned(),
        body,
        name: Some(name.into()),
        level,
        resampling: Resampling::Bilinear,
        transform: terrafuse::store::lattice::Transform::Lattice,
        vertical: VerticalDatum::Unspecified,
        memory_budget: 512 << 20,
        threads: Some(2),
        progress: false,
        finest_only: false,
        watch: None,
    }
}

/// Every sample DEM, at a level where gdalwarp's bilinear is plain bilinear (every axis of the
/// target finer than the source, so gdalwarp does not widen its kernel): our samples equal
/// gdalwarp's with the exact transformer (`-et 0`) to float rounding, far below the sources'
/// 1 m vertical step.
#[test]
fn every_sample_dem_matches_gdalwarp_on_the_same_qsc_grid() {
    let dir = common::scratch("store/gdalwarp");
    let all = &Face::ALL[..];
    // The global grid on the faces where gdalwarp does plain bilinear: not the polar faces (the
    // source's columns converge there, so gdalwarp widens its kernel) and not the back face
    // (gdalwarp does not wrap the source across ±180°; the store does). `terrafuse bench import`
    // reports all six faces.
    let equatorial = &[Face::Front, Face::Right, Face::Left][..];
    type Case<'a> = (&'a str, Ellipsoid, u8, &'a [Face], f64, f64);
    let cases: [Case; 5] = [
        // file, body, level, faces, mean limit, 99th-percentile limit (metres)
        ("earth_srtm3_demcompare_N39E040.tif", Ellipsoid::WGS84, 10, all, 1e-3, 1e-3),
        ("earth_jacksboro_srtm3_epsg4326.tif", Ellipsoid::WGS84, 10, all, 1e-3, 1e-3),
        ("earth_topobathy_merc2min_epsg3857.tif", Ellipsoid::WGS84, 7, all, 1e-3, 1e-3),
        ("moon_lola_north_stere_1600m.tif", Ellipsoid::MOON, 4, all, 1e-3, 1e-3),
        ("moon_lola_ldem_4ppd_global.tif", Ellipsoid::MOON, 2, equatorial, 1e-3, 1e-3),
    ];
    let mut table = String::new();
    for (k, (file, body, level, faces, mean_limit, p99_limit)) in cases.into_iter().enumerate() {
        let store_path = dir.join(format!("s{k}.gpkg"));
        let name = format!("d{k}");
        import(&options(&[data(file)], &store_path, body, &name, LevelChoice::Level(level))).unwrap();
        let store = Store::open_read_only(&store_path).unwrap();
        let c =
            warp_comparison(&store, &name, level, &[data(file)], "bilinear", WarpMode::Exact, 2, &dir, faces).unwrap();
        table += &format!(
            "{file} level {level}: {} samples, mean {:.2e} m, p99 {:.2e} m, max {:.2e} m\n",
            c.compared, c.mean_m, c.p99_m, c.max_m
        );
        assert!(c.compared > 10_000, "{file}: only {} samples compared", c.compared);
        assert!(c.mean_m < mean_limit && c.p99_m < p99_limit, "{file}: {c:?}");
    }
    println!("{table}");
}

/// Samples that two faces share (their common edges, cube corners) agree, at the finest level
/// (resampled) and at the coarser ones (averaged across the edge); heights just either side of
/// every edge agree too.
#[test]
fn seams_agree_across_every_face_edge_and_cube_corner() {
    let dir = common::scratch("store/seams");
    let store_path = dir.join("moon.gpkg");
    import(&options(
        &[data("moon_lola_ldem_4ppd_global.tif")],
        &store_path,
        Ellipsoid::MOON,
        "lola",
        LevelChoice::Level(2),
    ))
    .unwrap();
    let mut reader = GridReader::new(Store::open_read_only(&store_path).unwrap(), "lola").unwrap();
    for level in 0..=2u8 {
        let m = grid::intervals_per_face_edge(level);
        let mut worst = 0.0f64;
        let mut pairs = 0;
        for face in Face::ALL {
            for t in 0..=m {
                for (i, j) in [(0, t), (m, t), (t, 0), (t, m)] {
                    // The same point seen from the adjacent face: fold one step out and one back in.
                    let outward = if i == 0 {
                        (-1, j)
                    } else if i == m {
                        (m + 1, j)
                    } else if j == 0 {
                        (i, -1)
                    } else {
                        (i, m + 1)
                    };
                    let further = (2 * outward.0 - i, 2 * outward.1 - j);
                    let (other, oi, oj) = fold_sample(face, level, outward.0, outward.1).unwrap();
                    let (other2, fi, fj) = fold_sample(face, level, further.0, further.1).unwrap();
                    assert_eq!(other2, other);
                    // One step in, two steps in: the edge is one step back out.
                    let (ei, ej) = (2 * oi - fi, 2 * oj - fj);
                    let a = reader.sample(face, level, i, j).unwrap();
                    let b = reader.sample(other, level, ei, ej).unwrap();
                    assert!(!a.is_nan() && !b.is_nan(), "{face} {level} {i} {j}");
                    worst = worst.max(f64::from((a - b).abs()));
                    pairs += 1;
                }
            }
        }
        // Resampled edges: the same geodetic point from two faces' formulas, same f32; averaged
        // ones: the same stencil from both sides (cube corners weighted symmetrically).
        assert!(worst < 1e-3, "level {level}: {pairs} shared samples, worst {worst} m");
        println!("level {level}: {pairs} shared samples, worst difference {worst:.2e} m");
    }
    // The renderer's read: a quad's grid with a border from its neighbours. Inside a face the
    // border is the neighbours' own samples; across face edges it is filled as well.
    let q = QuadId::new(Face::Front, 2, 1, 2).unwrap();
    let b = reader.grid_with_border(q, 1).unwrap().unwrap();
    let n = 259usize;
    let west = reader.grid(QuadId::new(Face::Front, 2, 0, 2).unwrap()).unwrap().unwrap();
    let north = reader.grid(QuadId::new(Face::Front, 2, 1, 3).unwrap()).unwrap().unwrap();
    let own = reader.grid(q).unwrap().unwrap();
    for k in 0..257u32 {
        assert_eq!(b[(k as usize + 1) * n], west.get(255, k));
        assert_eq!(b[258 * n + k as usize + 1], north.get(k, 1));
        assert_eq!(b[(k as usize + 1) * n + 1], own.get(0, k));
    }
    for corner in [QuadId::new(Face::Top, 2, 3, 3).unwrap(), QuadId::new(Face::Bottom, 2, 0, 0).unwrap()] {
        let b = reader.grid_with_border(corner, 2).unwrap().unwrap();
        let missing = b.iter().filter(|v| v.is_nan()).count();
        // Only the 2×2 block beyond the cube corner has no point.
        assert_eq!(missing, 4, "{corner}");
    }
    // Heights a hair either side of face edges (on meridians ±45°, ±135° and the edges of the
    // polar faces at lat ≈ 35–45°) agree.
    let mut worst = 0.0f64;
    for k in 0..720 {
        let lon = -180.0 + f64::from(k) * 0.5;
        for (lat, dlon, dlat) in [(20.0f64, 1e-7, 0.0), (41.0, 0.0, 1e-7)] {
            let edge_lon = if dlon != 0.0 { [-135.0, -45.0, 45.0, 135.0][k as usize % 4] } else { lon };
            let a = reader.height_at((lat - dlat).to_radians(), (edge_lon - dlon).to_radians(), 2).unwrap();
            let b = reader.height_at((lat + dlat).to_radians(), (edge_lon + dlon).to_radians(), 2).unwrap();
            worst = worst.max((a - b).abs());
        }
    }
    assert!(worst < 0.05, "heights across face edges differ by {worst} m");
}

/// GDAL reports the same grid whether a GeoTIFF says pixel-is-area or pixel-is-point; the
/// import follows GDAL's geotransform, so both land in the same place. Reading the point file
/// the wrong way (GTIFF_POINT_GEO_IGNORE) moves SRTM by half a pixel, 45 m, which the store shows.
#[test]
fn pixel_is_point_and_pixel_is_area_sources_land_on_the_same_place() {
    let dir = common::scratch("store/pixel");
    let area = data("earth_jacksboro_srtm3_epsg4326.tif");
    let point = dir.join("point.tif");
    run_tool(
        "gdal_translate",
        &["-q", "-mo", "AREA_OR_POINT=Point", area.to_str().unwrap(), point.to_str().unwrap()],
        "",
    );
    let info = run_tool("gdalinfo", &[point.to_str().unwrap()], "");
    assert!(info.contains("AREA_OR_POINT=Point"), "{info}");
    let ignored = Command::new("gdalinfo").env("GTIFF_POINT_GEO_IGNORE", "TRUE").arg(&point).output().unwrap();
    let origin = |text: &str| text.lines().find(|l| l.starts_with("Origin")).unwrap_or_default().to_owned();
    assert_ne!(
        origin(&info),
        origin(&String::from_utf8_lossy(&ignored.stdout)),
        "the point file must store a shifted tie point"
    );

    let store_path = dir.join("s.gpkg");
    for (name, src) in [("area", &area), ("point", &point)] {
        import(&options(std::slice::from_ref(src), &store_path, Ellipsoid::WGS84, name, LevelChoice::Level(10)))
            .unwrap();
    }
    let store = Store::open_read_only(&store_path).unwrap();
    let quads = store.data_quads("area", 10).unwrap();
    assert_eq!(quads, store.data_quads("point", 10).unwrap());
    for q in quads.iter().take(6) {
        assert_eq!(store.read_grid("area", *q).unwrap(), store.read_grid("point", *q).unwrap(), "{q}");
    }
    // The wrong reading, half a pixel off: heights differ by metres on this relief.
    let wrong = Command::new(BIN)
        .env("GTIFF_POINT_GEO_IGNORE", "TRUE")
        .args([
            "import",
            point.to_str().unwrap(),
            "--store",
            store_path.to_str().unwrap(),
            "--body",
            "wgs84",
            "--name",
            "wrong",
            "--max-level",
            "10",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(wrong.status.success(), "{}", String::from_utf8_lossy(&wrong.stderr));
    let mut a = GridReader::new(Store::open_read_only(&store_path).unwrap(), "area").unwrap();
    let mut w = GridReader::new(Store::open_read_only(&store_path).unwrap(), "wrong").unwrap();
    let (mut sum, mut n) = (0.0, 0);
    for k in 0..400 {
        let lat = 36.2 + 0.2 * f64::from(k % 20) / 20.0;
        let lon = -84.35 + 0.2 * f64::from(k / 20) / 20.0;
        let (x, y) = (
            a.height_at(lat.to_radians(), lon.to_radians(), 10).unwrap(),
            w.height_at(lat.to_radians(), lon.to_radians(), 10).unwrap(),
        );
        sum += (x - y).abs();
        n += 1;
    }
    assert!(sum / f64::from(n) > 2.0, "a 45 m shift should change heights by metres here: {}", sum / f64::from(n));
}

/// --vertical-datum egm96 adds the EGM96 undulation through PROJ: against cct's vgridshift with
/// the same grid, and ≈ +29.6 m near Erzurum.
#[test]
fn egm96_heights_become_ellipsoidal_heights_as_proj_computes_them() {
    let dir = common::scratch("store/geoid");
    let store_path = dir.join("s.gpkg");
    let src = data("earth_srtm3_demcompare_N39E040.tif");
    import(&options(std::slice::from_ref(&src), &store_path, Ellipsoid::WGS84, "geoid", LevelChoice::Level(8)))
        .unwrap();
    let mut o = options(&[src], &store_path, Ellipsoid::WGS84, "ellipsoidal", LevelChoice::Level(8));
    o.vertical = "egm96".parse().unwrap();
    import(&o).unwrap();
    let store = Store::open_read_only(&store_path).unwrap();
    assert!(
        store
            .dataset("ellipsoidal")
            .unwrap()
            .unwrap()
            .settings
            .vertical_datum
            .starts_with("ellipsoidal: converted from EGM96")
    );
    assert!(store.dataset("geoid").unwrap().unwrap().settings.vertical_datum.contains("EGM96 geoid heights"));
    let mut g = GridReader::new(Store::open_read_only(&store_path).unwrap(), "geoid").unwrap();
    let mut e = GridReader::new(Store::open_read_only(&store_path).unwrap(), "ellipsoidal").unwrap();
    let points: Vec<(f64, f64)> =
        (0..50).map(|k| (39.2 + 0.75 * f64::from(k % 10) / 10.0, 40.05 + 0.7 * f64::from(k / 10) / 5.0)).collect();
    let input: String = points.iter().map(|(lat, lon)| format!("{lon} {lat} 0\n")).collect();
    let cct = run_tool("cct", &["-d", "6", "+proj=vgridshift", "+grids=egm96_15.gtx", "+multiplier=1"], &input);
    for ((lat, lon), line) in points.iter().zip(cct.lines()) {
        let n: f64 = line.split_whitespace().nth(2).unwrap().parse().unwrap();
        let h_geoid = g.height_at(lat.to_radians(), lon.to_radians(), 8).unwrap();
        let h_ell = e.height_at(lat.to_radians(), lon.to_radians(), 8).unwrap();
        // Bilinear between samples that each got their own N: within the variation of N over a cell.
        assert!((h_ell - h_geoid - n).abs() < 0.01, "{lat} {lon}: store {} cct {n}", h_ell - h_geoid);
        assert!((20.0..35.0).contains(&n));
    }
}

/// Each face table opens in GDAL as a georeferenced Float32 raster in its QSC CRS, with the
/// quadtree levels as overviews; GDAL reads the very values the store holds.
#[test]
fn gdal_opens_every_face_table_as_a_georeferenced_raster() {
    let dir = common::scratch("store/gdalinfo");
    let store_path = dir.join("s.gpkg");
    import(&options(
        &[data("moon_lola_ldem_4ppd_global.tif")],
        &store_path,
        Ellipsoid::MOON,
        "lola",
        LevelChoice::Auto,
    ))
    .unwrap();
    let store = Store::open_read_only(&store_path).unwrap();
    let level = store.dataset("lola").unwrap().unwrap().settings.finest_level;
    assert_eq!(level, 1);
    for face in Face::ALL {
        let table = format!("GPKG:{}:lola_{}", store_path.display(), face.name());
        let info = run_tool("gdalinfo", &[&table], "");
        assert!(
            info.contains("Quadrilateralized_Spherical_Cube") || info.contains("Quadrilateralized Spherical Cube"),
            "{info}"
        );
        assert!(info.contains("Size is 512, 512") && info.contains("Type=Float32"), "{info}");
        assert!(info.contains("AREA_OR_POINT=Point") && info.contains("Overviews: 256x256"), "{info}");
        assert!(info.contains("Origin = (-1737400.000000000000000,1737400.000000000000000)"), "{info}");
        // Pixel (col, row) holds sample i = col, j = 511 − row.
        let quad = QuadId::new(face, 1, 1, 0).unwrap();
        let g = store.read_grid("lola", quad).unwrap().unwrap();
        for (col, row) in [(256u32, 511u32), (300, 300), (511, 256)] {
            let v = run_tool("gdallocationinfo", &["-valonly", &table, &col.to_string(), &row.to_string()], "");
            let (i, j) = (col - 256, 511 - row);
            let gdal: f32 = v.trim().parse().unwrap();
            assert_eq!(gdal, g.get(i, j), "{face} pixel {col},{row}");
        }
    }
}

/// Bad input is refused with the file and the problem named, and the store is left as it was.
#[test]
fn bad_input_is_refused_by_name_and_leaves_the_store_untouched() {
    let dir = common::scratch("store/bad");
    let store_path = dir.join("s.gpkg");
    import(&options(
        &[data("earth_topobathy_merc2min_epsg3857.tif")],
        &store_path,
        Ellipsoid::WGS84,
        "topo",
        LevelChoice::Auto,
    ))
    .unwrap();
    let before = std::fs::read(&store_path).unwrap();
    let text = dir.join("notes.tif");
    std::fs::write(&text, "not a raster").unwrap();
    let nocrs = dir.join("nocrs.vrt");
    std::fs::write(&nocrs, format!(
        "<VRTDataset rasterXSize=\"120\" rasterYSize=\"91\"><GeoTransform>0, 1000, 0, 0, 0, -1000</GeoTransform><VRTRasterBand dataType=\"Int16\" band=\"1\"><SimpleSource><SourceFilename>{}</SourceFilename><SourceBand>1</SourceBand></SimpleSource></VRTRasterBand></VRTDataset>",
        data("earth_topobathy_merc2min_epsg3857.tif").display()
    )).unwrap();
    let nodata = dir.join("nodata.tif");
    run_tool(
        "gdal_translate",
        &[
            "-q",
            "-scale",
            "-1437",
            "2205",
            "-32768",
            "-32768",
            "-a_nodata",
            "-32768",
            data("earth_topobathy_merc2min_epsg3857.tif").to_str().unwrap(),
            nodata.to_str().unwrap(),
        ],
        "",
    );
    let vrt = |name: &str, w: u64, h: u64| {
        let p = dir.join(name);
        std::fs::write(&p, format!(
            "<VRTDataset rasterXSize=\"{w}\" rasterYSize=\"{h}\"><SRS>EPSG:4326</SRS><GeoTransform>0, 0.001, 0, 10, 0, -0.001</GeoTransform><VRTRasterBand dataType=\"Int16\" band=\"1\"/></VRTDataset>"
        )).unwrap();
        p
    };
    let huge = vrt("huge.vrt", 2_000_000_000, 2_000_000_000);
    let zero = vrt("zero.vrt", 0, 10);
    let cases: [(&PathBuf, &str, &str); 6] = [
        (&text, "wgs84", "not a raster GDAL can read"),
        (&nocrs, "wgs84", "no coordinate reference system"),
        (&nodata, "wgs84", "every sample is no data"),
        (&huge, "wgs84", "absurd raster size"),
        (&zero, "wgs84", ""),
        (&data("moon_lola_ldem_4ppd_global.tif"), "wgs84", "wrong --body"),
    ];
    for (src, body, message) in cases {
        let out = Command::new(BIN)
            .args(["import", src.to_str().unwrap(), "--store", store_path.to_str().unwrap(), "--body", body, "--quiet"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{} was accepted", src.display());
        assert!(
            err.contains(src.file_name().unwrap().to_str().unwrap()) && err.contains(message),
            "{}: {err}",
            src.display()
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(std::fs::read(&store_path).unwrap() == before, "{} changed the store", src.display());
    }
    // A store of another body, an unknown body.
    let out = terrafuse(
        &[
            "import",
            data("moon_lola_north_stere_1600m.tif").to_str().unwrap(),
            "--store",
            store_path.to_str().unwrap(),
            "--body",
            "moon",
            "--quiet",
        ],
        "",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("s.gpkg") && err.contains("is a store of body wgs84"), "{err}");
    let out = terrafuse(
        &[
            "import",
            data("moon_lola_north_stere_1600m.tif").to_str().unwrap(),
            "--store",
            dir.join("new.gpkg").to_str().unwrap(),
            "--body",
            "pluto",
        ],
        "",
    );
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("pluto"));
    assert!(!dir.join("new.gpkg").exists());
    assert!(std::fs::read(&store_path).unwrap() == before, "the refused imports changed the store");
}

/// An import killed at several moments leaves a store that opens (and says it is incomplete);
/// the same command completes it without redoing finished tiles, and the result equals an
/// uninterrupted import tile for tile.
#[test]
fn a_killed_import_leaves_a_store_that_opens_and_resumes_to_the_same_result() {
    let dir = common::scratch("store/kill");
    let src = data("moon_lola_ldem_4ppd_global.tif");
    let reference = dir.join("reference.gpkg");
    let t = std::time::Instant::now();
    import(&options(std::slice::from_ref(&src), &reference, Ellipsoid::MOON, "lola", LevelChoice::Level(4))).unwrap();
    // Kills at fractions of how long an import takes on this machine, so that some land during it
    // however fast the machine is.
    let run = t.elapsed();
    let store_path = dir.join("killed.gpkg");
    let args = [
        "import",
        src.to_str().unwrap(),
        "--store",
        store_path.to_str().unwrap(),
        "--body",
        "moon",
        "--name",
        "lola",
        "--max-level",
        "4",
        "--threads",
        "2",
        "--quiet",
    ];
    let mut interrupted = 0;
    for fraction in [0.1, 0.3, 0.5, 0.7, 0.9] {
        let mut child = Command::new(BIN).args(args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        std::thread::sleep(run.mul_f64(fraction));
        let _ = child.kill();
        let _ = child.wait();
        if !store_path.exists() {
            continue;
        }
        let info = terrafuse(&["store", "info", store_path.to_str().unwrap()], "");
        assert!(info.status.success(), "killed store does not open: {}", String::from_utf8_lossy(&info.stderr));
        if String::from_utf8_lossy(&info.stdout).contains("INCOMPLETE") {
            interrupted += 1;
        }
    }
    assert!(interrupted >= 1, "no kill landed during the import");
    let out = terrafuse(&args, "");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(report.contains("finished by an earlier run") || report.contains("already complete"), "{report}");
    let a = Store::open_read_only(&reference).unwrap();
    let b = Store::open_read_only(&store_path).unwrap();
    assert!(b.dataset("lola").unwrap().unwrap().completed.is_some());
    for level in 0..=4 {
        let quads = a.data_quads("lola", level).unwrap();
        assert_eq!(quads, b.data_quads("lola", level).unwrap(), "level {level}");
        for q in quads {
            assert_eq!(a.read_grid("lola", q).unwrap(), b.read_grid("lola", q).unwrap(), "{q}");
        }
    }
}

#[test]
fn a_cancelled_import_reports_its_progress_keeps_a_valid_store_and_resumes_to_the_same_result() {
    let dir = common::scratch("store/cancel");
    let src = data("moon_lola_ldem_4ppd_global.tif");
    let reference = dir.join("reference.gpkg");
    import(&options(std::slice::from_ref(&src), &reference, Ellipsoid::MOON, "lola", LevelChoice::Level(3))).unwrap();
    let store_path = dir.join("cancelled.gpkg");
    let watch = std::sync::Arc::new(ImportWatch::default());
    let mut opts = options(std::slice::from_ref(&src), &store_path, Ellipsoid::MOON, "lola", LevelChoice::Level(3));
    opts.watch = Some(watch.clone());
    // Cancel from another thread once 40 tiles (one committed batch and more) are done.
    let watcher = {
        let watch = watch.clone();
        std::thread::spawn(move || {
            let mut seen = Vec::new();
            loop {
                let p = watch.progress();
                if p.done >= 40 {
                    watch.cancel();
                    return (seen, p);
                }
                seen.push(p);
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        })
    };
    let err = import(&opts).unwrap_err();
    let (_, at_cancel) = watcher.join().unwrap();
    assert!(err.to_string().contains("cancelled"), "{err}");
    assert_eq!(at_cancel.phase, "level 3");
    assert!(at_cancel.total > 40 && at_cancel.done <= at_cancel.total, "{at_cancel:?}");
    let store = Store::open_read_only(&store_path).unwrap();
    assert!(store.dataset("lola").unwrap().unwrap().completed.is_none(), "a cancelled import is incomplete");
    assert!(!store.finished_quads("lola", 3).unwrap().is_empty(), "the committed batch stays");
    drop(store);
    opts.watch = None;
    let resumed = import(&opts).unwrap();
    assert!(resumed.levels.iter().any(|&(_, _, earlier)| earlier > 0), "{:?}", resumed.levels);
    let (a, b) = (Store::open_read_only(&reference).unwrap(), Store::open_read_only(&store_path).unwrap());
    for level in 0..=3 {
        let quads = a.data_quads("lola", level).unwrap();
        assert_eq!(quads, b.data_quads("lola", level).unwrap(), "level {level}");
        for q in quads {
            assert_eq!(a.read_grid("lola", q).unwrap(), b.read_grid("lola", q).unwrap(), "{q}");
        }
    }
}

/// `store info`, `store sample` and `store export` as a user runs them; the export is checked
/// by GDAL against the store.
#[test]
fn store_info_sample_and_export_from_the_command_line() {
    let dir = common::scratch("store/cli");
    let store_path = dir.join("erzurum.gpkg");
    let s = store_path.to_str().unwrap();
    let out = terrafuse(
        &[
            "import",
            data("earth_srtm3_demcompare_N39E040.tif").to_str().unwrap(),
            "--store",
            s,
            "--body",
            "wgs84",
            "--name",
            "erzurum",
            "--quiet",
        ],
        "",
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(summary.contains("finest level 9") && summary.contains("level  0"), "{summary}");
    let info = String::from_utf8_lossy(&terrafuse(&["store", "info", s], "").stdout).into_owned();
    for needle in [
        "body: wgs84",
        "dataset erzurum: complete",
        "WGS 84, EPSG:4326",
        "Int16",
        "pixel-is-area",
        "nodata -32768",
        "extent lon 40.00000 … 40.83333",
        "unspecified",
    ] {
        assert!(info.contains(needle), "missing '{needle}' in\n{info}");
    }
    let out = terrafuse(&["store", "sample", s], "39.5 40.5\n39.5 40.5\n10 10\nnonsense\n");
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    assert_eq!(lines[0], lines[1]);
    let h: f64 = lines[0].parse().unwrap();
    assert!((1_111.0..3_270.0).contains(&h));
    assert_eq!(lines[2], "nan");
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("nonsense"));
    // The coarse level exists and gives a nearby height.
    let coarse: f64 =
        String::from_utf8_lossy(&terrafuse(&["store", "sample", s, "--level", "6"], "39.5 40.5\n").stdout)
            .trim()
            .parse()
            .unwrap();
    assert!((coarse - h).abs() < 300.0);

    let tif = dir.join("utm.tif");
    let out = terrafuse(
        &[
            "store",
            "export",
            s,
            tif.to_str().unwrap(),
            "--crs",
            "EPSG:32637",
            "--bounds",
            "600000,4350000,640000,4390000",
            "--resolution",
            "200",
        ],
        "",
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let info = run_tool("gdalinfo", &[tif.to_str().unwrap()], "");
    assert!(
        info.contains("Size is 200, 200")
            && info.contains("UTM zone 37N")
            && info.contains("TERRAFUSE_DATASET=erzurum"),
        "{info}"
    );
    let mut reader = GridReader::new(Store::open_read_only(&store_path).unwrap(), "erzurum").unwrap();
    let level: u8 = info.lines().find_map(|l| l.trim().strip_prefix("TERRAFUSE_LEVEL=")).unwrap().parse().unwrap();
    for (x, y) in [(600_100.0, 4_389_900.0), (620_100.0, 4_369_900.0), (639_900.0, 4_350_100.0)] {
        let v: f64 = run_tool(
            "gdallocationinfo",
            &["-valonly", "-geoloc", tif.to_str().unwrap(), &x.to_string(), &y.to_string()],
            "",
        )
        .trim()
        .parse()
        .unwrap();
        let ll = run_tool("cs2cs", &["-f", "%.10f", "EPSG:32637", "EPSG:4326"], &format!("{x} {y}\n"));
        let p: Vec<f64> = ll.split_whitespace().take(2).map(|t| t.parse().unwrap()).collect();
        // Pixel centres: the probes sit 100 m (half a pixel) from the corner, on centres.
        let h = reader.height_at(p[0].to_radians(), p[1].to_radians(), level).unwrap();
        assert!((v - h).abs() < 0.05, "export {v} vs store {h} at {x},{y}");
    }
    let bad = terrafuse(
        &[
            "store",
            "export",
            s,
            dir.join("x.tif").to_str().unwrap(),
            "--crs",
            "EPSG:999999",
            "--bounds",
            "0,0,1,1",
            "--resolution",
            "1",
        ],
        "",
    );
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("EPSG:999999"));
}

/// The lattice of source positions (the import's default) against the exact chain at random
/// points of every quad, on every sample DEM at its import level and coarser: within twice the
/// tolerance its own check enforces at the cell centres; and the whole import within float
/// rounding of the exact one.
#[test]
fn lattice_positions_stay_within_their_bound_and_imports_match_the_exact_transform() {
    use rand::{Rng, SeedableRng};
    use terrafuse::ecm::CubeProjection;
    use terrafuse::store::lattice::{
        LatticeStats, PixelLattice, QuadPositions, SPACINGS, TOLERANCE_PX, Transform, exact_positions,
    };
    use terrafuse::store::source::{SourceInfo, SourceReader};
    let cases = [
        ("earth_srtm3_demcompare_N39E040.tif", Ellipsoid::WGS84, [9u8, 11]),
        ("earth_jacksboro_srtm3_epsg4326.tif", Ellipsoid::WGS84, [8, 10]),
        ("earth_topobathy_merc2min_epsg3857.tif", Ellipsoid::WGS84, [5, 7]),
        ("moon_lola_north_stere_1600m.tif", Ellipsoid::MOON, [3, 5]),
        ("moon_lola_ldem_4ppd_global.tif", Ellipsoid::MOON, [2, 4]),
        ("earth_srtm3_blurred_shifted_N39E040.tif", Ellipsoid::WGS84, [9, 10]),
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let mut table = String::new();
    for (file, body, levels) in cases {
        let info = SourceInfo::open(&data(file), &body).unwrap();
        let reader = SourceReader::new(&info, &body).unwrap();
        for level in levels {
            let [w, s, e, n] = info.bounds_deg;
            let mut quads = std::collections::BTreeSet::new();
            for a in 0..=40 {
                for b in 0..=40 {
                    let (lat, lon) = (s + (n - s) * f64::from(a) / 40.0, w + (e - w) * f64::from(b) / 40.0);
                    let p = CubeProjection::Qsc.face_point_from_geodetic(&body, lat.to_radians(), lon.to_radians());
                    quads.insert(QuadId::containing(p, level).unwrap());
                }
            }
            let stats = LatticeStats::default();
            let mut worst = 0.0f64;
            for &q in &quads {
                let span = [0.0, 256.0];
                let Some(l) = PixelLattice::build(&reader, &body, q, span, span, &SPACINGS, &stats) else { continue };
                let (us, vs): (Vec<f64>, Vec<f64>) =
                    (0..200).map(|_| (rng.random_range(0.0..=256.0), rng.random_range(0.0..=256.0))).unzip();
                let (xs, ys) = exact_positions(&reader, &body, q, &us, &vs);
                for k in 0..us.len() {
                    let (x, y) = l.at(us[k], vs[k]);
                    worst = worst.max((x - xs[k]).abs()).max((y - ys[k]).abs());
                }
            }
            // Quads whose whole lattice misses the bound, split into blocks and cells: every point
            // that a block's or cell's lattice covers is within the same bound.
            let split_stats = LatticeStats::default();
            let (mut split_worst, mut covered, mut exact_points) = (0.0f64, 0usize, 0usize);
            for &q in &quads {
                let span = [0.0, 256.0];
                let p = QuadPositions::build(&reader, &body, q, span, span, &split_stats);
                if !matches!(p, QuadPositions::Blocks { .. }) {
                    continue;
                }
                let (us, vs): (Vec<f64>, Vec<f64>) =
                    (0..400).map(|_| (rng.random_range(0.0..=256.0), rng.random_range(0.0..=256.0))).unzip();
                let (xs, ys) = exact_positions(&reader, &body, q, &us, &vs);
                for k in 0..us.len() {
                    match p.block(us[k], vs[k]) {
                        Some(l) => {
                            let (x, y) = l.at(us[k], vs[k]);
                            split_worst = split_worst.max((x - xs[k]).abs()).max((y - ys[k]).abs());
                            covered += 1;
                        }
                        None => exact_points += 1,
                    }
                }
            }
            let split = split_stats.summary();
            if split.split > 0 {
                table += &format!(
                    "{file} level {level}: {} quads split, {} cells of 16² exact; random points: {covered} on a \
                     lattice (largest error {split_worst:.1e} px), {exact_points} exact\n",
                    split.split, split.exact_cells
                );
            }
            assert!(split_worst <= 2.0 * TOLERANCE_PX, "{file} level {level}: {split_worst:e} px in a split quad");
            let sum = stats.summary();
            let ([l16, l8, l4], exact, centre) =
                (sum.by_spacing, quads.len() as u64 - sum.by_spacing.iter().sum::<u64>(), sum.max_error_px);
            table += &format!(
                "{file} level {level}: {} quads: {l16}/{l8}/{l4} on 16/8/4-sample lattices, {exact} exact; \
                 largest error at cell centres {centre:.1e} px, at 200 random points per quad {worst:.1e} px\n",
                quads.len()
            );
            assert!(worst <= 2.0 * TOLERANCE_PX, "{file} level {level}: {worst:e} px at a random point");
        }
    }
    // High-level imports are interpolated, not computed exactly; the pole's quads are split.
    assert!(table.contains("earth_srtm3_demcompare_N39E040.tif level 11") && !table.contains(" 0/0/0 on"), "{table}");
    assert!(table.contains("moon_lola_north_stere_1600m.tif level 5: ") && table.contains("quads split"), "{table}");
    println!("{table}");

    // A whole import both ways: the same samples to float rounding.
    let dir = common::scratch("store/lattice");
    let src = data("earth_srtm3_demcompare_N39E040.tif");
    let mut stores = Vec::new();
    for transform in [Transform::Lattice, Transform::Exact] {
        let path = dir.join(format!("{}.gpkg", transform.name()));
        let mut o = options(std::slice::from_ref(&src), &path, Ellipsoid::WGS84, "d", LevelChoice::Level(10));
        o.transform = transform;
        o.finest_only = true;
        import(&o).unwrap();
        stores.push(Store::open_read_only(&path).unwrap());
    }
    // A complete dataset made on one path is complete for the other (the same samples to float
    // rounding): stores made before the lattice are not refused.
    let old = dir.join("old.gpkg");
    let mut o = options(std::slice::from_ref(&src), &old, Ellipsoid::WGS84, "d", LevelChoice::Level(7));
    o.transform = Transform::Exact;
    import(&o).unwrap();
    o.transform = Transform::Lattice;
    assert!(import(&o).unwrap().already_complete, "a store made exactly is found complete");
    let (mean, max, n, one) = terrafuse::cli::store_difference(&stores[0], &stores[1], "d", 10).unwrap();
    println!(
        "lattice vs exact, SRTM level 10: {n} samples, mean {mean:.1e} m, max {max:.1e} m, {one} with data in one only"
    );
    assert!(n > 1_000_000 && one == 0, "{n} samples, {one} differ in data");
    assert!(mean < 1e-6 && max < 1e-3, "mean {mean:e} m, max {max:e} m");
}

/// The pyramid's average of a quad reads its region by runs of samples per child grid; the same
/// region read sample by sample (`GridReader::sample`, what `fill_area_mean_region` describes)
/// gives the same grid bit for bit, on a small area and across every face edge of the Moon.
#[test]
fn the_pyramids_average_reads_the_same_region_as_sample_by_sample() {
    use terrafuse::ecm::area_mean::{AREA_MEAN_SPAN, area_mean, fill_area_mean_region};
    use terrafuse::store::resample::average_quad;
    let dir = common::scratch("store/average");
    let cases = [
        ("earth_srtm3_demcompare_N39E040.tif", Ellipsoid::WGS84, 9u8),
        ("moon_lola_ldem_4ppd_global.tif", Ellipsoid::MOON, 2),
    ];
    for (file, body, level) in cases {
        let path = dir.join(format!("{level}.gpkg"));
        import(&options(&[data(file)], &path, body, "d", LevelChoice::Level(level))).unwrap();
        let mut reader = GridReader::new(Store::open_read_only(&path).unwrap(), "d").unwrap();
        let quads: Vec<QuadId> = reader.store().data_quads("d", level - 1).unwrap().into_iter().collect();
        assert!(!quads.is_empty());
        for q in quads {
            let mut region = vec![f32::NAN; AREA_MEAN_SPAN * AREA_MEAN_SPAN];
            fill_area_mean_region(q, &mut region, &mut |f, l, i, j| reader.sample(f, l, i, j).unwrap());
            let reference = area_mean(q, &region);
            let fast = average_quad(&mut reader, q).unwrap().expect("a quad with data");
            let same = reference.iter().zip(&fast.values).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{file}: quad {q:?} differs from the sample-by-sample average");
        }
    }
}
