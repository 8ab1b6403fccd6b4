//! An edit or erosion layer's operations and its undo position: what is in effect, moving the
//! position, recording a new operation (which drops what was undone), dropping the undone ones.

use super::*;

/// The operations in effect of a log with an undo position (`applied`; None: all of them).
fn in_effect<T>(operations: &[T], applied: Option<usize>) -> &[T] {
    &operations[..applied.unwrap_or(operations.len()).min(operations.len())]
}

/// Drops the operations of a log past its undo position, which then is at its end; returns how
/// many were dropped.
fn drop_past(operations: &mut Vec<impl Sized>, applied: &mut Option<usize>) -> usize {
    let kept = in_effect(operations, *applied).len();
    let dropped = operations.len() - kept;
    operations.truncate(kept);
    *applied = None;
    dropped
}

impl EditLayer {
    /// The strokes in effect (those before the undo position).
    pub fn in_effect(&self) -> &[crate::edit::Stroke] {
        in_effect(&self.strokes, self.applied)
    }
}

impl ErosionLayer {
    /// The runs in effect (those before the undo position).
    pub fn in_effect(&self) -> &[crate::erosion::operation::Operation] {
        in_effect(&self.runs, self.applied)
    }
}

impl LayerSpec {
    /// An edit or erosion layer's undo position (None: all operations in effect, or another kind).
    pub fn applied(&self) -> Option<usize> {
        match &self.payload {
            LayerPayload::Edit(e) => e.applied,
            LayerPayload::Erosion(e) => e.applied,
            _ => None,
        }
    }

    /// An erosion layer's runs in effect (those before its undo position).
    pub fn applied_runs(&self) -> &[crate::erosion::operation::Operation] {
        self.as_erosion().map_or(&[], ErosionLayer::in_effect)
    }

    /// An edit layer's strokes in effect (those before its undo position).
    pub fn applied_strokes(&self) -> &[crate::edit::Stroke] {
        self.as_edit().map_or(&[], EditLayer::in_effect)
    }

    /// How many of an edit or erosion layer's operations there are.
    pub fn operations(&self) -> usize {
        self.strokes().len() + self.runs().len()
    }

    /// Moves an edit or erosion layer's undo position back by `undo` or forward by `redo` of its
    /// operations (strokes or runs); returns how many are in effect after it. The errors name the
    /// command-line flag.
    pub fn move_applied(&mut self, undo: Option<usize>, redo: Option<usize>) -> Result<usize, crate::Invalid> {
        let total = self.operations();
        let what = if self.kind() == LayerKind::Erosion { "runs" } else { "strokes" };
        let applied = self.applied().unwrap_or(total).min(total);
        let to = match (undo, redo) {
            (Some(n), None) => {
                applied.checked_sub(n).ok_or_else(|| format!("--undo {n}: only {applied} {what} are applied"))?
            }
            (None, Some(n)) if applied + n <= total => applied + n,
            (None, Some(n)) => return Err(format!("--redo {n}: only {} {what} can be redone", total - applied).into()),
            _ => return Err("give either --undo N or --redo N".into()),
        };
        let position = (to < total).then_some(to);
        match &mut self.payload {
            LayerPayload::Edit(e) => e.applied = position,
            LayerPayload::Erosion(e) => e.applied = position,
            _ => {
                return Err(format!(
                    "layer '{}' is a {} layer: only edit and erosion layers undo",
                    self.name,
                    self.kind().name()
                )
                .into());
            }
        }
        Ok(to)
    }

    /// Records a stroke on an edit layer after its strokes in effect (those undone are dropped);
    /// returns how many were dropped. An error on any other kind.
    pub fn record_stroke(&mut self, stroke: crate::edit::Stroke) -> Result<usize, LayerError> {
        let (name, kind) = (self.name.clone(), self.kind());
        let edit = self.as_edit_mut().ok_or_else(|| not_a(&name, kind, "edit"))?;
        let dropped = drop_past(&mut edit.strokes, &mut edit.applied);
        edit.strokes.push(stroke);
        Ok(dropped)
    }

    /// Records a run on an erosion layer after its runs in effect (those undone are dropped);
    /// returns how many were dropped. An error on any other kind.
    pub fn record_run(&mut self, run: crate::erosion::operation::Operation) -> Result<usize, LayerError> {
        let (name, kind) = (self.name.clone(), self.kind());
        let erosion = self.as_erosion_mut().ok_or_else(|| not_a(&name, kind, "erosion"))?;
        let dropped = drop_past(&mut erosion.runs, &mut erosion.applied);
        erosion.runs.push(run);
        Ok(dropped)
    }

    /// Drops the operations past an edit or erosion layer's undo position (nothing for others).
    pub fn drop_undone(&mut self) {
        match &mut self.payload {
            LayerPayload::Edit(e) => {
                drop_past(&mut e.strokes, &mut e.applied);
            }
            LayerPayload::Erosion(e) => {
                drop_past(&mut e.runs, &mut e.applied);
            }
            _ => {}
        }
    }
}
