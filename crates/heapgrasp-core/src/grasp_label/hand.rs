//! The hand of the grasp labeller: a parallel-jaw gripper as boxes in its TCP frame.
//!
//! The numbers are those of `heapgrasp.geometry.gripper.GripperGeometry` (the caller
//! passes them; nothing here knows which gripper it is). TCP frame: z is the approach
//! direction (fingertips at positive z), the fingers close along y, x runs across the
//! finger width; the fingers' inner pads sit at `y = ±opening / 2`.

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

    /// The labeller's boxes for this hand with the fingers at `max_opening`.
    pub(crate) fn boxes(&self, pregrasp_distance: f64) -> HandBoxes {
        let o2 = 0.5 * self.max_opening;
        let hw = 0.5 * self.finger_width;
        let [fx, fy] = self.palm_front_half;
        let [bx, by] = self.palm_back_half;
        let palm_front =
            TcpBox::from_bounds([-fx, -fy, self.palm_split], [fx, fy, self.palm_front]);
        let palm_back = TcpBox::from_bounds([-bx, -by, self.palm_back], [bx, by, self.palm_split]);
        let finger = |sign: f64, thickness: f64, z0: f64, z1: f64| {
            let (a, b) = (sign * o2, sign * (o2 + thickness));
            TcpBox::from_bounds([-hw, a.min(b), z0], [hw, a.max(b), z1])
        };
        let parts = [
            palm_front,
            palm_back,
            finger(1.0, self.tip_thickness, self.finger_split, self.finger_tip),
            finger(
                1.0,
                self.base_thickness,
                self.finger_base,
                self.finger_split,
            ),
            finger(-1.0, self.tip_thickness, self.finger_split, self.finger_tip),
            finger(
                -1.0,
                self.base_thickness,
                self.finger_base,
                self.finger_split,
            ),
        ];
        let swept = parts.map(|b| b.swept_back(pregrasp_distance));
        // The part of each finger next to its pad, over the finger's whole length. As a
        // finger closes, it covers its pad's prism and nothing else that it did not
        // cover already, so casting this slab finds the finger's first contact.
        let pad = self.tip_thickness.min(self.base_thickness);
        let pads = [
            finger(1.0, pad, self.finger_base, self.finger_tip),
            finger(-1.0, pad, self.finger_base, self.finger_tip),
        ];
        let bound = swept.iter().skip(1).fold(swept[0], |acc, b| acc.union(b));
        HandBoxes { swept, pads, bound }
    }
}

/// An axis-aligned box in the TCP frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TcpBox {
    pub centre: [f64; 3],
    pub half: [f64; 3],
}

impl TcpBox {
    pub fn from_bounds(lo: [f64; 3], hi: [f64; 3]) -> Self {
        Self {
            centre: std::array::from_fn(|i| 0.5 * (lo[i] + hi[i])),
            half: std::array::from_fn(|i| 0.5 * (hi[i] - lo[i])),
        }
    }

    fn lo(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.centre[i] - self.half[i])
    }

    fn hi(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.centre[i] + self.half[i])
    }

    /// The volume the box covers moving from `d` back along −z to where it is: the box
    /// itself, longer by `d` toward −z (the approach is a translation along z).
    pub fn swept_back(&self, d: f64) -> Self {
        let mut lo = self.lo();
        lo[2] -= d;
        Self::from_bounds(lo, self.hi())
    }

    /// The volume the box covers moving by `d` along `axis` (sign of `d` = direction).
    pub fn swept(&self, axis: usize, d: f64) -> Self {
        let (mut lo, mut hi) = (self.lo(), self.hi());
        if d < 0.0 {
            lo[axis] += d;
        } else {
            hi[axis] += d;
        }
        Self::from_bounds(lo, hi)
    }

    pub fn union(&self, other: &Self) -> Self {
        let (a, b) = (self.lo(), other.lo());
        let (c, d) = (self.hi(), other.hi());
        Self::from_bounds(
            std::array::from_fn(|i| a[i].min(b[i])),
            std::array::from_fn(|i| c[i].max(d[i])),
        )
    }

    /// Whether a ball at `p` (TCP frame) of radius `r` may come within the box.
    #[inline]
    pub fn near(&self, p: &[f64; 3], r: f64) -> bool {
        (0..3).all(|i| (p[i] - self.centre[i]).abs() <= self.half[i] + r)
    }
}

/// The hand's boxes in the TCP frame, fingers at the widest opening.
#[derive(Debug, Clone)]
pub(crate) struct HandBoxes {
    /// Palm front, palm back, then the left (+y) finger's tip and base parts and the
    /// right (−y) finger's, each swept back along −z by the pre-grasp distance.
    pub swept: [TcpBox; 6],
    /// The slab at each finger's pad (left = +y, right = −y) over the finger's length.
    pub pads: [TcpBox; 2],
    /// A box around all of `swept`.
    pub bound: TcpBox,
}
