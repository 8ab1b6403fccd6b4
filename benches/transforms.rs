//! Forward and inverse QSC and geodetic ↔ ECEF: Terrafuse against the same transform through
//! GDAL/PROJ (`CoordTransform`), on the same seeded points, in one run. After the timings the
//! bench prints how far the two disagree and how far GDAL/PROJ is from Terrafuse near the face
//! centres (where PROJ's acos form loses digits; the 60-digit reference test
//! `tests/references.rs` shows Terrafuse is within 1e-15 of the exact value there).
//!
//! Run: `cargo bench --bench transforms`. See benches/README.md.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use terrafuse::ecm::{CubeProjection, Face, FacePoint};
use terrafuse::geodesy::{self, Ellipsoid, Geodetic};

const N: usize = 10_000;

/// Points on the front face (|lon| < 40°, |lat| < 30°) so that PROJ's single-face projection
/// and ours agree on the face; degrees.
fn front_face_points() -> Vec<(f64, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    (0..N).map(|_| (rng.random_range(-30.0..30.0), rng.random_range(-40.0..40.0))).collect()
}

fn srs(proj: &str) -> SpatialRef {
    let mut srs = SpatialRef::from_proj4(proj).expect("PROJ string");
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    srs
}

fn transform(from: &str, to: &str) -> CoordTransform {
    CoordTransform::new(&srs(from), &srs(to)).expect("transform")
}

const LONLAT: &str = "+proj=longlat +ellps=WGS84 +no_defs";
const QSC_FRONT: &str = "+proj=qsc +lat_0=0 +lon_0=0 +ellps=WGS84 +no_defs";
const GEOCENT: &str = "+proj=geocent +ellps=WGS84 +units=m +no_defs";

/// Times GDAL/PROJ on the same points: copies the input arrays (as a caller of the in-place
/// `transform_coords` must) and transforms them.
fn bench_gdal(
    group: &mut criterion::BenchmarkGroup<criterion::measurement::WallTime>,
    transform: &CoordTransform,
    x: &[f64],
    y: &[f64],
    z: &[f64],
) {
    group.bench_function(BenchmarkId::new("gdal_proj", N), |b| {
        b.iter(|| {
            let (mut x, mut y, mut z) = (x.to_vec(), y.to_vec(), z.to_vec());
            transform.transform_coords(&mut x, &mut y, &mut z).expect("transform");
            black_box(x[0] + y[0] + z[0])
        })
    });
}

fn bench(c: &mut Criterion) {
    let e = Ellipsoid::WGS84;
    let zeros = vec![0.0; N];
    let points = front_face_points();
    let lons: Vec<f64> = points.iter().map(|p| p.1).collect();
    let lats: Vec<f64> = points.iter().map(|p| p.0).collect();

    let mut group = c.benchmark_group("qsc_forward");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function(BenchmarkId::new("terrafuse", N), |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for (lat, lon) in &points {
                let p = CubeProjection::Qsc.face_point_from_geodetic(&e, lat.to_radians(), lon.to_radians());
                sum += p.x + p.y;
            }
            black_box(sum)
        })
    });
    let forward = transform(LONLAT, QSC_FRONT);
    bench_gdal(&mut group, &forward, &lons, &lats, &zeros);
    group.finish();

    let face_points: Vec<FacePoint> = points
        .iter()
        .map(|(lat, lon)| CubeProjection::Qsc.face_point_from_geodetic(&e, lat.to_radians(), lon.to_radians()))
        .collect();
    let xs: Vec<f64> = face_points.iter().map(|p| p.x * e.a_m()).collect();
    let ys: Vec<f64> = face_points.iter().map(|p| p.y * e.a_m()).collect();
    let mut group = c.benchmark_group("qsc_inverse");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function(BenchmarkId::new("terrafuse", N), |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for p in &face_points {
                let (lat, lon) = CubeProjection::Qsc.geodetic_from_face_point(&e, *p).expect("on face");
                sum += lat.to_degrees() + lon.to_degrees();
            }
            black_box(sum)
        })
    });
    let inverse = transform(QSC_FRONT, LONLAT);
    bench_gdal(&mut group, &inverse, &xs, &ys, &zeros);
    group.finish();

    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let geodetic: Vec<Geodetic> = (0..N)
        .map(|_| {
            Geodetic::from_degrees(
                rng.random_range(-90.0..=90.0),
                rng.random_range(-180.0..180.0),
                rng.random_range(-12_000.0..1e7),
            )
        })
        .collect();
    let heights: Vec<f64> = geodetic.iter().map(|g| g.height_m).collect();
    let glons: Vec<f64> = geodetic.iter().map(|g| g.lon_rad.to_degrees()).collect();
    let glats: Vec<f64> = geodetic.iter().map(|g| g.lat_rad.to_degrees()).collect();
    let mut group = c.benchmark_group("geodetic_to_ecef");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function(BenchmarkId::new("terrafuse", N), |b| {
        b.iter(|| {
            let mut sum = DVec3::ZERO;
            for g in &geodetic {
                sum += geodesy::ecef_from_geodetic(&e, *g);
            }
            black_box(sum)
        })
    });
    let to_ecef = transform(LONLAT, GEOCENT);
    bench_gdal(&mut group, &to_ecef, &glons, &glats, &heights);
    group.finish();

    let ecef: Vec<DVec3> = geodetic.iter().map(|g| geodesy::ecef_from_geodetic(&e, *g)).collect();
    let (ex, ey, ez): (Vec<f64>, Vec<f64>, Vec<f64>) =
        (ecef.iter().map(|p| p.x).collect(), ecef.iter().map(|p| p.y).collect(), ecef.iter().map(|p| p.z).collect());
    let mut group = c.benchmark_group("ecef_to_geodetic");
    group.throughput(Throughput::Elements(N as u64));
    group.bench_function(BenchmarkId::new("terrafuse", N), |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for p in &ecef {
                let g = geodesy::geodetic_from_ecef(&e, *p);
                sum += g.lat_rad + g.height_m;
            }
            black_box(sum)
        })
    });
    let from_ecef = transform(GEOCENT, LONLAT);
    bench_gdal(&mut group, &from_ecef, &ex, &ey, &ez);
    group.finish();

    accuracy_report(&forward, &from_ecef, &ecef);
}

/// Differences between Terrafuse and GDAL/PROJ on the benchmark points and near face centres.
fn accuracy_report(forward: &CoordTransform, from_ecef: &CoordTransform, ecef: &[DVec3]) {
    let e = Ellipsoid::WGS84;
    let mut worst_m: f64 = 0.0;
    let mut worst_centre_m: f64 = 0.0;
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for zone in [false, true] {
        let points: Vec<(f64, f64)> = (0..N)
            .map(|_| {
                if zone {
                    // Within 1e-6 degrees of the front face centre.
                    (rng.random_range(-1e-6..1e-6), rng.random_range(-1e-6..1e-6))
                } else {
                    (rng.random_range(-30.0..30.0), rng.random_range(-40.0..40.0))
                }
            })
            .collect();
        let (mut x, mut y, mut z): (Vec<f64>, Vec<f64>, Vec<f64>) =
            (points.iter().map(|p| p.1).collect(), points.iter().map(|p| p.0).collect(), vec![0.0; N]);
        forward.transform_coords(&mut x, &mut y, &mut z).expect("transform");
        for (i, (lat, lon)) in points.iter().enumerate() {
            let p = CubeProjection::Qsc.face_point_from_geodetic(&e, lat.to_radians(), lon.to_radians());
            assert_eq!(p.face, Face::Front);
            let d = (p.x * e.a_m() - x[i]).abs().max((p.y * e.a_m() - y[i]).abs());
            if zone {
                worst_centre_m = worst_centre_m.max(d);
            } else {
                worst_m = worst_m.max(d);
            }
        }
    }
    let (mut x, mut y, mut z): (Vec<f64>, Vec<f64>, Vec<f64>) =
        (ecef.iter().map(|p| p.x).collect(), ecef.iter().map(|p| p.y).collect(), ecef.iter().map(|p| p.z).collect());
    from_ecef.transform_coords(&mut x, &mut y, &mut z).expect("transform");
    let mut worst_h: f64 = 0.0;
    for (i, p) in ecef.iter().enumerate() {
        let ours = geodesy::geodetic_from_ecef(&e, *p);
        let dlat_m = ((ours.lat_rad.to_degrees() - y[i]).to_radians() * e.a_m()).abs();
        worst_h = worst_h.max((ours.height_m - z[i]).abs()).max(dlat_m);
    }
    eprintln!(
        "accuracy: QSC forward, Terrafuse vs GDAL/PROJ: max {worst_m:.2e} m away from the face centre, {worst_centre_m:.2e} m within 1e-6° of it (PROJ's acos); ECEF→geodetic: max {worst_h:.2e} m"
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
