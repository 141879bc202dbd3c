//! A held mouse button (or a finger) as motion steps, the paper's input
//! model as the window and the web page both run it: one step per frame,
//! at most [`navigate::STEP_RATE`] a second; forward, back and orbit about
//! the point under the cursor (found again only when the cursor moves),
//! turns toward the cursor. The time is passed in, in seconds from any
//! fixed origin (a page has no clock of its own here).

use glam::DVec3;
use holodeck_protocol::View;

use crate::navigate::{self, ImagePoint, Step};

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

impl Motion {
    /// What a button does (0 left, 1 middle, 2 right, as the web numbers
    /// them), with shift held or not; `None` for other buttons.
    pub fn of_button(button: u32, shift: bool) -> Option<Motion> {
        match (button, shift) {
            (0, false) => Some(Motion::Forward),
            (2, false) => Some(Motion::Backward),
            (1, false) => Some(Motion::Turn),
            (0, true) => Some(Motion::OrbitAcross(-1.0)),
            (2, true) => Some(Motion::OrbitAcross(1.0)),
            (1, true) => Some(Motion::OrbitOver),
            _ => None,
        }
    }
}

/// A motion in progress.
#[derive(Clone, Debug)]
pub struct Held {
    /// What it does.
    pub motion: Motion,
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
    pub fn new(motion: Motion, cursor: (f64, f64)) -> Held {
        Held {
            motion,
            cursor,
            target: None,
            last_step: None,
            steps: 0,
        }
    }

    /// The point the motion moves about, once one was under the cursor.
    pub fn target(&self) -> Option<DVec3> {
        self.target.map(|(p, _)| p)
    }

    /// When the next step is due (seconds, the clock of [`Held::next`]'s
    /// `now`): at once before the first.
    pub fn next_step_at(&self) -> Option<f64> {
        self.last_step.map(|t| t + 1.0 / navigate::STEP_RATE)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_button_steps_toward_the_point_at_most_thirty_times_a_second() {
        let view = View::parse("-vtv -vp 2 2 2 -vd 1 0.2 0 -vu 0 0 1 -vh 60 -vv 45").unwrap();
        let target = DVec3::new(3.0, 2.0, 2.0);
        let mut held = Held::new(Motion::of_button(0, false).unwrap(), (32.0, 24.0));
        assert_eq!(held.next_step_at(), None);
        let v = held.next(&view, 1.0, 64, 48, false, &|_, _| Some(target)).unwrap();
        assert!((v.position - (target + (view.position - target) * 0.9)).length() < 1e-12);
        assert_eq!(v.direction, view.direction);
        assert_eq!(held.target(), Some(target));
        assert!(held.next(&v, 1.01, 64, 48, false, &|_, _| Some(target)).is_none());
        assert!((held.next_step_at().unwrap() - (1.0 + 1.0 / navigate::STEP_RATE)).abs() < 1e-12);
        assert!(held.next(&v, 1.04, 64, 48, false, &|_, _| Some(target)).is_some());
        assert_eq!(held.steps, 2);
        // Nothing under the cursor: no step; other buttons do nothing.
        let mut blind = Held::new(Motion::Backward, (1.0, 1.0));
        assert!(blind.next(&view, 1.0, 64, 48, false, &|_, _| None).is_none());
        assert_eq!(Motion::of_button(2, true), Some(Motion::OrbitAcross(1.0)));
        assert_eq!(Motion::of_button(3, false), None);
    }
}
