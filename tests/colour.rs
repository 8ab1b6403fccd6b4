//! Colour ramps against gdaldem color-relief (an independent implementation of the same file
//! format), pixel for pixel on a real DEM.

mod common;

use common::{repo_path, run_tool};
use terrafuse::colour::Ramp;

#[test]
fn gdaldem_colour_files_colour_like_gdaldem() {
    let dir = common::out_path("colour");
    std::fs::create_dir_all(&dir).unwrap();
    let colours = dir.join("relief.txt");
    std::fs::write(
        &colours,
        "# a hypsometric ramp\n1100 0 0 255\n1800,0,255,0\n2500:255:255:0\n3300 255 255 255 200\nnv 0 0 0 0\n",
    )
    .unwrap();
    let dem = repo_path("projects/data/earth_srtm3_demcompare_N39E040.tif");
    let out = dir.join("relief.tif");
    run_tool(
        "gdaldem",
        &["color-relief", dem.to_str().unwrap(), colours.to_str().unwrap(), out.to_str().unwrap(), "-alpha", "-q"],
        "",
    );
    let ramp = Ramp::from_file(&colours, (0.0, 1.0), [9, 9, 9, 9]).unwrap();
    let heights = gdal::Dataset::open(&dem).unwrap().rasterband(1).unwrap().read_band_as::<f64>().unwrap();
    let coloured = gdal::Dataset::open(&out).unwrap();
    let bands: Vec<Vec<u8>> =
        (1..=4).map(|b| coloured.rasterband(b).unwrap().read_band_as::<u8>().unwrap().data().to_vec()).collect();
    let (mut worst, mut n) = (0f64, 0usize);
    for (k, &h) in heights.data().iter().enumerate() {
        let expected = ramp.colour_at(h);
        for c in 0..4 {
            let d = (f64::from(bands[c][k]) - expected[c]).abs();
            worst = worst.max(d);
            // gdaldem rounds to bytes; we keep the exact value.
            assert!(
                d <= 1.0,
                "height {h}: gdaldem {:?} vs {expected:?}",
                bands.iter().map(|b| b[k]).collect::<Vec<_>>()
            );
        }
        n += 1;
    }
    assert_eq!(n, 1_000_000);
    eprintln!("{n} pixels within {worst:.3} of gdaldem color-relief");
}
