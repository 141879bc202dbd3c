//! A held mouse button (or a finger) as motion steps, by the native
//! window's rule: one step per frame, at most
//! [`navigate::STEP_RATE`] a second; forward, back and orbit about the
//! point under the cursor (found again only when the cursor moves), turns
//! toward the cursor.

use glam::DVec3;
use holodeck_display::navigate::{self, ImagePoint, Step};
use holodeck_protocol::View;

/// What a held button does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    /// Toward the point under the cursor (left button, one finger).
    Forward,
    /// Away from it (right button, two fingers).
    Backward,
    /// Turn toward the cursor (middle button).
    Turn,
    /// Around the point, across (shift with left: -1, right: +1).
    OrbitAcross(f64),
    /// Around the point, over it (shift with middle).
    OrbitOver,
}

/// A motion in progress.
#[derive(Clone, Debug)]
pub struct Held {
    /// What it does.
    pub motion: Motion,
    /// The button that started it.
    pub button: u32,
    /// Where the cursor is, in pixels from the top left.
    pub cursor: (f64, f64),
    /// The point under the cursor and the cursor position it was found at.
    target: Option<(DVec3, (f64, f64))>,
    /// When the last step was taken, seconds.
    last_step: Option<f64>,
    /// Steps taken.
    pub steps: u32,
}

impl Held {
    /// A motion that starts with the cursor at `cursor`.
    pub fn new(motion: Motion, button: u32, cursor: (f64, f64)) -> Held {
        Held {
            motion,
            button,
            cursor,
            target: None,
            last_step: None,
            steps: 0,
        }
    }

    /// The view after the step due at `now` from `view` (a `width` x
    /// `height` frame), if one is due and makes a valid view; `point_at`
    /// is the world point a pixel shows.
    pub fn next(
        &mut self,
        view: &View,
        now: f64,
        width: u32,
        height: u32,
        head_fixed: bool,
        point_at: &dyn Fn(u32, u32) -> Option<DVec3>,
    ) -> Option<View> {
        if self.last_step.is_some_and(|t| now - t < 1.0 / navigate::STEP_RATE) {
            return None;
        }
        let cursor = self.cursor;
        let at = ImagePoint::of_pixel(cursor.0.floor(), cursor.1.floor(), width, height);
        let next = if self.motion == Motion::Turn {
            navigate::turn_partly(view, at, 1.0 / navigate::STEP_RATE)
        } else {
            if self.target.is_none_or(|(_, c)| c != cursor) {
                let (col, row) = (cursor.0.max(0.0) as u32, cursor.1.max(0.0) as u32);
                if let Some(p) = point_at(col.min(width.saturating_sub(1)), row.min(height.saturating_sub(1))) {
                    self.target = Some((p, cursor));
                }
            }
            let (target, _) = self.target?;
            let step = match self.motion {
                Motion::Forward => Step::Forward,
                Motion::Backward => Step::Backward,
                Motion::OrbitAcross(n) => Step::OrbitAcross(n),
                Motion::OrbitOver | Motion::Turn => Step::OrbitOver(1.0),
            };
            navigate::step(view, target, step, head_fixed)
        };
        self.last_step = Some(now);
        if next.is_some() {
            self.steps += 1;
        }
        next
    }
}
