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
    let opened = gui::open(&ViewOptions {
        project: project.to_path_buf(),
        view: Some(view.into()),
        camera: None,
        lod_threshold: None,
        width: SIZE.x as u32,
        height: SIZE.y as u32,
        screenshot: None,
        timeout: Duration::from_secs(60),
    })
    .unwrap();
    Harness::builder()
        .with_size(SIZE)
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
    let dir = repo_path("tests/out/workstation");
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
    assert!((g.height_m - hit.height_m).abs() < 50.0, "the surface point lies at its height: {g:?} {hit:?}");

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
    h.get_by_role(egui::accesskit::Role::TextInput).focus();
    h.step();
    h.get_by_role(egui::accesskit::Role::TextInput).type_text("tycho-again");
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

    // The layers panel: hiding the (only) layer takes it out of the renderer's stack at once
    // and, saved, is in the project file; shown again, the terrain comes back. (The view is not
    // settled while the layer is hidden: without data, quads refine to level 6 for the shape of
    // the ellipsoid, which takes lavapipe minutes to draw.)
    h.get_by_label("visible").click_accesskit();
    h.step();
    assert!(h.state().unsaved());
    assert!(!h.state().stack().layers[0].spec.visible);
    h.get_by_label("save project *").click_accesskit();
    h.step();
    let saved = Project::load(&project).unwrap();
    assert!(!saved.layers[0].visible);
    assert_eq!(saved.version, 2);
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
    h.get_by_label("remove").click_accesskit();
    h.step();
    assert_eq!(h.state().stack().layers.len(), 1);
}
