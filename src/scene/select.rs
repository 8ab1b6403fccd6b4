//! Quad selection (paper, section 5): from the six roots, a quad is split while it is visible
//! (inside the view frustum and above the planet's horizon, for every height its terrain may
//! have) and one of its samples covers more than t pixels. Refinement waits for data: a quad is
//! split only when all four children are ready to draw, so until they are it is drawn itself,
//! standing in for them; the children are asked for. Quads are visited coarsest first, and a cap
//! on the number of quads stops refinement in that order.

use std::collections::VecDeque;

use glam::DVec3;

use super::camera::Camera;
use crate::ecm::QuadId;
use crate::ecm::geometry::QuadBounds;

/// What selection needs to know about a quad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadInfo {
    /// A box around everything the quad may draw (with its height range and exaggeration).
    pub bounds: QuadBounds,
    /// The longest edge of the quad, metres.
    pub edge_m: f64,
}

/// The data side of selection: bounds, readiness, how deep data go.
pub trait QuadSource {
    /// The quad's box and size.
    fn info(&mut self, quad: QuadId) -> QuadInfo;
    /// Whether the quad can be drawn now (its data are on the GPU, or it has none to wait for).
    fn ready(&self, quad: QuadId) -> bool;
    /// Whether splitting the quad adds detail (finer data exist, or the geometry needs it).
    fn refinable(&self, quad: QuadId) -> bool;
}

/// Selection settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelectParams {
    /// Split while a sample covers more than this many pixels.
    pub threshold_px: f64,
    /// Most quads to draw.
    pub max_quads: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Semi-axes (a, b) of the ellipsoid that hides what is behind it: the body lowered to the
    /// lowest terrain, metres.
    pub occluder_m: (f64, f64),
}

/// The result of one selection.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Selection {
    /// Quads to draw, coarsest first.
    pub quads: Vec<QuadId>,
    /// Quads that would be drawn if their data were ready, coarsest and largest first.
    pub wanted: Vec<QuadId>,
    /// Quads split this frame: the next frame splits them again only if they are still ready,
    /// so their data must stay on the GPU even when nothing under them is drawn (all their
    /// children culled).
    pub split: Vec<QuadId>,
    /// Quads dropped outside the frustum.
    pub culled_frustum: usize,
    /// Quads dropped behind the horizon.
    pub culled_horizon: usize,
    /// Whether the cap stopped a split.
    pub capped: bool,
    /// Quads visited.
    pub visited: usize,
}

impl Selection {
    /// Quads drawn per level, (level, count) for the levels drawn, coarsest first.
    pub fn per_level(&self) -> Vec<(u8, usize)> {
        let mut counts = std::collections::BTreeMap::new();
        for q in &self.quads {
            *counts.entry(q.level).or_insert(0) += 1;
        }
        counts.into_iter().collect()
    }
}

/// Whether every point (ECEF) lies behind the horizon of the occluding ellipsoid as seen from
/// `eye`: inside the shadow cone of the ellipsoid (scaled to a unit sphere) and beyond its plane
/// of tangency. That region is convex (a cone cut by a half-space) and scaling keeps convexity,
/// so when the eight corners of a box are in it, the whole box is.
pub fn behind_horizon(eye: DVec3, points: &[DVec3], occluder_m: (f64, f64)) -> bool {
    let (a, b) = occluder_m;
    let scale = DVec3::new(1.0 / a, 1.0 / a, 1.0 / b);
    let c = eye * scale;
    let cc = c.length();
    if cc <= 1.0 {
        return false;
    }
    let axis = c / cc;
    let cos_half_angle = (1.0 - 1.0 / (cc * cc)).sqrt();
    points.iter().all(|&point| {
        let p = point * scale;
        let v = p - c;
        let dist = v.length();
        // Beyond the plane of the tangent circle (dot(x, ĉ) = 1/|c|), inside the cone around −ĉ.
        p.dot(axis) < 1.0 / cc && dist > 0.0 && v.dot(-axis) / dist >= cos_half_angle
    })
}

/// Pixels one of the quad's 256 sample spacings covers, seen from `camera` at the quad's
/// nearest point.
pub fn pixels_per_sample(camera: &Camera, info: &QuadInfo, height_px: u32) -> f64 {
    let distance = info.bounds.distance_m(camera.position).max(camera.near_m);
    info.edge_m / 256.0 * camera.focal_px(height_px) / distance
}

/// Why a box is not drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Culled {
    /// Wholly outside the view frustum.
    Frustum,
    /// Wholly behind the horizon of the occluding ellipsoid.
    Horizon,
}

/// Whether a box (a quad's or a patch's) is culled, and why.
pub(crate) fn cull_box(
    camera: &Camera,
    planes: &[super::camera::Plane; 5],
    occluder_m: (f64, f64),
    bounds: &QuadBounds,
) -> Option<Culled> {
    if planes.iter().any(|p| bounds.outside_plane(p.normal, p.d)) {
        return Some(Culled::Frustum);
    }
    if behind_horizon(camera.position, &bounds.corners(), occluder_m) {
        return Some(Culled::Horizon);
    }
    None
}

/// Counts a box's culling into the frustum's or the horizon's tally; whether it was culled.
pub(crate) fn tally(culled: Option<Culled>, frustum: &mut usize, horizon: &mut usize) -> bool {
    match culled {
        Some(Culled::Frustum) => *frustum += 1,
        Some(Culled::Horizon) => *horizon += 1,
        None => return false,
    }
    true
}

fn cull(camera: &Camera, planes: &[super::camera::Plane; 5], params: &SelectParams, info: &QuadInfo) -> Option<Culled> {
    cull_box(camera, planes, params.occluder_m, &info.bounds)
}

fn visible(camera: &Camera, planes: &[super::camera::Plane; 5], params: &SelectParams, info: &QuadInfo) -> bool {
    cull(camera, planes, params, info).is_none()
}

/// Selects the quads to draw.
pub fn select(camera: &Camera, params: &SelectParams, source: &mut impl QuadSource) -> Selection {
    let mut out = Selection::default();
    let planes = camera.frustum(params.width, params.height);
    let mut queue: VecDeque<QuadId> = VecDeque::new();
    for face in crate::ecm::Face::ALL {
        let root = QuadId::root(face);
        if source.ready(root) {
            queue.push_back(root);
        } else {
            out.wanted.push(root);
        }
    }
    let mut wanted_scored: Vec<(u8, f64, QuadId)> = Vec::new();
    while let Some(quad) = queue.pop_front() {
        out.visited += 1;
        let info = source.info(quad);
        if tally(cull(camera, &planes, params, &info), &mut out.culled_frustum, &mut out.culled_horizon) {
            continue;
        }
        let px = pixels_per_sample(camera, &info, params.height);
        let children = quad.children().filter(|_| px > params.threshold_px && source.refinable(quad));
        let Some(children) = children else {
            out.quads.push(quad);
            continue;
        };
        // Children that will be culled need no data: only the visible ones must be ready.
        let missing: Vec<QuadId> = children
            .iter()
            .copied()
            .filter(|c| !source.ready(*c) && visible(camera, &planes, params, &source.info(*c)))
            .collect();
        if !missing.is_empty() {
            wanted_scored.extend(missing.into_iter().map(|c| (c.level, -px, c)));
            out.quads.push(quad);
        } else if out.quads.len() + queue.len() + 4 > params.max_quads {
            out.capped = true;
            out.quads.push(quad);
        } else {
            out.split.push(quad);
            queue.extend(children);
        }
    }
    wanted_scored.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    out.wanted.extend(wanted_scored.into_iter().map(|w| w.2));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::CubeProjection;
    use crate::ecm::geometry::QuadGeometry;
    use crate::geodesy::Ellipsoid;
    use crate::project::CameraSpec;
    use std::collections::{HashMap, HashSet};

    /// Bounds from a coarse geometry, all data ready unless listed.
    struct Fake {
        infos: HashMap<QuadId, QuadInfo>,
        missing: HashSet<QuadId>,
        max_level: u8,
    }

    impl QuadSource for Fake {
        fn info(&mut self, quad: QuadId) -> QuadInfo {
            *self.infos.entry(quad).or_insert_with(|| {
                let g = QuadGeometry::compute(&Ellipsoid::MOON, CubeProjection::Qsc, quad, 9);
                let q = g.corners_ecef;
                QuadInfo {
                    bounds: QuadBounds::compute(&g, -100.0, 100.0),
                    edge_m: (q[1] - q[0]).length().max((q[2] - q[0]).length()),
                }
            })
        }
        fn ready(&self, quad: QuadId) -> bool {
            !self.missing.contains(&quad)
        }
        fn refinable(&self, quad: QuadId) -> bool {
            quad.level < self.max_level
        }
    }

    fn params(t: f64) -> SelectParams {
        SelectParams {
            threshold_px: t,
            max_quads: 10_000,
            width: 640,
            height: 480,
            occluder_m: (1_737_300.0, 1_737_300.0),
        }
    }

    fn camera(alt: f64, pitch: f64) -> Camera {
        Camera::new(&Ellipsoid::MOON, CameraSpec { lat: 10.0, lon: 20.0, alt, heading: 0.0, pitch, fov: 60.0 }, 1.0)
    }

    #[test]
    fn quads_beyond_the_horizon_are_culled() {
        let mut fake = Fake { infos: HashMap::new(), missing: HashSet::new(), max_level: 12 };
        // From 50 000 km the Moon is ~15 px: the roots are enough.
        let far = select(&camera(5e7, -90.0), &params(1.5), &mut fake);
        assert!(far.quads.iter().all(|q| q.level == 0), "{:?}", far.quads);
        // From 300 km, looking down, quads on the far side are dropped before they are split.
        let near = select(&camera(3e5, -90.0), &params(1.5), &mut fake);
        assert!(near.culled_horizon >= 1, "{near:?}");
        let c = camera(3e5, -90.0);
        for q in &near.quads {
            let b = fake.info(*q).bounds;
            assert!(!behind_horizon(c.position, &b.corners(), params(1.5).occluder_m));
        }
    }

    #[test]
    fn closer_cameras_and_smaller_thresholds_draw_finer_quads() {
        let mut fake = Fake { infos: HashMap::new(), missing: HashSet::new(), max_level: 14 };
        let coarse = select(&camera(2e5, -60.0), &params(8.0), &mut fake);
        let fine = select(&camera(2e5, -60.0), &params(1.0), &mut fake);
        assert!(fine.quads.len() > coarse.quads.len(), "{} vs {}", fine.quads.len(), coarse.quads.len());
        let deepest = |s: &Selection| s.quads.iter().map(|q| q.level).max().unwrap();
        assert!(deepest(&fine) > deepest(&coarse));
        assert!(fine.culled_frustum > 0);
        // Every drawn quad is, at its nearest point, at most t pixels per sample, or at the data's
        // finest level.
        for q in &fine.quads {
            let px = pixels_per_sample(&camera(2e5, -60.0), &fake.info(*q), 480);
            assert!(px <= 1.0 || q.level == 14, "{q}: {px}");
        }
        // The drawn quads never overlap: no quad is an ancestor of another.
        let set: HashSet<QuadId> = fine.quads.iter().copied().collect();
        for q in &fine.quads {
            for a in q.ancestors() {
                assert!(!set.contains(&a), "{a} and its descendant {q}");
            }
        }
    }

    #[test]
    fn missing_children_leave_the_parent_drawn_and_are_asked_for() {
        let cam = camera(2e5, -60.0);
        let mut all = Fake { infos: HashMap::new(), missing: HashSet::new(), max_level: 14 };
        let full = select(&cam, &params(1.5), &mut all);
        let deep = *full.quads.iter().max_by_key(|q| q.level).unwrap();
        let parent = deep.parent().unwrap();
        let mut fake = Fake { infos: all.infos.clone(), missing: HashSet::from([deep]), max_level: 14 };
        let partial = select(&cam, &params(1.5), &mut fake);
        assert!(partial.quads.contains(&parent));
        assert!(!partial.quads.contains(&deep));
        assert_eq!(partial.wanted, [deep]);
        assert!(full.wanted.is_empty());
    }

    #[test]
    fn culled_children_need_no_data() {
        // Looking at the horizon from low altitude: some children of split quads are culled. If
        // they lack data the split still happens (they would not be drawn anyway).
        let cam = camera(2e4, -10.0);
        let mut all = Fake { infos: HashMap::new(), missing: HashSet::new(), max_level: 14 };
        let full = select(&cam, &params(1.5), &mut all);
        let drawn: HashSet<QuadId> = full.quads.iter().copied().collect();
        let planes = cam.frustum(640, 480);
        let culled: HashSet<QuadId> = full
            .quads
            .iter()
            .filter_map(|q| q.parent())
            .flat_map(|p| p.children().unwrap())
            .filter(|c| !drawn.contains(c) && !visible(&cam, &planes, &params(1.5), &all.info(*c)))
            .collect();
        assert!(!culled.is_empty());
        let mut fake = Fake { infos: all.infos.clone(), missing: culled, max_level: 14 };
        let partial = select(&cam, &params(1.5), &mut fake);
        assert_eq!(partial.quads, full.quads);
        assert!(partial.wanted.is_empty());
    }

    #[test]
    fn the_cap_keeps_the_coarsest_first_order() {
        let cam = camera(2e5, -60.0);
        let mut fake = Fake { infos: HashMap::new(), missing: HashSet::new(), max_level: 14 };
        let full = select(&cam, &params(1.0), &mut fake);
        let capped = select(&cam, &SelectParams { max_quads: 30, ..params(1.0) }, &mut fake);
        assert!(capped.capped && capped.quads.len() <= 30, "{}", capped.quads.len());
        // Nothing finer than the uncapped selection, and its levels are a prefix of the full one's.
        let max_capped = capped.quads.iter().map(|q| q.level).max().unwrap();
        assert!(max_capped <= full.quads.iter().map(|q| q.level).max().unwrap());
    }

    #[test]
    fn horizon_test_against_closed_form() {
        let r = 1000.0;
        let eye = DVec3::new(2000.0, 0.0, 0.0);
        // The tangent circle is at x = 500, radius 866: the cone's half-angle is 30°.
        let hidden = |p: DVec3| behind_horizon(eye, &[p], (r, r));
        assert!(hidden(DVec3::new(-1500.0, 0.0, 0.0)), "straight behind");
        assert!(!hidden(DVec3::new(-1500.0, 3000.0, 0.0)), "beside, far out");
        assert!(!hidden(DVec3::new(500.0, 866.03, 0.0) * 1.001), "just above the tangent point");
        assert!(hidden(DVec3::new(499.0, 800.0, 0.0)), "just behind the tangent plane, inside the cone");
        // On the cone's surface 3000 behind the eye: tan 30° · 3500 = 2020.7 off the axis.
        assert!(hidden(DVec3::new(-1500.0, 2020.0, 0.0)));
        assert!(!hidden(DVec3::new(-1500.0, 2022.0, 0.0)));
        // A set is hidden only if all of it is; an eye inside the body hides nothing.
        assert!(!behind_horizon(eye, &[DVec3::new(-1500.0, 0.0, 0.0), DVec3::new(-1500.0, 3000.0, 0.0)], (r, r)));
        assert!(!behind_horizon(DVec3::new(10.0, 0.0, 0.0), &[DVec3::new(-1500.0, 0.0, 0.0)], (r, r)));
    }
}
