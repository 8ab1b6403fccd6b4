//! The parameters of an erosion run, each with its unit and range, and presets.

use serde::{Deserialize, Serialize};

/// Standard gravity on Earth, m/s² (a run on another body sets its own).
pub const EARTH_G: f64 = 9.806_65;
/// Surface gravity of the Moon, m/s².
pub const MOON_G: f64 = 1.62;
/// Surface gravity of Mars, m/s².
pub const MARS_G: f64 = 3.721;

/// The surface gravity of a project's body (`moon`, `mars`; the Earth's otherwise), m/s².
pub fn gravity_of_body(body: &str) -> f64 {
    match body.to_ascii_lowercase().as_str() {
        "moon" => MOON_G,
        "mars" => MARS_G,
        _ => EARTH_G,
    }
}

/// What an erosion run does per second of simulated time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Rain, m/s of water depth (0 … 10⁻²; 10⁻⁵ m/s is 36 mm/h, a downpour).
    pub rain_m_s: f64,
    /// Evaporation, the fraction of the water lost per second (0 … 1).
    pub evaporation_per_s: f64,
    /// Sediment capacity: the depth of sediment water of 1 m depth flowing at 1 m/s down a slope
    /// of sin α = 1 can carry, metres (0 … 10); capacity = this · sin α · |v| / (1 m/s) ·
    /// min(depth, `capacity_depth_m`).
    pub capacity: f64,
    /// The water depth beyond which capacity no longer grows, metres (10⁻³ … 100).
    pub capacity_depth_m: f64,
    /// The least sin α capacity uses (flat ground still carries a little), 0 … 1.
    pub min_slope: f64,
    /// Dissolving: the fraction of the capacity deficit taken from the terrain per second (0 … 10).
    pub dissolve_per_s: f64,
    /// Deposition: the fraction of the capacity excess laid down per second (0 … 10).
    pub deposit_per_s: f64,
    /// Talus angle, degrees (0 … 89): ground steeper than this slides (thermal erosion).
    pub talus_deg: f64,
    /// Thermal erosion: the fraction of the excess over the talus moved per second (0 … 10).
    pub thermal_per_s: f64,
    /// Friction, the fraction of a pipe's flux lost per second (0 … 100): without it water on a
    /// slope accelerates for ever (Mei et al.'s pipes have none); water on a slope of sin α
    /// reaches about g·sin α / friction.
    pub friction_per_s: f64,
    /// Hardness (≥ 1; dissolving and sliding are divided by it).
    pub hardness: f64,
    /// Gravity along the ellipsoid normal, m/s² (0.1 … 30).
    pub gravity_m_s2: f64,
    /// The time step asked for, seconds (10⁻⁴ … 10⁴); the run takes less where the CFL bound
    /// requires it.
    pub dt_s: f64,
    /// The CFL number (0.05 … 0.5): Δt ≤ CFL · cell length / (|v| + √(g·d)).
    pub cfl: f64,
    /// Borders: `closed` (walls) or `open` (water and sediment leave, counted).
    #[serde(default)]
    pub border: Border,
    /// The water a run starts with: `dry`, or `steady` (each cell's share of the rain at steady
    /// state, so that rivers carry from the first step; see [`super::start`]).
    #[serde(default, skip_serializing_if = "Start::is_dry")]
    pub start: Start,
}

/// The sediment capacity of the unscaled `river` preset.
const RIVER_CAPACITY: f64 = 0.2;

/// How many times the physical transport the time-scaled presets (`rain`, `river`) carry.
pub const TRANSPORT_SCALE: f64 = 10.0;

/// The water a run starts with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// None.
    #[default]
    Dry,
    /// The steady state of its rain: rivers and lakes full ([`super::start`]).
    Steady,
}

impl Start {
    /// Whether this is `dry` (the default, not written).
    pub fn is_dry(&self) -> bool {
        *self == Start::Dry
    }
}

/// What a region's border does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Border {
    /// Walls: nothing leaves.
    #[default]
    Closed,
    /// Water flows out (to a virtual cell at the border cell's terrain height, without water) and
    /// takes its sediment; both are counted in the budgets.
    Open,
}

/// A parameter outside its range: its name, value and range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field}: {value} is outside {range}")]
pub struct ParamError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// Its range, in words.
    pub range: &'static str,
}

impl Params {
    /// The presets: `rain` (a downpour cutting gullies and channels in a minute), `river` (the
    /// rivers of a steady rain cutting their beds), `thermal` (sliding only: scree slopes),
    /// `gentle` (light rain, slow dissolving, from a dry start).
    ///
    /// `rain` and `river` are **time-scaled**: they start from the water of their rain at steady
    /// state ([`Start::Steady`]), so rivers carry from the first step instead of after hours of
    /// simulated filling, carry ten times the sediment of the physical rates (`capacity` 2 against
    /// 0.2 for the unscaled `river`), and lay none down while the water flows (`deposit_per_s` 0,
    /// detachment-limited): a few minutes of simulated flow then cut what centuries of floods
    /// would. [`Params::unscaled`] gives them without the scaling.
    pub const PRESETS: [&'static str; 4] = ["rain", "river", "thermal", "gentle"];

    /// A preset by name, on a body with gravity `gravity_m_s2`.
    pub fn preset(name: &str, gravity_m_s2: f64) -> Option<Params> {
        let unscaled = Params::unscaled(name, gravity_m_s2)?;
        let scaled = Params {
            start: Start::Steady,
            evaporation_per_s: 0.0,
            capacity: RIVER_CAPACITY * TRANSPORT_SCALE,
            deposit_per_s: 0.0,
            ..unscaled
        };
        Some(match name {
            "rain" => Params { rain_m_s: 2e-4, capacity_depth_m: 1.0, ..scaled },
            "river" => Params { rain_m_s: 1e-4, capacity_depth_m: 10.0, ..scaled },
            _ => unscaled,
        })
    }

    /// A preset by name with physical rates and a dry start: what `rain` and `river` were before
    /// they were time-scaled (project format 4), and what `thermal` and `gentle` are.
    pub fn unscaled(name: &str, gravity_m_s2: f64) -> Option<Params> {
        let base = Params {
            rain_m_s: 1e-4,
            evaporation_per_s: 0.005,
            capacity: 0.05,
            capacity_depth_m: 1.0,
            min_slope: 0.01,
            dissolve_per_s: 0.5,
            deposit_per_s: 0.5,
            talus_deg: 40.0,
            thermal_per_s: 0.1,
            friction_per_s: 1.0,
            hardness: 1.0,
            gravity_m_s2,
            dt_s: 0.5,
            cfl: 0.25,
            border: Border::Open,
            start: Start::Dry,
        };
        Some(match name {
            "rain" => base,
            "river" => Params { rain_m_s: 2e-5, capacity: RIVER_CAPACITY, evaporation_per_s: 0.001, ..base },
            "thermal" => Params { rain_m_s: 0.0, capacity: 0.0, thermal_per_s: 0.5, talus_deg: 33.0, ..base },
            "gentle" => Params { rain_m_s: 2e-5, dissolve_per_s: 0.1, deposit_per_s: 0.2, ..base },
            _ => return None,
        })
    }

    /// The unscaled `rain` preset at the Earth's standard gravity: what an operation without
    /// `params` (a stream-power run) holds, and so what is not written for one. Fixed: a run
    /// saved without its parameters reads back as it was saved whatever the presets become.
    pub fn standard() -> Params {
        Params::unscaled("rain", 9.806_65).expect("rain is a preset")
    }

    /// Whether these are [`Params::standard`] (skipped when saved: reading them back gives the
    /// same).
    pub fn is_standard(&self) -> bool {
        *self == Params::standard()
    }

    /// Checks every field against its range.
    pub fn check(&self) -> Result<(), ParamError> {
        let within = |field, value: f64, lo: f64, hi: f64, range| {
            if value.is_finite() && (lo..=hi).contains(&value) {
                Ok(())
            } else {
                Err(ParamError { field, value, range })
            }
        };
        within("rain_m_s", self.rain_m_s, 0.0, 1e-2, "[0, 0.01] m/s")?;
        within("evaporation_per_s", self.evaporation_per_s, 0.0, 1.0, "[0, 1] per s")?;
        within("capacity", self.capacity, 0.0, 10.0, "[0, 10]")?;
        within("capacity_depth_m", self.capacity_depth_m, 1e-3, 100.0, "[0.001, 100] m")?;
        within("min_slope", self.min_slope, 0.0, 1.0, "[0, 1]")?;
        within("dissolve_per_s", self.dissolve_per_s, 0.0, 10.0, "[0, 10] per s")?;
        within("deposit_per_s", self.deposit_per_s, 0.0, 10.0, "[0, 10] per s")?;
        within("talus_deg", self.talus_deg, 0.0, 89.0, "[0, 89] degrees")?;
        within("thermal_per_s", self.thermal_per_s, 0.0, 10.0, "[0, 10] per s")?;
        within("friction_per_s", self.friction_per_s, 0.0, 100.0, "[0, 100] per s")?;
        within("hardness", self.hardness, 1.0, 1e6, "[1, 10⁶]")?;
        within("gravity_m_s2", self.gravity_m_s2, 0.1, 30.0, "[0.1, 30] m/s²")?;
        within("dt_s", self.dt_s, 1e-4, 1e4, "[10⁻⁴, 10⁴] s")?;
        within("cfl", self.cfl, 0.05, 0.5, "[0.05, 0.5]")?;
        Ok(())
    }
}
