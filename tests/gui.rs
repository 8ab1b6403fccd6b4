//! The workstation window in a real X server (Xvfb, started here) with lavapipe presenting
//! through Vulkan's X11 surface: the viewport of the window shows what the headless renderer
//! draws for the same camera, the panels are there, and bad input is refused before a window
//! opens.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::sample_project;

fn out_dir() -> PathBuf {
    let dir = common::out_path("gui");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An Xvfb server of this test run (never the user's display), stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        for n in 0..50 {
            let number = 140 + (std::process::id() as usize + n) % 400;
            if Path::new(&format!("/tmp/.X11-unix/X{number}")).exists()
                || Path::new(&format!("/tmp/.X{number}-lock")).exists()
            {
                continue;
            }
            let display = format!(":{number}");
            let mut child = Command::new("Xvfb")
                .args([&display, "-screen", "0", "1400x1000x24", "-nolisten", "tcp"])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap_or_else(|e| panic!("cannot start Xvfb ({e}): install it with scripts/install-deps"));
            let start = Instant::now();
            while start.elapsed() < Duration::from_secs(20) {
                if Path::new(&format!("/tmp/.X11-unix/X{number}")).exists() {
                    return Xvfb { child, display };
                }
                if let Ok(Some(_)) = child.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        panic!("no Xvfb display could be started");
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn terrafuse_on(display: Option<&str>, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_terrafuse"));
    c.args(args).env_remove("WAYLAND_DISPLAY");
    match display {
        Some(d) => c.env("DISPLAY", d),
        None => c.env_remove("DISPLAY"),
    };
    c.output().expect("terrafuse runs")
}

/// The value after `key: ` on a line of the report.
fn field<'a>(report: &'a str, key: &str) -> &'a str {
    report
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{key}: ")))
        .unwrap_or_else(|| panic!("no '{key}:' line in\n{report}"))
}

#[test]
fn the_window_shows_what_the_renderer_draws() {
    let x = Xvfb::start();
    for (name, view) in [("erzurum", "30km"), ("moon-lola", "globe")] {
        let project = sample_project(name, &out_dir());
        let shot = out_dir().join(format!("{name}-{view}.window.png"));
        let _ = std::fs::remove_file(&shot);
        let p = project.to_str().unwrap();
        let o = terrafuse_on(
            Some(&x.display),
            &[
                "view",
                p,
                "--view",
                view,
                "--width",
                "960",
                "--height",
                "640",
                "--screenshot",
                shot.to_str().unwrap(),
                "--timeout",
                "240",
            ],
        );
        let report = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{name}: {report}\n{}", String::from_utf8_lossy(&o.stderr));
        let window = image::open(&shot).unwrap().to_rgba8();
        assert_eq!((window.width(), window.height()), (960, 640), "the window's size");

        // The viewport: where it is in the window and the camera it was drawn with.
        let rect: Vec<u32> =
            field(&report, "viewport").split_whitespace().take(4).map(|v| v.parse().unwrap()).collect();
        let (vx, vy, vw, vh) = (rect[0], rect[1], rect[2], rect[3]);
        assert!(vx >= 150 && vw >= 400 && vh >= 400 && vx + vw <= 960 && vy + vh <= 640, "{rect:?}");
        let camera = field(&report, "camera");
        // The legend drawn over the viewport (bottom left) is no part of the terrain's picture.
        let legend: Vec<f64> =
            field(&report, "legend").split_whitespace().take(4).map(|v| v.parse().unwrap()).collect();
        assert!(legend[2] > 50.0 && legend[3] > 20.0, "a legend is drawn: {legend:?}");
        let in_legend = |x: u32, y: u32| {
            let (x, y) = (f64::from(x), f64::from(y));
            x >= legend[0].floor()
                && x <= (legend[0] + legend[2]).ceil()
                && y >= legend[1].floor()
                && y <= (legend[1] + legend[3]).ceil()
        };

        // The same camera and size, headless.
        let reference = out_dir().join(format!("{name}-{view}.render.png"));
        let (w, h) = (vw.to_string(), vh.to_string());
        let r = terrafuse_on(
            None,
            &["render", p, "--camera", camera, "--width", &w, "--height", &h, "--out", reference.to_str().unwrap()],
        );
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let count = |s: &str| s.split_whitespace().next().unwrap().parse::<usize>().unwrap();
        let rendered = String::from_utf8_lossy(&r.stdout).into_owned();
        assert_eq!(count(field(&rendered, "quads")), count(field(&report, "frame")), "both drew as many quads");
        let headless = image::open(&reference).unwrap().to_rgba8();
        let (mut sum, mut big, mut terrain, mut pixels) = (0f64, 0usize, 0usize, 0usize);
        let mut diff = image::RgbaImage::new(vw, vh);
        for y in 0..vh {
            for x in 0..vw {
                if in_legend(vx + x, vy + y) {
                    continue;
                }
                pixels += 1;
                let a = window.get_pixel(vx + x, vy + y).0;
                let b = headless.get_pixel(x, y).0;
                let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap();
                sum += (0..3).map(|c| f64::from(a[c].abs_diff(b[c]))).sum::<f64>() / 3.0;
                big += usize::from(d > 24);
                terrain += usize::from(b[..3] != [0, 0, 0]);
                diff.put_pixel(x, y, image::Rgba([d.saturating_mul(4), d.saturating_mul(4), d.saturating_mul(4), 255]));
            }
        }
        let pixels = pixels as f64;
        let (mean, share) = (sum / pixels, big as f64 / pixels);
        // The same device draws both: they should agree to the byte, but allow a driver some rounding.
        if mean > 0.25 || share > 0.001 {
            diff.save(out_dir().join(format!("{name}-{view}.diff.png"))).unwrap();
        }
        assert!(terrain as f64 > 0.3 * pixels, "{name}: terrain covers {terrain} of {pixels} pixels");
        assert!(
            mean <= 1.0 && share <= 0.005,
            "{name}: window vs headless: mean {mean:.3}, {:.3} % off by > 24",
            share * 100.0
        );

        // The settings panel left of the viewport holds widgets and text: many distinct colours.
        let mut colours = std::collections::BTreeSet::new();
        for y in (0..vh).step_by(3) {
            for x in (0..vx).step_by(3) {
                colours.insert(window.get_pixel(x, y).0);
            }
        }
        assert!(colours.len() > 20, "{name}: the side panel shows {} colours", colours.len());
        eprintln!(
            "{name} {view}: window vs headless mean {mean:.3}, {:.4} % > 24; {}",
            share * 100.0,
            field(&report, "frame")
        );
    }
}

#[test]
fn bad_input_is_refused_before_a_window_opens() {
    let project = sample_project("moon-lola", &out_dir());
    let p = project.to_str().unwrap();
    // No display: says what to do instead.
    let o = terrafuse_on(None, &["view", p]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("DISPLAY is not set") && e.contains("terrafuse render"), "{e}");
    // With a display named (none needs to exist: these fail before one is opened).
    let fake = Some(":9999");
    let o = terrafuse_on(fake, &["view", p, "--view", "nowhere"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("nowhere") && e.contains("globe"), "{e}");
    let o = terrafuse_on(fake, &["view", p, "--screenshot", "/nonexistent/folder/shot.png"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("/nonexistent/folder"), "{e}");
    let o = terrafuse_on(fake, &["view", p, "--camera", "10,20,-5e9,0"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--camera"), "{e}");
    let o = terrafuse_on(fake, &["view", "/nonexistent/project.json"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("/nonexistent/project.json"), "{e}");
}

/// The window's own state, as its debug hook writes it each frame (`gui::app::debug_hook`).
fn window_state(dir: &Path) -> Option<serde_json::Value> {
    serde_json::from_str(&std::fs::read_to_string(dir.join("state.json")).ok()?).ok()
}

/// Waits until the window's state passes `done` (or panics after `limit`), returning it.
fn wait_state(dir: &Path, limit: Duration, what: &str, done: impl Fn(&serde_json::Value) -> bool) -> serde_json::Value {
    let start = Instant::now();
    loop {
        if let Some(s) = window_state(dir)
            && done(&s)
        {
            return s;
        }
        assert!(start.elapsed() < limit, "{what}: {:?}", window_state(dir));
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs `xdotool` with its commands on `display`.
fn xdotool(display: &str, args: &[String]) -> String {
    let out = Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .unwrap_or_else(|e| panic!("cannot run xdotool ({e}): install it with scripts/install-deps"));
    assert!(out.status.success(), "xdotool {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A drag with the left button from `from` to `to` (screen pixels) in `steps` moves over
/// `seconds`, as a hand does it.
fn drag_args(from: (f64, f64), to: (f64, f64), steps: usize, seconds: f64) -> Vec<String> {
    let mut a: Vec<String> =
        vec!["mousemove".into(), format!("{:.0}", from.0), format!("{:.0}", from.1), "mousedown".into(), "1".into()];
    for k in 1..=steps {
        let t = k as f64 / steps as f64;
        a.extend([
            "sleep".into(),
            format!("{:.3}", seconds / steps as f64),
            "mousemove".into(),
            format!("{:.0}", from.0 + (to.0 - from.0) * t),
            format!("{:.0}", from.1 + (to.1 - from.1) * t),
        ]);
    }
    a.extend(["mouseup".into(), "1".into()]);
    a
}

#[test]
fn the_real_window_takes_every_event_between_slow_frames() {
    use terrafuse::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic, geodetic_from_ecef};
    use terrafuse::project::{CameraSpec, Project};
    use terrafuse::scene::Camera;
    // A flat Moon (a constant layer at 0 m): the terrain under a pixel is the ray's crossing of
    // the sphere, which the test computes itself from the window's camera.
    let dir = common::scratch("gui/real-window");
    let mut p = Project::new("moon");
    p.layers.push(terrafuse::layers::LayerSpec::constant("datum", 0.0));
    p.layers.push(terrafuse::layers::LayerSpec::edit("sculpt"));
    let path = dir.join("flat.json");
    p.save(&path).unwrap();
    let debug = dir.join("debug");
    std::fs::create_dir_all(&debug).unwrap();
    let x = Xvfb::start();
    let mut window = Command::new(env!("CARGO_BIN_EXE_terrafuse"))
        .args(["view", path.to_str().unwrap(), "--camera", "0,0,400000,0,-90,45", "--width", "1000", "--height", "760"])
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("TERRAFUSE_DEBUG_WINDOW", &debug)
        .env("TERRAFUSE_FRAME_DELAY_MS", "1000")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    struct Kill<'a>(&'a mut Child);
    impl Drop for Kill<'_> {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let _window = Kill(&mut window);
    let settled = wait_state(&debug, Duration::from_secs(120), "the window draws", |s| {
        s["frame"].as_u64().unwrap_or(0) >= 3 && s["viewport_px"].is_array()
    });
    let id = xdotool(&x.display, &["search".into(), "--sync".into(), "--name".into(), "Terrafuse".into()]);
    let id = id.lines().next().unwrap().trim().to_string();
    let geometry = xdotool(&x.display, &["getwindowgeometry".into(), "--shell".into(), id.clone()]);
    let at = |key: &str| -> f64 {
        geometry.lines().find_map(|l| l.strip_prefix(&format!("{key}="))).unwrap().trim().parse().unwrap()
    };
    let (wx, wy) = (at("X"), at("Y"));
    // No window manager gives the window the keyboard: the test does, as a desktop would.
    xdotool(&x.display, &["windowfocus".into(), "--sync".into(), id.clone()]);
    let vp: Vec<f64> = settled["viewport_px"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let target: Vec<u32> = settled["target"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as u32).collect();
    let (tw, th) = (target[0], target[1]);
    // A screen pixel's target pixel, and back.
    let to_target =
        |s: (f64, f64)| ((s.0 - wx - vp[0]) * f64::from(tw) / vp[2], (s.1 - wy - vp[1]) * f64::from(th) / vp[3]);
    let centre = (wx + vp[0] + 0.5 * vp[2], wy + vp[1] + 0.5 * vp[3]);
    let e = Ellipsoid::MOON;
    let camera_of = |s: &serde_json::Value| {
        let c: Vec<f64> = s["camera"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        Camera::new(&e, CameraSpec { lat: c[0], lon: c[1], alt: c[2], heading: c[3], pitch: c[4], fov: c[5] }, 1.0)
    };
    let under = |cam: &Camera, s: (f64, f64)| {
        let (px, py) = to_target(s);
        terrafuse::gui::navigate::fallback_target(&e, cam, cam.ray(px, py, tw, th))
    };
    let on_screen = |cam: &Camera, p: glam::DVec3| {
        let (x, y, _) = cam.project(p - cam.position, tw, th).unwrap();
        (x * vp[2] / f64::from(tw) + wx + vp[0], y * vp[3] / f64::from(th) + wy + vp[1])
    };
    let frames = |s: &serde_json::Value| s["frame"].as_u64().unwrap();

    // 1. A 300 px drag over a second (a frame lasts a second): the grabbed point ends 300 px on.
    let before = window_state(&debug).unwrap();
    let grabbed = under(&camera_of(&before), centre);
    let to = (centre.0 + 300.0, centre.1);
    xdotool(&x.display, &drag_args(centre, to, 10, 1.0));
    let n = frames(&window_state(&debug).unwrap());
    let after = wait_state(&debug, Duration::from_secs(30), "the drag is drawn", |s| {
        frames(s) >= n + 3 && s["camera"] != before["camera"]
    });
    let landed = on_screen(&camera_of(&after), grabbed);
    let off = ((landed.0 - to.0).powi(2) + (landed.1 - to.1).powi(2)).sqrt();
    assert!(
        off <= 0.02 * 300.0,
        "the grabbed point is {off:.1} px from the cursor: at {landed:?}, cursor {to:?}; before {before}, after {after}"
    );

    // 2. A stroke drawn over a second starts where the button went down and ends where it came up.
    std::fs::write(debug.join("commands"), "tab brush\nbrush on\n").unwrap();
    wait_state(&debug, Duration::from_secs(30), "the brush is armed", |s| s["brush_armed"] == true);
    let camera = camera_of(&window_state(&debug).unwrap());
    let (from, to) = ((centre.0 - 150.0, centre.1 + 40.0), (centre.0 + 150.0, centre.1 - 40.0));
    xdotool(&x.display, &drag_args(from, to, 12, 1.0));
    let stroked = wait_state(&debug, Duration::from_secs(60), "the stroke is kept", |s| s["layers"]["sculpt"][0] == 1);
    let path = stroked["last_stroke_path"].as_array().unwrap().clone();
    let point = |v: &serde_json::Value| {
        let (lat, lon) = (v[0].as_f64().unwrap(), v[1].as_f64().unwrap());
        on_screen(
            &camera,
            ecef_from_geodetic(&e, Geodetic { lat_rad: lat.to_radians(), lon_rad: lon.to_radians(), height_m: 0.0 }),
        )
    };
    let (first, last) = (point(&path[0]), point(path.last().unwrap()));
    let dist = |a: (f64, f64), b: (f64, f64)| ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
    assert!(dist(first, from) <= 2.0, "the stroke starts at {first:?}, the press was at {from:?}");
    assert!(dist(last, to) <= 2.0, "the stroke ends at {last:?}, the release was at {to:?}");
    assert!(path.len() >= 3, "it follows the path drawn: {} points", path.len());
    let _ = geodetic_from_ecef(&e, grabbed);

    // 3. Ctrl+Z tapped for 100 ms undoes exactly one stroke (no repeat, the modifier of the press).
    xdotool(&x.display, &["mousemove".into(), format!("{:.0}", centre.0), format!("{:.0}", centre.1)]);
    xdotool(
        &x.display,
        &[
            "keydown".into(),
            "ctrl".into(),
            "keydown".into(),
            "z".into(),
            "sleep".into(),
            "0.1".into(),
            "keyup".into(),
            "z".into(),
            "keyup".into(),
            "ctrl".into(),
        ],
    );
    let n = frames(&window_state(&debug).unwrap());
    let undone = wait_state(&debug, Duration::from_secs(30), "the undo", |s| frames(s) >= n + 2);
    assert_eq!(undone["layers"]["sculpt"], serde_json::json!([1, 0]), "one stroke undone: {undone}");

    // 4. On the Erosion tab (the brush still ticked on Brush), a left drag moves the globe.
    std::fs::write(debug.join("commands"), "tab erosion\n").unwrap();
    wait_state(&debug, Duration::from_secs(30), "the erosion tab", |s| s["tab"] == "Erosion");
    let before = window_state(&debug).unwrap();
    xdotool(&x.display, &drag_args(centre, (centre.0 - 120.0, centre.1), 6, 0.6));
    let n = frames(&before);
    let after = wait_state(&debug, Duration::from_secs(30), "the drag is drawn", |s| frames(s) >= n + 3);
    assert_eq!(after["layers"]["sculpt"], serde_json::json!([1, 0]), "no stroke was painted: {after}");
    assert_ne!(after["camera"], before["camera"], "the drag moved the globe");

    // 5. While an erosion run goes on (its progress shown on the terrain), a frame costs what
    //    drawing costs (the median of the last frames: showing progress recomposes quads, which
    //    on a software GPU takes seconds, so it is paced) and a double click zooms within two
    //    frames.
    let median = |s: &serde_json::Value| {
        let mut v: Vec<f64> = s["recent_ms"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let idle_ms = median(&after);
    std::fs::write(debug.join("commands"), "erosion 1000000 5000\n").unwrap();
    let drawn = |s: &serde_json::Value| s["drawn"].as_u64().unwrap();
    let shown = wait_state(&debug, Duration::from_secs(120), "the run's progress shows", |s| {
        s["erosion"].as_array().is_some_and(|e| e[0].as_u64().unwrap_or(0) > 0) && drawn(s) > drawn(&after) + 1
    });
    let n = frames(&shown);
    let later = wait_state(&debug, Duration::from_secs(60), "frames during the run", |s| frames(s) >= n + 8);
    let run_ms = median(&later);
    assert!(
        run_ms < 2.0 * idle_ms + 200.0,
        "frames during the run took {run_ms:.0} ms (idle {idle_ms:.0} ms): {later}"
    );
    let alt = |s: &serde_json::Value| s["camera"][2].as_f64().unwrap();
    let (n, before_alt) = (frames(&later), alt(&later));
    xdotool(
        &x.display,
        &[
            "mousemove".into(),
            format!("{:.0}", centre.0),
            format!("{:.0}", centre.1),
            "click".into(),
            "--repeat".into(),
            "2".into(),
            "--delay".into(),
            "80".into(),
            "1".into(),
        ],
    );
    let zoomed = wait_state(&debug, Duration::from_secs(30), "the double click", |s| alt(s) < 0.8 * before_alt);
    assert!(frames(&zoomed) <= n + 2, "the double click took {} frames", frames(&zoomed) - n);
}
