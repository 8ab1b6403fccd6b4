//! What each kind of layer answers to the parts that use it. Every consumer (the composition on
//! the CPU and the GPU, quad selection, `export`, `compare`, `coregister`, `profile`, `brush`,
//! `erode`, replay, the workstation) asks a layer these questions instead of matching its kind;
//! the kind is named only to display it.
//!
//! A new kind plugs in here: its payload struct and variant in [`super::spec`], its fields in
//! [`LayerKind::own_fields`], and one arm in each method below (the compiler lists them). The
//! conformance matrix in `tests/layer_matrix.rs` then needs its row.

use super::noise;
use super::spec::{LayerKind, LayerPayload, LayerSpec, NoiseSpec};
use crate::ecm::grid::spacing_m;
use crate::geodesy::Ellipsoid;

/// Where a layer's value at a sample comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueSource<'a> {
    /// A tile of a dataset's store at the quad (or an ancestor's, upsampled).
    StoreTile,
    /// A tile of deltas rebuilt from the layer's recorded operations (strokes, runs); 0 where
    /// none reached.
    Deltas,
    /// One value everywhere, metres.
    Constant(f64),
    /// Noise evaluated at the sample's position on the ellipsoid.
    Noise(&'a NoiseSpec),
    /// No height: the layer draws the difference of its operands.
    Nothing,
}

impl ValueSource<'_> {
    /// Whether the value is read from a tile per quad (a store's or a delta raster's), so that
    /// the layer reaches only where that tile has data.
    pub fn reads_tiles(self) -> bool {
        matches!(self, ValueSource::StoreTile | ValueSource::Deltas)
    }
}

impl LayerSpec {
    /// Where the layer's value comes from.
    pub fn value_source(&self) -> ValueSource<'_> {
        match &self.payload {
            LayerPayload::Dataset(_) => ValueSource::StoreTile,
            LayerPayload::Edit(_) | LayerPayload::Erosion(_) => ValueSource::Deltas,
            LayerPayload::Constant(c) => ValueSource::Constant(c.height_m),
            LayerPayload::Procedural(p) => ValueSource::Noise(&p.noise),
            LayerPayload::Difference(_) => ValueSource::Nothing,
        }
    }

    /// Whether the layer gives heights (every kind but a difference, which draws its operands').
    pub fn gives_heights(&self) -> bool {
        self.value_source() != ValueSource::Nothing
    }

    /// Whether the layer would be drawn as the difference layer were it the topmost such
    /// ([`drawn_difference`]): a difference, shown, with opacity.
    pub fn draws_difference(&self) -> bool {
        !self.gives_heights() && self.visible && self.opacity > 0.0
    }

    /// Whether the layer's heights are deltas kept in a raster made from its recorded operations
    /// (strokes, runs), rebuilt by replay and stamped per quad by that raster.
    pub fn holds_deltas(&self) -> bool {
        self.value_source() == ValueSource::Deltas
    }

    /// Whether the layer's value counts as data in the stack (what `beyond_data` detail and the
    /// data spacing look at): a dataset's samples, not deltas, noise or constants.
    pub fn is_data(&self) -> bool {
        self.value_source() == ValueSource::StoreTile
    }

    /// The finest cube-map level at which the layer adds detail: a dataset's finest stored
    /// level (`stored_level`, what its store says), the finest level of an edit layer's strokes
    /// in effect, an erosion layer's level, the level at which a procedural layer's every octave
    /// is resolved. None for a layer that adds no detail at any level (a constant, a difference,
    /// an edit or erosion layer with nothing in effect).
    pub fn detail_level(&self, ellipsoid: &Ellipsoid, stored_level: Option<u8>) -> Option<u8> {
        match &self.payload {
            LayerPayload::Dataset(_) => stored_level,
            LayerPayload::Edit(_) => self.applied_strokes().iter().map(|s| s.level).max(),
            LayerPayload::Erosion(_) => self.applied_runs().iter().map(|r| r.level).max(),
            LayerPayload::Procedural(p) => Some(noise_detail_level(&p.noise, ellipsoid)),
            LayerPayload::Constant(_) | LayerPayload::Difference(_) => None,
        }
    }

    /// The range of the layer's raw value (before scale, offset and valid range), metres, where
    /// a tile's values span `tile_raw_m` (a dataset's or a delta raster's range).
    pub fn raw_range_m(&self, tile_raw_m: (f64, f64)) -> (f64, f64) {
        match self.value_source() {
            ValueSource::StoreTile | ValueSource::Deltas => tile_raw_m,
            ValueSource::Constant(h) => (h, h),
            ValueSource::Noise(n) => noise::noise_range_m(n),
            ValueSource::Nothing => (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl LayerKind {
    /// Every kind, in the order the workstation lists them.
    pub const ALL: [LayerKind; 6] = [
        LayerKind::Dataset,
        LayerKind::Constant,
        LayerKind::Procedural,
        LayerKind::Edit,
        LayerKind::Erosion,
        LayerKind::Difference,
    ];
}

/// The difference layer drawn among `specs` (bottom to top): the topmost that
/// [`LayerSpec::draws_difference`]; the stack, the workstation's panels and the legend all ask
/// this.
pub fn drawn_difference<'a, I>(specs: I) -> Option<usize>
where
    I: IntoIterator<Item = &'a LayerSpec>,
    I::IntoIter: DoubleEndedIterator + ExactSizeIterator,
{
    specs.into_iter().rposition(LayerSpec::draws_difference)
}

/// The coarsest level at which every octave of `noise` is wholly resolved (its finest
/// wavelength at least two samples, [`noise::resolved_weight`] = 1): finer levels add nothing.
pub fn noise_detail_level(noise: &NoiseSpec, ellipsoid: &Ellipsoid) -> u8 {
    let finest_m = noise::octave_wavelength_m(noise, noise.octaves.saturating_sub(1));
    (0..=crate::ecm::MAX_LEVEL)
        .find(|&level| noise::resolved_weight(finest_m, spacing_m(ellipsoid, level)) >= 1.0)
        .unwrap_or(crate::ecm::MAX_LEVEL)
}

/// The level a request works at by default: the level its resolution needs (`wanted`), no finer
/// than the finest level at which any of the layers it reads adds detail (`detail`: the maximum
/// of their [`LayerSpec::detail_level`]s; None: none adds any, so the coarsest level serves).
pub fn default_level(wanted: u8, detail: Option<u8>) -> u8 {
    wanted.min(detail.unwrap_or(0))
}
