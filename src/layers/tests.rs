//! The stack's semantics checked against an independent evaluation of the README's formulas,
//! written out by hand per case (not through `fold`).

use super::compose::{DataAt, SamplePoint, compose_sample, range_bound};
use super::spec::{BlendMode, ExtentSpec, LayerSpec, NoiseSpec};
use super::stack::Stack;
use crate::ecm::points::sample_point;
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;

fn constant(name: &str, h: f64, blend: BlendMode, opacity: f64) -> LayerSpec {
    LayerSpec { blend, opacity, ..LayerSpec::constant(name, h) }
}

fn at(stack: &Stack, quad: QuadId, i: u32, j: u32) -> SamplePoint {
    let (ecef, lon_rad, lat_rad) = sample_point(&stack.ellipsoid, quad, 257, i, j);
    SamplePoint { ecef, lon_rad, lat_rad }
}

/// Composes constant layers (and datasets given by `raw`) at the centre of a front-face quad.
fn compose(specs: &[LayerSpec], raw: &[f64]) -> f64 {
    let mut stack = Stack::new(Ellipsoid::MOON, specs).unwrap();
    for (k, l) in specs.iter().enumerate() {
        if l.is_data() {
            stack.set_dataset_info(k, (0.0, 1.0), None);
            stack.layers[k].data_spacing_m = 100.0;
        }
    }
    let quad = QuadId { face: Face::Front, level: 3, x: 2, y: 5 };
    let plan = stack.plan(quad, &|_| true, true);
    let raw_of = |k: usize| {
        let index = plan.layers[k].index;
        raw.get(index).copied().unwrap_or(f64::NAN)
    };
    compose_sample(&stack, &plan, &at(&stack, quad, 128, 128), &|k| DataAt::raw(raw_of(k)))
}

#[test]
fn each_blend_mode_follows_its_formula() {
    let base = constant("base", 100.0, BlendMode::Over, 1.0);
    // over: h + α(v − h) = 100 + 0.25·(300 − 100)
    assert_eq!(compose(&[base.clone(), constant("v", 300.0, BlendMode::Over, 0.25)], &[]), 150.0);
    // add: h + α·v = 100 + 0.5·40
    assert_eq!(compose(&[base.clone(), constant("v", 40.0, BlendMode::Add, 0.5)], &[]), 120.0);
    // min: h + α(min(h, v) − h) = 100 + 0.5·(60 − 100)
    assert_eq!(compose(&[base.clone(), constant("v", 60.0, BlendMode::Min, 0.5)], &[]), 80.0);
    assert_eq!(compose(&[base.clone(), constant("v", 160.0, BlendMode::Min, 0.5)], &[]), 100.0);
    // max: h + α(max(h, v) − h) = 100 + 0.5·(160 − 100)
    assert_eq!(compose(&[base.clone(), constant("v", 160.0, BlendMode::Max, 0.5)], &[]), 130.0);
    // Where h has no data: over, min and max set h = v (whatever α); add gives nothing.
    assert_eq!(compose(&[constant("v", 7.0, BlendMode::Over, 0.1)], &[]), 7.0);
    assert_eq!(compose(&[constant("v", 7.0, BlendMode::Min, 0.1)], &[]), 7.0);
    assert!(compose(&[constant("v", 7.0, BlendMode::Add, 1.0)], &[]).is_nan());
    // Nothing at all: no data.
    assert!(compose(&[], &[]).is_nan());
}

#[test]
fn a_mean_group_is_a_weighted_mean_applied_with_over_at_its_largest_coverage() {
    let base = constant("base", 0.0, BlendMode::Over, 1.0);
    let member = |name: &str, h: f64, opacity: f64, weight: f64| LayerSpec {
        weight,
        ..constant(name, h, BlendMode::Mean, opacity)
    };
    // Σ wαv / Σ wα = (1·1·100 + 3·0.5·200) / (1 + 1.5) = 160; over with α = max(1, 0.5) = 1.
    let h = compose(&[base.clone(), member("a", 100.0, 1.0, 1.0), member("b", 200.0, 0.5, 3.0)], &[]);
    assert!((h - 160.0).abs() < 1e-12, "{h}");
    // Group coverage below 1: over at α = 0.5 → 0 + 0.5·(mean 100) = 50.
    let h = compose(&[base.clone(), member("a", 100.0, 0.5, 1.0)], &[]);
    assert_eq!(h, 50.0);
    // A member without data does not count: datasets given raw values (NaN: none).
    let d = |name: &str| LayerSpec { blend: BlendMode::Mean, ..LayerSpec::dataset(name, "s.gpkg") };
    let h = compose(&[d("x"), d("y"), d("z")], &[10.0, f64::NAN, 40.0]);
    assert_eq!(h, 25.0);
    // Two groups separated by another layer are two means.
    let h = compose(
        &[
            member("a", 100.0, 1.0, 1.0),
            member("b", 300.0, 1.0, 1.0),
            constant("c", 0.0, BlendMode::Add, 1.0),
            member("d", 50.0, 1.0, 1.0),
        ],
        &[],
    );
    assert_eq!(h, 50.0, "the second group replaces (over, α 1) the first's 200");
}

#[test]
fn scale_offset_and_valid_range_apply_to_the_value() {
    let d = LayerSpec {
        scale: 0.5,
        offset_m: 10.0,
        valid_range_m: Some([0.0, 100.0]),
        ..LayerSpec::dataset("d", "s.gpkg")
    };
    assert_eq!(compose(std::slice::from_ref(&d), &[100.0]), 60.0);
    assert!(compose(std::slice::from_ref(&d), &[300.0]).is_nan(), "160 m is outside [0, 100]: no data");
    let base = constant("base", 5.0, BlendMode::Over, 1.0);
    assert_eq!(compose(&[base, d], &[300.0]), 5.0, "an invalid value leaves h as it was");
}

#[test]
fn invisible_and_transparent_layers_are_not_read_but_still_stamp_the_quad() {
    let quad = QuadId { face: Face::Front, level: 3, x: 2, y: 5 };
    let mut specs = vec![constant("a", 1.0, BlendMode::Over, 1.0), constant("b", 2.0, BlendMode::Over, 1.0)];
    specs[1].visible = false;
    let mut stack = Stack::new(Ellipsoid::MOON, &specs).unwrap();
    let plan = stack.plan(quad, &|_| true, true);
    assert_eq!(plan.layers.len(), 1);
    let mut b = specs[1].clone();
    b.visible = true;
    stack.set(1, b).unwrap();
    let plan2 = stack.plan(quad, &|_| true, true);
    assert_eq!(plan2.layers.len(), 2);
    assert_ne!(plan.stamp, plan2.stamp, "making a touching layer visible changes the stamp");
    // A layer whose extent misses the quad neither stamps it nor is read.
    let far = LayerSpec {
        extent: Some(ExtentSpec::Box([100.0, 10.0, 110.0, 20.0])),
        ..constant("far", 9.0, BlendMode::Over, 1.0)
    };
    stack.insert(2, far.clone()).unwrap();
    let plan3 = stack.plan(quad, &|_| true, true);
    assert_eq!(plan3.layers.len(), 2);
    let mut far2 = far;
    far2.offset_m = 5.0;
    stack.set(2, far2).unwrap();
    assert_eq!(stack.plan(quad, &|_| true, true).stamp, plan3.stamp, "an edit far away does not stale this quad");
}

#[test]
fn the_feather_follows_the_distance_on_the_ellipsoid_across_a_face_edge() {
    // A box on the Moon whose western edge (lon −45.5°) lies half a degree west of the
    // front/left face edge (lon −45°), so its 30 km (≈ 1°) feather straddles the face edge: the
    // mask at samples of quads on both faces follows smoothstep(d / feather), with d the
    // great-circle distance to the meridian, R·asin(sin Δλ·cos φ) on a sphere.
    let r = Ellipsoid::MOON.a_m();
    let feather = 30_000.0;
    let layer = LayerSpec {
        extent: Some(ExtentSpec::Box([-45.5, -20.0, 20.0, 20.0])),
        feather_m: feather,
        ..constant("box", 100.0, BlendMode::Over, 1.0)
    };
    let stack = Stack::new(Ellipsoid::MOON, &[constant("base", 0.0, BlendMode::Over, 1.0), layer]).unwrap();
    let mut checked = 0;
    for quad in
        [QuadId { face: Face::Front, level: 5, x: 0, y: 15 }, QuadId { face: Face::Left, level: 5, x: 31, y: 15 }]
    {
        let plan = stack.plan(quad, &|_| true, true);
        for (i, j) in [(0u32, 128u32), (64, 100), (200, 50), (256, 256)] {
            let p = at(&stack, quad, i, j);
            let h = compose_sample(&stack, &plan, &p, &|_| DataAt::raw(f64::NAN));
            let dlon = p.lon_rad + 45.5f64.to_radians();
            let d = r * (dlon.sin() * p.lat_rad.cos()).asin();
            let expected = if dlon < 0.0 { 0.0 } else { 100.0 * crate::maths::smoothstep(d / feather) };
            // The chord's sag (0.05° chords on the Moon: 0.17 m) and chord-vs-arc (< 0.01 m at
            // 30 km) move d by < 0.2 m: 100 m × 1.5/30 km × 0.2 m = 0.001 m.
            assert!((h - expected).abs() < 2e-3, "{quad} ({i},{j}): {h} vs {expected} (d {d})");
            checked += 1;
        }
    }
    assert_eq!(checked, 8);
}

#[test]
fn bounds_hold_every_composed_sample() {
    let noise = NoiseSpec {
        noise_type: super::NoiseType::Fbm,
        seed: 3,
        amplitude_m: 50.0,
        wavelength_m: 20_000.0,
        octaves: 6,
        lacunarity: 2.0,
        gain: 0.5,
        placement: super::DetailWhere::Everywhere,
    };
    let specs = [
        constant("base", 100.0, BlendMode::Over, 1.0),
        LayerSpec::procedural("detail", noise),
        constant("raise", 5000.0, BlendMode::Add, 1.0),
        constant("cap", 5120.0, BlendMode::Min, 0.7),
    ];
    let stack = Stack::new(Ellipsoid::MOON, &specs).unwrap();
    let quad = QuadId { face: Face::Top, level: 6, x: 20, y: 40 };
    let plan = stack.plan(quad, &|_| true, true);
    let (lo, hi) = range_bound(&stack, &plan, &|k| stack.layers[plan.layers[k].index].value_range_m()).unwrap();
    let heights = super::compose_quad(&stack, &plan, &|_| super::LayerTiles::default());
    for h in heights {
        assert!(h as f64 >= lo - 1e-3 && h as f64 <= hi + 1e-3, "{h} outside [{lo}, {hi}]");
    }
    assert!(lo >= 5000.0 - 100.0 && hi <= 5200.0, "[{lo}, {hi}]");
}

#[test]
fn bad_layers_name_the_layer_and_the_field() {
    let cases: Vec<(LayerSpec, &str)> = vec![
        (LayerSpec { opacity: 1.5, ..LayerSpec::constant("c", 0.0) }, "layer 'c': opacity: 1.5 must lie in [0, 1]"),
        (
            LayerSpec { feather_m: 10.0, ..LayerSpec::constant("c", 0.0) },
            "layer 'c': feather_m: feathers the extent's edge",
        ),
        (
            with_dataset(|d| d.feather_edge_m = -5.0),
            "layer 'd': feather_edge_m: -5 must be a distance in metres from 0 to",
        ),
        (
            with_dataset(|d| d.shift_m = [20_000.0, 0.0]),
            "layer 'd': shift_m: [20000.0, 0.0] must be [east, north] in metres, each within ±10000",
        ),
        (
            LayerSpec { extent: Some(ExtentSpec::Box([0.0, 10.0, 5.0, 5.0])), ..LayerSpec::constant("c", 0.0) },
            "layer 'c': extent: box south 10 and north 5",
        ),
        (
            LayerSpec {
                extent: Some(ExtentSpec::Polygon(vec![[0.0, 0.0], [1.0, 1.0]])),
                ..LayerSpec::constant("c", 0.0)
            },
            "a polygon needs at least 3 vertices",
        ),
    ];
    for (spec, expected) in cases {
        let e = spec.check(6.4e6).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}\n  expected: {expected}");
    }
    let mut n = NoiseSpec {
        noise_type: super::NoiseType::Ridged,
        seed: 0,
        amplitude_m: 1.0,
        wavelength_m: 1.0,
        octaves: 24,
        lacunarity: 2.0,
        gain: 0.5,
        placement: super::DetailWhere::Everywhere,
    };
    let e = LayerSpec::procedural("n", n.clone()).check(6.4e6).unwrap_err().to_string();
    assert!(e.contains("layer 'n': noise.octaves: the finest octave's wavelength"), "{e}");
    n.gain = 1.0;
    let e = LayerSpec::procedural("n", n).check(6.4e6).unwrap_err().to_string();
    assert!(e.contains("noise.gain"), "{e}");
    let dup = Stack::new(Ellipsoid::MOON, &[LayerSpec::constant("a", 0.0), LayerSpec::constant("a", 1.0)]);
    assert!(dup.unwrap_err().to_string().contains("layer 'a': name: is used by another layer"));
}

fn with_dataset(change: impl FnOnce(&mut super::DatasetLayer)) -> LayerSpec {
    let mut spec = LayerSpec::dataset("d", "s");
    change(spec.as_dataset_mut().unwrap());
    spec
}

/// A layer read from a file's JSON (what a project's `layers` holds).
fn read_layer(json: &str) -> Result<LayerSpec, serde_json::Error> {
    serde_json::from_str::<LayerSpec>(json)
}

#[test]
fn a_file_that_gives_a_layer_another_kinds_field_is_refused_by_name() {
    let cases = [
        (
            r#"{"name": "d", "kind": "dataset", "store": "s", "height_m": 1}"#,
            "layer 'd': height_m: is not a field of a dataset layer",
        ),
        (r#"{"name": "d", "kind": "dataset"}"#, "layer 'd': store: a dataset layer needs its store"),
        (
            r#"{"name": "c", "kind": "constant", "height_m": 0, "shift_m": [5, 0]}"#,
            "layer 'c': shift_m: is not a field of a constant layer",
        ),
        (
            r#"{"name": "c", "kind": "constant", "height_m": 0, "feather_edge_m": 500}"#,
            "layer 'c': feather_edge_m: is not a field of a constant layer",
        ),
        (
            r#"{"name": "c", "kind": "constant", "height_m": 0, "of": ["a", "b"]}"#,
            "layer 'c': of: is not a field of a constant layer",
        ),
        (
            r#"{"name": "c", "kind": "constant", "height_m": 0, "applied": 2}"#,
            "layer 'c': applied: is not a field of a constant layer",
        ),
        (
            r#"{"name": "dh", "kind": "difference", "store": "s.gpkg", "of": ["a", "b"]}"#,
            "layer 'dh': store: is not a field of a difference layer",
        ),
        (r#"{"name": "dh", "kind": "difference"}"#, "layer 'dh': of: a difference layer needs its operands"),
        (
            r#"{"name": "d", "kind": "dataset", "store": "s", "applied": 0}"#,
            "layer 'd': applied: is not a field of a dataset layer",
        ),
        (r#"{"name": "p", "kind": "procedural"}"#, "layer 'p': noise: a procedural layer needs its noise settings"),
        (r#"{"name": "c", "kind": "constant"}"#, "layer 'c': height_m: a constant layer needs its height"),
        (r#"{"name": "c", "kind": "crater", "height_m": 0}"#, "unknown variant `crater`"),
        (r#"{"name": "c", "kind": "constant", "height_m": 0, "colour": "red"}"#, "unknown field `colour`"),
    ];
    for (json, expected) in cases {
        let e = read_layer(json).unwrap_err();
        assert!(e.to_string().contains(expected), "{json}: {e}\n  expected: {expected}");
    }
    // What older files wrote for every kind (a zero shift, no edge feather, the identity
    // transform on a difference) still reads.
    for json in [
        r#"{"name": "c", "kind": "constant", "height_m": 0, "shift_m": [0, 0], "feather_edge_m": 0}"#,
        r#"{"name": "dh", "kind": "difference", "of": ["a", "b"], "scale": 1.0, "offset_m": 0.0}"#,
        r#"{"name": "e", "kind": "edit", "strokes": [], "blend": "add"}"#,
    ] {
        read_layer(json).unwrap_or_else(|e| panic!("{json}: {e}"));
    }
}

#[test]
fn every_kind_reads_back_as_it_was_written() {
    let n = NoiseSpec {
        noise_type: super::NoiseType::Ridged,
        seed: 3,
        amplitude_m: 10.0,
        wavelength_m: 5000.0,
        octaves: 5,
        lacunarity: 2.0,
        gain: 0.5,
        placement: super::DetailWhere::BeyondData,
    };
    let specs = [
        with_dataset(|d| {
            d.shift_m = [3.0, -4.0];
            d.feather_edge_m = 250.0;
            d.dataset = Some("srtm".into());
        }),
        LayerSpec::constant("c", -12.5),
        LayerSpec::procedural("p", n),
        LayerSpec::edit("e"),
        LayerSpec::erosion("r"),
        LayerSpec::difference(
            "dh",
            super::Operand::Layer("d".into()),
            super::Operand::Group(vec!["c".into(), "p".into()]),
        ),
    ];
    for spec in specs {
        let json = serde_json::to_string(&spec).unwrap();
        assert!(json.contains(&format!("\"kind\":\"{}\"", spec.kind().name())), "{json}");
        assert_eq!(read_layer(&json).unwrap(), spec, "{json}");
    }
}

#[test]
fn detail_beyond_the_data_leaves_what_the_data_resolve() {
    // A dataset of 100 m spacing under fBm whose octaves (800 … 100 m) the data already have
    // (λ ≥ 2 × 100 m) except the finest: only that one adds; without data, all of them do.
    let n = NoiseSpec {
        noise_type: super::NoiseType::Fbm,
        seed: 5,
        amplitude_m: 20.0,
        wavelength_m: 800.0,
        octaves: 4,
        lacunarity: 2.0,
        gain: 0.5,
        placement: super::DetailWhere::BeyondData,
    };
    let specs = [LayerSpec::dataset("d", "s.gpkg"), LayerSpec::procedural("detail", n.clone())];
    let mut stack = Stack::new(Ellipsoid::MOON, &specs).unwrap();
    stack.set_dataset_info(0, (0.0, 1.0), None);
    stack.layers[0].data_spacing_m = 100.0;
    let quad = QuadId { face: Face::Front, level: 12, x: 2000, y: 2100 };
    let plan = stack.plan(quad, &|_| true, false);
    let p = at(&stack, quad, 100, 100);
    let with_data = compose_sample(&stack, &plan, &p, &|k| DataAt::raw(if k == 0 { 1000.0 } else { f64::NAN }));
    let weights = super::noise::octave_weights(&n, 0.0, 100.0, 1.0);
    assert_eq!(weights, vec![0.0, 0.0, 0.0, 1.0]);
    let expected = 1000.0 + super::noise::noise_at(&n, p.ecef, &weights);
    assert!((with_data - expected).abs() < 1e-9, "{with_data} vs {expected}");
}

#[test]
fn difference_layers_name_their_operands_and_refuse_what_would_break_them() {
    use super::spec::{DifferenceStyle, Operand};
    let layer = |n: &str| Operand::Layer(n.into());
    let dh = |a: &str, b: &str| LayerSpec::difference("dh", layer(a), layer(b));
    let styled = |mut spec: LayerSpec, style: DifferenceStyle| {
        spec.as_difference_mut().unwrap().style = style;
        spec
    };
    let cases: Vec<(LayerSpec, &str)> = vec![
        (dh("a", "a"), "layer 'dh': of: A and B are both 'a'"),
        (
            LayerSpec { blend: BlendMode::Max, ..dh("a", "b") },
            "layer 'dh': blend: is not a field of a difference layer",
        ),
        (LayerSpec { offset_m: 3.0, ..dh("a", "b") }, "layer 'dh': offset_m: is not a field of a difference layer"),
        (
            styled(dh("a", "b"), DifferenceStyle { range_m: Some(-2.0), ..Default::default() }),
            "layer 'dh': style.range_m: -2 must be a positive height",
        ),
        (
            styled(dh("a", "b"), DifferenceStyle { percentile: 0.0, ..Default::default() }),
            "layer 'dh': style.percentile: 0 must lie in (0, 100]",
        ),
    ];
    for (spec, expected) in cases {
        let e = spec.check(6.4e6).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}\n  expected: {expected}");
    }
    let base = [constant("a", 1.0, BlendMode::Over, 1.0), constant("b", 2.0, BlendMode::Over, 1.0)];
    let with = |d: LayerSpec| [base[0].clone(), base[1].clone(), d];
    let e = Stack::new(Ellipsoid::MOON, &with(dh("a", "nope"))).unwrap_err().to_string();
    assert!(e.contains("layer 'dh': of: operand B names 'nope', which is not a layer (layers: a, b, dh)"), "{e}");
    let e = Stack::new(
        Ellipsoid::MOON,
        &[base[0].clone(), dh("a", "dh2"), LayerSpec::difference("dh2", layer("a"), layer("b"))],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("operand B names 'dh2', a difference layer"), "{e}");
    // Operands may be listed above the difference; the stack refuses to remove or rename them.
    let mut stack = Stack::new(Ellipsoid::MOON, &[dh("a", "b"), base[0].clone(), base[1].clone()]).unwrap();
    let e = stack.remove(1).unwrap_err().to_string();
    assert!(e.contains("layer 'a': name: difference layer 'dh' reads it"), "{e}");
    let e = stack.set(2, LayerSpec { name: "c".into(), ..base[1].clone() }).unwrap_err().to_string();
    assert!(e.contains("layer 'b': name: difference layer 'dh' reads it"), "{e}");
    stack.set(2, constant("b", 5.0, BlendMode::Over, 1.0)).unwrap();
    // A group operand: a + b composed (b over a) minus a alone: 5 − 1 everywhere.
    let group = Operand::Group(vec!["a".into(), "b".into()]);
    stack.set(0, LayerSpec::difference("dh", group, layer("a"))).unwrap();
    let quad = QuadId::root(Face::Front);
    let plan = stack.plan(quad, &|_| true, true);
    let d = plan.difference.as_ref().expect("drawn");
    assert_eq!((d.a.layers.len(), d.b.layers.len()), (2, 1));
    let dh = super::compose::compose_difference(&stack, d, &|_| super::LayerTiles::default());
    assert!(dh.iter().all(|v| *v == 4.0), "{:?}", &dh[..4]);
    // The heights' plan reads the two constants only, and the difference is part of the stamp.
    assert_eq!(plan.layers.iter().map(|l| l.index).collect::<Vec<_>>(), vec![1, 2]);
    let mut hidden = stack.layers[0].spec.clone();
    hidden.visible = false;
    stack.set(0, hidden).unwrap();
    let plain = stack.plan(quad, &|_| true, true);
    assert!(plain.difference.is_none() && plain.stamp != plan.stamp && plain.layers == plan.layers);
}
