//! Undo and redo of every edit: the scene as edited plus the viewer's
//! toggles, as whole snapshots (a scene description is a few kilobytes).
//!
//! Not egui's `util::undoer::Undoer`: it closes a step once the state has
//! been stable for a while (a second by default), so two quick edits
//! become one step and a slow slider drag several. Here a step is one
//! gesture: every change made while a mouse button is held (a slider or
//! camera drag) or while the wheel scrolls is one step, closed when the
//! gesture ends; any other change is a step of its own.

use super::settings::ViewSettings;
use crate::render::SceneDesc;

/// Everything an undo step restores.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    pub desc: SceneDesc,
    pub view: ViewSettings,
}

/// Steps kept; the oldest are dropped beyond this.
const MAX_STEPS: usize = 500;

#[derive(Debug)]
pub struct History {
    /// The state after the last closed step.
    baseline: Snapshot,
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
}

impl History {
    pub fn new(state: Snapshot) -> History {
        History {
            baseline: state,
            undo: Vec::new(),
            redo: Vec::new(),
        }
    }

    /// Called once a frame with the current state: a change becomes a step
    /// unless a gesture is still under way (`gesture`), in which case it
    /// waits for the gesture's end.
    pub fn observe(&mut self, state: &Snapshot, gesture: bool) {
        if gesture || *state == self.baseline {
            return;
        }
        let before = std::mem::replace(&mut self.baseline, state.clone());
        self.undo.push(before);
        if self.undo.len() > MAX_STEPS {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    /// Whether `desc` and `view` are the state after the last closed step
    /// (compared in place: no copy of the scene every frame).
    pub fn is_baseline(&self, desc: &SceneDesc, view: &ViewSettings) -> bool {
        self.baseline.view == *view && self.baseline.desc == *desc
    }

    /// The state before the last step, if any (`current` is closed as a
    /// step first if it has not been).
    pub fn undo(&mut self, current: &Snapshot) -> Option<Snapshot> {
        self.observe(current, false);
        let previous = self.undo.pop()?;
        self.redo
            .push(std::mem::replace(&mut self.baseline, previous.clone()));
        Some(previous)
    }

    /// The state the last undo left, if any.
    pub fn redo(&mut self, current: &Snapshot) -> Option<Snapshot> {
        self.observe(current, false);
        let next = self.redo.pop()?;
        self.undo
            .push(std::mem::replace(&mut self.baseline, next.clone()));
        Some(next)
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Forgets every step (another scene was opened).
    pub fn reset(&mut self, state: Snapshot) {
        *self = History::new(state);
    }
}

impl History {
    /// The state after the last closed step.
    pub fn baseline(&self) -> &Snapshot {
        &self.baseline
    }
}
