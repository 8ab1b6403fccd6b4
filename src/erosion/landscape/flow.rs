//! Flow routing for landscape evolution on a region's grid: which cells are base level, each
//! cell's receiver by steepest descent to one of its 8 neighbours (across face edges as the grid
//! is folded, see [`crate::erosion::region`]), an order in which every receiver comes before its
//! donors, and the drainage area in m² on the ellipsoid.
//!
//! Closed depressions are resolved as fastscapelib's `MSTSinkResolver` resolves them by default
//! (Cordonnier, Bovy & Braun 2019, "carve"): each closed basin leaves over its lowest pass, found
//! here by a Priority-Flood (Barnes, Lehman & Mulla 2014) from the cells that already drain to base
//! level (the flood reaches basins in order of their spill level, as Prim's algorithm builds the
//! minimum spanning tree of the basins), and the flow path from the pass down to the basin's pit
//! is reversed, so water leaves the lake through its spill point. Slopes for erosion are read on
//! the true surface (a cell routed uphill out of a depression does not erode).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use serde::{Deserialize, Serialize};

use crate::erosion::grid::{Grid, PIPES};

/// How drainage area is accumulated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Routing {
    /// Single flow direction: all of a cell's area to its steepest neighbour.
    #[default]
    D8,
    /// Multiple flow directions: a cell's area shared among every lower neighbour.
    Mfd,
}

impl Routing {
    /// Whether it is the default (not written to the project).
    pub fn is_d8(&self) -> bool {
        *self == Routing::D8
    }

    /// The name the command line and the project use.
    pub fn name(self) -> &'static str {
        match self {
            Routing::D8 => "d8",
            Routing::Mfd => "mfd",
        }
    }
}

/// Freeman's (1991) exponent of the slope that shares a cell's area among its lower neighbours.
pub const MFD_EXPONENT: f64 = 1.1;

/// The routing of one surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Flow {
    /// Each cell's receiver (a base-level cell: itself).
    pub receiver: Vec<usize>,
    /// The distance to the receiver, metres (0 for base level).
    pub distance_m: Vec<f64>,
    /// The cells, every receiver before its donors (each base-level cell, then its basin).
    pub order: Vec<usize>,
    /// Drainage area: the cell's own area and every cell upstream of it, m².
    pub area_m2: Vec<f64>,
    /// The surface with its closed depressions filled to their spill level (lakes), metres.
    pub flooded_m: Vec<f64>,
    /// Cells under a lake's level (raised by the flood).
    pub lake_cells: usize,
}

/// The base-level cells: the region's border ring, cells without data, and cells next to a cell
/// without data (beyond a cube corner): their height is held, and what reaches them leaves.
pub fn base_level(grid: &Grid) -> Vec<bool> {
    let (w, h) = (grid.width, grid.height);
    (0..grid.len())
        .map(|i| {
            let (x, y) = (i % w, i / w);
            x == 0
                || y == 0
                || x + 1 == w
                || y + 1 == h
                || grid.base_m[i].is_nan()
                || (0..8).any(|k| grid.neighbour(i, k).is_some_and(|j| grid.base_m[j].is_nan()))
        })
        .collect()
}

/// The centre-to-centre distance from cell `i` to its neighbour `j` through pipe `k`, metres:
/// the grid's lengths along +x and +y are each cell's to its next, so a step towards −x or −y
/// takes the neighbour's (the same distance both ways).
pub fn pipe_distance_m(grid: &Grid, i: usize, j: usize, k: usize) -> f64 {
    pipe_distance2_m2(grid, i, j, k).sqrt()
}

/// The square of [`pipe_distance_m`], m² (the routing compares slopes by their squares, so that
/// only the steepest way down takes a square root).
fn pipe_distance2_m2(grid: &Grid, i: usize, j: usize, k: usize) -> f64 {
    let (dx, dy) = PIPES[k];
    let lx = match dx {
        0 => 0.0,
        1 => grid.dx_m[i],
        _ => grid.dx_m[j],
    };
    let ly = match dy {
        0 => 0.0,
        1 => grid.dy_m[i],
        _ => grid.dy_m[j],
    };
    lx * lx + ly * ly
}

/// A cell in the flood's queue: lowest first, then the lowest index (so the order is total and
/// the routing deterministic).
#[derive(Clone, Copy, PartialEq)]
struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The pipes in the order the routing and the flood visit them: row by row from the south-west
/// neighbour to the north-east one, as fastscapelib's raster grid lists a node's neighbours, so
/// that equal slopes and equal flooded heights are settled the same way.
const VISIT: [usize; 8] = [5, 3, 6, 1, 0, 7, 2, 4];

/// Floods the closed depressions of `heights` (Priority-Flood+ε) from the cells that already
/// drain to base level (`open`): the flooded surface (every closed cell ends strictly above the
/// neighbour it was reached from; open cells and cells without data keep their height) and, per
/// closed basin (indexed by its pit, `pit_of`), the first of its cells the flood reached and the
/// cell it was reached from: its pass. A surface with a few lakes costs little more than one
/// without.
pub fn flood(grid: &Grid, heights: &[f64], open: &[bool], pit_of: &[usize]) -> (Vec<f64>, Vec<Option<(usize, usize)>>) {
    let n = grid.len();
    let mut flooded = heights.to_vec();
    let mut pass = vec![None; n];
    let mut reached: Vec<bool> = (0..n).map(|i| open[i] || heights[i].is_nan()).collect();
    let mut queue = BinaryHeap::new();
    for i in (0..n).filter(|&i| open[i] && !heights[i].is_nan()) {
        if VISIT.iter().any(|&k| grid.neighbour(i, k).is_some_and(|j| !reached[j])) {
            queue.push(Queued(heights[i], i));
        }
    }
    while let Some(Queued(level, c)) = queue.pop() {
        for k in VISIT {
            let Some(j) = grid.neighbour(c, k) else { continue };
            if reached[j] {
                continue;
            }
            reached[j] = true;
            if pass[pit_of[j]].is_none() {
                pass[pit_of[j]] = Some((j, c));
            }
            flooded[j] = heights[j].max(level.next_up());
            queue.push(Queued(flooded[j], j));
        }
    }
    (flooded, pass)
}

/// The distance between neighbouring cells `i` and `j`, metres.
fn neighbour_distance_m(grid: &Grid, i: usize, j: usize) -> f64 {
    let w = grid.width as isize;
    let (dx, dy) = ((j as isize % w) - (i as isize % w), (j as isize / w) - (i as isize / w));
    let k = PIPES.iter().position(|&(a, b)| (a as isize, b as isize) == (dx, dy)).expect("neighbours");
    pipe_distance_m(grid, i, j, k)
}

/// Receivers by steepest descent on `surface` for the cells `which` selects (the others, base
/// level and cells without data: themselves), with the distances to them.
fn steepest(grid: &Grid, surface: &[f64], base: &[bool], which: &dyn Fn(usize) -> bool) -> (Vec<usize>, Vec<f64>) {
    let n = grid.len();
    let mut receiver: Vec<usize> = (0..n).collect();
    let mut distance_m = vec![0.0; n];
    for i in 0..n {
        if base[i] || surface[i].is_nan() || !which(i) {
            continue;
        }
        // Not base level, so not on the border: all eight neighbours exist. Slopes compared by
        // their squares (the same order for drops > 0).
        let mut steepest2 = 0.0;
        let mut best_d2 = 0.0;
        for k in VISIT {
            let (dx, dy) = PIPES[k];
            let j = (i as isize + dx as isize + dy as isize * grid.width as isize) as usize;
            let drop = surface[i] - surface[j];
            // (A NaN neighbour gives a NaN drop, which is not > 0.)
            if drop.is_nan() || drop <= 0.0 {
                continue;
            }
            let d2 = pipe_distance2_m2(grid, i, j, k);
            let slope2 = drop * drop / d2;
            if slope2 > steepest2 {
                (steepest2, receiver[i], best_d2) = (slope2, j, d2);
            }
        }
        distance_m[i] = best_d2.sqrt();
    }
    (receiver, distance_m)
}

/// The cells in an order where every receiver comes before its donors (Braun & Willett 2013's
/// stack): from each base-level cell, depth first through its donors. Cells that do not reach
/// base level (none once depressions are resolved) are left out.
fn stack(receiver: &[usize], valid: &dyn Fn(usize) -> bool) -> Vec<usize> {
    let n = receiver.len();
    let mut start = vec![0usize; n + 1];
    for i in (0..n).filter(|&i| valid(i) && receiver[i] != i) {
        start[receiver[i] + 1] += 1;
    }
    for k in 0..n {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut donors = vec![0usize; start[n]];
    for i in (0..n).filter(|&i| valid(i) && receiver[i] != i) {
        donors[fill[receiver[i]]] = i;
        fill[receiver[i]] += 1;
    }
    let mut order = Vec::with_capacity(n);
    let mut pending: Vec<usize> = (0..n).rev().filter(|&i| valid(i) && receiver[i] == i).collect();
    while let Some(c) = pending.pop() {
        order.push(c);
        pending.extend(donors[start[c]..start[c + 1]].iter().rev());
    }
    order
}

/// Routes `heights`: receivers by steepest descent, closed depressions carved out over their
/// passes, the order and the drainage areas.
pub fn route(grid: &Grid, heights: &[f64], base: &[bool]) -> Flow {
    let n = grid.len();
    let valid = |i: usize| !heights[i].is_nan();
    let (mut receiver, mut distance_m) = steepest(grid, heights, base, &|_| true);
    let mut order = stack(&receiver, &valid);
    // Each cell's root (a base-level cell, or the pit of a closed basin).
    let mut pit_of: Vec<usize> = (0..n).collect();
    for &i in &order {
        pit_of[i] = if receiver[i] == i { i } else { pit_of[receiver[i]] };
    }
    let open: Vec<bool> = (0..n).map(|i| base[pit_of[i]]).collect();
    let closed = (0..n).any(|i| valid(i) && !open[i]);
    let mut flooded = heights.to_vec();
    if closed {
        let (f, pass) = flood(grid, heights, &open, &pit_of);
        flooded = f;
        let downhill = receiver.clone();
        for pit in (0..n).filter(|&i| valid(i) && !open[i] && downhill[i] == i) {
            let Some((entry, from)) = pass[pit] else { continue };
            // Reverse the path from the pass down to the pit; the pass drains across the saddle.
            let (mut previous, mut cell) = (from, entry);
            loop {
                let next = downhill[cell];
                receiver[cell] = previous;
                distance_m[cell] = neighbour_distance_m(grid, cell, previous);
                if cell == pit {
                    break;
                }
                (previous, cell) = (cell, next);
            }
        }
        order = stack(&receiver, &valid);
    }
    let mut area_m2: Vec<f64> = (0..n).map(|i| if valid(i) { grid.area_m2[i] } else { 0.0 }).collect();
    for &i in order.iter().rev() {
        let r = receiver[i];
        if r != i {
            area_m2[r] += area_m2[i];
        }
    }
    let lake_cells = (0..n).filter(|&i| flooded[i] > heights[i]).count();
    Flow { receiver, distance_m, order, area_m2, flooded_m: flooded, lake_cells }
}

/// Multiple flow directions (Freeman 1991) on a surface without closed depressions
/// ([`Flow::flooded_m`]): the cells from the highest down, and each one's lower neighbours with
/// the share of its flow each takes, in proportion to slope^1.1. On the flooded surface every
/// cell but base level has a lower neighbour, so whatever is accumulated reaches base level, as
/// with one flow direction; only the way it spreads differs (divergent on hillslopes,
/// convergent in valleys).
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    /// The cells that pass their flow on, highest first (equal heights by index).
    pub order: Vec<usize>,
    /// Where each cell's shares start in `shares` (indexed by cell; one past the last cell too).
    start: Vec<usize>,
    /// (lower neighbour, share), the shares of a cell summing to 1.
    shares: Vec<(usize, f64)>,
}

impl Spread {
    /// The shares of `flooded`'s cells (base level and cells without data pass nothing on).
    pub fn of(grid: &Grid, flooded: &[f64], base: &[bool]) -> Spread {
        let n = grid.len();
        let mut order: Vec<usize> = (0..n).filter(|&i| !flooded[i].is_nan() && !base[i]).collect();
        order.sort_by(|&a, &b| flooded[b].total_cmp(&flooded[a]).then(a.cmp(&b)));
        let mut start = vec![0usize; n + 1];
        let mut shares = Vec::with_capacity(order.len() * 3);
        let mut by_cell: Vec<(usize, usize)> = vec![(0, 0); n];
        for &i in &order {
            let first = shares.len();
            let mut total = 0.0;
            for k in VISIT {
                let Some(j) = grid.neighbour(i, k) else { continue };
                if flooded[j].is_nan() || flooded[j] >= flooded[i] {
                    continue;
                }
                let w = ((flooded[i] - flooded[j]) / pipe_distance_m(grid, i, j, k)).powf(MFD_EXPONENT);
                shares.push((j, w));
                total += w;
            }
            for share in &mut shares[first..] {
                share.1 /= total;
            }
            by_cell[i] = (first, shares.len());
        }
        // Reindex by cell, so that a cell's shares are found in O(1).
        let mut flat = Vec::with_capacity(shares.len());
        for i in 0..n {
            start[i] = flat.len();
            let (a, b) = by_cell[i];
            flat.extend_from_slice(&shares[a..b]);
        }
        start[n] = flat.len();
        Spread { order, start, shares: flat }
    }

    /// Cell `i`'s lower neighbours and their shares.
    pub fn shares(&self, i: usize) -> &[(usize, f64)] {
        &self.shares[self.start[i]..self.start[i + 1]]
    }

    /// Accumulates `own` (one value per cell) down the shares: each cell's own value plus what
    /// reaches it from above.
    pub fn accumulate(&self, own: &[f64]) -> Vec<f64> {
        let mut total = own.to_vec();
        for &i in &self.order {
            let here = total[i];
            for &(j, w) in self.shares(i) {
                total[j] += here * w;
            }
        }
        total
    }
}

/// Drainage area by multiple flow directions on `flooded` (see [`Spread`]).
pub fn area_mfd(grid: &Grid, flooded: &[f64], base: &[bool]) -> Vec<f64> {
    let own: Vec<f64> = (0..grid.len()).map(|i| if flooded[i].is_nan() { 0.0 } else { grid.area_m2[i] }).collect();
    Spread::of(grid, flooded, base).accumulate(&own)
}
