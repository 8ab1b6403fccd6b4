//! The layer stack in memory: each layer's spec, compiled extent, identity and revision, and per
//! quad the plan of what composing it reads. A layer's revision is bumped by every change to it;
//! a quad's stamp is a hash over the identities, revisions and order of the layers that touch it,
//! so a composed quad is stale exactly when a layer that touches it changed (or one that touches
//! it was added, removed or moved past another).

use crate::ecm::points::quad_ball;
use glam::DVec3;

use super::LayerError;
use super::correction::Correction;
use super::extent::{Extent, NearEdge, Relation};
use super::noise;
use super::spec::{BlendMode, LayerSpec, Operand};
use crate::ecm::QuadId;
use crate::ecm::grid::{GRID, spacing_m};
use crate::geodesy::Ellipsoid;

/// One layer of a stack.
#[derive(Clone, Debug)]
pub struct Layer {
    /// As the project file has it.
    pub spec: LayerSpec,
    /// Identity, stable while the stack is open (moves keep it).
    pub uid: u64,
    /// Bumped by every change.
    pub revision: u64,
    /// The compiled extent.
    pub extent: Option<Extent>,
    /// Dataset layers: the bias corrections placed on the body (empty: none).
    pub correction: Correction,
    /// Dataset layers: the raw value range of the data (before scale and offset), metres.
    pub raw_range_m: (f64, f64),
    /// Dataset layers: the sample spacing of the dataset's finest level, metres (∞ otherwise).
    pub data_spacing_m: f64,
    /// Dataset layers: the finest level their store holds (None until the store is opened, and
    /// for other kinds).
    pub stored_level: Option<u8>,
}

impl Layer {
    /// Whether the layer can change any height: visible, with opacity, and (in a mean group)
    /// with weight.
    pub fn active(&self) -> bool {
        self.spec.visible && self.spec.opacity > 0.0 && !(self.spec.blend == BlendMode::Mean && self.spec.weight == 0.0)
    }

    /// The finest level at which the layer adds detail ([`LayerSpec::detail_level`]); None for
    /// a layer that adds none, or that is not [`Layer::active`].
    pub fn detail_level(&self, ellipsoid: &Ellipsoid) -> Option<u8> {
        if !self.active() {
            return None;
        }
        self.spec.detail_level(ellipsoid, self.stored_level)
    }

    /// The layer's value range after scale, offset and valid range, metres (before coverage).
    pub fn value_range_m(&self) -> (f64, f64) {
        self.value_range_from_raw_m(self.raw_range_m)
    }

    /// The same, for a dataset whose raw values span `dataset_raw_m` (e.g. one loaded tile's
    /// range instead of the whole dataset's); other kinds ignore it.
    pub fn value_range_from_raw_m(&self, dataset_raw_m: (f64, f64)) -> (f64, f64) {
        if !self.spec.gives_heights() {
            return (f64::INFINITY, f64::NEG_INFINITY);
        }
        // An edit or erosion layer's raw range is its deltas' (recorded like a dataset's).
        let raw = self.spec.raw_range_m(dataset_raw_m);
        let (a, b) = (raw.0 * self.spec.scale + self.spec.offset_m, raw.1 * self.spec.scale + self.spec.offset_m);
        let bias = self.correction.bound_m();
        let (lo, hi) = (a.min(b) - bias, a.max(b) + bias);
        match self.spec.valid_range_m {
            Some([vlo, vhi]) => (lo.max(vlo), hi.min(vhi)),
            None => (lo, hi),
        }
    }
}

/// How one layer enters a quad's composition.
#[derive(Clone, Debug, PartialEq)]
pub enum MaskPlan {
    /// Mask 1 at every sample (no extent, or the quad deep inside it).
    Full,
    /// The extent's edge is near: evaluate the mask per sample against these segments.
    Partial(NearEdge),
}

/// One layer of a quad's plan.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedLayer {
    /// Its index in the stack.
    pub index: usize,
    /// Its mask.
    pub mask: MaskPlan,
    /// Procedural layers: octaves the quad evaluates (finer ones are below its sample spacing).
    pub octaves: u32,
    /// How it folds in: its own blend mode, or `over` for a layer alone (a difference's operand).
    pub blend: BlendMode,
    /// Its opacity: its own, or 1 for a layer alone.
    pub opacity: f64,
}

/// What a quad's difference layer reads: operands A and B planned like heights (each its own
/// composition), drawn as A − B.
#[derive(Clone, Debug, PartialEq)]
pub struct DifferencePlan {
    /// The difference layer's index in the stack.
    pub layer: usize,
    /// A's plan.
    pub a: QuadPlan,
    /// B's plan.
    pub b: QuadPlan,
}

/// What composing a quad reads, and the stamp it is cached under.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadPlan {
    /// The quad.
    pub quad: QuadId,
    /// Hash of (position, identity, revision) of every layer that touches the quad, active or not.
    pub stamp: u64,
    /// The active layers that touch it, bottom to top: the only ones read.
    pub layers: Vec<PlannedLayer>,
    /// Sample spacing of the quad, metres.
    pub spacing_m: f64,
    /// The drawn difference layer's operands at the quad (the topmost shown difference layer),
    /// composed beside the heights; its stamp is part of the quad's.
    pub difference: Option<Box<DifferencePlan>>,
}

impl QuadPlan {
    /// Whether composing the quad can give data: a planned layer other than `add` (which adds
    /// only where there is data already).
    pub fn has_data(&self, _stack: &Stack) -> bool {
        self.layers.iter().any(|l| l.blend != BlendMode::Add)
    }

    /// Indices of the dataset layers the plan reads (their source tiles must be loaded).
    pub fn datasets<'a>(&'a self, stack: &'a Stack) -> impl Iterator<Item = usize> + 'a {
        self.layers.iter().map(|l| l.index).filter(|&i| stack.layers[i].spec.is_data())
    }

    /// Every planned layer the quad reads: the heights', then the difference's A and B.
    pub fn all_layers(&self) -> impl Iterator<Item = &PlannedLayer> {
        let operands = self.difference.iter().flat_map(|d| d.a.layers.iter().chain(d.b.layers.iter()));
        self.layers.iter().chain(operands)
    }
}

/// The stack.
#[derive(Clone, Debug)]
pub struct Stack {
    /// The body.
    pub ellipsoid: Ellipsoid,
    /// Bottom to top.
    pub layers: Vec<Layer>,
    next_uid: u64,
}

fn mix(stamp: u64, value: u64) -> u64 {
    // FNV-1a over the value's bytes.
    value.to_le_bytes().iter().fold(stamp, |h, b| (h ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3))
}

impl Stack {
    /// A stack of checked specs on a body. Dataset ranges and spacings are filled in by the
    /// caller that opens the stores ([`Stack::set_dataset_info`]).
    pub fn new(ellipsoid: Ellipsoid, specs: &[LayerSpec]) -> Result<Stack, LayerError> {
        let mut stack = Stack { ellipsoid, layers: Vec::new(), next_uid: 1 };
        for spec in specs {
            stack.insert_unchecked(stack.layers.len(), spec.clone())?;
        }
        for layer in &stack.layers {
            stack.check_operands(&layer.spec)?;
        }
        Ok(stack)
    }

    /// The index of the layer called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.layers.iter().position(|l| l.spec.name == name)
    }

    /// A difference layer's operands must name layers of the stack that are not differences.
    fn check_operands(&self, spec: &LayerSpec) -> Result<(), LayerError> {
        let Some(of) = spec.as_difference().map(|d| &d.of) else { return Ok(()) };
        for (side, operand) in ["A", "B"].iter().zip(of) {
            for name in operand.names() {
                match self.index_of(name) {
                    None => {
                        let known = self.layers.iter().map(|l| l.spec.name.as_str()).collect::<Vec<_>>().join(", ");
                        return Err(LayerError::field(
                            &spec.name,
                            "of",
                            format!("operand {side} names '{name}', which is not a layer (layers: {known})"),
                        ));
                    }
                    Some(i) if !self.layers[i].spec.gives_heights() => {
                        return Err(LayerError::field(
                            &spec.name,
                            "of",
                            format!("operand {side} names '{name}', a difference layer: operands are heights"),
                        ));
                    }
                    Some(_) => {}
                }
            }
        }
        Ok(())
    }

    /// The difference layer whose operands name layer `name`, if one does.
    fn used_by(&self, name: &str) -> Option<&str> {
        self.layers
            .iter()
            .find(|l| l.spec.as_difference().is_some_and(|d| d.of.iter().any(|o| o.names().contains(&name))))
            .map(|l| l.spec.name.as_str())
    }

    /// The difference layer drawn: the topmost shown one with opacity.
    pub fn drawn_difference(&self) -> Option<usize> {
        super::kind::drawn_difference(self.layers.iter().map(|l| &l.spec))
    }

    /// Checks a spec and places its extent and correction on the body.
    fn compile(&self, spec: &LayerSpec) -> Result<(Option<Extent>, Correction), LayerError> {
        spec.check(self.ellipsoid.a_m())?;
        let extent = spec.extent.as_ref().map(|e| Extent::new(e, spec.feather_m, &self.ellipsoid));
        let biases = spec.as_dataset().map_or(&[][..], |d| &d.correction);
        Ok((extent, Correction::new(biases, &self.ellipsoid)))
    }

    /// Inserts a layer at `index` (0: bottom). Names must stay unique; a difference's operands
    /// must be layers of the stack.
    pub fn insert(&mut self, index: usize, spec: LayerSpec) -> Result<(), LayerError> {
        self.check_operands(&spec)?;
        self.insert_unchecked(index, spec)
    }

    fn insert_unchecked(&mut self, index: usize, spec: LayerSpec) -> Result<(), LayerError> {
        if self.layers.iter().any(|l| l.spec.name == spec.name) {
            return Err(LayerError::field(&spec.name, "name", "is used by another layer".into()));
        }
        let (extent, correction) = self.compile(&spec)?;
        let uid = self.next_uid;
        self.next_uid += 1;
        let layer = Layer {
            spec,
            uid,
            revision: 1,
            extent,
            correction,
            raw_range_m: (0.0, 0.0),
            data_spacing_m: f64::INFINITY,
            stored_level: None,
        };
        self.layers.insert(index.min(self.layers.len()), layer);
        Ok(())
    }

    /// Replaces a layer's spec (its identity stays; its revision is bumped).
    pub fn set(&mut self, index: usize, spec: LayerSpec) -> Result<(), LayerError> {
        if self.layers.iter().enumerate().any(|(k, l)| k != index && l.spec.name == spec.name) {
            return Err(LayerError::field(&spec.name, "name", "is used by another layer".into()));
        }
        let (extent, correction) = self.compile(&spec)?;
        self.check_operands(&spec)?;
        let old = &self.layers[index].spec.name;
        if *old != spec.name
            && let Some(user) = self.used_by(old)
        {
            return Err(LayerError::field(
                old,
                "name",
                format!("difference layer '{user}' reads it: change its operands before renaming"),
            ));
        }
        let layer = &mut self.layers[index];
        if layer.spec != spec {
            layer.spec = spec;
            layer.extent = extent;
            layer.correction = correction;
            layer.revision += 1;
        }
        Ok(())
    }

    /// Sets an edit layer's strokes and undo position without bumping its revision: what the
    /// strokes change is stamped per quad by the layer's raster (`EditRaster::stamp`, mixed into
    /// plans by the scene), so that a stroke recomposes only the quads it changed.
    pub fn set_strokes(&mut self, index: usize, strokes: Vec<crate::edit::Stroke>, applied: Option<usize>) {
        if let Some(edit) = self.layers[index].spec.as_edit_mut() {
            edit.strokes = strokes;
            edit.applied = applied;
        }
    }

    /// An erosion layer's runs and undo position, without bumping its revision (like
    /// [`Stack::set_strokes`]: the raster's per-quad stamps say what changed).
    pub fn set_runs(&mut self, index: usize, runs: Vec<crate::erosion::operation::Operation>, applied: Option<usize>) {
        if let Some(erosion) = self.layers[index].spec.as_erosion_mut() {
            erosion.runs = runs;
            erosion.applied = applied;
        }
    }

    /// Removes a layer (not one a difference layer reads).
    pub fn remove(&mut self, index: usize) -> Result<Layer, LayerError> {
        let name = &self.layers[index].spec.name;
        if let Some(user) = self.used_by(name) {
            return Err(LayerError::field(
                name,
                "name",
                format!("difference layer '{user}' reads it: remove that layer or change its operands first"),
            ));
        }
        Ok(self.layers.remove(index))
    }

    /// Moves a layer from one position to another (0: bottom).
    pub fn move_layer(&mut self, from: usize, to: usize) {
        let layer = self.layers.remove(from);
        self.layers.insert(to.min(self.layers.len()), layer);
    }

    /// Records what a dataset layer's store says (raw height range and finest level), or an edit
    /// or erosion layer's raster (its deltas' range; `stored_level` None, spacing ∞).
    pub fn set_dataset_info(&mut self, index: usize, raw_range_m: (f64, f64), stored_level: Option<u8>) {
        let ellipsoid = self.ellipsoid;
        let layer = &mut self.layers[index];
        layer.raw_range_m = raw_range_m;
        layer.stored_level = stored_level;
        layer.data_spacing_m = stored_level.map_or(f64::INFINITY, |l| spacing_m(&ellipsoid, l));
    }

    /// The finest level at which any of the layers `which` picks adds detail (the maximum of
    /// their [`Layer::detail_level`]s; None where none adds any).
    pub fn detail_level(&self, which: &dyn Fn(usize) -> bool) -> Option<u8> {
        (0..self.layers.len()).filter(|&i| which(i)).filter_map(|i| self.layers[i].detail_level(&self.ellipsoid)).max()
    }

    /// The specs, bottom to top (what a project saves).
    pub fn specs(&self) -> Vec<LayerSpec> {
        self.layers.iter().map(|l| l.spec.clone()).collect()
    }

    /// The plan of a quad: `covers(i)` says whether dataset layer i has data at the quad (its own
    /// tile or an ancestor's), or edit layer i a stroke that reaches it. `octave_skipping` off evaluates every octave at every level (the
    /// reference the skipping's error is measured against).
    pub fn plan(&self, quad: QuadId, covers: &dyn Fn(usize) -> bool, octave_skipping: bool) -> QuadPlan {
        let spacing = spacing_m(&self.ellipsoid, quad.level);
        let ball =
            if self.layers.iter().any(|l| l.extent.is_some()) { Some(quad_ball(&self.ellipsoid, quad)) } else { None };
        let touch = |index: usize| self.touches(index, covers, ball);
        let mut stamp = 0xcbf2_9ce4_8422_2325u64;
        let mut layers = Vec::new();
        for (index, layer) in self.layers.iter().enumerate() {
            if !layer.spec.gives_heights() {
                continue;
            }
            let Some(mask) = touch(index) else { continue };
            stamp = mix(mix(mix(stamp, index as u64), layer.uid), layer.revision);
            if !layer.active() {
                continue;
            }
            layers.extend(self.planned(index, mask, spacing, octave_skipping, layer.spec.blend, layer.spec.opacity));
        }
        let spacing_m = if octave_skipping { spacing } else { 0.0 };
        let difference = self.drawn_difference().and_then(|d| {
            let of = &self.layers[d].spec.as_difference()?.of;
            // Its operands' layers are in the stamp already (every layer that touches the quad
            // is); the difference adds which one is drawn and what it reads, not its colours.
            stamp = mix(stamp, self.layers[d].uid);
            for name in of.iter().flat_map(|o| o.names()).chain(["|"]) {
                stamp = name.bytes().fold(stamp, |h, b| mix(h, u64::from(b)));
            }
            let [a, b] = [&of[0], &of[1]].map(|operand| QuadPlan {
                quad,
                stamp: 0,
                layers: self.operand_layers(operand, &touch, spacing, octave_skipping),
                spacing_m,
                difference: None,
            });
            Some(Box::new(DifferencePlan { layer: d, a, b }))
        });
        QuadPlan { quad, stamp, layers, spacing_m, difference }
    }

    /// How layer `index` meets the quad: None where it does not (a dataset without data there, an
    /// extent outside it), else its mask.
    fn touches(
        &self,
        index: usize,
        covers: &dyn Fn(usize) -> bool,
        ball: Option<(DVec3, (f64, f64), f64)>,
    ) -> Option<MaskPlan> {
        let layer = &self.layers[index];
        // Datasets without a tile there, and edit layers no stroke reached there, add nothing.
        if layer.spec.value_source().reads_tiles() && !covers(index) {
            return None;
        }
        match (&layer.extent, ball) {
            (Some(extent), Some((centre, lon_lat, radius))) => match extent.relation(centre, lon_lat, radius) {
                Relation::Outside => None,
                Relation::Inside => Some(MaskPlan::Full),
                Relation::Partial(segments) => Some(MaskPlan::Partial(segments)),
            },
            _ => Some(MaskPlan::Full),
        }
    }

    /// A planned layer (None for a procedural layer with no octave resolved at the quad).
    fn planned(
        &self,
        index: usize,
        mask: MaskPlan,
        spacing: f64,
        octave_skipping: bool,
        blend: BlendMode,
        opacity: f64,
    ) -> Option<PlannedLayer> {
        let layer = &self.layers[index];
        let octaves = match layer.spec.noise() {
            Some(n) if octave_skipping => noise::octaves_resolved(n, spacing),
            Some(n) => n.octaves,
            None => 0,
        };
        if layer.spec.noise().is_some() && octaves == 0 {
            return None;
        }
        Some(PlannedLayer { index, mask, octaves, blend, opacity })
    }

    /// The planned layers of one operand: a layer alone (`over`, opacity 1), or a group's layers in
    /// the stack's order with their own blend modes and opacities (shown, whatever the project's
    /// visibility; transparent ones and weightless mean members read nothing).
    fn operand_layers(
        &self,
        operand: &Operand,
        touch: &dyn Fn(usize) -> Option<MaskPlan>,
        spacing: f64,
        octave_skipping: bool,
    ) -> Vec<PlannedLayer> {
        let names = operand.names();
        let alone = matches!(operand, Operand::Layer(_));
        let mut layers = Vec::new();
        for (index, layer) in self.layers.iter().enumerate() {
            if !names.contains(&layer.spec.name.as_str()) || !layer.spec.gives_heights() {
                continue;
            }
            let Some(mask) = touch(index) else { continue };
            let spec = &layer.spec;
            let (blend, opacity) = if alone { (BlendMode::Over, 1.0) } else { (spec.blend, spec.opacity) };
            if opacity <= 0.0 || (blend == BlendMode::Mean && spec.weight == 0.0) {
                continue;
            }
            layers.extend(self.planned(index, mask, spacing, octave_skipping, blend, opacity));
        }
        layers
    }

    /// Whether splitting the plan's quad shows detail that a planned layer of deltas adds at a
    /// finer level (an edit layer's strokes, an erosion layer's runs; the plan holds such a layer
    /// only where its operations reach).
    pub fn deltas_refine(&self, plan: &QuadPlan) -> bool {
        plan.layers.iter().any(|l| {
            let layer = &self.layers[l.index];
            layer.spec.holds_deltas() && layer.detail_level(&self.ellipsoid).is_some_and(|d| plan.quad.level < d)
        })
    }

    /// Whether splitting `quad` adds detail that the layers make beyond the datasets: a child
    /// resolves more octaves of an active procedural layer that touches the quad than the quad
    /// does (so refinement stops where the remaining octaves are below the grid's spacing).
    pub fn refines_below_data(&self, quad: QuadId) -> bool {
        let spacing = spacing_m(&self.ellipsoid, quad.level);
        let child_spacing = spacing / 2.0;
        let mut ball = None;
        self.layers.iter().any(|l| {
            l.active()
                && l.spec
                    .noise()
                    .is_some_and(|n| noise::octaves_resolved(n, child_spacing) > noise::octaves_resolved(n, spacing))
                && l.extent.as_ref().is_none_or(|e| {
                    let (c, ll, r) = *ball.get_or_insert_with(|| quad_ball(&self.ellipsoid, quad));
                    e.relation(c, ll, r) != Relation::Outside
                })
        })
    }
}

/// Samples along a quad's edge.
pub const SAMPLES: u32 = GRID;
