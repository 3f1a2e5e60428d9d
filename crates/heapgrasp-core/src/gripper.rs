//! The parallel-jaw gripper's box model, one definition for the antipodal planner
//! ([`crate::antipodal`], which puts the boxes on its lattice) and the grasp labeller
//! ([`crate::grasp_label`], which collides them as convex parts): the fields of
//! `heapgrasp.geometry.gripper.GripperGeometry`.
//!
//! TCP frame: z is the approach direction (fingertips at positive z), the fingers close
//! along y (the left finger, on the +y side, moves along −y), x runs across the finger
//! width.

use crate::error::{Error, Result};

/// Collision model of a parallel-jaw gripper in its TCP frame (metres): the fields of
/// `GripperGeometry`.
#[derive(Debug, Clone, PartialEq)]
pub struct HandGeometry {
    /// Finger extent along x.
    pub finger_width: f64,
    /// z of the fingertips.
    pub finger_tip: f64,
    /// z where the fingers leave the hand.
    pub finger_base: f64,
    /// z where a finger changes from its thin tip part to its thicker base part.
    pub finger_split: f64,
    /// Extent along y (from the inner pad outwards) of the finger's tip part.
    pub tip_thickness: f64,
    /// Extent along y of the finger's base part.
    pub base_thickness: f64,
    /// z of the hand's face toward the fingertips.
    pub palm_front: f64,
    /// z where the hand's front part meets its back part.
    pub palm_split: f64,
    /// z of the back of the hand.
    pub palm_back: f64,
    /// `(x, y)` half extents of the hand's front part.
    pub palm_front_half: [f64; 2],
    /// `(x, y)` half extents of the hand's back part.
    pub palm_back_half: [f64; 2],
    /// Widest opening between the finger pads.
    pub max_opening: f64,
}

impl HandGeometry {
    /// Checks that every length is finite, extents are positive and the parts are
    /// ordered along z as `GripperGeometry` requires.
    ///
    /// # Errors
    /// [`Error::Value`] naming the first offending field (`hand.finger_width`, ...).
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("finger_width", self.finger_width),
            ("tip_thickness", self.tip_thickness),
            ("base_thickness", self.base_thickness),
            ("max_opening", self.max_opening),
            ("palm_front_half[0]", self.palm_front_half[0]),
            ("palm_front_half[1]", self.palm_front_half[1]),
            ("palm_back_half[0]", self.palm_back_half[0]),
            ("palm_back_half[1]", self.palm_back_half[1]),
        ];
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return Err(Error::value(
                    &format!("hand.{name}"),
                    v,
                    "must be finite and > 0 m",
                ));
            }
        }
        let finite = [
            ("finger_tip", self.finger_tip),
            ("finger_base", self.finger_base),
            ("finger_split", self.finger_split),
            ("palm_front", self.palm_front),
            ("palm_split", self.palm_split),
            ("palm_back", self.palm_back),
        ];
        for (name, v) in finite {
            if !v.is_finite() {
                return Err(Error::value(&format!("hand.{name}"), v, "must be finite"));
            }
        }
        if !(self.finger_base < self.finger_split && self.finger_split < self.finger_tip) {
            return Err(Error::value(
                "hand.finger_split",
                self.finger_split,
                format!(
                    "finger_base < finger_split < finger_tip is required (finger_base {}, finger_tip {})",
                    self.finger_base, self.finger_tip
                ),
            ));
        }
        if !(self.palm_back < self.palm_split
            && self.palm_split < self.palm_front
            && self.palm_front < self.finger_tip)
        {
            return Err(Error::value(
                "hand.palm_split",
                self.palm_split,
                format!(
                    "palm_back < palm_split < palm_front < finger_tip is required (palm_back {}, palm_front {}, finger_tip {})",
                    self.palm_back, self.palm_front, self.finger_tip
                ),
            ));
        }
        Ok(())
    }

    /// How far the fingertips reach beyond the palm's face.
    pub fn finger_depth(&self) -> f64 {
        self.finger_tip - self.palm_front
    }

    /// The Franka Panda hand (the collision meshes of `pybullet_data/franka_panda`;
    /// `PANDA_HAND` in Python).
    pub fn panda() -> Self {
        Self {
            finger_width: 0.021,
            finger_tip: 0.0072,
            finger_base: -0.0466,
            finger_split: -0.02,
            tip_thickness: 0.016,
            base_thickness: 0.026,
            palm_front: -0.039,
            palm_split: -0.075,
            palm_back: -0.131,
            palm_front_half: [0.022, 0.101],
            palm_back_half: [0.032, 0.104],
            max_opening: 0.08,
        }
    }

    /// Every length but `max_opening`, named by its field, in the fields' order.
    pub fn named_lengths(&self) -> [(&'static str, f64); 13] {
        [
            ("finger_width", self.finger_width),
            ("finger_tip", self.finger_tip),
            ("finger_base", self.finger_base),
            ("finger_split", self.finger_split),
            ("tip_thickness", self.tip_thickness),
            ("base_thickness", self.base_thickness),
            ("palm_front", self.palm_front),
            ("palm_split", self.palm_split),
            ("palm_back", self.palm_back),
            ("palm_front_half[0]", self.palm_front_half[0]),
            ("palm_front_half[1]", self.palm_front_half[1]),
            ("palm_back_half[0]", self.palm_back_half[0]),
            ("palm_back_half[1]", self.palm_back_half[1]),
        ]
    }
}

/// The 8 corners of the axis-aligned box from `lo` to `hi`, flat `(8, 3)` (x slowest,
/// z fastest).
pub fn box_corners(lo: [f64; 3], hi: [f64; 3]) -> Vec<f64> {
    let mut v = Vec::with_capacity(24);
    for x in [lo[0], hi[0]] {
        for y in [lo[1], hi[1]] {
            for z in [lo[2], hi[2]] {
                v.extend([x, y, z]);
            }
        }
    }
    v
}
