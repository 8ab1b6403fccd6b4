use super::grid::Grid;
use super::params::{Border, EARTH_G, Params};
use super::sim::Run;

fn params() -> Params {
    Params::unscaled("rain", EARTH_G).unwrap()
}

/// A deterministic rough terrain: waves and a PCG jitter, metres.
fn rough(width: usize, height: usize, amplitude_m: f64) -> Vec<f64> {
    let mut state = 7u32;
    (0..width * height)
        .map(|i| {
            state = crate::maths::pcg(state);
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            amplitude_m * ((x / 5.0).sin() + (y / 7.0).cos()) + f64::from(state % 1000) / 1000.0
        })
        .collect()
}

fn check_state(run: &Run) {
    for i in 0..run.grid.len() {
        assert!(run.state.water[i] >= 0, "negative water at {i}");
        assert!(run.state.sediment[i] >= 0, "negative sediment at {i}");
        assert!(run.state.speed_m_s[i].is_finite(), "speed at {i}");
        assert!(run.state.flux_m3_s[i].iter().all(|f| f.is_finite() && *f >= 0.0), "flux at {i}");
        if !run.grid.base_m[i].is_nan() {
            assert!(run.height_m(i).is_finite(), "height at {i}");
        }
    }
}

#[test]
fn water_and_soil_are_conserved_exactly_over_100_000_steps_under_stress() {
    // A 12 × 12 grid of 30 m cells with 1000 m cliffs between neighbouring columns, a no-data
    // hole (a sink), a downpour (a hundred times the preset's) and no evaporation, open borders:
    // after 10⁵ steps no NaN, no infinity, no negative water or sediment, and the budgets explain
    // every unit of water and soil.
    let (w, h) = (12, 12);
    let mut base = rough(w, h, 20.0);
    for (i, b) in base.iter_mut().enumerate() {
        if (i % w) % 3 == 0 {
            *b += 1000.0;
        }
    }
    base[5 * w + 7] = f64::NAN;
    let grid = Grid::flat_patch(w, h, 30.0, base);
    let p = Params { rain_m_s: 1e-2, evaporation_per_s: 0.0, border: Border::Open, ..params() };
    let mut run = Run::new(grid, p).unwrap();
    let mut smallest_dt = f64::INFINITY;
    for step in 0..100_000 {
        let r = run.step();
        smallest_dt = smallest_dt.min(r.dt_s);
        assert!(r.dt_s > 0.0 && r.dt_s <= run.params.dt_s && r.dt_s <= r.cfl_bound_s, "step {step}: {r:?}");
        if step % 10_000 == 0 {
            check_state(&run);
            assert_eq!(run.unexplained(), (0, 0), "step {step}");
        }
    }
    check_state(&run);
    assert_eq!(run.unexplained(), (0, 0));
    let b = run.budget;
    assert!(b.rain_in > 0 && b.water_out > 0, "{b:?}");
    assert!(b.soil_out > 0, "the downpour carried soil out: {b:?}");
    assert!(smallest_dt < run.params.dt_s, "the CFL bound was reached");
}

#[test]
fn a_closed_basin_keeps_every_unit_and_perfectly_flat_ground_does_not_move() {
    // Closed walls: nothing leaves; the water held is the rain minus evaporation, exactly.
    let grid = Grid::flat_patch(16, 16, 10.0, rough(16, 16, 5.0));
    let mut run = Run::new(grid, Params { border: Border::Closed, ..params() }).unwrap();
    for _ in 0..2000 {
        run.step();
    }
    assert_eq!(run.budget.water_out, 0);
    assert_eq!(run.budget.soil_out, 0);
    assert_eq!(run.unexplained(), (0, 0));
    let (water, soil) = run.totals();
    assert_eq!(water, run.budget.rain_in - run.budget.evaporated);
    assert_eq!(soil, 0);
    // Flat ground under even rain, closed: water rises evenly (the rain dither's units, 10 µm
    // each, make ripples of a few tenths of a millimetre on 14 mm of water), nothing erodes
    // (sin α = 0 gives the minimum slope's capacity, and the ripples no speed above the dry
    // limit).
    let flat = Grid::flat_patch(8, 8, 10.0, vec![100.0; 64]);
    let mut run = Run::new(flat, Params { border: Border::Closed, ..params() }).unwrap();
    for _ in 0..500 {
        run.step();
    }
    assert!(run.state.soil.iter().all(|s| *s == 0), "flat ground moved");
    let (lo, hi) = (run.state.water.iter().min().unwrap(), run.state.water.iter().max().unwrap());
    assert!(*lo > 0 && hi - lo <= 50, "water level uneven: {lo} … {hi} units");
}

#[test]
fn the_same_run_gives_the_same_state_bit_for_bit_whatever_the_threads() {
    let grid = Grid::flat_patch(24, 20, 25.0, rough(24, 20, 40.0));
    let go = |threads: usize| {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
            let mut run = Run::new(grid.clone(), params()).unwrap();
            for _ in 0..300 {
                run.step();
            }
            run
        })
    };
    let (one, three) = (go(1), go(3));
    assert_eq!(one.state, three.state);
    assert_eq!(one.budget, three.budget);
    assert!(one.state.soil.iter().any(|s| *s != 0), "the run eroded");
}

/// The four-fold anisotropy of the erosion on a cone under rain (41 × 41 cells of 20 m, 300 m
/// high): over rings of radius 6 to 16 cells, |Δh| at 64 angles each; the amplitude of its
/// cos 4θ component relative to its mean (0: the same in every direction; grid-aligned channels
/// make it large).
fn cone_anisotropy(diagonal_weight: f64) -> f64 {
    let n = 41usize;
    let base: Vec<f64> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64 - 20.0, (i / n) as f64 - 20.0);
            300.0 - 15.0 * (x * x + y * y).sqrt()
        })
        .collect();
    let mut grid = Grid::flat_patch(n, n, 20.0, base);
    for w in &mut grid.pipe_weight[4..] {
        *w = diagonal_weight;
    }
    let mut run = Run::new(grid, Params { border: Border::Open, ..params() }).unwrap();
    for _ in 0..3000 {
        run.step();
    }
    let delta = run.delta_m();
    let at = |x: f64, y: f64| {
        let (fx, fy) = (x + 20.0, y + 20.0);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let v = |x: usize, y: usize| delta[y * n + x].abs();
        (v(x0, y0) * (1.0 - tx) + v(x0 + 1, y0) * tx) * (1.0 - ty)
            + (v(x0, y0 + 1) * (1.0 - tx) + v(x0 + 1, y0 + 1) * tx) * ty
    };
    let (mut sum, mut re, mut im) = (0.0, 0.0, 0.0);
    for r in 6..=16 {
        for k in 0..64 {
            let theta = std::f64::consts::TAU * f64::from(k) / 64.0;
            let v = at(f64::from(r) * theta.cos(), f64::from(r) * theta.sin());
            sum += v;
            re += v * (4.0 * theta).cos();
            im += v * (4.0 * theta).sin();
        }
    }
    assert!(sum > 0.0, "the cone eroded");
    2.0 * (re * re + im * im).sqrt() / sum
}

#[test]
fn channels_on_a_cone_follow_the_slope_not_the_grid() {
    // Eight pipes: the erosion around a radially symmetric cone varies little with the direction
    // (its four-fold component is small: measured 0.067 of the mean); four pipes (the diagonals'
    // weight 0) make it follow the grid: twice as large (0.130).
    let (eight, four) = (cone_anisotropy(super::grid::PIPE_WEIGHT[4]), cone_anisotropy(0.0));
    assert!(eight < 0.1 && eight * 1.6 < four, "four-fold anisotropy: eight pipes {eight:.3}, four {four:.3}");
}

#[test]
fn parameters_out_of_range_name_the_field() {
    let bad = Params { talus_deg: 95.0, ..params() };
    let e = Run::new(Grid::flat_patch(2, 2, 1.0, vec![0.0; 4]), bad).unwrap_err();
    assert_eq!(e.to_string(), "talus_deg: 95 is outside [0, 89] degrees");
    assert!(Params { rain_m_s: f64::NAN, ..params() }.check().is_err());
    for name in Params::PRESETS {
        Params::preset(name, EARTH_G).unwrap().check().unwrap();
    }
}

#[test]
fn a_region_across_a_face_edge_is_one_grid_and_erodes_without_a_seam() {
    // A region of 3 × 3 level-9 quads on the Moon centred on the front face's last column, so
    // that its east third lies on the right face; a cone centred on the face edge's sample row
    // (at 45°E) under rain. The grid is contiguous across the edge (lengths within 1 % of their
    // neighbours'), and the erosion is mirror-symmetric about the edge as the geometry is: the
    // largest difference of Δ at k samples west of the edge and k east is no larger than the
    // same cone's about its centre in the middle of a face (the rounding dither is not mirror-
    // symmetric, so neither run is exactly: what the face edge must not add is a seam).
    use super::region::Region;
    use crate::ecm::{Face, QuadId};
    use crate::geodesy::Ellipsoid;
    let e = Ellipsoid::MOON;
    let level = 9u8;
    let n = 1u32 << level;
    // Returns (largest |Δ|, largest mirror difference) of the cone centred at column 48 of a
    // 97 × 64 region starting at `i0`, `j0` of `quad`'s face.
    let erode = |quad: QuadId, i0: i64, j0: i64, check_edge: bool| -> (f64, f64) {
        let region = Region { i0, j0, width: 97, height: 64, ..Region::around(quad, 1) };
        let c = region.cell(48, 32).unwrap();
        let centre = crate::ecm::points::sample_point(&e, c.quad, 257, c.i, c.j).0;
        let cone = |q: QuadId| -> Result<Vec<f32>, crate::errors::Failure> {
            Ok((0..257 * 257)
                .map(|k| {
                    let p = crate::ecm::points::sample_point(&e, q, 257, (k % 257) as u32, (k / 257) as u32).0;
                    (200.0 - 0.1 * (p - centre).length()).max(0.0) as f32
                })
                .collect())
        };
        let grid = region.grid(&e, &cone).unwrap();
        let w = grid.width;
        for y in 0..grid.height {
            for x in 1..w - 1 {
                let (a, b) = (grid.dx_m[y * w + x - 1], grid.dx_m[y * w + x]);
                assert!((a - b).abs() < 0.01 * a, "lengths jump at ({x}, {y}): {a} → {b}");
            }
        }
        if check_edge {
            // The edge is column 48; the right face's samples lie east of it.
            assert_eq!(region.cell(48, 0).unwrap().quad.face, Face::Front);
            assert_eq!(region.cell(49, 0).unwrap().quad.face, Face::Right);
        }
        let p = Params {
            gravity_m_s2: super::params::MOON_G,
            border: Border::Open,
            rain_m_s: 1e-3,
            capacity: 1.0,
            ..params()
        };
        let mut run = Run::new(grid, p).unwrap();
        for _ in 0..400 {
            run.step();
        }
        assert_eq!(run.unexplained(), (0, 0));
        let delta = run.delta_m();
        let largest = delta.iter().fold(0f64, |m, d| m.max(d.abs()));
        let mut worst = 0f64;
        for y in 0..run.grid.height {
            for k in 1..=40 {
                worst = worst.max((delta[y * w + 48 - k] - delta[y * w + 48 + k]).abs());
            }
        }
        (largest, worst)
    };
    let quad = QuadId::new(Face::Front, level, n - 1, n / 2).unwrap();
    let edge_i = i64::from(n) * 256;
    let (largest, worst) = erode(quad, edge_i - 48, i64::from(quad.y) * 256 + 96, true);
    let middle = QuadId::new(Face::Front, level, n / 2, n / 2).unwrap();
    let (largest_mid, worst_mid) = erode(middle, i64::from(n) * 128 - 48, i64::from(n) * 128 + 96, false);
    assert!(largest > 0.002 && largest_mid > 0.002, "the cones eroded: {largest} m, {largest_mid} m");
    assert!(
        worst <= 1.5 * worst_mid.max(0.01 * largest_mid),
        "asymmetry across the edge {worst:.3e} m of {largest:.3e} m; in the middle of a face {worst_mid:.3e} m of {largest_mid:.3e} m"
    );
}

#[test]
fn masks_localise_rain_and_erosion_and_masked_out_cells_are_sinks() {
    // Rain only on the west half; a masked-out column (erosion mask 0) down the middle of the
    // east half: no rain falls east, the masked column holds nothing (what flows in leaves and
    // is counted), and the budgets still explain every unit.
    let (w, h) = (20, 12);
    let mut grid = Grid::flat_patch(w, h, 10.0, rough(w, h, 10.0));
    grid.rain_mask = Some((0..w * h).map(|i| if i % w < w / 2 { 1.0 } else { 0.0 }).collect());
    grid.erosion_mask = Some((0..w * h).map(|i| if i % w == 15 { 0.0 } else { 1.0 }).collect());
    let mut run = Run::new(grid, Params { border: Border::Closed, evaporation_per_s: 0.0, ..params() }).unwrap();
    let mut rained_east = 0;
    for _ in 0..3000 {
        let rain_before = run.budget.rain_in;
        run.step();
        // Rain added this step: only where the mask has it (checked through the budget: the
        // step's rain is at most what the west half can receive).
        let step_rain = run.budget.rain_in - rain_before;
        let per_cell = ((run.params.rain_m_s * run.params.dt_s * 100.0 / run.unit_m3()).floor()) as i64;
        if step_rain > per_cell * (w / 2 * h) as i64 {
            rained_east += 1;
        }
    }
    assert_eq!(rained_east, 0, "rain fell outside its mask");
    for y in 0..h {
        assert_eq!(run.state.water[y * w + 15], 0, "the sink column holds water");
        assert_eq!(run.state.soil[y * w + 15], 0, "the sink column changed");
    }
    assert!(run.budget.water_out > 0, "water flowed into the sink column: {:?}", run.budget);
    assert_eq!(run.unexplained(), (0, 0));
}

#[test]
fn regions_on_the_moon_and_the_earth_from_level_8_to_22_stay_finite_and_balanced() {
    // A 16 × 16 region at levels 8, 14 and 22 on both bodies (cells from ≈ 660 m down to ≈ 1 cm),
    // over hills of 5 % of the cell size, under the rain preset with ten times its rain: 2000
    // steps each, no NaN or infinity, no negative water, budgets exact, the CFL bound followed.
    use super::region::Region;
    use crate::ecm::{Face, QuadId};
    use crate::geodesy::Ellipsoid;
    for (e, g) in [(Ellipsoid::MOON, super::params::MOON_G), (Ellipsoid::WGS84, EARTH_G)] {
        for level in [8u8, 14, 22] {
            let n = 1u32 << level;
            let quad = QuadId::new(Face::Top, level, n / 3, n / 5).unwrap();
            let region = Region { width: 16, height: 16, ..Region::around(quad, 0) };
            let spacing = crate::ecm::grid::spacing_m(&e, level);
            let hills = |q: QuadId| -> Result<Vec<f32>, crate::errors::Failure> {
                Ok((0..257 * 257)
                    .map(|k| {
                        let p = crate::ecm::points::sample_point(&e, q, 257, (k % 257) as u32, (k / 257) as u32).0;
                        (0.05 * spacing * 16.0 * ((p.x / (4.0 * spacing)).sin() + (p.y / (5.0 * spacing)).cos())) as f32
                    })
                    .collect())
            };
            let grid = region.grid(&e, &hills).unwrap();
            let p = Params { gravity_m_s2: g, rain_m_s: 1e-3, ..params() };
            let mut run = Run::new(grid, p).unwrap();
            for _ in 0..2000 {
                let r = run.step();
                assert!(r.dt_s <= r.cfl_bound_s && r.dt_s > 0.0, "{level}: {r:?}");
            }
            check_state(&run);
            assert_eq!(run.unexplained(), (0, 0), "{} level {level}", e.name());
            assert!(run.budget.rain_in > 0, "{} level {level}: no rain", e.name());
        }
    }
}

#[test]
fn a_box_across_a_face_edge_becomes_one_region_whose_cells_fold_back_onto_the_box() {
    // A box on the equator across 45°E (the front and right faces' edge), level 8: the region is
    // in the index space of the face under its centre, runs past that face's edge, and every point of the box lies in a
    // cell of it; inverted boxes and boxes too large for a region are refused.
    use super::region::Region;
    use crate::ecm::{CubeProjection, Face, QuadId};
    use crate::geodesy::Ellipsoid;
    let e = Ellipsoid::WGS84;
    let b = |w, s, e, n| crate::geodesy::GeoBox::new(w, s, e, n).unwrap();
    let region = Region::from_box(&e, b(44.7, -0.2, 45.4, 0.2), 8).unwrap();
    // The box's centre (0°, 45.05°E) is on the right face: the region runs past its west edge.
    assert_eq!(region.face, Face::Right);
    assert_eq!((region.width % 256, region.height % 256), (0, 0));
    assert!(region.i0 < 0 && region.i0 + region.width as i64 > 0, "{region:?} does not cross the edge");
    let quads = region.quads();
    assert!(quads.iter().any(|q| q.face == Face::Right) && quads.iter().any(|q| q.face == Face::Front));
    for (lat, lon) in [(-0.19, 44.71), (0.19, 45.39), (0.0, 45.0), (-0.1, 45.3), (0.15, 44.9)] {
        let p = CubeProjection::Qsc.face_point_from_geodetic(&e, f64::to_radians(lat), f64::to_radians(lon));
        let q = QuadId::containing(p, 8).unwrap();
        assert!(quads.contains(&q), "({lat}, {lon}) in {q} is outside the region's quads");
    }
    assert!(crate::geodesy::GeoBox::new(44.7, 0.2, 45.4, -0.2).unwrap_err().to_string().contains("south < north"));
    assert!(Region::from_box(&e, b(0.0, 0.0, 10.0, 10.0), 10).unwrap_err().to_string().contains("at most 4096"));
    assert!(Region::from_box(&e, b(-170.0, -10.0, 170.0, 10.0), 2).unwrap_err().to_string().contains("opposite"));
    // A box across the antimeridian (west > east) is one region on the back face, 1° wide.
    let across = Region::from_box(&e, b(179.5, -0.2, -179.5, 0.2), 8).unwrap();
    assert_eq!(across.face, Face::Back);
    let quads = across.quads();
    for lon in [179.6, 180.0, -179.6] {
        let p = CubeProjection::Qsc.face_point_from_geodetic(&e, 0.0, f64::to_radians(lon));
        assert!(quads.contains(&QuadId::containing(p, 8).unwrap()), "{lon}°E is outside {across:?}");
    }
    // 1° is about 790 samples of 140 m, rounded out to whole quads of 256: 4 or 5 quads wide.
    assert!((768..=1280).contains(&across.width), "{across:?} is not the 1° asked for");
}
