//! The workstation driven as a user drives it, headless through egui_kittest on lavapipe: the
//! renderer draws into the viewport on egui-wgpu's device, the probe reads the terrain under
//! the cursor, dragging, the wheel and the keys move the camera, and views and settings are
//! saved into the project file.

mod common;

use std::time::Duration;

use common::{repo_path, sample_project};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use terrafuse::geodesy::{Ellipsoid, geodetic_from_ecef};
use terrafuse::gui::{self, ViewOptions, app::App};
use terrafuse::project::Project;

const SIZE: egui::Vec2 = egui::vec2(1000.0, 900.0);

fn harness(project: &std::path::Path, view: &str) -> Harness<'static, App> {
    harness_of_size(project, view, SIZE)
}

/// A window of another size (a tall one shows the whole settings panel without scrolling).
fn harness_of_size(project: &std::path::Path, view: &str, size: egui::Vec2) -> Harness<'static, App> {
    let opened = gui::open(&ViewOptions {
        project: project.to_path_buf(),
        view: Some(view.into()),
        camera: None,
        lod_threshold: None,
        pixel_error: None,
        width: size.x as u32,
        height: size.y as u32,
        screenshot: None,
        timeout: Duration::from_secs(60),
        config_dir: None,
        debug: None,
    })
    .unwrap();
    Harness::builder()
        .with_size(size)
        .wgpu_setup(gui::wgpu_setup())
        .build_eframe(move |cc| gui::build_app(cc, opened).expect("the workstation starts"))
}

/// Steps until the view is drawn and nothing is loading, then a few more frames for the probe.
fn settle(h: &mut Harness<'static, App>) {
    for _ in 0..3000 {
        h.step();
        if h.state().settled() {
            for _ in 0..4 {
                std::thread::sleep(Duration::from_millis(20));
                h.step();
            }
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("the view did not settle");
}

/// The viewport's centre: right of the settings panel, above the status bar.
fn centre() -> egui::Pos2 {
    egui::pos2(0.5 * (300.0 + SIZE.x), 0.5 * (SIZE.y - 30.0))
}

fn drag(h: &mut Harness<'static, App>, from: egui::Pos2, to: egui::Pos2) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for k in 1..=4 {
        h.hover_at(from + (to - from) * (k as f32 / 4.0));
        h.step();
    }
    h.drop_at(to);
    h.step();
}

#[test]
fn the_workstation_draws_probes_navigates_and_saves() {
    let dir = common::out_path("workstation");
    let project = sample_project("moon-lola", &dir);
    let mut h = harness(&project, "globe");
    settle(&mut h);
    let home = h.state().camera();

    // The probe at the centre of a straight-down view reads the terrain at the nadir.
    let hit = h.state().hit().expect("terrain under the centre");
    let g = geodetic_from_ecef(&Ellipsoid::MOON, hit.ecef);
    assert!((g.lat_rad.to_degrees() - home.lat).abs() < 0.2, "{g:?} under {home:?}");
    assert!((g.lon_rad.to_degrees() - home.lon).abs() < 0.2, "{g:?} under {home:?}");
    assert!(hit.has_data && (-9000.0..11000.0).contains(&hit.height_m), "{hit:?}");
    // The probe's point is the mesh's, which stands within the frame's drawn geometric error of
    // the data: a vertical miss δ at distance d shows as δ·f/d pixels at most, so δ is bounded by
    // max_error_px·d/f (kilometres from 3 500 km away; at the nadir it does not show at all).
    let viewport = h.state().viewport_rect_px().expect("a viewport");
    let focal_px = 0.5 * f64::from(viewport.height()) / (0.5 * home.fov).to_radians().tan();
    let bound_m = h.state().frame_stats().max_error_px * (home.alt + 10_000.0) / focal_px + 50.0;
    assert!(
        (g.height_m - hit.height_m).abs() < bound_m,
        "the surface point lies at its height within the drawn error ({bound_m:.0} m): {g:?} {hit:?}"
    );

    // Dragging the globe to the right turns the camera west, at the same altitude.
    drag(&mut h, centre(), centre() + egui::vec2(120.0, 0.0));
    let moved = h.state().camera();
    assert!(moved.lon < home.lon - 2.0 && (moved.lat - home.lat).abs() < 1.0, "{moved:?} from {home:?}");
    assert!((moved.alt - home.alt).abs() < 1e-3 * home.alt, "{moved:?}");

    // The wheel zooms in towards the cursor.
    h.hover_at(centre());
    h.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, 200.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Unknown,
        modifiers: egui::Modifiers::NONE,
    });
    for _ in 0..20 {
        h.step();
    }
    let zoomed = h.state().camera();
    assert!(zoomed.alt < 0.8 * moved.alt, "{zoomed:?} after zooming from {moved:?}");

    // A right drag orbits: the heading turns.
    h.hover_at(centre());
    h.step();
    h.event(egui::Event::PointerButton {
        pos: centre(),
        button: egui::PointerButton::Secondary,
        pressed: true,
        modifiers: egui::Modifiers::NONE,
    });
    h.step();
    for k in 1..=4 {
        h.hover_at(centre() + egui::vec2(25.0 * k as f32, 0.0));
        h.step();
    }
    h.event(egui::Event::PointerButton {
        pos: centre() + egui::vec2(100.0, 0.0),
        button: egui::PointerButton::Secondary,
        pressed: false,
        modifiers: egui::Modifiers::NONE,
    });
    h.step();
    let orbited = h.state().camera();
    let turned = (orbited.heading - zoomed.heading + 540.0).rem_euclid(360.0) - 180.0;
    assert!(turned.abs() > 10.0, "heading {} → {}", zoomed.heading, orbited.heading);

    // N turns north up; H goes home.
    h.remove_cursor();
    h.key_press(egui::Key::N);
    h.step();
    assert!(h.state().camera().heading.abs() < 1e-9);
    h.key_press(egui::Key::H);
    h.step();
    assert_eq!(h.state().camera(), home);

    // Another view, saved under a name into the project file.
    h.get_by_label("tycho").click();
    h.step();
    let tycho = h.state().camera();
    assert_eq!(tycho, Project::load(&project).unwrap().views["tycho"]);
    // The view name is the first text field of the panel (the brush's edit layer is another).
    h.get_all_by_role(egui::accesskit::Role::TextInput).next().unwrap().focus();
    h.step();
    h.get_all_by_role(egui::accesskit::Role::TextInput).next().unwrap().type_text("tycho-again");
    h.step();
    h.get_by_label("save view").click();
    h.step();
    let saved = Project::load(&project).unwrap();
    assert_eq!(saved.views.get("tycho-again"), Some(&tycho), "{}", h.state().message());

    // A colour map chosen in the panel is drawn and, once saved, is in the project file. (The
    // combo box and the save button are pressed through accesskit, as a screen reader does:
    // kittest's pointer clicks did not reach them inside the scrolled panel.)
    let colour_map = || (egui::accesskit::Role::ComboBox, "colour map");
    h.get_by_role_and_label(colour_map().0, colour_map().1).scroll_to_me();
    h.run_steps(2);
    h.get_by_role_and_label(colour_map().0, colour_map().1).click_accesskit();
    h.run_steps(2);
    h.get_by_label("grey").click();
    h.step();
    assert!(h.state().unsaved());
    settle(&mut h);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    assert!(!h.state().unsaved(), "{}", h.state().message());
    let saved = Project::load(&project).unwrap();
    assert_eq!(saved.visuals.colour_map.preset, "grey");
    assert_eq!(saved.views.get("tycho-again"), Some(&tycho), "the saved view is kept");
    // Colour by slope: the ramp's range becomes 0–45°, and, saved, `by` is in the file.
    let colour_by = || (egui::accesskit::Role::ComboBox, "colour by");
    // Every attribute of `export --attribute` is there: TPI's ramp spans ±5 m by default.
    h.get_by_role_and_label(colour_by().0, colour_by().1).click_accesskit();
    h.run_steps(2);
    h.get_by_label("tpi").click();
    h.run_steps(2);
    assert_eq!(
        h.state().renderer_visuals().colour_map.by,
        terrafuse::project::ColourBy::Attribute(terrafuse::attributes::Attribute::Tpi)
    );
    assert_eq!(h.state().renderer_ramp_range(), (-5.0, 5.0));
    // *data*: the TPI's 2nd–98th percentile on the quads drawn, symmetric about 0.
    h.get_by_label("data").click();
    h.run_steps(2);
    let (lo, hi) = h.state().renderer_ramp_range();
    assert!(hi > 0.0 && lo == -hi && hi != 5.0, "TPI range from the data drawn: {lo} … {hi}");
    h.get_by_role_and_label(colour_by().0, colour_by().1).click_accesskit();
    h.run_steps(2);
    h.get_by_label("slope").click();
    h.run_steps(2);
    assert_eq!(
        h.state().renderer_visuals().colour_map.by,
        terrafuse::project::ColourBy::Attribute(terrafuse::attributes::Attribute::Slope)
    );
    assert_eq!(h.state().renderer_ramp_range(), (0.0, 45.0));
    settle(&mut h);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    assert_eq!(
        Project::load(&project).unwrap().visuals.colour_map.by,
        terrafuse::project::ColourBy::Attribute(terrafuse::attributes::Attribute::Slope)
    );

    // The layers panel: hiding the (only) layer takes it out of the renderer's stack at once
    // and, saved, is in the project file; shown again, the terrain comes back. (The view is not
    // settled while the layer is hidden: without data, quads refine to level 6 for the shape of
    // the ellipsoid, which takes lavapipe minutes to draw.)
    h.get_by_label("visible").click_accesskit();
    // Two frames: the file bar above the panel shows the change from the next one.
    h.run_steps(2);
    assert!(h.state().unsaved());
    assert!(!h.state().stack().layers[0].spec.visible);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    let saved = Project::load(&project).unwrap();
    assert!(!saved.layers[0].visible);
    assert_eq!(saved.version, terrafuse::project::VERSION);
    h.get_by_label("visible").click_accesskit();
    h.step();
    assert!(h.state().stack().layers[0].spec.visible);
    settle(&mut h);
    // (What the terrain shows once the layer is back is tested on the renderer itself:
    // tests/compose.rs, hiding_and_showing_the_only_layer_brings_the_terrain_back.)

    // Procedural detail added from the panel goes on top of the stack, into the renderer and,
    // saved, into the project; removed again, it is gone from both.
    h.get_by_label("add detail").click_accesskit();
    // Two frames: the new layer's widgets appear in the second, moving the save button's id.
    h.run_steps(2);
    let stack = h.state().stack();
    assert_eq!(stack.layers.len(), 2);
    assert_eq!(stack.layers[1].spec.name, "detail");
    assert_eq!(stack.layers[1].spec.blend, terrafuse::layers::BlendMode::Add);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    let saved = Project::load(&project).unwrap();
    assert_eq!(
        saved.layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>(),
        ["lola_global", "detail"],
        "{} (unsaved {})",
        h.state().message(),
        h.state().unsaved()
    );
    // Every layer has its remove button; the top one (listed first) is the detail.
    h.get_all_by_label("remove").next().unwrap().click_accesskit();
    h.step();
    assert_eq!(h.state().stack().layers.len(), 1);
    assert_eq!(h.state().stack().layers[0].spec.name, "lola_global");
}

/// The strokes of the layer `sculpt` and how many are applied.
fn sculpt_strokes(h: &Harness<'static, App>) -> (usize, usize) {
    let l = h.state().project().layers.iter().find(|l| l.name == "sculpt").unwrap();
    (l.strokes().len(), l.applied_strokes().len())
}

/// Opens the Brush tab and ticks *brush (left drag paints)*.
fn arm_the_brush(h: &mut Harness<'static, App>) {
    h.get_by_label("Brush").click_accesskit();
    h.run_steps(2);
    h.get_by_label("brush (left drag paints)").click_accesskit();
    h.run_steps(2);
}

/// Steps (10 ms apart) while the window is `busy`, then two more; panics naming `what` if it is
/// still busy after `steps` steps and five minutes (work on worker threads is niced, and a loaded
/// machine running the other tests in parallel slows it, not what it does).
fn step_while(h: &mut Harness<'static, App>, steps: usize, what: &str, busy: impl Fn(&App) -> bool) {
    let deadline = std::time::Instant::now() + Duration::from_secs(300);
    let mut taken = 0;
    while taken < steps || std::time::Instant::now() < deadline {
        h.step();
        taken += 1;
        if !busy(h.state()) {
            h.run_steps(2);
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("{what} did not finish in {taken} steps");
}

/// Steps until the background import or opening of a dataset is over.
fn wait_for_dataset(h: &mut Harness<'static, App>) {
    step_while(h, 6000, "adding the dataset", |a| a.adding_dataset());
}

/// Types into the text field labelled `label`, replacing what it held.
fn type_into(h: &mut Harness<'static, App>, label: &str, text: &str) {
    h.get_by_label(label).focus();
    h.step();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.get_by_label(label).type_text(text);
    h.step();
}

#[test]
fn datasets_are_imported_in_the_background_cancelled_and_layers_reorder_by_dragging() {
    let dir = common::out_path("workstation-add");
    let _ = std::fs::remove_dir_all(dir.join("stores"));
    let project = sample_project("moon-lola", &dir);
    let mut h = harness_of_size(&project, "globe", egui::vec2(900.0, 1500.0));
    settle(&mut h);
    h.get_by_label("add a dataset").click_accesskit();
    h.run_steps(2);

    // A file that is not there: refused by name, nothing added.
    type_into(&mut h, "file", "/nonexistent/dem.tif");
    h.get_by_label("add dataset").click_accesskit();
    h.run_steps(2);
    assert!(h.state().message().contains("/nonexistent/dem.tif"), "{}", h.state().message());
    assert_eq!(h.state().stack().layers.len(), 1);

    // The north polar grid, imported into stores/north.gpkg beside the project in the
    // background while the window keeps drawing, then put on top of the stack.
    let raster = repo_path("projects/data/moon_lola_north_stere_1600m.tif");
    type_into(&mut h, "file", raster.to_str().unwrap());
    type_into(&mut h, "name", "north");
    h.get_by_label("add dataset").click_accesskit();
    h.step();
    assert!(h.state().adding_dataset(), "the import runs in the background");
    wait_for_dataset(&mut h);
    assert_eq!(h.state().message(), "added dataset layer 'north'");
    let stack = h.state().stack();
    assert_eq!(stack.layers.len(), 2);
    let north = &stack.layers[1];
    assert_eq!(north.spec.name, "north");
    assert_eq!(north.spec.as_dataset().unwrap().store, std::path::Path::new("stores/north.gpkg"));
    assert!(north.raw_range_m.1 > north.raw_range_m.0, "the dataset is attached: {:?}", north.raw_range_m);
    assert!(dir.join("stores/north.gpkg").exists());
    settle(&mut h);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    let saved = Project::load(&project).unwrap();
    assert_eq!(saved.layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>(), ["lola_global", "north"]);
    assert_eq!(saved.layers[1].as_dataset().unwrap().source.as_ref().unwrap().files, std::slice::from_ref(&raster));

    // The same raster again under another name, cancelled at once: nothing added, the store it
    // began stays a valid store that a later import resumes.
    type_into(&mut h, "name", "north again");
    h.get_by_label("add dataset").click_accesskit();
    h.run_steps(2);
    assert!(h.state().message().contains("not usable as a table name"), "{}", h.state().message());
    type_into(&mut h, "name", "north_again");
    h.get_by_label("add dataset").click_accesskit();
    h.run_steps(2);
    if h.state().adding_dataset() {
        h.get_by_label("cancel").click_accesskit();
    }
    wait_for_dataset(&mut h);
    assert_eq!(h.state().stack().layers.len(), 2, "{}", h.state().message());
    assert!(h.state().message().contains("cancelled"), "{}", h.state().message());
    let partial = dir.join("stores/north_again.gpkg");
    if partial.exists() {
        terrafuse::store::Store::open_read_only(&partial).expect("a cancelled import leaves a valid store");
    }

    // Dragging the top layer (listed first) by its handle onto the bottom one's row moves it to
    // the bottom.
    let handles: Vec<egui::Rect> = h.get_all_by_label("::").map(|n| n.rect()).collect();
    assert_eq!(handles.len(), 2);
    drag(&mut h, handles[0].center(), handles[1].center() + egui::vec2(40.0, 2.0));
    h.run_steps(2);
    let names: Vec<String> = h.state().stack().layers.iter().map(|l| l.spec.name.clone()).collect();
    assert_eq!(names, ["north", "lola_global"]);
}

/// Steps until the *Compare* section's computation is over.
fn wait_for_compare(h: &mut Harness<'static, App>) {
    step_while(h, 20_000, "the comparison", |a| a.compare_panel().busy());
}

#[test]
fn the_compare_section_shows_statistics_and_applies_a_coregistration() {
    let dir = common::out_path("workstation-compare");
    let project = sample_project("erzurum-compare", &dir);
    let mut h = harness_of_size(&project, "30km", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    // The sample draws blurred − srtm; its colour range is the 98th percentile of |dh|, computed
    // in the background.
    let range_before = wait_for_range(&mut h);
    assert!(range_before > 100.0, "a 3 and 5 pixel shift in mountains: {range_before} m");
    // Defaults: the top dataset (blurred) against the one below (srtm).
    h.get_by_label("Compare").click_accesskit();
    h.run_steps(2);
    h.get_by_label("compare").click_accesskit();
    h.step();
    assert!(h.state().compare_panel().busy(), "the comparison runs in the background");
    wait_for_compare(&mut h);
    let c = h.state().compare_panel().comparison().expect("statistics");
    assert_eq!((c.a.as_str(), c.b.as_str()), ("blurred", "srtm"));
    assert!(c.stats.count > 1_000_000 && c.stats.nmad_m > 50.0, "{:?}", c.stats);
    h.get_by_label("co-register").click_accesskit();
    h.step();
    wait_for_compare(&mut h);
    let r = h.state().compare_panel().coregistration().expect("a co-registration");
    let (east, north) = (r.east_m, r.north_m);
    assert!((east - 214.8).abs() < 1.0 && (north + 462.6).abs() < 1.0, "{east} {north}");
    h.get_by_label("apply to blurred").click_accesskit();
    h.run_steps(2);
    let blurred = h.state().stack().layers.iter().find(|l| l.spec.name == "blurred").unwrap().spec.clone();
    assert_eq!(blurred.shift_m(), [east, north]);
    assert!(h.state().message().starts_with("moved 'blurred' east"), "{}", h.state().message());
    settle(&mut h);
    // Co-registered, the differences shrink, and so does the range they are drawn over.
    let range_after = wait_for_range(&mut h);
    assert!(range_after < range_before / 2.0, "{range_before} m to {range_after} m");
    h.render().unwrap().save(dir.join("difference.png")).unwrap(); // for people, not compared
    // A pipeline: each step's line; applied, the ramp joins the layer's correction.
    type_into(&mut h, "pipeline", "nuth_kaab,deramp:1");
    h.get_by_label("co-register").click_accesskit();
    h.step();
    wait_for_compare(&mut h);
    let r = h.state().compare_panel().coregistration().expect("a co-registration");
    assert_eq!(r.pipeline, ["nuth_kaab", "deramp:1"]);
    assert_eq!(r.steps.len(), 2);
    h.run_steps(2);
    h.get_by_label("apply to blurred").click_accesskit();
    h.run_steps(2);
    let blurred = h.state().stack().layers.iter().find(|l| l.spec.name == "blurred").unwrap().spec.clone();
    let correction: Vec<String> = blurred.as_dataset().unwrap().correction.iter().map(|b| b.step_name()).collect();
    assert_eq!(correction, ["deramp:1"]);
    assert!(h.state().message().ends_with("corrected by deramp:1"), "{}", h.state().message());
    // The layers panel lists it, and takes it off again.
    h.get_by_label_contains("correction 1: deramp:1");
    h.get_by_label("remove correction 1").click_accesskit();
    h.run_steps(2);
    let blurred = h.state().stack().layers.iter().find(|l| l.spec.name == "blurred").unwrap().spec.clone();
    assert!(blurred.as_dataset().unwrap().correction.is_empty());
    // A bias a layer cannot hold is fitted and shown, with why it cannot be applied.
    type_into(&mut h, "pipeline", "terrain_bias:slope");
    h.get_by_label("co-register").click_accesskit();
    h.step();
    wait_for_compare(&mut h);
    h.run_steps(2);
    assert!(h.query_by_label("apply to blurred").is_none(), "a slope bias cannot be applied");
    h.get_by_label_contains("cannot apply: layer 'blurred': correction: terrain_bias:slope");
    type_into(&mut h, "pipeline", "nuth_kaab,deramp:7");
    h.get_by_label("co-register").click_accesskit();
    h.step();
    wait_for_compare(&mut h);
    h.run_steps(2);
    h.get_by_label_contains("--pipeline: 'deramp:7': the order must be 1, 2 or 3");
    // The uncertainty of the mean change: its numbers, the binned error and the variogram.
    h.get_by_label("uncertainty").click_accesskit();
    h.step();
    wait_for_compare(&mut h);
    h.run_steps(2);
    let u = h.state().compare_panel().uncertainty().expect("an uncertainty");
    assert!(u.mean_dh_sigma_m > 0.0 && u.volume_sigma_m3 > 0.0 && !u.variogram.models.is_empty());
    h.get_by_label_contains(&format!("mean dh {:+.3} ± {:.3} m (1σ)", u.mean_dh_m, u.mean_dh_sigma_m));
    h.get_by_label_contains("variogram of dh / σ: spherical ranges");
    h.render().unwrap().save(dir.join("uncertainty.png")).unwrap(); // for people, not compared
    // "show difference" with that difference drawn already adds no copy of it: it says which
    // layer draws it, and the project is not changed.
    let (layers, unsaved) = (h.state().stack().layers.len(), h.state().unsaved());
    h.get_by_label("show difference").click_accesskit();
    h.run_steps(2);
    let stack = h.state().stack();
    assert_eq!(stack.layers.len(), layers, "no second difference layer");
    let drawn = &stack.layers[stack.drawn_difference().expect("a drawn difference")].spec;
    assert_eq!((drawn.name.as_str(), drawn.kind()), ("blurred - srtm", terrafuse::layers::LayerKind::Difference));
    assert_eq!(h.state().unsaved(), unsaved, "showing what is shown changes nothing");
    h.get_by_label_contains("blurred - srtm is drawn by layer 'blurred - srtm'");
    settle(&mut h);
}

/// Steps until the drawn difference's range from its percentile is known; returns it.
fn wait_for_range(h: &mut Harness<'static, App>) -> f64 {
    for _ in 0..2000 {
        h.step();
        if !h.state().difference_range().1 {
            // Not busy: one more step starts a computation if the inputs changed.
            h.step();
            if !h.state().difference_range().1 {
                return h.state().difference_range().0;
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    panic!("the difference's range was not computed");
}

#[test]
fn swiping_shows_a_left_of_a_line_and_b_right_of_it_and_the_line_drags() {
    let dir = common::out_path("workstation-swipe");
    let project = sample_project("erzurum-compare", &dir);
    let mut h = harness_of_size(&project, "30km", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    h.get_by_label("Compare").click_accesskit();
    h.run_steps(2);
    h.get_by_label("swipe blurred | srtm").click_accesskit();
    h.run_steps(3);
    settle(&mut h);
    assert_eq!(h.state().swipe_position(), Some(0.5), "{}", h.state().message());
    let visible = |stack: &terrafuse::layers::Stack, name: &str| {
        stack.layers.iter().find(|l| l.spec.name == name).unwrap().spec.visible
    };
    assert!(visible(h.state().stack(), "blurred") && !visible(h.state().stack(), "srtm"), "left: A shown, B hidden");
    assert!(!visible(h.state().stack(), "blurred - srtm"), "no difference drawn over a swipe");
    let right = h.state().swipe_stack().expect("a second stack");
    assert!(!visible(right, "blurred") && visible(right, "srtm"), "right: B shown, A hidden");

    // Dragging the line moves it and not the camera.
    let r = h.state().viewport_rect_px().unwrap();
    let camera = h.state().camera();
    let (x, y) = (r.left() + 0.5 * r.width(), r.center().y);
    drag(&mut h, egui::pos2(x, y), egui::pos2(x + 120.0, y));
    let position = h.state().swipe_position().unwrap();
    assert!((position - (0.5 + 120.0 / r.width())).abs() < 0.02, "line at {position}");
    assert_eq!(h.state().camera(), camera, "the camera stayed");
    settle(&mut h);
    // The window as it looks, for people (not compared).
    h.render().unwrap().save(dir.join("swipe.png")).unwrap();
    // Side by side: two linked views, each the whole picture at half the width.
    h.get_by_label("side by side").click_accesskit();
    h.run_steps(2);
    settle(&mut h);
    assert!(h.state().side_by_side());
    let half = h.state().viewport_rect_px().unwrap();
    assert!((half.width() - r.width() / 2.0).abs() <= 1.0, "{} of {}", half.width(), r.width());
    h.render().unwrap().save(dir.join("side-by-side.png")).unwrap(); // for people, not compared
    // Unticked, the view is one picture again.
    h.get_by_label("swipe blurred | srtm").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().swipe_position(), None);
}

/// Clicks at a point of the viewport: hover until the probe reads that pixel, press, release.
fn click(h: &mut Harness<'static, App>, at: egui::Pos2) {
    h.hover_at(at);
    let r = h.state().viewport_rect_px().unwrap();
    let pixel = (at.x - r.left(), at.y - r.top());
    for _ in 0..500 {
        h.step();
        let probed = h.state().hit().is_some_and(|hit| {
            (hit.pixel.0 as f32 - pixel.0).abs() < 2.0 && (hit.pixel.1 as f32 - pixel.1).abs() < 2.0
        });
        if probed {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    h.drag_at(at);
    h.step();
    h.drop_at(at);
    h.step();
}

#[test]
fn a_profile_drawn_with_two_clicks_shows_each_visible_layer_and_saves_its_line() {
    let dir = common::out_path("workstation-profile");
    let project = sample_project("erzurum-compare", &dir);
    let mut h = harness_of_size(&project, "30km", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    h.get_by_label("Compare").click_accesskit();
    h.run_steps(2);
    h.get_by_label("draw a profile").click_accesskit();
    h.run_steps(2);
    let r = h.state().viewport_rect_px().unwrap();
    click(&mut h, egui::pos2(r.left() + 0.3 * r.width(), r.top() + 0.6 * r.height()));
    assert_eq!(h.state().message(), "profile: click its end");
    click(&mut h, egui::pos2(r.left() + 0.7 * r.width(), r.top() + 0.5 * r.height()));
    for _ in 0..3000 {
        h.step();
        if !h.state().profile_busy() {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let p = h.state().last_profile().expect("a profile");
    assert_eq!(p.layers.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(), ["srtm"], "the visible layers");
    assert!(p.length_m > 1000.0 && p.distance_m.len() == 400, "{} m, {} samples", p.length_m, p.distance_m.len());
    assert!(p.composed.iter().filter(|v| !v.is_nan()).count() > 300);
    h.run_steps(2);
    h.render().unwrap().save(dir.join("profile.png")).unwrap(); // for people, not compared
    h.get_by_label("save line").click_accesskit();
    h.step();
    assert!(h.state().project().comparison.profiles.contains_key("line 1"), "{}", h.state().message());
    assert!(h.state().unsaved());
    // And as CSV beside the project: a column per visible layer and the composed stack.
    let _ = std::fs::remove_file(dir.join("profile.csv"));
    h.get_by_label("write CSV").click_accesskit();
    h.step();
    let csv = std::fs::read_to_string(dir.join("profile.csv")).expect("profile.csv written");
    assert!(csv.starts_with("distance_m,lat_deg,lon_deg,srtm,composed\n"), "{}", &csv[..80.min(csv.len())]);
    assert_eq!(csv.lines().count(), 401);
}

#[test]
fn a_left_drag_with_the_brush_on_paints_a_stroke_and_ctrl_z_undoes_it() {
    let dir = common::out_path("workstation-brush");
    let project = sample_project("moon-brushing", &dir);
    let mut h = harness_of_size(&project, "sculpt", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    let strokes = |h: &Harness<'static, App>| sculpt_strokes(h);
    let (n, _) = strokes(&h);
    arm_the_brush(&mut h);
    assert!(h.state().brush_state().0, "the brush is on");
    let camera = h.state().camera();
    let r = h.state().viewport_rect_px().unwrap();
    let (x, y) = (r.center().x, r.center().y);
    let (from, to) = (egui::pos2(x - 80.0, y), egui::pos2(x + 80.0, y));
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for k in 1..=4 {
        h.hover_at(from + (to - from) * (k as f32 / 4.0));
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    // The terrain updates during the drag: the stroke so far is applied provisionally.
    assert_eq!(strokes(&h), (n + 1, n + 1), "a provisional stroke while dragging");
    let partial = h.state().project().layers.iter().find(|l| l.name == "sculpt").unwrap().strokes()[n].path.len();
    h.drop_at(to);
    h.step();
    h.run_steps(2);
    assert_eq!(h.state().camera(), camera, "painting does not move the camera");
    assert_eq!(strokes(&h), (n + 1, n + 1), "{}", h.state().message());
    assert!(h.state().message().starts_with(&format!("stroke {n} on 'sculpt'")), "{}", h.state().message());
    let stroke = h.state().project().layers.iter().find(|l| l.name == "sculpt").unwrap().strokes()[n].clone();
    assert!(stroke.path.len() >= 2 && stroke.path.len() >= partial, "the drag's path: {:?}", stroke.path);
    settle(&mut h);
    // The footprint follows the cursor (a ring on the terrain).
    h.hover_at(egui::pos2(x, y));
    h.run_steps(3);
    settle(&mut h);
    h.render().unwrap().save(dir.join("brushed.png")).unwrap(); // for people, not compared
    // Ctrl+Z undoes it, Ctrl+Shift+Z redoes it.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(strokes(&h), (n + 1, n), "{}", h.state().message());
    h.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(strokes(&h), (n + 1, n + 1), "{}", h.state().message());
    settle(&mut h);
}

#[test]
fn the_erosion_section_starts_steps_runs_keeps_undoes_and_brushes_a_run() {
    let dir = common::out_path("workstation-erosion");
    let project = sample_project("erzurum-erosion", &dir);
    let mut h = harness_of_size(&project, "eroded", egui::vec2(900.0, 2600.0));
    settle(&mut h);
    let runs = |h: &Harness<'static, App>| {
        let l = h.state().project().layers.iter().find(|l| l.name == "erosion").unwrap();
        (l.runs().len(), l.applied_runs().len())
    };
    assert_eq!(runs(&h), (2, 2));
    h.get_by_label("Erosion").click_accesskit();
    h.run_steps(2);
    h.state_mut().set_erosion(6, 2000.0);
    // The default preset (rain) is time-scaled, and the section says so.
    assert!(h.query_by_label_contains("time-scaled").is_some(), "the preset's scaling is not shown");
    h.get_by_label("start").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().erosion_progress(), Some((0, 6)), "{}", h.state().message());
    // One step, then the rest, on the run's own thread (lavapipe is no hardware GPU).
    h.get_by_label("step").click_accesskit();
    step_while(&mut h, 600, "one step", |a| a.erosion_progress() != Some((1, 6)));
    h.get_by_label("run").click_accesskit();
    step_while(&mut h, 600, "the run", |a| a.erosion_progress() != Some((6, 6)));
    h.run_steps(2);
    assert!(h.query_by_label("pause").is_none(), "paused when the steps are done");
    // The water is draped over the terrain while the run is on, by layers the project never holds.
    let live =
        |h: &Harness<'static, App>| h.state().stack().layers.iter().any(|l| l.spec.name == "erosion-live-overlay");
    assert!(live(&h), "the water is draped over the terrain");
    assert!(h.state().project().layers.iter().all(|l| !l.name.starts_with("erosion-live")));
    settle(&mut h);
    h.render().unwrap().save(dir.join("running.png")).unwrap(); // for people, not compared
    h.get_by_label("keep").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().erosion_progress(), None);
    assert!(!live(&h), "the drape goes with the run");
    assert_eq!(runs(&h), (3, 3), "{}", h.state().message());
    assert!(h.state().message().starts_with("erosion run 2 kept: 6 steps"), "{}", h.state().message());
    assert!(h.state().unsaved());
    let kept = h.state().project().layers.iter().find(|l| l.name == "erosion").unwrap().runs()[2].clone();
    assert_eq!((kept.steps, kept.level, kept.seed), (6, 10, 1));
    assert_eq!(kept.params.start, terrafuse::erosion::params::Start::Steady, "the rain preset starts steady");
    settle(&mut h);
    h.render().unwrap().save(dir.join("eroded.png")).unwrap(); // for people, not compared
    // Undo and redo among the runs.
    h.get_by_label("undo run").click_accesskit();
    h.run_steps(2);
    assert_eq!(runs(&h), (3, 2), "{}", h.state().message());
    h.get_by_label("redo run").click_accesskit();
    h.run_steps(2);
    assert_eq!(runs(&h), (3, 3), "{}", h.state().message());
    // The erosion brush: a left drag records a run localised along it.
    h.get_by_label("brush (left drag erodes)").click_accesskit();
    h.run_steps(2);
    let camera = h.state().camera();
    let r = h.state().viewport_rect_px().unwrap();
    let (x, y) = (r.center().x, r.center().y);
    drag(&mut h, egui::pos2(x - 60.0, y), egui::pos2(x + 60.0, y));
    step_while(&mut h, 3000, "the brush's run", |a| {
        a.project().layers.iter().find(|l| l.name == "erosion").unwrap().runs().len() < 4
    });
    assert_eq!(h.state().camera(), camera, "the erosion brush does not move the camera");
    assert_eq!(runs(&h), (4, 4), "{}", h.state().message());
    let brushed = h.state().project().layers.iter().find(|l| l.name == "erosion").unwrap().runs()[3].clone();
    let path = brushed.brush.expect("a brush run keeps its path");
    assert!(path.points.len() >= 2 && path.radius_m > 0.0, "{path:?}");
    // Landscape evolution: the whole run at once, kept as a stream-power run.
    h.get_by_label("brush (left drag erodes)").click_accesskit();
    h.run_steps(2);
    h.state_mut().set_landscape(2e4, 1e4);
    h.run_steps(2);
    h.get_by_label("run landscape").click_accesskit();
    step_while(&mut h, 3000, "the landscape run", |a| {
        a.project().layers.iter().find(|l| l.name == "erosion").unwrap().runs().len() < 5
    });
    assert_eq!(runs(&h), (5, 5), "{}", h.state().message());
    assert!(h.state().message().starts_with("landscape run 4 kept: 2 steps"), "{}", h.state().message());
    let evolved = h.state().project().layers.iter().find(|l| l.name == "erosion").unwrap().runs()[4].clone();
    assert_eq!(evolved.model, terrafuse::erosion::operation::Model::StreamPower);
    assert_eq!(evolved.stream_power.map(|p| p.years), Some(2e4));
    settle(&mut h);
    // The drainage overlay: the channel network of the visible stack, draped over the terrain.
    h.get_by_label("drainage").click_accesskit();
    h.run_steps(2);
    let summary = h.state().drainage_summary().to_string();
    assert!(summary.contains("channel cells"), "{summary} / {}", h.state().message());
    assert!(live(&h), "the drainage is draped over the terrain");
    assert!(h.state().project().layers.iter().all(|l| !l.name.starts_with("erosion-live")));
    settle(&mut h);
    h.render().unwrap().save(dir.join("drainage.png")).unwrap(); // for people, not compared
    // The uplift brush: a stream-power run whose uplift follows the drag; the drainage is
    // routed again on the raised terrain.
    h.get_by_label("uplift brush (left drag raises rock)").click_accesskit();
    h.run_steps(2);
    drag(&mut h, egui::pos2(x - 60.0, y), egui::pos2(x + 60.0, y));
    step_while(&mut h, 3000, "the uplift brush's run", |a| {
        a.project().layers.iter().find(|l| l.name == "erosion").unwrap().runs().len() < 6
    });
    h.run_steps(2);
    assert_eq!(runs(&h), (6, 6), "{}", h.state().message());
    let raised = h.state().project().layers.iter().find(|l| l.name == "erosion").unwrap().runs()[5].clone();
    assert_eq!(raised.model, terrafuse::erosion::operation::Model::StreamPower);
    assert!(raised.brush.is_some(), "the uplift brush keeps its path");
    assert!(live(&h), "the drainage follows the run");
    h.get_by_label("drainage").click_accesskit();
    h.run_steps(2);
    assert!(!live(&h), "unticked, the drainage goes");
    settle(&mut h);
}

/// A press at `from`, moves to `to` and the release there, all before the next frame.
fn drag_in_one_frame(h: &mut Harness<'static, App>, from: egui::Pos2, to: egui::Pos2) {
    let button = |pos, pressed| egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    h.event(egui::Event::PointerMoved(from));
    h.event(button(from, true));
    for k in 1..=5 {
        h.event(egui::Event::PointerMoved(from + (to - from) * (k as f32 / 5.0)));
    }
    h.event(button(to, false));
    h.step();
}

#[test]
fn a_press_its_moves_and_its_release_between_two_frames_are_all_taken() {
    let dir = common::out_path("workstation-events");
    let _ = std::fs::remove_dir_all(&dir);
    let project = sample_project("moon-brushing", &dir);
    let mut h = harness_of_size(&project, "sculpt", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    let home = h.state().camera();
    let r = h.state().viewport_rect_px().unwrap();
    let c = r.center();

    // A flick whose press, moves and release all fall into one frame moves the globe as far as
    // the same drag spread over frames.
    drag_in_one_frame(&mut h, c, c + egui::vec2(200.0, 0.0));
    let flicked = h.state().camera();
    assert!((flicked.lon - home.lon).abs() > 0.3, "the flick moved the globe: {flicked:?} from {home:?}");
    h.key_press(egui::Key::H);
    h.run_steps(2);
    assert_eq!(h.state().camera(), home, "H goes home");
    settle(&mut h);
    drag(&mut h, c, c + egui::vec2(200.0, 0.0));
    let dragged = h.state().camera();
    assert!(
        (flicked.lon - dragged.lon).abs() < 0.01 * (dragged.lon - home.lon).abs(),
        "one frame {flicked:?}, several {dragged:?}"
    );
    h.key_press(egui::Key::H);
    h.run_steps(2);
    settle(&mut h);

    // A stroke drawn between two frames starts where the button went down.
    let strokes = |h: &Harness<'static, App>| sculpt_strokes(h);
    let (n, _) = strokes(&h);
    arm_the_brush(&mut h);
    let press = c + egui::vec2(-90.0, 30.0);
    h.hover_at(press);
    settle(&mut h);
    let under = h.state().hit().expect("terrain under the press");
    let g = terrafuse::geodesy::geodetic_from_ecef(&Ellipsoid::MOON, under.ecef);
    drag_in_one_frame(&mut h, press, press + egui::vec2(180.0, -60.0));
    step_while(&mut h, 600, "the stroke", |a| {
        a.project().layers.iter().find(|l| l.name == "sculpt").unwrap().strokes().len() < n + 1
    });
    let stroke = h.state().project().layers.iter().find(|l| l.name == "sculpt").unwrap().strokes()[n].clone();
    let first = stroke.path[0];
    // Within a pixel: at this view a pixel is about 300 m, 0.01° on the Moon.
    assert!(
        (first[0] - g.lat_rad.to_degrees()).abs() < 0.01 && (first[1] - g.lon_rad.to_degrees()).abs() < 0.01,
        "the stroke starts at {first:?}, the press was over {:?}",
        (g.lat_rad.to_degrees(), g.lon_rad.to_degrees())
    );
    assert!(stroke.path.len() >= 3, "the moves are in the path: {:?}", stroke.path);
    assert_eq!(strokes(&h), (n + 1, n + 1));

    // Ctrl+Z pressed and released between two frames undoes exactly one stroke.
    let key = |pressed, modifiers| egui::Event::Key {
        key: egui::Key::Z,
        physical_key: None,
        pressed,
        repeat: false,
        modifiers,
    };
    h.event(key(true, egui::Modifiers::COMMAND));
    h.event(key(false, egui::Modifiers::COMMAND));
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    h.run_steps(2);
    assert_eq!(strokes(&h), (n + 1, n), "{}", h.state().message());
    // Held down, the key undoes once; its repeats (pressed again while down) nothing more.
    h.event(key(true, egui::Modifiers::COMMAND));
    h.run_steps(2);
    for _ in 0..3 {
        h.event(key(true, egui::Modifiers::COMMAND));
        h.step();
    }
    h.event(key(false, egui::Modifiers::COMMAND));
    h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    h.run_steps(2);
    assert_eq!(strokes(&h), (n + 1, n - 1), "a repeat is not a press");

    // Another tab disarms the brush: a left drag there moves the globe and paints nothing.
    h.get_by_label("Erosion").click_accesskit();
    h.run_steps(2);
    let before = h.state().camera();
    drag(&mut h, c, c + egui::vec2(-120.0, 0.0));
    h.run_steps(4);
    assert_eq!(strokes(&h), (n + 1, n - 1), "no stroke on the Erosion tab");
    assert_ne!(h.state().camera(), before, "the drag moved the globe");
    assert!(!h.state().brush_state().0, "leaving the Brush tab disarmed the brush");

    // An erosion run started on a new layer and discarded leaves the project as it was.
    let layers_before = h.state().project().layers.len();
    let unsaved = h.state().unsaved();
    h.state_mut().set_erosion(4, 3000.0);
    h.get_by_label("start").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().project().layers.len(), layers_before + 1, "{}", h.state().message());
    h.get_by_label("discard").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().project().layers.len(), layers_before, "the run's new layer went with it");
    assert_eq!(h.state().unsaved(), unsaved);
}

/// Steps until the project being opened has been taken over.
fn wait_for_open(h: &mut Harness<'static, App>) {
    step_while(h, 6000, "opening the project", |a| a.opening());
}

#[test]
fn the_file_bar_saves_as_opens_autosaves_and_offers_the_recovery_after_a_crash() {
    use terrafuse::project::recovery;
    let dir = common::out_path("workstation-file");
    let _ = std::fs::remove_dir_all(&dir);
    let project = sample_project("erzurum", &dir);
    let mut h = harness(&project, "30km");
    settle(&mut h);
    let title = h.state().title();
    assert!(title.starts_with("erzurum.json — ") && title.ends_with(" — Terrafuse"), "{title}");

    // A change: the title says so at once and the recovery file holds it (autosaved).
    h.get_by_label("visible").click_accesskit();
    h.run_steps(2);
    assert!(h.state().title().starts_with("*erzurum.json"), "{}", h.state().title());
    let kept = recovery::find(&project).expect("autosaved to the recovery file");
    assert!(!kept.load().unwrap().layers[0].visible, "the recovery file has the change");
    assert!(Project::load(&project).unwrap().layers[0].visible, "the project file does not, yet");

    // Save as, into another folder: the copy reaches the same store, the window edits it, the
    // original keeps no recovery file, and the copy heads the recent list.
    let copies = dir.join("copies");
    std::fs::create_dir_all(&copies).unwrap();
    let copy = copies.join("copy.json");
    h.get_by_label("save as…").click_accesskit();
    h.run_steps(2);
    type_into(&mut h, "Save the project as", copy.to_str().unwrap());
    h.get_by_label("ok").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().project_path(), copy.as_path(), "{}", h.state().message());
    assert!(!h.state().unsaved() && h.state().title().starts_with("copy.json"));
    let (a, b) = (Project::load(&project).unwrap(), Project::load(&copy).unwrap());
    let store = |p: &Project| std::path::absolute(p.resolve(&p.layers[0].as_dataset().unwrap().store)).unwrap();
    assert_eq!(store(&a), store(&b), "the copy reads the same store");
    assert!(!b.layers[0].visible);
    assert!(recovery::find(&project).is_none() && recovery::find(&copy).is_none());
    assert_eq!(std::path::absolute(&copy).unwrap(), h.state().recent()[0]);

    // Opening a file that is not a project names it and keeps the window on the copy.
    h.get_by_label("open…").click_accesskit();
    h.run_steps(2);
    let bad = dir.join("not-a-project.json");
    std::fs::write(&bad, "{\"format\": \"x\"}").unwrap();
    type_into(&mut h, "Open the project file", bad.to_str().unwrap());
    h.get_by_label("ok").click_accesskit();
    h.run_steps(2);
    assert!(h.state().message().contains("not-a-project.json: format: 'x'"), "{}", h.state().message());
    assert_eq!(h.state().project_path(), copy.as_path());

    // Open the original again (from the recent list's hook), change it and "crash" (drop the
    // window without saving): the next window offers the recovery file, and restoring it brings
    // the change back as unsaved.
    h.state_mut().open_project(&project, None);
    wait_for_open(&mut h);
    assert_eq!(h.state().project_path(), project.as_path(), "{}", h.state().message());
    assert!(h.state().stack().layers[0].spec.visible && !h.state().unsaved());
    settle(&mut h);
    h.get_by_label("visible").click_accesskit();
    h.run_steps(2);
    assert!(recovery::find(&project).is_some());
    drop(h);
    let mut h = harness(&project, "30km");
    h.run_steps(2);
    assert!(h.state().recovery_offered().is_some(), "the recovery is offered");
    h.get_by_label("restore them").click_accesskit();
    h.run_steps(2);
    wait_for_open(&mut h);
    assert!(h.state().unsaved() && !h.state().stack().layers[0].spec.visible, "{}", h.state().message());
    assert!(h.state().title().starts_with("*erzurum.json"));
    h.get_by_label("save project *").click_accesskit();
    h.step();
    assert!(!Project::load(&project).unwrap().layers[0].visible, "{}", h.state().message());
    assert!(recovery::find(&project).is_none(), "saving removes the recovery file");
}

#[test]
fn a_change_a_command_makes_while_the_window_has_unsaved_edits_is_never_written_over() {
    let dir = common::out_path("workstation-two-writers");
    let _ = std::fs::remove_dir_all(&dir);
    let project = sample_project("moon-brushing", &dir);
    let strokes_on_disk = || Project::load(&project).unwrap().layers[1].strokes().len();
    let brush = |lat: f64| {
        let path = format!("{lat},40;{lat},41");
        let args = ["brush", project.to_str().unwrap(), "--layer", "sculpt", "--tool", "raise"];
        let more = ["--radius-m", "20000", "--strength-m", "100", "--path", path.as_str(), "--wait", "30"];
        let out = common::terrafuse(&[&args[..], &more[..]].concat(), "");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    let wait_until = |h: &mut Harness<'static, App>, what: &str, done: &dyn Fn(&App) -> bool| {
        for _ in 0..200 {
            h.step();
            if done(h.state()) {
                h.run_steps(2);
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        panic!("{what}: {}", h.state().message());
    };
    let mut h = harness(&project, "sculpt");
    settle(&mut h);
    let n = strokes_on_disk();

    // An unsaved change in the window (a layer hidden), then a stroke by a command.
    h.get_all_by_label("visible").next().unwrap().click_accesskit();
    h.run_steps(2);
    assert!(h.state().unsaved());
    let hidden = h.state().project().layers.iter().position(|l| !l.visible).expect("a layer hidden");
    brush(1.0);
    assert_eq!(strokes_on_disk(), n + 1);
    // The window sees the change within a second and asks; "decide later", then a save: refused,
    // and the command's stroke stays in the file.
    wait_until(&mut h, "the conflict is offered", &|a| a.disk_conflict());
    h.render().unwrap().save(dir.join("conflict.png")).unwrap(); // for people, not compared
    h.get_by_label("decide later").click_accesskit();
    h.run_steps(2);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run_steps(2);
    assert!(h.state().disk_conflict() && h.state().unsaved(), "{}", h.state().message());
    assert!(h.state().message().contains("another process changed the file"), "{}", h.state().message());
    assert_eq!(strokes_on_disk(), n + 1, "the command's stroke is kept");

    // Kept as a copy: the copy holds the window's version, the project the command's.
    h.get_by_label("keep mine as a copy").click_accesskit();
    h.run_steps(2);
    let copy = dir.join("moon-brushing.mine.json");
    assert_eq!(h.state().project_path(), copy.as_path(), "{}", h.state().message());
    let mine = Project::load(&copy).unwrap();
    assert!(!mine.layers[hidden].visible && mine.layers[1].strokes().len() == n, "the window's version");
    assert_eq!(strokes_on_disk(), n + 1);

    // Back on the project with another unsaved change, another command's stroke: reloading takes
    // it and drops the window's change.
    h.state_mut().open_project(&project, None);
    wait_for_open(&mut h);
    settle(&mut h);
    h.get_all_by_label("visible").next().unwrap().click_accesskit();
    h.run_steps(2);
    brush(2.0);
    wait_until(&mut h, "the conflict is offered", &|a| a.disk_conflict());
    h.get_by_label("reload it (drop my changes)").click_accesskit();
    wait_for_open(&mut h);
    assert!(!h.state().unsaved() && h.state().project().layers[hidden].visible);
    assert_eq!(h.state().project().layers[1].strokes().len(), n + 2);

    // With nothing unsaved, a command's change is simply reloaded.
    settle(&mut h);
    brush(3.0);
    wait_until(&mut h, "the change is reloaded", &|a| a.project().layers[1].strokes().len() == n + 3);
    assert!(!h.state().disk_conflict() && !h.state().unsaved());
    // And the window's own save goes through again.
    h.get_all_by_label("visible").next().unwrap().click_accesskit();
    h.run_steps(2);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.run_steps(2);
    let saved = Project::load(&project).unwrap();
    assert!(!saved.layers[hidden].visible && saved.layers[1].strokes().len() == n + 3, "{}", h.state().message());
}

/// Steps until the cluster-import panel's plan or merge is over.
fn wait_for_cluster(h: &mut Harness<'static, App>) {
    step_while(h, 6000, "the plan or merge", |a| a.cluster_import().busy());
}

/// Runs shard `i` of a plan as the cluster would, into the parts folder.
fn run_shard(manifest: &std::path::Path, parts: &std::path::Path, i: usize) {
    std::fs::create_dir_all(parts).unwrap();
    let part = parts.join(format!("part-{i:04}.gpkg"));
    let (m, p, shard) = (manifest.to_str().unwrap(), part.to_str().unwrap(), i.to_string());
    let o = common::terrafuse(&["import", "--manifest", m, "--shard", &shard, "--store", p, "--quiet"], "");
    assert!(o.status.success(), "shard {i}: {}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_cluster_import_is_planned_followed_merged_in_two_goes_and_added_from_the_panel() {
    let dir = common::out_path("workstation-cluster");
    let _ = std::fs::remove_dir_all(dir.join("plans"));
    let project = sample_project("moon-lola", &dir);
    let mut h = harness_of_size(&project, "globe", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    h.get_by_label("cluster import").click_accesskit();
    h.run_steps(2);

    // Bad input is refused by field, and nothing is written.
    let raster = repo_path("projects/data/moon_lola_north_stere_1600m.tif");
    let manifest = dir.join("plans/polar.json");
    type_into(&mut h, "source", raster.to_str().unwrap());
    type_into(&mut h, "shards", "two");
    type_into(&mut h, "plan file", manifest.to_str().unwrap());
    h.get_by_label("write plan").click_accesskit();
    h.run_steps(2);
    assert!(h.state().cluster_import().message.contains("shards: 'two'"), "{}", h.state().cluster_import().message);
    assert!(!manifest.exists());

    // The plan: written in the background, opened, no shard done yet.
    type_into(&mut h, "shards", "2");
    h.get_by_label("write plan").click_accesskit();
    wait_for_cluster(&mut h);
    let c = h.state().cluster_import();
    assert!(c.message.starts_with("wrote plan "), "{}", c.message);
    assert_eq!(c.plan().map(|m| m.shards.len()), Some(2));
    assert_eq!(c.shards_done(), [false, false]);
    assert!(manifest.exists());
    h.get_by_label_contains("0 of 2 shards done");
    let parts = dir.join("plans/parts");
    assert_eq!(c.parts, parts.display().to_string(), "the parts folder defaults to plans/parts");

    // One shard finishes on the "cluster": merged alone, the store says what is missing.
    run_shard(&manifest, &parts, 0);
    h.get_by_label("refresh").click_accesskit();
    h.run_steps(2);
    assert_eq!(h.state().cluster_import().shards_done(), [true, false]);
    h.get_by_label("merge 1 parts").click_accesskit();
    wait_for_cluster(&mut h);
    let c = h.state().cluster_import();
    assert!(c.message.contains("INCOMPLETE, 1 of 2 shards missing"), "{}", c.message);
    assert!(c.merged().is_none());
    h.render().unwrap().save(dir.join("cluster-panel.png")).unwrap(); // for people, not compared

    // The other one: the second merge adds it and builds the pyramid; the dataset goes on the stack.
    run_shard(&manifest, &parts, 1);
    h.get_by_label("refresh").click_accesskit();
    h.run_steps(2);
    h.get_by_label("merge 2 parts").click_accesskit();
    wait_for_cluster(&mut h);
    let c = h.state().cluster_import();
    assert!(c.message.contains("complete, all 2 shards in"), "{}", c.message);
    let (store, dataset) = c.merged().cloned().expect("the merged dataset is complete");
    h.get_by_label("add merged dataset").click_accesskit();
    h.step();
    wait_for_dataset(&mut h);
    let stack = h.state().stack();
    assert_eq!(stack.layers.len(), 2, "{}", h.state().message());
    assert_eq!(stack.layers[1].spec.name, dataset);
    assert!(store.exists());
}

#[test]
fn a_flight_is_recorded_while_flying_and_replayed_along_its_path() {
    let dir = common::out_path("workstation-flight");
    let p = sample_project("erzurum", &dir);
    let mut h = harness(&p, "30km");
    settle(&mut h);
    // Recording: the camera joins the path as it moves, twice a second at most.
    h.state_mut().record_flight(true);
    h.step();
    drag(&mut h, centre(), centre() + egui::vec2(60.0, 20.0));
    std::thread::sleep(Duration::from_millis(600));
    h.run_steps(2);
    drag(&mut h, centre(), centre() + egui::vec2(-40.0, 50.0));
    std::thread::sleep(Duration::from_millis(600));
    h.run_steps(2);
    h.state_mut().record_flight(false);
    let (text, _, recording, _) = h.state().flight_state();
    assert!(!recording);
    let waypoints = text.split(';').count();
    assert!(waypoints >= 3, "{waypoints} waypoints recorded: {text}");
    assert!(terrafuse::scene::flight::Flight::parse(text, 50.0).is_ok(), "the recorded path reads back: {text}");
    // Replaying a path: one camera a frame, ending on the last waypoint.
    h.state_mut().set_flight("39.3,40.4,30000,0,-60;39.35,40.45,10000,30,-30", 10);
    h.state_mut().play_flight().unwrap();
    step_while(&mut h, 200, "the flight", |a| a.flight_state().3);
    let c = h.state().camera();
    assert!((c.lat - 39.35).abs() < 1e-9 && (c.lon - 40.45).abs() < 1e-9 && (c.alt - 10000.0).abs() < 1e-6, "{c:?}");
    assert!((c.heading - 30.0).abs() < 1e-9 && (c.pitch + 30.0).abs() < 1e-9, "{c:?}");
    // A path that does not read is refused, named.
    h.state_mut().set_flight("39.3,40.4,30000,0,-60", 10);
    let e = h.state_mut().play_flight().unwrap_err().to_string();
    assert!(e.contains("at least two waypoints"), "{e}");
    h.state_mut().set_flight("39.3,40.4,x,0,-60;39.35,40.45,10000,30,-30", 10);
    let e = h.state_mut().play_flight().unwrap_err().to_string();
    assert!(e.contains("waypoint 1"), "{e}");
}

#[test]
fn a_comparison_too_large_for_the_window_is_planned_followed_round_by_round_and_merged_in_the_panel() {
    let dir = common::out_path("workstation-cluster-compare");
    let _ = std::fs::remove_dir_all(dir.join("plans"));
    let project = sample_project("erzurum-compare", &dir);
    let mut h = harness_of_size(&project, "30km", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    h.get_by_label("Compare").click_accesskit();
    h.run_steps(2);
    h.get_by_label("on a cluster (too large for the window)").click_accesskit();
    h.run_steps(2);
    let wait = |h: &mut Harness<'static, App>| step_while(h, 6000, "the plan or merge", |a| a.cluster_compare().busy());
    // Bad input is refused by field, nothing written.
    let plan = dir.join("plans/cmp.json");
    type_into(&mut h, "shards", "three");
    type_into(&mut h, "level", "9");
    type_into(&mut h, "plan file", plan.to_str().unwrap());
    h.get_by_label("write plan").click_accesskit();
    h.run_steps(2);
    assert!(h.state().cluster_compare().message.contains("shards: 'three'"), "{}", h.state().cluster_compare().message);
    assert!(!plan.exists());
    // The plan, written in the background: blurred − srtm in 3 shards, none done.
    type_into(&mut h, "shards", "3");
    h.get_by_label("write plan").click_accesskit();
    wait(&mut h);
    let c = h.state().cluster_compare();
    assert!(c.message.starts_with("wrote plan "), "{}", c.message);
    assert_eq!(
        c.plan().map(|p| (p.a.as_str(), p.b.as_str(), p.level, p.shards.len())),
        Some(("blurred", "srtm", 9, 3))
    );
    h.get_by_label_contains("0 of 3 shards done");
    h.get_by_label_contains("terrafuse slurm submit");
    // One shard on the "cluster"; the merge names the round and the two still to run.
    let p = plan.to_str().unwrap();
    assert!(common::terrafuse(&["shard", p, "1"], "").status.success());
    h.get_by_label("merge").click_accesskit();
    wait(&mut h);
    assert_eq!(h.state().cluster_compare().round().cloned(), Some((0, vec![false, true, false])));
    h.get_by_label_contains("1 of 3 shards done");
    // Every round run; the merge shows the statistics one `compare` prints.
    let o = common::terrafuse(&["shards", "run", p, "--jobs", "2"], "");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    h.get_by_label("merge").click_accesskit();
    wait(&mut h);
    let merged = h.state().cluster_compare().merged().expect("the merged comparison").clone();
    let one =
        common::terrafuse(&["compare", project.to_str().unwrap(), "blurred", "srtm", "--level", "9", "--json"], "");
    let one: serde_json::Value = serde_json::from_slice(&one.stdout).unwrap();
    assert_eq!(merged.stats.count, one["count"].as_u64().unwrap());
    assert_eq!(merged.stats.median_m, one["median_m"].as_f64().unwrap());
    assert_eq!(merged.stats.nmad_m, one["nmad_m"].as_f64().unwrap());
    h.render().unwrap().save(dir.join("cluster-compare.png")).unwrap(); // for people, not compared
}

#[test]
fn the_project_tab_exports_a_geotiff_and_plans_merges_one_for_a_cluster() {
    let dir = common::out_path("workstation-export");
    let _ = std::fs::remove_dir_all(dir.join("exports"));
    let project = sample_project("erzurum", &dir);
    let mut h = harness_of_size(&project, "30km", egui::vec2(900.0, 1700.0));
    settle(&mut h);
    h.get_by_label("Project").click_accesskit();
    h.run_steps(2);
    h.get_by_label("export GeoTIFF").click_accesskit();
    h.run_steps(2);
    let wait = |h: &mut Harness<'static, App>| step_while(h, 6000, "the export", |a| a.export_panel().busy());
    let out = dir.join("exports/window.tif");
    type_into(&mut h, "output", out.to_str().unwrap());
    type_into(&mut h, "bounds", "40.2,39.3,40.8");
    h.get_by_label("export").click_accesskit();
    h.run_steps(2);
    assert!(
        h.state().export_panel().message.contains("bounds: '40.2,39.3,40.8'"),
        "{}",
        h.state().export_panel().message
    );
    type_into(&mut h, "bounds", "40.2,39.3,40.8,39.9");
    type_into(&mut h, "pixel size", "0.005");
    h.get_by_label("export").click_accesskit();
    wait(&mut h);
    assert!(h.state().export_panel().message.starts_with("wrote"), "{}", h.state().export_panel().message);
    // The command line's export of the same grid: the same pixels.
    let cli = dir.join("exports/cli.tif");
    let crs = "+proj=longlat +a=6378137 +b=6356752.314245179 +no_defs";
    let args = ["--crs", crs, "--bounds", "40.2,39.3,40.8,39.9", "--resolution", "0.005", "--compose", "cpu"];
    let o =
        common::terrafuse(&[&["export", project.to_str().unwrap(), cli.to_str().unwrap()][..], &args[..]].concat(), "");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let raw = |tif: &std::path::Path| {
        let r = tif.with_extension("raw");
        common::run_tool("gdal_translate", &["-q", "-of", "ENVI", tif.to_str().unwrap(), r.to_str().unwrap()], "");
        std::fs::read(r).unwrap()
    };
    let window = raw(&out);
    assert_eq!(window, raw(&cli), "the window's export is the command line's");
    // Too large for the window: a plan in 3 shards, run on the "cluster", merged here.
    std::fs::remove_file(&out).unwrap();
    type_into(&mut h, "shards", "3");
    h.get_by_label("write plan").click_accesskit();
    wait(&mut h);
    assert_eq!(h.state().export_panel().plan().map(|(p, d)| (p.shards.len(), d.to_vec())), Some((3, vec![false; 3])));
    h.get_by_label_contains("0 of 3 shards done");
    let plan = out.with_extension("plan.json");
    for i in 0..3 {
        let o = common::terrafuse(&["shard", plan.to_str().unwrap(), &i.to_string()], "");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    h.get_by_label("refresh").click_accesskit();
    h.run_steps(2);
    h.get_by_label_contains("3 of 3 shards done");
    h.get_by_label("merge").click_accesskit();
    wait(&mut h);
    assert!(h.state().export_panel().message.starts_with("merged"), "{}", h.state().export_panel().message);
    assert_eq!(raw(&out), window, "the merged export is the single one, pixel for pixel");
    h.render().unwrap().save(dir.join("export-panel.png")).unwrap(); // for people, not compared
}
