//! The stream-power model against the steady-state law and against itself (budgets, Newton's
//! root, determinism, depressions).

use super::*;
use crate::erosion::grid::Grid;
use crate::maths::pcg;

/// A patch of `size`² cells of `cell_m` with a few metres of seeded roughness.
fn rough_patch(size: usize, cell_m: f64, seed: u32) -> Grid {
    let heights =
        (0..size * size).map(|i| f64::from(pcg(i as u32 ^ seed.wrapping_mul(0x9e37_79b9)) % 1000) * 1e-3).collect();
    Grid::flat_patch(size, size, cell_m, heights)
}

/// The least-squares line through (x, y): (slope, intercept).
fn fit(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    let (sx, sy) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) =
        points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + (x - mx) * (y - my), b + (x - mx) * (x - mx)));
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

#[test]
fn a_steady_state_follows_the_slope_area_law() {
    // Uniform uplift, n = 1, no diffusion: S = (U/K)·A^(−m) on every channel cell.
    steady_state_law(0.0, flow::Routing::D8);
}

#[test]
fn with_deposition_a_steady_state_steepens_by_one_plus_g() {
    // ξ-q at steady state: Qs = U·A, so rivers cut (1 + G)·U and S = (1 + G)·(U/K)·A^(−m) for
    // n = 1 (Yuan et al. 2019).
    steady_state_law(1.0, flow::Routing::D8);
}

#[test]
fn with_multiple_flow_directions_the_law_holds_on_their_area() {
    // Incision to the steepest neighbour with the area by MFD: the slope follows the law with
    // that area. (Slower to settle: 24 Myr here against 3 Myr by D8.)
    steady_state_law(0.0, flow::Routing::Mfd);
}

/// Runs a rough patch to steady state with deposition coefficient `g` and `routing`, and checks
/// the slope–area regression over its channel cells: concavity m within 0.02, steepness
/// (1 + G)·U/K within 5 %.
fn steady_state_law(g: f64, routing: flow::Routing) {
    let params = LandscapeParams {
        uplift_m_per_year: 1e-3,
        k: 1e-4,
        m: 0.45,
        n: 1.0,
        kd_m2_per_year: 0.0,
        deposition: g,
        routing,
        // Deposition slows the approach to steady state (9 Myr for G = 1), and so do multiple
        // flow directions (24 Myr).
        years: if routing == flow::Routing::Mfd { 2.4e7 } else { 3e6 * (1.0 + 2.0 * g) },
        dt_years: 2e4,
    };
    let mut run = Evolution::new(rough_patch(64, 100.0, 7), params.clone()).unwrap();
    run.run_to_end();
    let before = run.heights_m();
    run.params.years += params.dt_years;
    run.step();
    let change = run.heights_m().iter().zip(&before).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(change < 1e-3, "not at steady state: a cell moved {change} m in the last step");
    let flow = run.flow.as_ref().unwrap();
    let h = run.heights_m();
    let channel: Vec<(f64, f64)> = (0..h.len())
        .filter(|&i| flow.receiver[i] != i && flow.area_m2[i] >= 1e5)
        .map(|i| {
            let s = (h[i] - h[flow.receiver[i]]) / flow.distance_m[i];
            (flow.area_m2[i].ln(), s.ln())
        })
        .collect();
    assert!(channel.len() > 200, "{} channel cells", channel.len());
    let (slope, intercept) = fit(&channel);
    let concavity = -slope;
    let steepness = intercept.exp();
    let expected = (1.0 + g) * params.uplift_m_per_year / params.k;
    assert!((concavity - params.m).abs() < 0.02, "concavity {concavity}, expected {}", params.m);
    assert!((steepness / expected - 1.0).abs() < 0.05, "steepness {steepness}, expected {expected}");
}

#[test]
fn a_nonlinear_drop_solves_its_equation() {
    for (delta0, f, n) in [(10.0, 0.5, 2.0), (3.0, 4.0, 1.5), (100.0, 1e-3, 0.7), (1.0, 1e3, 3.0)] {
        let d = spl::drop_after(delta0, f, n);
        let residual = d - delta0 + f * f64::powf(d, n);
        assert!(d > 0.0 && d <= delta0, "{d}");
        assert!(residual.abs() < 1e-9 * delta0.max(1.0), "δ0 {delta0} F {f} n {n}: δ {d}, residual {residual}");
    }
    assert_eq!(spl::drop_after(6.0, 2.0, 1.0), 2.0);
}

#[test]
fn budgets_explain_every_unit_and_runs_repeat_bit_for_bit() {
    let params = LandscapeParams { years: 2e5, dt_years: 1e4, kd_m2_per_year: 0.5, ..LandscapeParams::default() };
    let mut a = Evolution::new(rough_patch(40, 50.0, 3), params.clone()).unwrap();
    a.run_to_end();
    assert_eq!(a.steps, 20);
    assert_eq!(a.unexplained(), 0);
    assert!(a.budget.uplifted > 0 && a.budget.eroded > 0, "{:?}", a.budget);
    let mut b = Evolution::new(rough_patch(40, 50.0, 3), params).unwrap();
    b.run_to_end();
    assert_eq!(a.change, b.change);
    assert_eq!(a.budget, b.budget);
}

#[test]
fn water_leaves_a_closed_depression_through_its_spill_point() {
    // A bowl in the middle of a plain that slopes to the west border: every cell drains to the
    // border, and the bowl's cells drain through its rim.
    let size = 21;
    let heights: Vec<f64> = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64, (i / size) as f64);
            let r = ((x - 10.0).powi(2) + (y - 10.0).powi(2)).sqrt();
            x + if r < 4.0 { -20.0 + r } else { 0.0 }
        })
        .collect();
    let grid = Grid::flat_patch(size, size, 10.0, heights.clone());
    let base = flow::base_level(&grid);
    let routing = flow::route(&grid, &heights, &base);
    for start in 0..grid.len() {
        let (mut i, mut hops) = (start, 0);
        while routing.receiver[i] != i {
            i = routing.receiver[i];
            hops += 1;
            assert!(hops <= grid.len(), "a cycle from cell {start}");
        }
        assert!(base[i], "cell {start} ends in {i}, not at base level");
    }
    let total: f64 = grid.area_m2.iter().sum();
    let at_base: f64 = (0..grid.len()).filter(|&i| base[i]).map(|i| routing.area_m2[i]).sum();
    assert!((at_base - total).abs() < 1e-6 * total, "{at_base} of {total} m² reach base level");
}

#[test]
fn bad_values_are_refused_by_name() {
    let ok = LandscapeParams::default();
    assert!(ok.check().is_ok());
    for (p, field) in [
        (LandscapeParams { years: -1.0, ..ok.clone() }, "years"),
        (LandscapeParams { m: 1.5, ..ok.clone() }, "m"),
        (LandscapeParams { m: 0.0, ..ok.clone() }, "m"),
        (LandscapeParams { dt_years: 3e6, ..ok.clone() }, "dt_years"),
        (LandscapeParams { k: f64::NAN, ..ok.clone() }, "k"),
        (LandscapeParams { deposition: -1.0, ..ok.clone() }, "deposition"),
    ] {
        assert_eq!(p.check().unwrap_err().field, field, "{p:?}");
    }
}

#[test]
fn cells_without_data_are_base_level_and_spread_nothing() {
    // A patch with a hole of no data: the run erodes around it, and every height stays a number.
    let mut grid = rough_patch(32, 100.0, 5);
    for (i, h) in grid.base_m.iter_mut().enumerate() {
        let (x, y) = (i % 32, i / 32);
        if (12..16).contains(&x) && (12..16).contains(&y) {
            *h = f64::NAN;
        }
    }
    let params = LandscapeParams { years: 1e5, dt_years: 1e4, ..LandscapeParams::default() };
    let mut run = Evolution::new(grid, params).unwrap();
    run.run_to_end();
    let heights = run.heights_m();
    let holes = heights.iter().filter(|h| h.is_nan()).count();
    assert_eq!(holes, 16, "only the hole has no data");
    assert!(run.budget.eroded > 0, "{:?}", run.budget);
    assert_eq!(run.unexplained(), 0);
}

#[test]
fn uplift_follows_a_mask_and_rivers_leaving_it_build_fans() {
    // A range rises on the western third of a plain (the brush's mask); with G = 1 its rivers
    // lay sediment on the plain below it, and without deposition nothing on the plain rises.
    let size = 60;
    let grid = || {
        let mut g = rough_patch(size, 200.0, 11);
        g.erosion_mask = Some((0..size * size).map(|i| if i % size < size / 3 { 1.0 } else { 0.0 }).collect());
        g
    };
    let run = |g: f64| {
        let params = LandscapeParams {
            uplift_m_per_year: 2e-3,
            kd_m2_per_year: 0.0,
            deposition: g,
            years: 1e6,
            dt_years: 2e4,
            ..LandscapeParams::default()
        };
        let mut run = Evolution::new(grid(), params).unwrap();
        run.run_to_end();
        assert_eq!(run.unexplained(), 0, "G {g}");
        run
    };
    let plain = |i: usize| i % size > size / 3 + 1 && !flow::base_level(&grid())[i];
    let (bare, fans) = (run(0.0), run(1.0));
    let risen = |r: &Evolution| r.delta_m().iter().enumerate().filter(|&(i, d)| plain(i) && *d > 0.0).count();
    assert_eq!(risen(&bare), 0, "nothing deposits without G");
    assert!(risen(&fans) > 20, "{} plain cells rose", risen(&fans));
    let highest = fans.delta_m().iter().enumerate().filter(|&(i, _)| plain(i)).map(|(_, d)| *d).fold(0.0, f64::max);
    assert!(highest > 0.5, "the thickest fan is {highest} m");
    assert!(
        fans.budget.deposited > 0 && fans.budget.outflow < bare.budget.outflow,
        "{:?} vs {:?}",
        fans.budget,
        bare.budget
    );
    // The range rose only where the mask is.
    let range_top =
        fans.heights_m().iter().enumerate().filter(|&(i, _)| i % size < size / 3).map(|(_, h)| *h).fold(0.0, f64::max);
    assert!(range_top > 100.0, "the range is {range_top} m high");
}

#[test]
fn multiple_flow_directions_conserve_area_and_spread_it() {
    // A plane falling eastwards: every column passes its area on to the next, so away from the
    // north and south borders a cell x columns from the east-flowing start drains (x + 1) cells,
    // by one direction or by many; on a cone the many directions spread the area that one
    // direction gathers into a few straight lines.
    let (w, h, cell) = (20, 60, 30.0);
    let plane: Vec<f64> = (0..w * h).map(|i| 100.0 - (i % w) as f64).collect();
    let grid = Grid::flat_patch(w, h, cell, plane.clone());
    let base = flow::base_level(&grid);
    let d8 = flow::route(&grid, &plane, &base);
    let mfd = flow::area_mfd(&grid, &d8.flooded_m, &base);
    let a = cell * cell;
    for y in 25..35 {
        for x in 1..15 {
            let i = y * w + x;
            let expected = x as f64 * a;
            assert!((mfd[i] - expected).abs() < 1e-9 * expected, "({x}, {y}): {} vs {expected}", mfd[i]);
            assert!((d8.area_m2[i] - expected).abs() < 1e-9 * expected);
        }
    }
    let total: f64 = grid.area_m2.iter().sum();
    let at_base: f64 = (0..grid.len()).filter(|&i| base[i]).map(|i| mfd[i]).sum();
    assert!((at_base - total).abs() < 1e-9 * total, "{at_base} of {total} m² reach base level");

    let size = 41;
    let cone: Vec<f64> = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64 - 20.0, (i / size) as f64 - 20.0);
            100.0 - (x * x + y * y).sqrt()
        })
        .collect();
    let grid = Grid::flat_patch(size, size, cell, cone.clone());
    let base = flow::base_level(&grid);
    let d8 = flow::route(&grid, &cone, &base);
    let mfd = flow::area_mfd(&grid, &d8.flooded_m, &base);
    let largest = |areas: &[f64]| (0..grid.len()).filter(|&i| !base[i]).map(|i| areas[i]).fold(0.0, f64::max);
    assert!(largest(&mfd) < 0.8 * largest(&d8.area_m2), "MFD {} vs D8 {}", largest(&mfd), largest(&d8.area_m2));
}

#[test]
fn mfd_runs_keep_their_budgets_and_repeat() {
    let params = LandscapeParams {
        years: 2e5,
        dt_years: 1e4,
        routing: flow::Routing::Mfd,
        deposition: 0.5,
        ..LandscapeParams::default()
    };
    let mut a = Evolution::new(rough_patch(40, 50.0, 3), params.clone()).unwrap();
    a.run_to_end();
    assert_eq!(a.unexplained(), 0);
    let mut b = Evolution::new(rough_patch(40, 50.0, 3), params).unwrap();
    b.run_to_end();
    assert_eq!(a.change, b.change);
}
