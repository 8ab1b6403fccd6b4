//! The renderer on the GPU (Mesa's lavapipe in CI): positions against the CPU f32 reference and
//! the f64 truth, colours against the ramp, isolines against the interval, no cracks, reference
//! images, and the `terrafuse render` command.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{repo_path, terrafuse};
use terrafuse::ecm::geometry::{QuadFrame, sample_st, vertex_f32};
use terrafuse::ecm::{CubeProjection, Face, QuadId};
use terrafuse::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, PROBE_ORIGIN, PROBE_SUBSAMPLES, RenderedImage, Renderer};
use terrafuse::project::{CameraSpec, Project};
use terrafuse::scene::Scene;
use terrafuse::scene::patches::{PatchMorph, stand_on_edge, vertex_weights};

fn out_dir() -> PathBuf {
    let dir = common::out_path("render");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The sample project `name`, its datasets imported once into the test output folder's `render/`.
fn project(name: &str) -> PathBuf {
    common::sample_project(name, &out_dir())
}

fn renderer(project_path: &Path, edit: impl FnOnce(&mut Project)) -> Renderer {
    let mut p = Project::load(project_path).unwrap();
    edit(&mut p);
    let (scene, _) = Scene::open(&p).unwrap();
    let ctx =
        GpuContext::headless().expect("a GPU adapter (lavapipe in CI: scripts/install-deps, WGPU_BACKEND=vulkan)");
    Renderer::new(&ctx, scene, IMAGE_FORMAT).unwrap()
}

fn cam(lat: f64, lon: f64, alt: f64, heading: f64, pitch: f64) -> CameraSpec {
    CameraSpec { lat, lon, alt, heading, pitch, fov: 50.0 }
}

fn draw(r: &mut Renderer, camera: &CameraSpec, w: u32, h: u32, mode: DrawMode) -> RenderedImage {
    let stats = r.settle(camera, w, h, Duration::from_secs(120));
    assert_eq!(stats.pending, 0, "every wanted quad loaded: {stats:?}");
    assert!(stats.errors.is_empty(), "{:?}", stats.errors);
    r.render_image(mode).unwrap()
}

#[test]
fn vertex_positions_match_the_cpu_reference_and_the_f64_truth() {
    // Without geomorphing every vertex is its sample's; with it, a vertex the coarser stride
    // lacks has slid toward the midpoint of its two neighbours there (scene::patches's twins).
    check_vertex_positions(false);
    check_vertex_positions(true);
}

fn check_vertex_positions(morph: bool) {
    let path = project("erzurum");
    let mut r = renderer(&path, |_| {});
    r.set_geomorph(morph);
    // From 30 km over the SRTM tile: quads of levels 2–9, with and without data.
    let camera = cam(39.3, 40.42, 30_000.0, 0.0, -45.0);
    let image = draw(&mut r, &camera, 320, 240, DrawMode::Points);
    let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
    let drawn = r.drawn().to_vec();
    let instances = r.instances().to_vec();
    let cam = *r.last_camera().unwrap();
    let e = r.scene().ellipsoid;
    let patches = r.patches().patches.clone();
    let levels: std::collections::BTreeSet<u8> = drawn.iter().map(|q| q.level).collect();
    assert!(levels.len() >= 3, "levels {levels:?}");
    let mut geometries = std::collections::HashMap::new();
    let mut composed = std::collections::HashMap::new();
    let (mut checked, mut morphed, mut worst_cpu, mut worst_truth) = (0usize, 0usize, 0f64, 0f64);
    for (k, id) in ids.iter().enumerate() {
        if id[0] == 0 || id[3] & 2 != 0 {
            continue; // nothing drawn here, or a skirt vertex
        }
        // Every 7th vertex pixel keeps the test quick while covering every quad.
        if k % 7 != 0 {
            continue;
        }
        let index = (id[0] - 1) as usize;
        let quad = drawn[index];
        let (i, j, stride) =
            ((id[1] - PROBE_ORIGIN) / PROBE_SUBSAMPLES, (id[2] - PROBE_ORIGIN) / PROBE_SUBSAMPLES, id[3] >> 2);
        // The patches that may have drawn it (two or four share an edge or a corner): where they
        // morph differently, the pixel shows one of them, unknown which.
        let reaches: std::collections::BTreeSet<(u64, u64, (u32, u32))> = patches
            .iter()
            .filter(|p| p.quad as usize == index && p.stride == stride)
            .filter(|p| (p.px * 32..=p.px * 32 + 32).contains(&i) && (p.py * 32..=p.py * 32 + 32).contains(&j))
            .map(|p| {
                let (reach, up) = if p.morphs {
                    (f64::from(p.reach_m), f64::from(p.reach_up_m))
                } else {
                    (f64::INFINITY, f64::INFINITY)
                };
                (reach.to_bits(), up.to_bits(), p.origin())
            })
            .collect();
        // Two patches that share the vertex at one stride and reach draw it alike.
        let kinds: std::collections::BTreeSet<(u64, u64)> = reaches.iter().map(|r| (r.0, r.1)).collect();
        if kinds.len() != 1 {
            continue;
        }
        let &(reach, reach_up, origin) = reaches.first().unwrap();
        let (reach, reach_up) = (f64::from_bits(reach), f64::from_bits(reach_up));
        let g = geometries.entry(quad).or_insert_with(|| r.reference_geometry(quad));
        // The mesh stands on the quad's own samples at every stride.
        let lv = 0;
        composed.entry(quad).or_insert_with(|| r.read_heights(quad).unwrap());
        let h = |i: u32, j: u32, _level: u32| {
            composed[&quad].as_ref().map_or(0.0, |hs| {
                let v = hs[(j * 257 + i) as usize];
                if v.is_nan() { 0.0 } else { v }
            })
        };
        let frame: QuadFrame = g.frame(cam.position, f64::from(instances[index].reference_height_m()));
        let has_maps = instances[index].has_maps();
        let cpu_at = |i: u32, j: u32, level: u32| {
            let (s, t) = sample_st(257, i, j);
            let maps = if has_maps { g.maps_at(i, j) } else { None };
            vertex_f32(g.split, &frame, s as f32, t as f32, maps, h(i, j, level))
        };
        let truth_at = |i: u32, j: u32, level: u32| {
            g.exact_position(&e, CubeProjection::Qsc, cam.position, i, j, f64::from(h(i, j, level)))
        };
        let (mut cpu, mut truth) = (cpu_at(i, j, lv), truth_at(i, j, lv));
        let (a, b) = ((i - origin.0) / stride, (j - origin.1) / stride);
        let mut slack = 0.0;
        {
            // What the patch at twice the stride draws there, itself morphing toward four times
            // it, the factors from the f32 distances as the GPU has them (none without
            // geomorphing: infinite reaches); on a side whose edge a neighbour owns, the point of
            // that neighbour's edge, morphing or not (scene::patches::vertex_weights, the
            // shader's twin).
            let reaches_of = |p: &terrafuse::scene::patches::Patch| {
                if p.morphs { (f64::from(p.reach_m), f64::from(p.reach_up_m)) } else { (f64::INFINITY, f64::INFINITY) }
            };
            let own = patches.iter().find(|p| p.quad as usize == index && p.stride == stride && p.origin() == origin);
            let sides = own.map_or([None; 4], |p| {
                p.edge_owner.map(|c| {
                    patches.get(c as usize).map(|n| PatchMorph {
                        stride: n.stride,
                        reach_m: reaches_of(n).0,
                        reach_up_m: reaches_of(n).1,
                        origin: n.origin(),
                    })
                })
            });
            let this = PatchMorph { stride, reach_m: reach, reach_up_m: reach_up, origin };
            let weights = vertex_weights(this, (a, b), sides, |i, j| f64::from(cpu_at(i, j, lv).length()));
            let all: Vec<&((u32, u32), f64)> = weights.own.iter().chain(weights.edge.iter().flatten()).collect();
            if all.len() > 1 {
                // The blends round a few times more in f32.
                let moved = all.iter().map(|((i, j), _)| (truth_at(*i, *j, lv) - truth).length()).fold(0.0, f64::max);
                slack = 1e-5 * moved + 4.0 * truth.length() * 2f64.powi(-24);
                let up = (truth_at(i, j, lv)
                    - g.exact_position(&e, CubeProjection::Qsc, cam.position, i, j, f64::from(h(i, j, lv)) - 1.0))
                .normalize();
                let blend_cpu = |w: &[((u32, u32), f64)]| -> glam::Vec3 {
                    w.iter().map(|((i, j), w)| cpu_at(*i, *j, lv) * *w as f32).sum()
                };
                let blend_truth = |w: &[((u32, u32), f64)]| -> glam::DVec3 {
                    w.iter().map(|((i, j), w)| truth_at(*i, *j, lv) * *w).sum()
                };
                cpu = stand_on_edge(
                    blend_cpu(&weights.own).as_dvec3(),
                    weights.edge.as_deref().map(|w| blend_cpu(w).as_dvec3()),
                    up,
                )
                .as_vec3();
                truth = stand_on_edge(blend_truth(&weights.own), weights.edge.as_deref().map(blend_truth), up);
                morphed += 1;
            }
        }
        let gpu = glam::DVec3::new(f64::from(surface[k][0]), f64::from(surface[k][1]), f64::from(surface[k][2]));
        let distance = truth.length();
        let ulp = distance * 2f64.powi(-24);
        let d_cpu = (gpu - cpu.as_dvec3()).length();
        let d_truth = (gpu - truth).length();
        // The GPU may fuse multiply-adds the CPU rounds twice: a few units of the last place of
        // the camera distance; against the truth, the geometry issue's bound (1.55 f32 limits)
        // with the same allowance.
        assert!(
            d_cpu <= 4.0 * ulp + 1e-6 + slack,
            "{quad} ({i},{j}) stride {stride}: GPU {gpu} vs CPU {cpu}: {d_cpu} m at {distance} m"
        );
        assert!(
            d_truth <= 6.0 * ulp + 1e-6 + slack,
            "{quad} ({i},{j}) stride {stride}: GPU {gpu} vs f64 {truth}: {d_truth} m at {distance} m"
        );
        worst_cpu = worst_cpu.max(d_cpu / ulp);
        worst_truth = worst_truth.max(d_truth / ulp);
        // The pixel it landed on is where the f64 camera projects it.
        let (x, y, _) = cam.project(truth, 320, 240).unwrap();
        let (px, py) = ((k % 320) as f64 + 0.5, (k / 320) as f64 + 0.5);
        assert!(
            (x - px).abs() <= 1.0 && (y - py).abs() <= 1.0,
            "{quad} ({i},{j}) at ({px},{py}), projects to ({x},{y})"
        );
        checked += 1;
    }
    assert!(checked > 500, "only {checked} vertices checked");
    if morph {
        assert!(morphed > 20, "only {morphed} of {checked} vertices morphed");
    }
    eprintln!(
        "morph {morph}: {checked} vertices ({morphed} morphed): GPU − CPU ≤ {worst_cpu:.2} f32 limits, GPU − f64 ≤ {worst_truth:.2}"
    );
}

fn byte_diff(a: &[u8], b: [f64; 4]) -> f64 {
    (0..3).map(|c| (f64::from(a[c]) - b[c]).abs()).fold(0.0, f64::max)
}

#[test]
fn patch_errors_on_the_gpu_are_their_cpu_reference() {
    // δ of every patch at every stride from the kernel (shaders/render/patch_errors.wgsl) against
    // scene::patch_error::patch_errors in f64 on the heights the GPU composed (the mesh stands on
    // the quad's own samples at every stride; at 0 m where they have no data). Within the f32
    // rounding of heights of 1–3.5 km and of the mesh's interpolation.
    use terrafuse::scene::patch_error::patch_errors;
    let path = project("erzurum");
    let mut r = renderer(&path, |_| {});
    draw(&mut r, &cam(39.3, 40.42, 30_000.0, 0.0, -45.0), 320, 240, DrawMode::Colour);
    let drawn = r.drawn().to_vec();
    let (mut checked, mut worst, mut largest) = (0usize, 0f64, 0f64);
    for &quad in &drawn {
        let Some(gpu) = r.patch_errors(quad).map(<[_]>::to_vec) else { continue };
        let Some(own) = r.read_heights(quad).unwrap() else { continue };
        // Where a vertex has no data the terrain draws it at 0 m (the no-data fill).
        let vertex = |_: u32, i: u32, j: u32| {
            let h = f64::from(own[(j * 257 + i) as usize]);
            if h.is_nan() { 0.0 } else { h }
        };
        for (p, errors) in gpu.iter().enumerate() {
            let cpu = patch_errors(&own, p as u32 % 8, p as u32 / 8, &vertex);
            for (k, &c) in cpu.iter().enumerate() {
                // The kernel's are per stride, the reference's made monotone: compare the
                // running maximum.
                let g = errors[..=k].iter().copied().fold(0f32, f32::max);
                assert!((f64::from(g) - c).abs() <= 4e-3, "{quad} patch {p} stride {}: GPU {g} m, CPU {c} m", 1 << k);
                worst = worst.max((f64::from(g) - c).abs());
                largest = largest.max(c);
            }
            checked += 1;
        }
    }
    assert!(checked >= 64 * 4, "{checked} patches checked");
    assert!(largest > 10.0, "rough terrain: δ up to {largest} m");
    eprintln!("{checked} patches: GPU − CPU within {worst:.2e} m (δ up to {largest:.1} m)");
}

#[test]
fn a_coarse_mesh_shows_the_same_pixels_as_the_finest() {
    // Data per pixel: a pixel's colour is a function of the data where its ray meets them, not
    // of the mesh (the fragment stage follows the ray from the mesh to the data, and takes the
    // isolines' footprint there). At the default pixel error (1 px) and at the finest mesh
    // (0.05 px), 99 % of the terrain pixels away from silhouettes agree within 2/255 per channel,
    // and 99 % of those that read the same point of the same quad (within 0.01 of a sample).
    // Erzurum's view, straight down, and the Moon's Tycho view; the coarse mesh draws a fraction
    // of the triangles. The Moon's globe, whose face-sized quads' coarse triangles span 10° of
    // arc (where the chord's point and the projection's coordinates part most): 96 % and 97 %
    // (96.8 % and 97.9 % measured; 79 % before the mesh's point was placed over the ellipsoid
    // under it, BENCHMARKS.md).
    for (name, view, least, least_at_point) in [
        ("erzurum", "30km", 0.99, 0.99),
        ("erzurum", "down", 0.99, 0.99),
        ("moon-lola", "tycho", 0.99, 0.99),
        ("moon-lola", "globe", 0.96, 0.97),
    ] {
        let path = project(name);
        let p = Project::load(&path).unwrap();
        let camera = match view {
            "down" => cam(39.5, 40.5, 40_000.0, 0.0, -90.0),
            v => p.view(Some(v)).unwrap(),
        };
        let render_at = |tau: f64| {
            let mut r = renderer(&path, |p| p.detail.max_pixel_error = tau);
            let stats = r.settle(&camera, 320, 240, Duration::from_secs(120));
            (r.render_image(DrawMode::Probe).unwrap(), stats, r.drawn().to_vec())
        };
        let (coarse, coarse_stats, coarse_quads) = render_at(1.0);
        let (fine, fine_stats, fine_quads) = render_at(0.05);
        let (ci, fi) = (coarse.ids.as_ref().unwrap(), fine.ids.as_ref().unwrap());
        let (w, h) = (320usize, 240usize);
        let terrain = |ids: &[[u32; 4]], x: usize, y: usize| ids[y * w + x][0] > 0;
        let (mut compared, mut same, mut at_same_point, mut same_at_same_point) = (0usize, 0usize, 0usize, 0usize);
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let k = y * w + x;
                // Away from silhouettes: terrain here and all around in both.
                let inside = [(x, y), (x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)]
                    .iter()
                    .all(|&(a, b)| terrain(ci, a, b) && terrain(fi, a, b));
                if !inside {
                    continue;
                }
                compared += 1;
                let d = (0..3).map(|c| coarse.rgba[4 * k + c].abs_diff(fine.rgba[4 * k + c])).max().unwrap();
                same += usize::from(d <= 2);
                let quad = |ids: &[[u32; 4]], quads: &[QuadId]| quads[(ids[k][0] - 1) as usize];
                let near = |a: u32, b: u32| a.abs_diff(b) * 100 <= PROBE_SUBSAMPLES;
                if quad(ci, &coarse_quads) == quad(fi, &fine_quads)
                    && near(ci[k][1], fi[k][1])
                    && near(ci[k][2], fi[k][2])
                {
                    at_same_point += 1;
                    same_at_same_point += usize::from(d <= 2);
                }
            }
        }
        let share = same as f64 / compared as f64;
        let share_at_point = same_at_same_point as f64 / at_same_point.max(1) as f64;
        eprintln!(
            "{name} {view}: {:.2} % of {at_same_point} pixels reading the same point within 2/255, {:.2} % of all {compared}; \
             triangles {} at 1 px, {} at 0.05 px; max_error_px {:.3}",
            share_at_point * 100.0,
            share * 100.0,
            coarse_stats.triangles,
            fine_stats.triangles,
            coarse_stats.max_error_px
        );
        assert!(
            at_same_point * 2 > compared,
            "{name} {view}: {at_same_point} of {compared} pixels read the same point"
        );
        assert!(coarse_stats.max_error_px <= 1.0 + 1e-9 && fine_stats.max_error_px <= 0.05 + 1e-9);
        assert!(coarse_stats.triangles * 2 < fine_stats.triangles, "{name} {view}");
        assert!(share_at_point >= least_at_point, "{name} {view}: only {:.2} % the same", share_at_point * 100.0);
        assert!(share >= least, "{name} {view}: only {:.2} % of all pixels the same", share * 100.0);
    }
}

#[test]
fn each_pixel_reads_the_cpu_composition_where_it_stands() {
    // The fragment stage reads the composed heights at the pixel, bilinear between the four
    // samples around its sample coordinates, whatever stride drew it, and past its quad's edge
    // the neighbour's (through the page table). The probe returns those coordinates (to 1/256
    // of a sample) and the height it read; the CPU composition of the quad, or of the neighbour
    // at its level where the pixel read past the edge and that neighbour is drawn (so the GPU
    // read it, not a level around it), interpolated there in f64, agrees within the
    // coordinates' rounding times the slope and the f32 rounding of the heights: the Moon with
    // brushed layers, and Erzurum seen obliquely (where rays run past quads' edges).
    for (name, camera) in [("moon-brushing", None), ("erzurum", Some(cam(39.3, 40.42, 30_000.0, 0.0, -45.0)))] {
        let path = project(name);
        let mut r = renderer(&path, |_| {});
        let camera = camera.unwrap_or_else(|| Project::load(&path).unwrap().view(None).unwrap());
        let image = draw(&mut r, &camera, 240, 180, DrawMode::Probe);
        let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
        let drawn = r.drawn().to_vec();
        let mut composed: std::collections::HashMap<QuadId, Vec<f32>> = Default::default();
        let (mut checked, mut beyond, mut worst, mut strides) = (0, 0, 0f64, std::collections::BTreeSet::new());
        'pixels: for (k, id) in ids.iter().enumerate().step_by(3) {
            if id[0] == 0 || id[3] & 1 == 0 || id[3] & 2 != 0 {
                continue; // nothing drawn, no data or a skirt
            }
            let quad = drawn[(id[0] - 1) as usize];
            let coords = |v: u32| (f64::from(v) - f64::from(PROBE_ORIGIN)) / f64::from(PROBE_SUBSAMPLES);
            let (x, y) = (coords(id[1]), coords(id[2]));
            let inside = (0.0..=256.0).contains(&x) && (0.0..=256.0).contains(&y);
            let (a, b) = if inside {
                ((x.floor() as i64).min(255), (y.floor() as i64).min(255))
            } else {
                (x.floor() as i64, y.floor() as i64)
            };
            let (fx, fy) = (x - a as f64, y - b as f64);
            let mut c = [0.0; 4];
            for (n, (i, j)) in [(a, b), (a + 1, b), (a, b + 1), (a + 1, b + 1)].into_iter().enumerate() {
                // The sample's quad at this level: this one (its edges included), or the one beside.
                let side = |i: i64| if i < 0 { -1 } else { i64::from(i > 256) };
                let (dx, dy) = (side(i), side(j));
                let (Some(nx), Some(ny)) = (quad.x.checked_add_signed(dx as i32), quad.y.checked_add_signed(dy as i32))
                else {
                    continue 'pixels;
                };
                let holder = QuadId { x: nx, y: ny, ..quad };
                if holder != quad && !drawn.contains(&holder) {
                    continue 'pixels;
                }
                let h = composed.entry(holder).or_insert_with(|| r.scene().heights_cpu(holder).unwrap());
                let (li, lj) = ((i - 256 * dx) as usize, (j - 256 * dy) as usize);
                c[n] = f64::from(h[lj * 257 + li]);
            }
            if c.iter().any(|v| !v.is_finite() || *v < -1e37) {
                continue;
            }
            let want =
                c[0] * (1.0 - fx) * (1.0 - fy) + c[1] * fx * (1.0 - fy) + c[2] * (1.0 - fx) * fy + c[3] * fx * fy;
            let slope = (c[1] - c[0]).abs().max((c[3] - c[2]).abs()) + (c[2] - c[0]).abs().max((c[3] - c[1]).abs());
            let tolerance = slope / 256.0 + 4e-7 * want.abs() + 1e-3;
            let got = f64::from(surface[k][3]);
            assert!(
                (got - want).abs() <= tolerance,
                "{name}: pixel {k} of {quad} at ({x}, {y}): read {got} m, the CPU composition {want} m (±{tolerance})"
            );
            worst = worst.max((got - want).abs());
            strides.insert(id[3] >> 2);
            checked += 1;
            beyond += usize::from(!inside);
        }
        assert!(checked > 2000, "{name}: {checked} pixels checked");
        assert!(name != "erzurum" || beyond > 5, "{name}: {beyond} pixels read past their quad's edge");
        eprintln!(
            "{name}: {checked} pixels ({beyond} past their quad's edge) of {} quads at strides {strides:?}: within {worst:.2e} m",
            composed.len()
        );
    }
}

#[test]
fn no_seam_where_two_quads_meet() {
    // A pixel near its quad's edge reads the samples past it, in the quad beside it (its
    // central differences, the ray followed past the edge): the slope drawn per pixel is as
    // continuous across the edge between two quads of one level as inside a quad. Erzurum seen
    // at 60° from 5 km, coloured by slope without light or isolines: the colour step between
    // neighbouring pixels that two quads draw is, at the 99th percentile, no more than 1.5 times
    // the one inside quads (16/255 against 23/255 measured; 63/255 when each quad read only its
    // own samples: a hard line along the edge).
    let path = project("erzurum");
    let mut r = renderer(&path, |p| {
        p.visuals.colour_map.by = terrafuse::project::ColourBy::Attribute(terrafuse::attributes::Attribute::Slope);
        p.visuals.colour_map.range_m = Some([0.0, 40.0]);
        p.visuals.lighting.enabled = false;
        p.visuals.isolines.enabled = false;
    });
    let (w, h) = (320usize, 240usize);
    let image = draw(&mut r, &cam(39.42, 40.5, 5_000.0, 0.0, -60.0), w as u32, h as u32, DrawMode::Probe);
    let ids = image.ids.unwrap();
    let drawn = r.drawn().to_vec();
    let (mut across, mut within) = (Vec::new(), Vec::new());
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let k = y * w + x;
            for n in [k + 1, k + w] {
                let (a, b) = (ids[k], ids[n]);
                if a[0] == 0 || b[0] == 0 || a[3] & 3 != 1 || b[3] & 3 != 1 {
                    continue; // nothing drawn, no data or a skirt
                }
                let step = (0..3).map(|c| image.rgba[4 * k + c].abs_diff(image.rgba[4 * n + c])).max().unwrap();
                let (qa, qb) = (drawn[(a[0] - 1) as usize], drawn[(b[0] - 1) as usize]);
                if qa == qb {
                    within.push(step);
                } else if qa.level == qb.level {
                    across.push(step);
                }
            }
        }
    }
    let p99 = |v: &mut Vec<u8>| {
        v.sort();
        f64::from(v[v.len() * 99 / 100]).max(1.0)
    };
    assert!(across.len() > 200, "{} pixel pairs across quads' edges", across.len());
    let (a, b) = (p99(&mut across), p99(&mut within));
    eprintln!("colour step at the 99th percentile: {a} across {} edges' pairs, {b} within quads", across.len());
    assert!(a <= 1.5 * b, "a seam: {a}/255 across quads' edges, {b}/255 within");
}

#[test]
fn each_pixel_shows_the_data_where_its_ray_meets_them() {
    // The mesh stands within its error δ of the data; where a pixel's ray meets the mesh is δ·tan θ
    // beside the point of the data the eye sees through it. The fragment stage follows the ray
    // from the mesh to the data (`on_data`): the point each pixel read, its sample coordinates
    // and height from the probe placed on the ellipsoid in f64, lies on the pixel's ray. Erzurum
    // from 30 km at 45° and straight down from 40 km, and the Moon's globe (face-sized quads,
    // whose coarse triangles span 10° of arc), at the default pixel error: within 0.01 px at
    // the median and 0.1 px at the 99th percentile; the globe within 0.1 and 0.3 (0.057 and
    // 0.20 measured; 0.12 and 2.9 before the ray started under the mesh's point; not yet
    // explained).
    let globe = Project::load(&project("moon-lola")).unwrap().view(Some("globe")).unwrap();
    for (body, name, camera, bound) in [
        ("erzurum", "30km", cam(39.3, 40.42, 30_000.0, 0.0, -45.0), (0.01, 0.1)),
        ("erzurum", "down", cam(39.5, 40.5, 40_000.0, 0.0, -90.0), (0.01, 0.1)),
        ("moon-lola", "globe", globe, (0.1, 0.3)),
    ] {
        let mut r = renderer(&project(body), |_| {});
        let e = r.scene().ellipsoid;
        let exaggeration = r.scene().visuals.exaggeration;
        let (w, h) = (320u32, 240u32);
        let image = draw(&mut r, &camera, w, h, DrawMode::Probe);
        let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
        let drawn = r.drawn().to_vec();
        let eye = r.last_camera().unwrap().position;
        let focal = r.last_camera().unwrap().focal_px(h);
        let mut off = Vec::new();
        for k in 0..ids.len() {
            let id = ids[k];
            if id[0] == 0 || id[3] & 1 == 0 || id[3] & 2 != 0 {
                continue; // nothing drawn, no data or a skirt
            }
            let quad = drawn[(id[0] - 1) as usize];
            let (x0, y0) = quad.sample_xy(257, 0, 0);
            let (x1, y1) = quad.sample_xy(257, 256, 256);
            let coords = |v: u32| (f64::from(v) - f64::from(PROBE_ORIGIN)) / f64::from(PROBE_SUBSAMPLES) / 256.0;
            let (ci, cj) = (coords(id[1]), coords(id[2]));
            let point = terrafuse::ecm::FacePoint { face: quad.face, x: x0 + (x1 - x0) * ci, y: y0 + (y1 - y0) * cj };
            let (ground, up) = terrafuse::ecm::geometry::surface_and_normal(&e, CubeProjection::Qsc, point);
            let seen = ground + up * (f64::from(surface[k][3]) * exaggeration) - eye;
            let ray = glam::DVec3::new(f64::from(surface[k][0]), f64::from(surface[k][1]), f64::from(surface[k][2]))
                .normalize();
            off.push((seen - ray * seen.dot(ray)).length() / seen.length() * focal);
        }
        off.sort_by(f64::total_cmp);
        assert!(off.len() > 20_000, "{name}: {} pixels", off.len());
        let (median, p99, worst) = (off[off.len() / 2], off[off.len() * 99 / 100], off[off.len() - 1]);
        eprintln!(
            "{name}: the point read is {median:.4} px off the ray at the median, {p99:.4} at the 99th percentile, {worst:.3} at most"
        );
        assert!(median < bound.0 && p99 < bound.1, "{name}: {median} px at the median, {p99} at the 99th percentile");
    }
}

#[test]
fn colours_are_the_ramp_colour_of_the_height_at_each_pixel() {
    let path = project("moon-lola");
    let mut r = renderer(&path, |p| {
        p.visuals.lighting.enabled = false;
        p.visuals.isolines.enabled = false;
        p.visuals.background = [255, 0, 255, 255];
    });
    let image = draw(&mut r, &cam(-20.0, 30.0, 400_000.0, 20.0, -50.0), 256, 192, DrawMode::Probe);
    let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
    let ramp = r.scene().ramp.clone();
    let (mut terrain, mut worst) = (0, 0f64);
    for k in 0..(256 * 192) {
        let px = &image.rgba[4 * k..4 * k + 4];
        if ids[k][0] == 0 {
            assert_eq!(px, [255, 0, 255, 255], "background at pixel {k}");
            continue;
        }
        let expected =
            if ids[k][3] & 1 == 1 { ramp.colour_at(f64::from(surface[k][3])) } else { ramp.colour_at(f64::NAN) };
        let d = byte_diff(px, expected);
        // sRGB decode and re-encode in f32 and the final rounding: at most 1.5 levels.
        assert!(d <= 1.5, "pixel {k}: {px:?} for height {} should be {expected:?}", surface[k][3]);
        worst = worst.max(d);
        terrain += 1;
    }
    assert!(terrain > 256 * 192 / 3, "{terrain} terrain pixels");
    eprintln!("{terrain} pixels within {worst:.2} levels of the ramp");
}

#[test]
fn isoline_pixels_lie_on_multiples_of_the_interval() {
    let path = project("erzurum");
    let interval = 100.0;
    let mut r = renderer(&path, |p| {
        p.visuals.lighting.enabled = false;
        p.visuals.colour_map.preset = "grey".into();
        let iso = &mut p.visuals.isolines;
        (iso.enabled, iso.interval_m, iso.offset_m, iso.major_every) = (true, interval, 0.0, 0);
        (iso.width_px, iso.min_width_px, iso.colour) = (1.0, 1.0, [255, 0, 0, 255]);
    });
    let (w, h) = (320u32, 240u32);
    let image = draw(&mut r, &cam(39.45, 40.4, 12_000.0, 0.0, -90.0), w, h, DrawMode::Probe);
    let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
    let height = |x: u32, y: u32| f64::from(surface[(y * w + x) as usize][3]);
    let (mut on_line, mut line_pixels, mut exact, mut exact_drawn) = (0, 0, 0, 0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let k = (y * w + x) as usize;
            let neighbours = [k - 1, k + 1, k - w as usize, k + w as usize];
            if ids[k][0] == 0 || neighbours.iter().any(|&n| ids[n][3] & 1 == 0 || ids[n][0] == 0) || ids[k][3] & 1 == 0
            {
                continue;
            }
            // Metres per pixel, as fwidth sees it: the steeper one-sided difference along each
            // axis (a pixel's own triangle may be steeper than its neighbours' on average).
            let (c, l, rr) = (height(x, y), height(x - 1, y), height(x + 1, y));
            let (u, d) = (height(x, y - 1), height(x, y + 1));
            let fw = (rr - c).abs().max((c - l).abs()) + (d - c).abs().max((c - u).abs());
            let hk = height(x, y);
            let distance = (hk / interval - (hk / interval).round()).abs() * interval;
            let px = &image.rgba[4 * k..4 * k + 4];
            let grey = px[0] == px[1] && px[1] == px[2];
            if px[0] > 200 && px[1] < 60 && px[2] < 60 {
                line_pixels += 1;
                // A fully covered line pixel is within half the width (plus the pixel) of a line.
                assert!(
                    distance <= 1.5 * fw + 1e-3,
                    "line pixel ({x},{y}) at {hk} m is {distance} m from a line (fw {fw})"
                );
                on_line += 1;
            }
            // Pixels on a line where lines are far apart on screen must show it.
            if distance < 0.2 * fw && interval / fw > 12.0 {
                exact += 1;
                if !grey {
                    exact_drawn += 1;
                }
            }
        }
    }
    assert!(line_pixels > 200, "{line_pixels} line pixels");
    assert!(exact > 20 && exact_drawn as f64 >= 0.95 * exact as f64, "{exact_drawn} of {exact} pixels on a line drawn");
    eprintln!("{on_line} line pixels checked, {exact_drawn}/{exact} on-line pixels drawn");
}

/// Background pixels with terrain on both sides along the row and along the column.
fn holes(image: &RenderedImage, background: [u8; 4]) -> usize {
    let (w, h) = (image.width as usize, image.height as usize);
    let is_bg = |x: usize, y: usize| image.rgba[4 * (y * w + x)..4 * (y * w + x) + 4] == background;
    let mut holes = 0;
    for y in 0..h {
        for x in 0..w {
            if !is_bg(x, y) {
                continue;
            }
            let left = (0..x).any(|a| !is_bg(a, y));
            let right = (x + 1..w).any(|a| !is_bg(a, y));
            let up = (0..y).any(|b| !is_bg(x, b));
            let down = (y + 1..h).any(|b| !is_bg(x, b));
            if left && right && up && down {
                holes += 1;
            }
        }
    }
    holes
}

#[test]
fn no_cracks_between_levels_and_across_the_cube_corner() {
    let magenta = [255, 0, 255, 255];
    let moon = project("moon-lola");
    let mut r = renderer(&moon, |p| p.visuals.background = magenta);
    // Straight down onto the cube corner where front, right and top meet (geocentric latitude
    // asin(1/√3) on a sphere), and obliquely across it: quads of three faces and several levels.
    for (name, camera) in [
        ("corner-down", cam(35.264_389_682_754_654, 45.0, 150_000.0, 0.0, -90.0)),
        ("corner-oblique", cam(30.0, 40.0, 60_000.0, 30.0, -25.0)),
    ] {
        let image = draw(&mut r, &camera, 256, 192, DrawMode::Colour);
        let faces: std::collections::BTreeSet<Face> = r.drawn().iter().map(|q| q.face).collect();
        let levels: std::collections::BTreeSet<u8> = r.drawn().iter().map(|q| q.level).collect();
        assert!(faces.len() >= 2, "{name}: faces {faces:?}");
        let n = holes(&image, magenta);
        if n > 0 {
            terrafuse::cli::write_png(&out_dir().join(format!("{name}.cracks.png")), &image).unwrap();
        }
        assert_eq!(n, 0, "{name}: {n} background pixels inside the terrain (levels {levels:?}, faces {faces:?})");
    }
    // The Moon seen whole (its default view): face-sized quads whose patches of strides 8–32 meet
    // at T-junctions and at edges two reaches morph apart, where a chord lies beside the
    // ellipsoid horizontally too and no vertical skirt covers the gap from above (three
    // background pixels through the disk before the finer patch stood on the owner's edge).
    let globe = Project::load(&moon).unwrap().view(Some("globe")).unwrap();
    let image = draw(&mut r, &globe, 320, 240, DrawMode::Colour);
    let strides: std::collections::BTreeSet<u32> = r.patches().patches.iter().map(|p| p.stride).collect();
    assert!(strides.len() >= 2, "globe: strides {strides:?}");
    let n = holes(&image, magenta);
    if n > 0 {
        terrafuse::cli::write_png(&out_dir().join("globe.cracks.png"), &image).unwrap();
    }
    assert_eq!(n, 0, "globe: {n} background pixels inside the disk (strides {strides:?})");
    // Earth: level 9 data beside coarse quads without data, seen at a grazing angle.
    let erzurum = project("erzurum");
    let mut r = renderer(&erzurum, |p| p.visuals.background = magenta);
    let image = draw(&mut r, &cam(39.2, 40.1, 6_000.0, 40.0, -12.0), 256, 192, DrawMode::Colour);
    let levels: std::collections::BTreeSet<u8> = r.drawn().iter().map(|q| q.level).collect();
    assert!(levels.len() >= 3, "{levels:?}");
    assert_eq!(holes(&image, magenta), 0, "Erzurum: background inside the terrain (levels {levels:?})");
}

#[test]
fn patches_are_culled_and_strided_without_cracks_and_draw_the_same_surface() {
    // Each drawn quad as 8 × 8 patches, culled on their own and drawn at the stride their nearest
    // point needs, against the same quads drawn whole (every patch at stride 1).
    let magenta = [255, 0, 255, 255];
    let erzurum = project("erzurum");
    let mut r = renderer(&erzurum, |p| p.visuals.background = magenta);
    for (name, camera) in
        [("down-50km", cam(39.5, 40.5, 50_000.0, 0.0, -90.0)), ("oblique-6km", cam(39.2, 40.1, 6_000.0, 40.0, -12.0))]
    {
        r.set_adaptive_patches(false);
        let whole_stats = r.settle(&camera, 256, 192, Duration::from_secs(120));
        let whole = r.render_image(DrawMode::Probe).unwrap();
        r.set_adaptive_patches(true);
        let stats = r.settle(&camera, 256, 192, Duration::from_secs(120));
        let adaptive = r.render_image(DrawMode::Probe).unwrap();
        assert_eq!(stats.selection.quads, whole_stats.selection.quads, "{name}: the same quads");
        let p = &stats.patches;
        let strides: std::collections::BTreeSet<u32> = p.patches.iter().map(|x| x.stride).collect();
        assert!(
            p.culled_frustum + p.culled_horizon > 0 || strides.iter().any(|&s| s > 1),
            "{name}: nothing culled or coarsened: {strides:?}"
        );
        assert!(
            stats.triangles * 3 < whole_stats.triangles * 2,
            "{name}: {} vs {}",
            stats.triangles,
            whole_stats.triangles
        );
        let n = holes(&adaptive, magenta);
        if n > 0 {
            terrafuse::cli::write_png(&out_dir().join(format!("patches-{name}.cracks.png")), &adaptive).unwrap();
        }
        assert_eq!(n, 0, "{name}: {n} background pixels inside the terrain");
        // The same surface within the pixel error: each pixel's surface point lies above or
        // below the finest mesh's by δ, which seen from the eye is δ·f/d pixels (the error the
        // selection bounds by τ; on slopes seen at grazing angles the two rays' hits are farther
        // apart than δ, so the bound is held by nearly all pixels, not each), and terrain and sky
        // swap at almost no pixel.
        let (ws, wi) = (whole.surface.as_ref().unwrap(), whole.ids.as_ref().unwrap());
        let (s, i) = (adaptive.surface.as_ref().unwrap(), adaptive.ids.as_ref().unwrap());
        let cam_pos = r.last_camera().unwrap().position;
        let focal = r.last_camera().unwrap().focal_px(192);
        let tau = r.scene().detail.max_pixel_error;
        let (mut moved, mut swapped) = (Vec::new(), 0usize);
        for k in 0..ws.len() {
            match (wi[k][0] > 0, i[k][0] > 0) {
                (true, true) => {
                    let a = glam::DVec3::new(f64::from(ws[k][0]), f64::from(ws[k][1]), f64::from(ws[k][2]));
                    let b = glam::DVec3::new(f64::from(s[k][0]), f64::from(s[k][1]), f64::from(s[k][2]));
                    let up = (cam_pos + a).normalize();
                    moved.push((a - b).dot(up).abs() / a.length() * focal);
                }
                (false, false) => {}
                _ => swapped += 1,
            }
        }
        moved.sort_by(f64::total_cmp);
        assert!(moved.len() > 10_000, "{name}: {} terrain pixels", moved.len());
        let median = moved[moved.len() / 2];
        let p95 = moved[moved.len() * 95 / 100];
        let over_1px = moved.iter().filter(|&&m| m > tau).count();
        assert!(stats.max_error_px <= tau + 1e-9, "{name}: max_error_px {}", stats.max_error_px);
        assert!(median < 0.25 * tau, "{name}: the surface moved {median} px at the median pixel");
        assert!(p95 < tau, "{name}: the surface moved {p95} px at the 95th percentile");
        assert!(swapped * 1000 <= ws.len(), "{name}: {swapped} pixels swap terrain and sky");
        eprintln!(
            "{name}: {} → {} triangles, strides {strides:?}, culled {} + {}, moved {median:.4} px at the median, {p95:.3} at the 95th percentile, {over_1px} pixels > τ, swapped {swapped}",
            whole_stats.triangles, stats.triangles, p.culled_frustum, p.culled_horizon
        );
    }
}

#[test]
fn every_drawn_vertex_lies_in_its_patch_box_at_its_stride() {
    // Each patch is bounded by the heights it draws at its stride (its own data, the levels above
    // that the stride shows and morphs toward), read from its tiles' block ranges: a box that holds
    // every vertex drawn, and much tighter than the quad's whole range over rough terrain.
    let views = [
        ("erzurum", "30 km, 45°", cam(39.3, 40.42, 30_000.0, 0.0, -45.0), true),
        ("erzurum", "6 km, oblique", cam(39.2, 40.1, 6_000.0, 40.0, -12.0), true),
        // A brushed layer over the Moon, and an eroded layer with its drawn difference.
        ("moon-brushing", "sculpt", cam(-7.0, 45.0, 160_000.0, 0.0, -50.0), false),
        ("erzurum-erosion", "eroded", cam(39.385, 40.235, 7_000.0, 0.0, -50.0), false),
    ];
    for (project_name, name, camera, rough) in views {
        // A fine pixel error: many vertices at every stride.
        let mut r = renderer(&project(project_name), |p| p.detail.max_pixel_error = 0.1);
        let image = draw(&mut r, &camera, 320, 240, DrawMode::Points);
        let (surface, ids) = (image.surface.unwrap(), image.ids.unwrap());
        let eye = r.last_camera().unwrap().position;
        let (mut checked, mut outside) = (0usize, Vec::new());
        for (k, id) in ids.iter().enumerate() {
            if id[0] == 0 || id[3] & 2 != 0 {
                continue; // nothing drawn here, or a skirt vertex
            }
            let (index, i, j, stride) = (
                (id[0] - 1) as usize,
                (id[1] - PROBE_ORIGIN) / PROBE_SUBSAMPLES,
                (id[2] - PROBE_ORIGIN) / PROBE_SUBSAMPLES,
                id[3] >> 2,
            );
            let rel = glam::DVec3::new(f64::from(surface[k][0]), f64::from(surface[k][1]), f64::from(surface[k][2]));
            let p = eye + rel;
            // f32 camera-relative positions: 10⁻⁶ of the distance, and a centimetre.
            let tolerance = 1e-6 * rel.length() + 0.01;
            // A vertex on a patch edge belongs to the patches on both sides.
            let sides = |a: u32| [a / 32, a.saturating_sub(1) / 32].map(|p| p.min(7));
            let inside = sides(i).iter().any(|&px| {
                sides(j).iter().any(|&py| {
                    r.patch_box(index, px, py, stride).is_some_and(|b| {
                        let local = b.axes.map(|a| (p - b.center_ecef).dot(a).abs());
                        (0..3).all(|n| local[n] <= b.half_extents_m[n] + tolerance)
                    })
                })
            });
            checked += 1;
            if !inside {
                outside.push((index, i, j, stride));
            }
        }
        assert!(checked > 5_000, "{name}: {checked} vertices");
        assert!(
            outside.is_empty(),
            "{name}: {} of {checked} vertices outside their patch box: {:?}",
            outside.len(),
            &outside[..outside.len().min(5)]
        );
        if !rough {
            eprintln!("{name}: {checked} vertices inside their patch boxes");
            continue;
        }
        // Tighter than the quads' ranges: the median patch spans at most half its quad's range.
        let drawn = r.drawn().to_vec();
        let mut ratios = Vec::new();
        for p in &r.patches().patches.clone() {
            let quad = drawn[p.quad as usize];
            let (lo, hi) = r.quad_height_range(quad);
            let b = r.patch_box(p.quad as usize, p.px, p.py, p.stride).unwrap();
            if hi - lo > 100.0 {
                ratios.push((b.height_range_m.1 - b.height_range_m.0) / f64::from(hi - lo));
            }
        }
        ratios.sort_by(f64::total_cmp);
        assert!(ratios.len() > 20, "{name}: {} patches over rough terrain", ratios.len());
        let median = ratios[ratios.len() / 2];
        assert!(median < 0.5, "{name}: a patch's range is {median} of its quad's at the median");
        eprintln!(
            "{name}: {checked} vertices inside their patch boxes; patch span / quad span {median:.3} at the median"
        );
    }
}

/// Compares with `tests/reference/NAME.png`: mean difference ≤ 1 level per channel and at most
/// 0.5 % of pixels off by more than 24 levels. A failing run writes NAME.new.png and
/// NAME.diff.png to the test output folder's `render/`; UPDATE_SNAPSHOTS=1 writes the reference instead.
fn check_reference(name: &str, image: &RenderedImage) {
    let reference = repo_path(&format!("tests/reference/{name}.png"));
    if std::env::var_os("UPDATE_SNAPSHOTS").is_some() {
        std::fs::create_dir_all(reference.parent().unwrap()).unwrap();
        terrafuse::cli::write_png(&reference, image).unwrap();
        return;
    }
    let old = image::open(&reference)
        .unwrap_or_else(|e| panic!("{}: {e} (create it with UPDATE_SNAPSHOTS=1)", reference.display()))
        .to_rgba8();
    assert_eq!((old.width(), old.height()), (image.width, image.height), "{name}: size");
    let mut diff = Vec::with_capacity(image.rgba.len());
    let (mut sum, mut big) = (0f64, 0usize);
    for (a, b) in image.rgba.chunks(4).zip(old.as_raw().chunks(4)) {
        let d: Vec<u8> = (0..3).map(|c| a[c].abs_diff(b[c])).collect();
        sum += d.iter().map(|&v| f64::from(v)).sum::<f64>() / 3.0;
        let m = *d.iter().max().unwrap();
        if m > 24 {
            big += 1;
        }
        diff.extend_from_slice(&[m.saturating_mul(4), m.saturating_mul(4), m.saturating_mul(4), 255]);
    }
    let pixels = (image.width * image.height) as f64;
    let (mean, share) = (sum / pixels, big as f64 / pixels);
    if mean > 1.0 || share > 0.005 {
        let dir = out_dir();
        terrafuse::cli::write_png(&dir.join(format!("{name}.new.png")), image).unwrap();
        let d = RenderedImage { rgba: diff, surface: None, ids: None, gpu_ms: None, ..image.clone() };
        terrafuse::cli::write_png(&dir.join(format!("{name}.diff.png")), &d).unwrap();
        panic!(
            "{name}: mean difference {mean:.3}, {:.3} % of pixels off by > 24; see {}",
            share * 100.0,
            dir.display()
        );
    }
}

#[test]
fn sample_views_match_their_reference_images() {
    let moon = project("moon-lola");
    let mut r = renderer(&moon, |_| {});
    let p = Project::load(&moon).unwrap();
    let image = draw(&mut r, &p.view(Some("globe")).unwrap(), 320, 256, DrawMode::Colour);
    check_reference("moon-globe", &image);
    let erzurum = project("erzurum");
    let mut r = renderer(&erzurum, |_| {});
    let p = Project::load(&erzurum).unwrap();
    for view in ["30km", "2km"] {
        let image = draw(&mut r, &p.view(Some(view)).unwrap(), 320, 240, DrawMode::Colour);
        check_reference(&format!("erzurum-{view}"), &image);
    }
}

#[test]
fn the_render_command_writes_the_png_and_reports_what_it_drew() {
    let moon = project("moon-lola");
    let out = out_dir().join("cli-moon.png");
    let _ = std::fs::remove_file(&out);
    let o = terrafuse(
        &[
            "render",
            moon.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--width",
            "200",
            "--height",
            "150",
            "--view",
            "tycho",
        ],
        "",
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    for expected in
        ["device: ", "quads: ", "L1:", "patches: ", "at stride ", "triangles: ", "cpu: selection ", "gpu: ", "wrote "]
    {
        assert!(stdout.contains(expected), "missing '{expected}' in:\n{stdout}");
    }
    let png = image::open(&out).unwrap();
    assert_eq!((png.width(), png.height()), (200, 150));
    // A finer threshold draws more of the finest data: count the deepest level's quads.
    let erzurum = project("erzurum");
    let deepest = |threshold: &str| -> (u8, usize) {
        let args =
            ["render", erzurum.to_str().unwrap(), "--out", out.to_str().unwrap(), "--width", "200", "--height", "150"];
        let o =
            terrafuse(&[&args[..], &["--camera", "39.3,40.42,60000,0,-50", "--lod-threshold", threshold]].concat(), "");
        let s = String::from_utf8_lossy(&o.stdout).to_string();
        let line = s.lines().find(|l| l.starts_with("quads: ")).unwrap_or_else(|| panic!("{s}"));
        let last = line.split_whitespace().rfind(|w| w.starts_with('L')).unwrap().trim_end_matches([')', ',']);
        let (level, count) = last[1..].split_once(':').unwrap();
        (level.parse().unwrap(), count.parse().unwrap())
    };
    let (fine, coarse) = (deepest("0.5"), deepest("8"));
    assert!(fine.0 > coarse.0 || (fine.0 == coarse.0 && fine.1 > coarse.1), "t 0.5: {fine:?}, t 8: {coarse:?}");

    // Bad input: named, never a panic, nothing written.
    let missing = out_dir().join("missing.json");
    let bad_view = terrafuse(
        &[
            "render",
            moon.to_str().unwrap(),
            "--out",
            common::out_path("compare/x.png").to_str().unwrap(),
            "--view",
            "nowhere",
        ],
        "",
    );
    assert!(!bad_view.status.success());
    assert!(
        String::from_utf8_lossy(&bad_view.stderr)
            .contains("no view 'nowhere'; the project has: globe, north-pole, tycho")
    );
    let bad_camera = terrafuse(
        &[
            "render",
            moon.to_str().unwrap(),
            "--out",
            common::out_path("compare/x.png").to_str().unwrap(),
            "--camera",
            "95,0,1000,0,-90",
        ],
        "",
    );
    assert!(String::from_utf8_lossy(&bad_camera.stderr).contains("latitude 95"));
    let no_file = terrafuse(
        &["render", missing.to_str().unwrap(), "--out", common::out_path("compare/x.png").to_str().unwrap()],
        "",
    );
    assert!(String::from_utf8_lossy(&no_file.stderr).contains("missing.json: cannot read"));
    let mut p = Project::load(&moon).unwrap();
    let data = p.layers[0].as_dataset_mut().unwrap();
    data.store = out_dir().join("absent.gpkg");
    data.source = None;
    let orphan = out_dir().join("orphan.json");
    p.save(&orphan).unwrap();
    let o = terrafuse(
        &["render", orphan.to_str().unwrap(), "--out", common::out_path("compare/x.png").to_str().unwrap()],
        "",
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("orphan.json") && e.contains("absent.gpkg") && e.contains("no source"), "{e}");
    assert!(!out_dir().join("absent.gpkg").exists());
}

/// `frames.csv` as rows of named fields.
fn read_frames(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines.map(|l| header.iter().cloned().zip(l.split(',').map(String::from)).collect()).collect()
}

#[test]
fn a_flight_writes_its_frames_and_geomorphing_hides_the_changes_of_density() {
    // Down from 40 km to 4 km over the Erzurum tile at t = 2, where level and stride changes
    // show: with geomorphing and without.
    let erzurum = project("erzurum");
    let flight = "39.3,40.3,40000,0,-90;39.4,40.45,4000,30,-20";
    let fly = |dir: &str, extra: &[&str]| {
        let out = out_dir().join(dir);
        let _ = std::fs::remove_dir_all(&out);
        let mut args = vec![
            "render",
            erzurum.to_str().unwrap(),
            "--flight",
            flight,
            "--frames",
            "30",
            "--width",
            "320",
            "--height",
            "256",
            "--lod-threshold",
            "2",
            "--out-dir",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = terrafuse(&args, "");
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
        assert!(stdout.contains("flight: 30 frames of 320x256 at t = 2"), "{stdout}");
        for k in 0..30 {
            let png = image::open(out.join(format!("frame_{k:04}.png"))).unwrap();
            assert_eq!((png.width(), png.height()), (320, 256));
        }
        let header = std::fs::read_to_string(out.join("frames.csv")).unwrap();
        assert!(
            header
                .starts_with("frame,quads,patches,triangles,terrain_pixels,levels,pop_px,max_error_px,gpu_ms,cpu_ms\n"),
            "{header}"
        );
        read_frames(&out.join("frames.csv"))
    };
    let morphed = fly("flight-morph", &[]);
    let popping = fly("flight-pop", &["--no-geomorph"]);
    assert_eq!(morphed.len(), 30);
    let pop = |rows: &[std::collections::HashMap<String, String>]| -> Vec<f64> {
        rows.iter().map(|r| r["pop_px"].parse().unwrap()).collect()
    };
    let (with, without) = (pop(&morphed), pop(&popping));
    assert_eq!(with[0], 0.0, "the first frame has nothing to pop from");
    // The same frames are drawn (morphing moves vertices and hangs skirts between patches that
    // morph differently, not what is selected).
    for (a, b) in morphed.iter().zip(&popping) {
        for field in ["quads", "patches", "levels"] {
            assert_eq!(a[field], b[field], "frame {}: {field}", a["frame"]);
        }
        assert!(a["terrain_pixels"].parse::<usize>().unwrap() > 0);
    }
    let worst = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    // Without morphing, each change of stride jumps by up to the error bound (τ = 1 px).
    assert!(worst(&without) > 0.3, "density changes without morphing pop: {without:?}");
    // With it, a change of stride draws what was drawn before (0 up to the rounding of the f64
    // evaluation), even where the coarser patch was itself morphing, while the camera moves by
    // less than the band's start (10 % a frame here): the issue's 0.1 px in every frame whose
    // quads keep their levels. Where a quad is split or merged, the child's patches morph by
    // reaches from their own errors, not the parent's, so a stride's morph state changes, by less
    // than both meshes' error, at most τ (1 px) each side of the data: what pops there is far
    // less than without (docs/rendering.md).
    for (k, row) in morphed.iter().enumerate().skip(1) {
        if row["levels"] == morphed[k - 1]["levels"] {
            assert!(with[k] <= 0.1, "frame {k} changed strides only and popped: {with:?}");
        }
    }
    assert!(worst(&with) <= 1.0, "morphing leaves pops: {with:?}");
    let total = |v: &[f64]| v.iter().sum::<f64>();
    assert!(total(&with) * 5.0 < total(&without), "morphing hides most: {with:?} against {without:?}");
    let still = with.iter().filter(|&&p| p <= 0.01).count();
    assert!(still * 4 >= with.len() * 3, "most frames do not pop at all: {with:?}");
    for row in &morphed {
        let e: f64 = row["max_error_px"].parse().unwrap();
        assert!(e <= 1.0 + 1e-9, "frame {}: max_error_px {e}", row["frame"]);
    }
    // Bad flights are refused by name.
    let o = terrafuse(
        &["render", erzurum.to_str().unwrap(), "--flight", "39,40,x,0,-90;39,40,100,0,-90", "--out-dir", "/tmp/x"],
        "",
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("waypoint 1 '39,40,x,0,-90'"), "{stderr}");
    let o = terrafuse(&["render", erzurum.to_str().unwrap(), "--flight", flight], "");
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--out-dir"));
}

#[test]
fn quads_wait_for_their_data_and_the_parent_stands_in() {
    let path = project("moon-lola");
    let mut r = renderer(&path, |_| {});
    let camera = cam(-43.0, -11.0, 200_000.0, 0.0, -60.0);
    // The first frame has nothing on the GPU: it draws nothing and asks for the roots.
    let first = r.prepare(&camera, 200, 150);
    assert!(first.selection.quads.is_empty() && first.pending > 0, "{first:?}");
    // Frames never block: each one draws what has arrived, coarser quads standing in.
    let mut previous_finest = 0;
    for _ in 0..400 {
        let s = r.prepare(&camera, 200, 150);
        let finest = s.selection.quads.iter().map(|q| q.level).max().unwrap_or(0);
        assert!(finest + 1 >= previous_finest, "refinement only moves forward");
        previous_finest = finest;
        if s.pending == 0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let settled = r.prepare(&camera, 200, 150);
    assert_eq!(settled.pending, 0);
    assert!(settled.selection.quads.iter().any(|q| q.level >= 1), "{:?}", settled.selection.quads);
    let root_face = QuadId::root(Face::Front);
    assert!(!settled.selection.quads.contains(&root_face) || settled.selection.quads.len() < 6);
}

#[test]
fn datasets_fill_each_other_and_show_below_their_finest_level() {
    use terrafuse::ecm::grid::upsample;
    use terrafuse::layers::{LayerTiles, compose_quad};
    use terrafuse::scene::loader::read_source;
    use terrafuse::store::Store;
    // Both Moon grids: the polar one (levels 0–3) on top of the global one (levels 0–1).
    let mut p = Project::load(&repo_path("projects/moon-lola.json")).unwrap();
    let stores = common::store_dir(&out_dir(), "moon-fusion", &serde_json::to_string(&p.layers).unwrap());
    p.layers.retain(|l| l.is_data());
    for layer in &mut p.layers {
        layer.extent = None; // plain `over`: the polar samples win exactly where they exist
        layer.feather_m = 0.0;
        let d = layer.as_dataset_mut().unwrap();
        d.store = stores.join("moon-fusion.gpkg");
        if let Some(s) = &mut d.source {
            s.files = s.files.iter().map(|f| repo_path("projects").join(f)).collect();
        }
    }
    let (scene, _) = Scene::open(&p).unwrap();
    let north_layer = scene.stack.layers.iter().position(|l| l.spec.name == "lola_north").unwrap();
    let global_layer = scene.stack.layers.iter().position(|l| l.spec.name == "lola_global").unwrap();
    assert!(north_layer > global_layer, "the polar grid is above the global one");
    let north = &scene.datasets[scene.dataset_of_layer(north_layer).unwrap()];
    let global = &scene.datasets[scene.dataset_of_layer(global_layer).unwrap()];
    assert_eq!((north.finest_level, global.finest_level), (3, 1));
    let store = Store::open_read_only(&north.store).unwrap();
    let fuse = |quad: QuadId| {
        let plan = scene.plan(quad);
        let tiles: Vec<Vec<f32>> = plan
            .layers
            .iter()
            .map(|l| {
                let d = &scene.datasets[scene.dataset_of_layer(l.index).unwrap()];
                read_source(quad, d, &mut None).unwrap().grid
            })
            .collect();
        compose_quad(&scene.stack, &plan, &|k| LayerTiles { raw: Some(&tiles[k][..]), edge_m: None })
    };
    // A level-2 quad the polar grid only partly covers: the global grid (upsampled from level 1)
    // fills the rest, and the polar samples stay as they are.
    let partial = north.present[2]
        .iter()
        .copied()
        .find(|q| store.read_grid(&north.dataset, *q).unwrap().unwrap().values.iter().any(|h| h.is_nan()))
        .expect("a level-2 quad at the polar grid's edge");
    let polar = store.read_grid(&north.dataset, partial).unwrap().unwrap();
    let fused = fuse(partial);
    assert!(fused.iter().all(|h| h.is_finite()), "{partial}: no data left");
    for (f, n) in fused.iter().zip(&polar.values) {
        if !n.is_nan() {
            assert_eq!(f.to_bits(), n.to_bits());
        }
    }
    // A level-3 quad on the equator, outside the polar grid: the global grid's level-1 ancestor,
    // upsampled.
    let equator = QuadId { face: Face::Front, level: 3, x: 3, y: 4 };
    assert!(!north.covers(equator) && global.covers(equator));
    let ancestor = global.source_quad(equator);
    assert_eq!(ancestor.level, 1);
    let coarse = store.read_grid(&global.dataset, ancestor).unwrap().unwrap();
    let fused = fuse(equator);
    let expected = upsample(&coarse.values, ancestor, equator);
    assert!(fused.iter().zip(&expected).all(|(a, b)| a.to_bits() == b.to_bits()));
    assert!(fused.iter().all(|h| h.is_finite()));
}

#[test]
fn hillshade_and_isolines_on_the_gpu_are_their_cpu_twins() {
    use terrafuse::gpu::shading::{ShadingProbe, hillshade, isoline_coverage, probe, slope_aspect};
    let ctx = GpuContext::headless().unwrap();
    let mut rng = 0x1234_5678u32;
    let mut next = || {
        rng = terrafuse::maths::pcg(rng);
        (rng >> 8) as f32 / (1u32 << 24) as f32
    };
    let mut probes = Vec::new();
    for _ in 0..4096 {
        let up = glam::Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize();
        let n = (up + 0.6 * glam::Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5)).normalize();
        probes.push(ShadingProbe {
            normal: [n.x, n.y, n.z, 0.0],
            up: [up.x, up.y, up.z, 0.0],
            sun: [next() * std::f32::consts::TAU, 0.05 + next() * 1.5, next(), 0.0],
            iso: [next() * 40.0 - 20.0, 0.002 + next() * 0.3, 0.2 + next() * 3.0, 1.0],
            spacing: [if next() < 0.5 { 1.0 } else { 5.0 }, 0.5 + 4.0 * next(), 0.0, 0.0],
        });
    }
    let gpu = probe(&ctx, &probes).unwrap();
    let (mut worst_shade, mut worst_iso, mut worst_slope, mut worst_aspect) = (0f32, 0f32, 0f32, 0f32);
    for (p, g) in probes.iter().zip(&gpu) {
        let v = |a: [f32; 4]| glam::Vec3::new(a[0], a[1], a[2]);
        let shade = hillshade(v(p.normal), v(p.up), p.sun[0], p.sun[1], p.sun[2]);
        let iso = isoline_coverage(p.iso[0], p.iso[1], p.iso[2], p.iso[3], p.spacing[0]);
        // Relative to the value: the GPU's sin, cos and division may differ by a few ulps.
        worst_shade = worst_shade.max((g[0] - shade).abs() / shade.abs().max(1.0));
        worst_iso = worst_iso.max((g[1] - iso).abs());
        let [slope, aspect] = slope_aspect(v(p.normal), v(p.up), p.spacing[1]);
        worst_slope = worst_slope.max((g[2] - slope).abs());
        // Aspect turns freely on the flat: compared where the slope passes 1°.
        if slope > 1.0 {
            let d = (g[3] - aspect).abs();
            worst_aspect = worst_aspect.max(d.min(360.0 - d));
        }
    }
    // Tolerances: WGSL's sin/cos on lavapipe and GPUs are accurate to ~2⁻¹⁶ absolute over the
    // sun's angles; coverage is a clamp of differences of values of order 10³ pixels.
    assert!(worst_shade < 1e-4, "hillshade: GPU − CPU up to {worst_shade}");
    assert!(worst_iso < 2e-3, "isoline coverage: GPU − CPU up to {worst_iso}");
    // Slope and aspect: atan and atan2 to a few ulps of degrees (≤ 360 · 2⁻²⁰ near 360°).
    assert!(worst_slope < 1e-3 && worst_aspect < 2e-2, "slope {worst_slope}°, aspect {worst_aspect}°");
    eprintln!(
        "shading probe: hillshade within {worst_shade:.2e}, isolines within {worst_iso:.2e}, slope {worst_slope:.2e}°, aspect {worst_aspect:.2e}°"
    );
}

#[test]
fn hillshade_of_a_plane_is_gdaldems() {
    // A tilted plane written as a GeoTIFF in metres (EPSG:32637), shaded by gdaldem: Horn's
    // gradient is exact on a plane, so the centre pixel is 1 + 254·cos(angle to the sun),
    // rounded, which is the CPU hillshade at strength 1 times sin(elevation).
    let dir = common::scratch("hillshade-gdaldem");
    let (gx, gy) = (0.35f64, -0.2f64); // dz/dx east, dz/dy north
    let (azimuth_deg, altitude_deg) = (315.0f64, 45.0f64);
    let mut xyz = String::new();
    for j in 0..5 {
        for i in 0..5 {
            let (x, y) = (500_000.0 + 10.0 * f64::from(i), 4_400_000.0 - 10.0 * f64::from(j));
            xyz.push_str(&format!("{x} {y} {}\n", 1000.0 + gx * (x - 500_000.0) + gy * (y - 4_400_000.0)));
        }
    }
    let xyz_path = dir.join("plane.xyz");
    std::fs::write(&xyz_path, xyz).unwrap();
    let tif = dir.join("plane.tif");
    let shade = dir.join("shade.tif");
    common::run_tool(
        "gdal_translate",
        &["-q", "-a_srs", "EPSG:32637", xyz_path.to_str().unwrap(), tif.to_str().unwrap()],
        "",
    );
    common::run_tool(
        "gdaldem",
        &[
            "hillshade",
            "-q",
            "-az",
            &azimuth_deg.to_string(),
            "-alt",
            &altitude_deg.to_string(),
            tif.to_str().unwrap(),
            shade.to_str().unwrap(),
        ],
        "",
    );
    let out = common::run_tool("gdallocationinfo", &["-valonly", shade.to_str().unwrap(), "2", "2"], "");
    let gdal: f64 = out.trim().parse().unwrap();
    // The normal of z = gx·x + gy·y in east-north-up, on the equator at longitude 0 (up = x,
    // east = y, north = z).
    let n = glam::DVec3::new(1.0, -gx, -gy).normalize();
    let factor = terrafuse::gpu::shading::hillshade(
        n.as_vec3(),
        glam::Vec3::X,
        azimuth_deg.to_radians() as f32,
        altitude_deg.to_radians() as f32,
        1.0,
    );
    let ours = 1.0 + 254.0 * f64::from(factor) * altitude_deg.to_radians().sin();
    assert!((ours - gdal).abs() <= 1.0, "ours {ours:.2} vs gdaldem {gdal}");
}

#[test]
fn colour_by_slope_and_aspect_draws_a_planes_slope_and_aspect_whatever_the_exaggeration() {
    // A plane rising 0.35 m/m west and 0.2 m/m north (z = 1500 − 0.35·east + 0.2·north in the
    // local metres of 40.1°E 39.6°N), seen from straight above with lighting and isolines off
    // and heights exaggerated twice: its slope is atan(√(0.35² + 0.2²)) = 21.96° and it faces
    // east-south-east, 119.7°, whatever the exaggeration.
    let dir = common::scratch("colour-by-slope");
    let (ge, gn) = (-0.35f64, 0.2f64);
    let (m_lat, m_lon) = (111_034.0f64, 111_320.0 * 39.6f64.to_radians().cos());
    let mut xyz = String::new();
    for j in 0..=200 {
        for i in 0..=200 {
            let (lon, lat) = (40.0 + 0.001 * f64::from(i), 39.7 - 0.001 * f64::from(j));
            let z = 1500.0 + ge * (lon - 40.1) * m_lon + gn * (lat - 39.6) * m_lat;
            xyz.push_str(&format!("{lon:.3} {lat:.3} {z:.4}\n"));
        }
    }
    std::fs::write(dir.join("plane.xyz"), xyz).unwrap();
    common::run_tool(
        "gdal_translate",
        &[
            "-q",
            "-a_srs",
            "EPSG:4326",
            "-ot",
            "Float32",
            dir.join("plane.xyz").to_str().unwrap(),
            dir.join("plane.tif").to_str().unwrap(),
        ],
        "",
    );
    let slope = ge.hypot(gn).atan().to_degrees();
    let aspect = (-ge).atan2(-gn).to_degrees().rem_euclid(360.0);
    for (by, range, value) in [("slope", [0.0, 45.0], slope), ("aspect", [0.0, 360.0], aspect)] {
        let project = format!(
            r#"{{"format": "terrafuse-project", "version": 4, "body": "wgs84",
            "layers": [{{"name": "plane", "kind": "dataset", "store": "plane.gpkg", "source": {{"files": ["plane.tif"]}}}}],
            "visuals": {{"colour_map": {{"preset": "hypsometric", "range_m": [{}, {}], "by": "{by}"}},
              "isolines": {{"enabled": false}}, "lighting": {{"enabled": false}}, "exaggeration": 2.0}},
            "views": {{"top": {{"lat": 39.6, "lon": 40.1, "alt": 6000.0, "heading": 0.0, "pitch": -90.0, "fov": 40.0}}}},
            "default_view": "top"}}"#,
            range[0], range[1]
        );
        let p = dir.join(format!("{by}.json"));
        std::fs::write(&p, project).unwrap();
        let out = dir.join(format!("{by}.png"));
        let args = ["render", p.to_str().unwrap(), "--out", out.to_str().unwrap(), "--width", "200", "--height", "150"];
        let run = common::terrafuse(&args, "");
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let image = image::open(&out).unwrap().to_rgba8();
        let ramp = terrafuse::colour::Ramp::preset("hypsometric", (range[0], range[1]), [0, 0, 0, 255]).unwrap();
        let want = ramp.colour_at(value);
        for (x, y) in [(100, 75), (60, 50), (140, 100)] {
            let got = image.get_pixel(x, y).0;
            let worst = (0..3).map(|c| (f64::from(got[c]) - want[c]).abs()).fold(0.0, f64::max);
            // The ramp changes by ≤ 6 units a degree here; the f32 normal is good to 0.1°.
            assert!(worst <= 3.0, "{by} at ({x}, {y}): {got:?}, the ramp at {value:.2}° is {want:?}");
        }
    }
}

#[test]
fn colour_by_curvature_draws_a_domes_curvature_per_pixel_whatever_the_exaggeration() {
    // A dome of radius R = 20 km, z = 1500 − (e² + n²)/(2R) in the local metres of 40.1°E 39.6°N,
    // imported with cubic resampling (exact for a quadratic): its curvature −2(z_xx + z_yy) is
    // 4/R per metre, 0.02 per 100 m, at every sample whatever the spacing drawn, and the ramp
    // (viridis over 0–0.04) shows it in its middle; a plane's TPI and curvature are 0.
    let dir = common::scratch("colour-by-curvature");
    let r = 20_000.0f64;
    let (m_lat, m_lon) = (111_034.0f64, 111_320.0 * 39.6f64.to_radians().cos());
    let mut dome = String::new();
    let mut plane = String::new();
    for j in 0..=200 {
        for i in 0..=200 {
            let (lon, lat) = (40.0 + 0.001 * f64::from(i), 39.7 - 0.001 * f64::from(j));
            let (e, n) = ((lon - 40.1) * m_lon, (lat - 39.6) * m_lat);
            dome.push_str(&format!("{lon:.3} {lat:.3} {:.5}\n", 1500.0 - (e * e + n * n) / (2.0 * r)));
            plane.push_str(&format!("{lon:.3} {lat:.3} {:.5}\n", 1500.0 - 0.35 * e + 0.2 * n));
        }
    }
    let viridis = |range: [f64; 2]| terrafuse::colour::Ramp::preset("viridis", (range[0], range[1]), [0, 0, 0, 255]);
    for (name, xyz, by, range, want, tolerance) in [
        ("dome", &dome, "curvature", [0.0, 0.04], 400.0 / r, 0.02 * 400.0 / r),
        ("plane", &plane, "curvature", [-0.04, 0.04], 0.0, 2e-4),
        ("plane", &plane, "tpi", [-0.1, 0.1], 0.0, 5e-3),
    ] {
        std::fs::write(dir.join(format!("{name}.xyz")), xyz).unwrap();
        let tif = dir.join(format!("{name}.tif"));
        let xyz = dir.join(format!("{name}.xyz"));
        common::run_tool(
            "gdal_translate",
            &["-q", "-a_srs", "EPSG:4326", "-ot", "Float32", xyz.to_str().unwrap(), tif.to_str().unwrap()],
            "",
        );
        let store = dir.join(format!("{name}.gpkg"));
        if !store.exists() {
            let args = ["import", tif.to_str().unwrap(), "--store", store.to_str().unwrap(), "--resampling", "cubic"];
            let run = common::terrafuse(&[&args[..], &["--body", "wgs84", "--quiet"]].concat(), "");
            assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        }
        let project = format!(
            r#"{{"format": "terrafuse-project", "version": 4, "body": "wgs84",
            "layers": [{{"name": "{name}", "kind": "dataset", "store": "{name}.gpkg"}}],
            "visuals": {{"colour_map": {{"preset": "viridis", "range_m": [{}, {}], "by": "{by}"}},
              "isolines": {{"enabled": false}}, "lighting": {{"enabled": false}}, "exaggeration": 2.0}},
            "views": {{"top": {{"lat": 39.6, "lon": 40.1, "alt": 6000.0, "heading": 0.0, "pitch": -90.0, "fov": 40.0}}}},
            "default_view": "top"}}"#,
            range[0], range[1]
        );
        let p = dir.join(format!("{name}-{by}.json"));
        std::fs::write(&p, project).unwrap();
        let out = dir.join(format!("{name}-{by}.png"));
        let args = ["render", p.to_str().unwrap(), "--out", out.to_str().unwrap(), "--width", "200", "--height", "150"];
        let run = common::terrafuse(&args, "");
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let image = image::open(&out).unwrap().to_rgba8();
        let ramp = viridis(range).unwrap();
        // The value whose ramp colour is nearest the pixel's (viridis is one-to-one).
        let value_of = |rgb: [u8; 4]| {
            (0..=4000)
                .map(|k| range[0] + (range[1] - range[0]) * f64::from(k) / 4000.0)
                .min_by(|a, b| {
                    let d = |v: f64| {
                        let c = ramp.colour_at(v);
                        (0..3).map(|m| (c[m] - f64::from(rgb[m])).powi(2)).sum::<f64>()
                    };
                    d(*a).total_cmp(&d(*b))
                })
                .unwrap()
        };
        for (x, y) in [(100, 75), (30, 20), (170, 130), (60, 110)] {
            let got = value_of(image.get_pixel(x, y).0);
            assert!(
                (got - want).abs() <= tolerance + (range[1] - range[0]) / 250.0,
                "{name} {by} at ({x}, {y}): {got:.5}, want {want:.5}"
            );
        }
    }
    // The workstation's *data* range of the dome's curvature over its finest quads: the constant
    // 4/R, symmetric about 0.
    let store = terrafuse::store::Store::open(&dir.join("dome.gpkg")).unwrap();
    let record = store.datasets().unwrap().remove(0);
    let quads: Vec<_> = store.data_quads(&record.name, record.settings.finest_level).unwrap().into_iter().collect();
    let project = terrafuse::project::Project::load(&dir.join("dome-curvature.json")).unwrap();
    let (scene, _) = terrafuse::scene::Scene::open(&project).unwrap();
    let attribute = terrafuse::attributes::Attribute::Curvature;
    let (lo, hi) = terrafuse::compare::attribute_range(&scene, &quads, attribute, 4).unwrap().unwrap();
    assert!(lo == -hi && (hi - 400.0 / r).abs() < 0.02 * 400.0 / r, "curvature range {lo} … {hi}");
}

#[test]
fn isolines_of_a_tilted_plane_fall_on_their_true_place_and_are_drawn_their_width() {
    // A plane linear in longitude and latitude, z = 1500 + 0.3·east + 0.15·north metres (local
    // metres of 40.1°E 39.6°N), imported with cubic resampling (exact for it), with isolines every
    // 100 m, 2 px wide, in pure red over a grey ramp, lighting off. Its isoline of height v is the
    // line of points (lon, lat, v): projected with the f64 camera, that is where each line must be
    // drawn, straight down and oblique, at the default pixel error and at the finest mesh. Along
    // a row, a line's coverage (from the green channel against the render without isolines, in
    // linear light) sums to w / |dy| (dy: the line's direction on screen, vertical part), centred
    // on the true crossing.
    let dir = common::scratch("isolines-of-a-plane");
    let (ge, gn) = (0.3f64, 0.15f64);
    let (m_lat, m_lon) = (111_034.0f64, 111_320.0 * 39.6f64.to_radians().cos());
    let height = |lon: f64, lat: f64| 1500.0 + ge * (lon - 40.1) * m_lon + gn * (lat - 39.6) * m_lat;
    let mut xyz = String::new();
    for j in 0..=200 {
        for i in 0..=200 {
            let (lon, lat) = (40.0 + 0.001 * f64::from(i), 39.7 - 0.001 * f64::from(j));
            xyz.push_str(&format!("{lon:.3} {lat:.3} {:.5}\n", height(lon, lat)));
        }
    }
    std::fs::write(dir.join("plane.xyz"), xyz).unwrap();
    let (xyz, tif, store) = (dir.join("plane.xyz"), dir.join("plane.tif"), dir.join("plane.gpkg"));
    common::run_tool(
        "gdal_translate",
        &["-q", "-a_srs", "EPSG:4326", "-ot", "Float64", xyz.to_str().unwrap(), tif.to_str().unwrap()],
        "",
    );
    let args = ["import", tif.to_str().unwrap(), "--store", store.to_str().unwrap(), "--resampling", "cubic"];
    let run = common::terrafuse(&[&args[..], &["--body", "wgs84", "--quiet"]].concat(), "");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let (w, h, width_px, interval) = (320u32, 240u32, 2.0f64, 100.0f64);
    let views = [
        ("down", CameraSpec { lat: 39.6, lon: 40.1, alt: 6000.0, heading: 0.0, pitch: -90.0, fov: 40.0 }),
        ("oblique", CameraSpec { lat: 39.56, lon: 40.1, alt: 4000.0, heading: 10.0, pitch: -40.0, fov: 40.0 }),
    ];
    let render = |name: &str, camera: &CameraSpec, isolines: bool, pixel_error: f64| {
        let project = format!(
            r#"{{"format": "terrafuse-project", "version": 4, "body": "wgs84",
            "layers": [{{"name": "plane", "kind": "dataset", "store": "plane.gpkg"}}],
            "detail": {{"max_pixel_error": {pixel_error}}},
            "visuals": {{"colour_map": {{"preset": "grey", "range_m": [-5000.0, 5000.0]}},
              "isolines": {{"enabled": {isolines}, "interval_m": {interval}, "offset_m": 0.0, "major_every": 0,
                "width_px": {width_px}, "min_width_px": 1.0, "colour": [255, 0, 0, 255]}},
              "lighting": {{"enabled": false}}, "exaggeration": 1.0}},
            "views": {{"v": {{"lat": {}, "lon": {}, "alt": {}, "heading": {}, "pitch": {}, "fov": {}}}}},
            "default_view": "v"}}"#,
            camera.lat, camera.lon, camera.alt, camera.heading, camera.pitch, camera.fov
        );
        let p = dir.join(format!("{name}.json"));
        std::fs::write(&p, project).unwrap();
        let out = dir.join(format!("{name}.png"));
        let args = ["render", p.to_str().unwrap(), "--out", out.to_str().unwrap(), "--width", "320", "--height", "240"];
        let run = common::terrafuse(&args, "");
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        image::open(&out).unwrap().to_rgba8()
    };
    let linear = |c: u8| {
        let c = f64::from(c) / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    for (view, spec) in &views {
        let camera = terrafuse::scene::camera::Camera::new(&terrafuse::geodesy::Ellipsoid::WGS84, *spec, 1.0);
        // Each isoline on screen: a polyline of its points every 2 m or so of latitude.
        let lines: Vec<Vec<(f64, f64)>> = (5..=25)
            .map(|k| {
                let v = f64::from(k) * interval;
                (0..=10_000)
                    .filter_map(|s| {
                        let lat = 39.5 + 0.2 * f64::from(s) / 10_000.0;
                        let lon = 40.1 + (v - 1500.0 - gn * (lat - 39.6) * m_lat) / (ge * m_lon);
                        let p = terrafuse::geodesy::ecef_from_geodetic(
                            &terrafuse::geodesy::Ellipsoid::WGS84,
                            terrafuse::geodesy::Geodetic::from_degrees(lat, lon, v),
                        );
                        camera.project(p - camera.position, w, h).map(|(x, y, _)| (x, y))
                    })
                    .collect()
            })
            .collect();
        let base = render(&format!("{view}-off"), spec, false, 1.0);
        for pixel_error in [1.0, 0.05] {
            let image = render(&format!("{view}-{pixel_error}"), spec, true, pixel_error);
            let coverage = |x: u32, y: u32| {
                let (on, off) = (linear(image.get_pixel(x, y).0[1]), linear(base.get_pixel(x, y).0[1]));
                if off < 0.02 { f64::NAN } else { (1.0 - on / off).clamp(0.0, 1.0) }
            };
            let (mut crossings, mut worst_place, mut worst_width) = (0usize, 0f64, 0f64);
            for y in 0..h {
                let yc = f64::from(y) + 0.5;
                for line in &lines {
                    // Where the line crosses the row's centre, and its direction there.
                    let Some((xt, dy)) = line.windows(2).find_map(|s| {
                        let ((x0, y0), (x1, y1)) = (s[0], s[1]);
                        ((y0 - yc) * (y1 - yc) <= 0.0 && y0 != y1).then(|| {
                            let t = (yc - y0) / (y1 - y0);
                            (x0 + t * (x1 - x0), ((y1 - y0) / (x1 - x0).hypot(y1 - y0)).abs())
                        })
                    }) else {
                        continue;
                    };
                    let (lo, hi) = ((xt - 6.0).floor(), (xt + 6.0).ceil());
                    if lo < 0.0 || hi >= f64::from(w) {
                        continue;
                    }
                    let samples: Vec<(f64, f64)> =
                        (lo as u32..=hi as u32).map(|x| (f64::from(x) + 0.5, coverage(x, y))).collect();
                    if samples.iter().any(|s| s.1.is_nan()) {
                        continue;
                    }
                    let total: f64 = samples.iter().map(|s| s.1).sum();
                    let centre = samples.iter().map(|s| s.0 * s.1).sum::<f64>() / total.max(1e-9);
                    let drawn_width = total * dy;
                    crossings += 1;
                    worst_place = worst_place.max((centre - xt).abs());
                    worst_width = worst_width.max((drawn_width - width_px).abs());
                    assert!(
                        (centre - xt).abs() <= 0.5 && (drawn_width - width_px).abs() <= 0.5,
                        "{view}, pixel error {pixel_error}: the line crossing row {y} at x = {xt:.2} is drawn at \
                         {centre:.2}, {drawn_width:.2} px wide ({samples:?})"
                    );
                }
            }
            assert!(crossings > 1000, "{view}: {crossings} crossings");
            eprintln!(
                "{view}, pixel error {pixel_error}: {crossings} crossings, place within {worst_place:.3} px, width \
                 {width_px} ± {worst_width:.3} px"
            );
        }
    }
}
