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
