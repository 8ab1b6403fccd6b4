//! The project file's tests: defaults, checks, migrations, saving.

use super::*;

const MINIMAL: &str = r#"{"format": "terrafuse-project", "version": 1, "body": "moon"}"#;

#[test]
fn a_minimal_project_gets_the_defaults() {
    let p = Project::parse(MINIMAL).unwrap();
    assert_eq!(p.body, "moon");
    assert_eq!(p.detail.lod_threshold_px, 1.5);
    assert!(p.visuals.lighting.enabled);
    assert!(p.view(None).unwrap_err().to_string().contains("no views"));
}

#[test]
fn save_and_load_round_trip_and_paths_resolve_against_the_file() {
    let dir = std::env::temp_dir().join(format!("terrafuse-project-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut p = Project::new("wgs84");
    p.layers.push(LayerSpec::dataset("srtm", "s/e.gpkg"));
    p.views.insert("near".into(), CameraSpec::parse("39.9,41.3,2000,30,-20").unwrap());
    let path = dir.join("p.json");
    p.save(&path).unwrap();
    let q = Project::load(&path).unwrap();
    assert_eq!(q.layers, p.layers);
    assert_eq!(q.views, p.views);
    assert_eq!(q.resolve(&q.layers[0].as_dataset().unwrap().store), dir.join("s/e.gpkg"));
    assert_eq!(q.view(None).unwrap().heading, 30.0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_projects_are_refused_with_the_reason() {
    let cases = [
        ("{", "not valid JSON"),
        (r#"{"format": "x", "version": 1, "body": "moon"}"#, "format: 'x' is not"),
        (r#"{"format": "terrafuse-project", "version": 9, "body": "moon"}"#, "version: 9 is not supported"),
        (r#"{"format": "terrafuse-project", "version": 1, "body": "pluto"}"#, "body"),
        (r#"{"format": "terrafuse-project", "version": 1, "body": "moon", "colour": 1}"#, "unknown field"),
        (
            r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
                "views": {"v": {"lat": 95, "lon": 0, "alt": 1}}}"#,
            "view 'v': camera latitude 95",
        ),
        (
            r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
                "visuals": {"isolines": {"interval_m": 0}}}"#,
            "interval_m 0 must be positive",
        ),
    ];
    for (text, expected) in cases {
        let e = Project::parse(text).unwrap_err();
        assert!(e.to_string().contains(expected), "{text}: {e}");
    }
    let e = Project::load(Path::new("/nonexistent/p.json")).unwrap_err().to_string();
    assert!(e.starts_with("/nonexistent/p.json: cannot read"), "{e}");
}

#[test]
fn version_1_files_migrate_to_layers_first_listed_on_top() {
    let v1 = r#"{"format": "terrafuse-project", "version": 1, "body": "moon",
        "datasets": [{"name": "north", "store": "s.gpkg", "source": {"files": ["n.tif"]}},
                     {"name": "global", "store": "s.gpkg", "dataset": "lola"}]}"#;
    let p = Project::parse(v1).unwrap();
    assert_eq!(p.version, VERSION);
    let names: Vec<&str> = p.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["global", "north"], "bottom to top: the first listed ends on top");
    assert!(p.layers.iter().all(|l| l.is_data() && l.blend == crate::layers::BlendMode::Over));
    assert_eq!(p.layers[0].store_dataset(), "lola");
    assert_eq!(p.layers[1].as_dataset().unwrap().source.as_ref().unwrap().files, [PathBuf::from("n.tif")]);
    let text = serde_json::to_string(&p).unwrap();
    assert!(
        text.contains(&format!("\"version\":{VERSION}"))
            && text.contains("\"layers\"")
            && !text.contains("\"datasets\"")
    );
    // A version-2 file with datasets is refused (the field is gone), naming it.
    let e = Project::parse(r#"{"format": "terrafuse-project", "version": 2, "body": "moon", "datasets": []}"#);
    assert!(e.unwrap_err().to_string().contains("unknown field `datasets`"));
}

#[test]
fn every_kept_older_version_migrates_step_by_step_to_the_current_one() {
    // One kept file per older version, each read by the chain of steps from its version.
    let fixtures = [(1, "moon-lola-v1.json"), (2, "erzurum-erosion-v2.json"), (3, "erzurum-erosion-v3.json")];
    assert_eq!(fixtures.len(), migrate::STEPS.len(), "a kept file for every step");
    for (version, file) in fixtures {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(migrate::header(&text).unwrap(), version, "{file}");
        let p = Project::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(p.version, VERSION);
        assert!(!p.layers.is_empty() && !p.views.is_empty(), "{file}: layers and views kept");
        // Saved again, it reads back as the same project in the current version.
        let again = Project::parse(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(again.layers, p.layers);
    }
    // Version 3's erosion regions were [lat_min, lon_min, lat_max, lon_max]: they migrate to
    // [west, south, east, north], the same boxes the current sample holds.
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let old = Project::load(&fixtures.join("erzurum-erosion-v3.json")).unwrap();
    let now = Project::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("projects/erzurum-erosion.json")).unwrap();
    let text = std::fs::read_to_string(fixtures.join("erzurum-erosion-v3.json")).unwrap();
    let raw: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (old_runs, now_runs) = (old.layers[1].runs(), now.layers[1].runs());
    assert!(!old_runs.is_empty());
    for (k, (o, n)) in old_runs.iter().zip(now_runs).enumerate() {
        let [lat0, lon0, lat1, lon1]: [f64; 4] =
            serde_json::from_value(raw["layers"][1]["runs"][k]["region"].clone()).unwrap();
        assert_eq!(o.region.to_array(), [lon0, lat0, lon1, lat1], "run {k}");
        assert_eq!(o.region, n.region, "run {k}");
    }
    assert_eq!(old.layers, now.layers);
    let v2 = r#"{"format": "terrafuse-project", "version": 2, "body": "moon", "checks": {}}"#;
    let e = Project::parse(v2).unwrap_err();
    assert!(e.to_string().contains("migrating version 2 to 3: checks: a version-2 project has no checks"), "{e}");
}

#[test]
fn the_committed_schema_is_the_one_the_types_generate() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/project.schema.json");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == Project::schema(),
        "{} is out of date: run `cargo run -- project schema > docs/project.schema.json`",
        path.display()
    );
    // Every field of the top level is described (the docs page explains them with units).
    let schema: serde_json::Value = serde_json::from_str(&committed).unwrap();
    for (field, spec) in schema["properties"].as_object().unwrap() {
        assert!(spec.get("description").is_some(), "{field} has no description");
    }
}

#[test]
fn the_docs_page_holds_the_reference_the_types_generate() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/project-format.md");
    let page = std::fs::read_to_string(&path).unwrap_or_default();
    let marker = "<!-- reference: generated by `terrafuse project schema --markdown`; do not edit below -->\n";
    let generated = page.split_once(marker).map(|(_, r)| r).unwrap_or_default();
    assert!(
        generated == reference::markdown(),
        "{}: the reference is out of date: run scripts/project-docs",
        path.display()
    );
}

#[test]
fn errors_name_the_field_by_its_path() {
    let cases = [
        (
            r#"{"format": "terrafuse-project", "version": 4, "body": "moon",
                "layers": [{"name": "e", "kind": "edit", "strokes": [{"tool": "raise", "radius_m": "wide"}]}]}"#,
            "layers[0].strokes[0].radius_m: invalid type: string \"wide\", expected f64",
        ),
        (
            r#"{"format": "terrafuse-project", "version": 4, "body": "moon", "visuals": {"lighting": {"sun": 1}}}"#,
            "visuals.lighting.sun: unknown field `sun`, expected one of",
        ),
        (
            r#"{"format": "terrafuse-project", "version": 4, "body": "r=1e10"}"#,
            "body: a semi-major axis of 10000000000.0 m",
        ),
        (
            r#"{"format": "terrafuse-project", "version": 4, "body": "moon", "detail": {"max_quads": 1e99}}"#,
            "detail.max_quads",
        ),
        (r#"{"format": "terrafuse-project", "version": "3", "body": "moon"}"#, "version: \"3\" is not a whole number"),
        (r#"{"format": "terrafuse-project", "version": 4, "body": "moon"} {}"#, "trailing characters"),
        (
            r#"{"format": "terrafuse-project", "version": 4, "body": "moon", "checks": {"c": {"level": 4, "view": "v"}}}"#,
            "checks.c.view: 'v' is not one of the views",
        ),
    ];
    for (text, expected) in cases {
        let e = Project::parse(text).unwrap_err();
        assert!(e.to_string().contains(expected), "{text}: {e}");
    }
}

#[test]
fn save_as_elsewhere_rewrites_relative_paths_to_the_same_files() {
    let mut p = Project::new("moon");
    p.base_dir = PathBuf::from("/data/projects");
    let mut a = LayerSpec::dataset("a", "stores/a.gpkg");
    a.as_dataset_mut().unwrap().source =
        Some(SourceSpec { files: vec!["data/a.tif".into(), "/abs/b.tif".into()], ..Default::default() });
    p.layers.push(a);
    p.rebase(Path::new("/data/other/sub"));
    let data = p.layers[0].as_dataset().unwrap();
    assert_eq!(data.store, Path::new("../../projects/stores/a.gpkg"));
    let files = &data.source.as_ref().unwrap().files;
    assert_eq!(files, &[PathBuf::from("../../projects/data/a.tif"), PathBuf::from("/abs/b.tif")]);
    assert_eq!(p.resolve(&data.store), Path::new("/data/other/sub/../../projects/stores/a.gpkg"));
}

#[test]
fn layers_are_checked_with_their_index_and_name() {
    let bad = r#"{"format": "terrafuse-project", "version": 2, "body": "moon",
        "layers": [{"name": "sea", "kind": "constant", "height_m": 0},
                   {"name": "n", "kind": "procedural", "noise": {"amplitude_m": 5, "wavelength_m": -1}}]}"#;
    let e = Project::parse(bad).unwrap_err();
    assert!(e.to_string().contains("layers[1]: layer 'n': noise.wavelength_m: -1 must be a positive length"), "{e}");
    let bad = r#"{"format": "terrafuse-project", "version": 2, "body": "moon",
        "layers": [{"name": "sea", "kind": "constant", "height_m": 0, "blend": "screen"}]}"#;
    assert!(Project::parse(bad).unwrap_err().to_string().contains("unknown variant `screen`"));
}

#[test]
fn cameras_parse_from_the_command_line() {
    let c = CameraSpec::parse("39.9, 41.27, 30000, 45, -30").unwrap();
    assert_eq!((c.lat, c.lon, c.alt, c.heading, c.pitch, c.fov), (39.9, 41.27, 30000.0, 45.0, -30.0, 45.0));
    assert!(CameraSpec::parse("1,2,3").unwrap_err().to_string().contains("got 3 values"));
    assert!(CameraSpec::parse("1,2,x,4,5").unwrap_err().to_string().contains("'x' is not a number"));
    assert!(CameraSpec::parse("0,0,100,0,-100").unwrap_err().to_string().contains("pitch"));
}
