//! The codes the CPU writes into the kernels' structs and the shaders switch on, defined once
//! here: [`wgsl`] writes them as WGSL constants, which every shader that includes
//! `generated/codes.wgsl` receives (see [`super::shaders::composed`]), so that neither side holds
//! a bare number.

/// "No slot": a tile or map that is not resident.
pub const NO_SLOT: u32 = u32::MAX;

/// How a composed layer gets its value (`JobLayer.kind`).
pub mod kind {
    /// A dataset's raw heights from its store tile.
    pub const STORE_TILE: u32 = 0;
    /// Procedural noise.
    pub const NOISE: u32 = 1;
    /// A constant height.
    pub const CONSTANT: u32 = 2;
    /// An edit or erosion layer's deltas.
    pub const DELTAS: u32 = 3;
}

/// How a layer folds into the heights below it (`JobLayer.blend`).
pub mod blend {
    /// (1 − α)·h + α·x.
    pub const OVER: u32 = 0;
    /// h + α·x.
    pub const ADD: u32 = 1;
    /// The lower of the two.
    pub const MIN: u32 = 2;
    /// The higher of the two.
    pub const MAX: u32 = 3;
    /// The weighted mean of a group of consecutive layers.
    pub const MEAN: u32 = 4;
}

/// A dataset layer's bias correction (the head of its entry in the compose kernel's `shapes`).
pub mod bias {
    /// A polynomial of local east and north.
    pub const DERAMP: u32 = 0;
    /// Binned by the layer's elevation.
    pub const ELEVATION: u32 = 1;
    /// Sinusoids along an azimuth.
    pub const DIRECTIONAL: u32 = 2;
}

/// A terrain attribute (`Params.size.z` of the attributes kernel), in `attributes::Attribute::ALL`
/// order: the kernel tells the gradient ones by `<= HILLSHADE` and the curvatures by
/// `<= PROFILE_CURVATURE`.
pub mod attribute {
    /// Degrees.
    pub const SLOPE: u32 = 0;
    /// Degrees from north.
    pub const ASPECT: u32 = 1;
    /// 1–255.
    pub const HILLSHADE: u32 = 2;
    /// 100/m.
    pub const CURVATURE: u32 = 3;
    /// 100/m.
    pub const PLANFORM_CURVATURE: u32 = 4;
    /// 100/m.
    pub const PROFILE_CURVATURE: u32 = 5;
    /// Metres.
    pub const TPI: u32 = 6;
    /// Metres.
    pub const TRI: u32 = 7;
    /// Metres.
    pub const ROUGHNESS: u32 = 8;
}

/// A brush tool (`Tile.head.z` of the stroke kernel).
pub mod tool {
    /// Raise by the strength.
    pub const RAISE: u32 = 0;
    /// Lower by the strength.
    pub const LOWER: u32 = 1;
    /// Add one noise octave.
    pub const NOISE: u32 = 2;
    /// Move δ back towards 0.
    pub const RESTORE: u32 = 3;
    /// Towards a height.
    pub const FLATTEN: u32 = 4;
    /// Towards a ramp between two points.
    pub const RAMP: u32 = 5;
    /// Towards the mean of a ring around the sample.
    pub const SMOOTH: u32 = 6;
}

/// A brush falloff (`Tile.head.w` of the stroke kernel).
pub mod falloff {
    /// 1 − smoothstep.
    pub const SMOOTH: u32 = 0;
    /// 1 − t.
    pub const LINEAR: u32 = 1;
    /// √(1 − t²).
    pub const SPHERICAL: u32 = 2;
    /// (1 − t)³.
    pub const TIP: u32 = 3;
}

/// The codes as WGSL constants (`KIND_STORE_TILE`, `BLEND_OVER`, `BIAS_DERAMP`, `TOOL_RAISE`, `FALLOFF_SMOOTH`,
/// `NO_SLOT`, …) and the hillshade attribute's light, `HILLSHADE_LIGHT`.
pub fn wgsl() -> String {
    let groups: [(&str, &[(&str, u32)]); 6] = [
        (
            "KIND",
            &[
                ("STORE_TILE", kind::STORE_TILE),
                ("NOISE", kind::NOISE),
                ("CONSTANT", kind::CONSTANT),
                ("DELTAS", kind::DELTAS),
            ],
        ),
        (
            "BLEND",
            &[
                ("OVER", blend::OVER),
                ("ADD", blend::ADD),
                ("MIN", blend::MIN),
                ("MAX", blend::MAX),
                ("MEAN", blend::MEAN),
            ],
        ),
        ("BIAS", &[("DERAMP", bias::DERAMP), ("ELEVATION", bias::ELEVATION), ("DIRECTIONAL", bias::DIRECTIONAL)]),
        (
            "ATTRIBUTE",
            &[
                ("SLOPE", attribute::SLOPE),
                ("ASPECT", attribute::ASPECT),
                ("HILLSHADE", attribute::HILLSHADE),
                ("CURVATURE", attribute::CURVATURE),
                ("PLANFORM_CURVATURE", attribute::PLANFORM_CURVATURE),
                ("PROFILE_CURVATURE", attribute::PROFILE_CURVATURE),
                ("TPI", attribute::TPI),
                ("TRI", attribute::TRI),
                ("ROUGHNESS", attribute::ROUGHNESS),
            ],
        ),
        (
            "TOOL",
            &[
                ("RAISE", tool::RAISE),
                ("LOWER", tool::LOWER),
                ("NOISE", tool::NOISE),
                ("RESTORE", tool::RESTORE),
                ("FLATTEN", tool::FLATTEN),
                ("RAMP", tool::RAMP),
                ("SMOOTH", tool::SMOOTH),
            ],
        ),
        (
            "FALLOFF",
            &[
                ("SMOOTH", falloff::SMOOTH),
                ("LINEAR", falloff::LINEAR),
                ("SPHERICAL", falloff::SPHERICAL),
                ("TIP", falloff::TIP),
            ],
        ),
    ];
    let mut out = String::from("// Generated from src/gpu/codes.rs.\n");
    out.push_str(&format!("const NO_SLOT: u32 = {NO_SLOT}u;\n"));
    // The light of the hillshade attribute (azimuth, altitude), radians.
    let light = [crate::attributes::LIGHT_AZIMUTH_DEG, crate::attributes::LIGHT_ALTITUDE_DEG].map(f64::to_radians);
    out.push_str(&format!(
        "const HILLSHADE_LIGHT: vec2<f32> = vec2<f32>({:?}, {:?});\n",
        light[0] as f32, light[1] as f32
    ));
    for (group, codes) in groups {
        for (name, value) in codes {
            out.push_str(&format!("const {group}_{name}: u32 = {value}u;\n"));
        }
    }
    out
}

// stroke.wgsl tells the tools that aim at a target (flatten, ramp, smooth) by `tool >= FLATTEN`.
const _: () = assert!(tool::RAISE < tool::FLATTEN && tool::NOISE < tool::FLATTEN && tool::RESTORE < tool::FLATTEN);
const _: () = assert!(tool::FLATTEN < tool::RAMP && tool::FLATTEN < tool::SMOOTH);
