//! The hand of the grasp labeller: a parallel-jaw gripper as convex parts in its TCP
//! frame, the fingers at their widest opening.
//!
//! TCP frame: z is the approach direction (fingertips at positive z), the fingers close
//! along y (the left finger, on the +y side, moves along −y), x runs across the finger
//! width. The parts are either the boxes of a [`HandGeometry`]
//! ([`HandGeometry::parts`]) or any convex pieces ([`HandParts`], e.g. the hulls of a
//! simulator's collision meshes); nothing here knows which gripper it is.

use parry3d::shape::ConvexPolyhedron;

use super::convex::convex_hull;
use crate::error::{Error, Result};
use crate::gripper::{box_corners, HandGeometry};

impl HandGeometry {
    /// The hand's boxes as convex parts: the palm's front and back parts, each finger's
    /// tip and base parts, the fingers' inner pads at `y = ±max_opening / 2`.
    pub fn parts(&self) -> HandParts {
        let o2 = 0.5 * self.max_opening;
        let hw = 0.5 * self.finger_width;
        let [fx, fy] = self.palm_front_half;
        let [bx, by] = self.palm_back_half;
        let finger = |sign: f64| {
            let part = |thickness: f64, z0: f64, z1: f64| {
                let (a, b) = (sign * o2, sign * (o2 + thickness));
                box_corners([-hw, a.min(b), z0], [hw, a.max(b), z1])
            };
            vec![
                part(self.tip_thickness, self.finger_split, self.finger_tip),
                part(self.base_thickness, self.finger_base, self.finger_split),
            ]
        };
        HandParts {
            palm: vec![
                box_corners([-fx, -fy, self.palm_split], [fx, fy, self.palm_front]),
                box_corners([-bx, -by, self.palm_back], [bx, by, self.palm_split]),
            ],
            left: finger(1.0),
            right: finger(-1.0),
            max_opening: self.max_opening,
            palm_threshold: 0.0,
            finger_threshold: 0.0,
        }
    }
}

/// A parallel-jaw hand as convex parts in its TCP frame (metres), fingers at the widest
/// opening: each part a flat `(V, 3)` vertex array collided as its convex hull.
#[derive(Debug, Clone, PartialEq)]
pub struct HandParts {
    /// The body of the hand (does not move while the fingers close).
    pub palm: Vec<Vec<f64>>,
    /// The finger on the +y side, closing along −y.
    pub left: Vec<Vec<f64>>,
    /// The finger on the −y side, closing along +y.
    pub right: Vec<Vec<f64>>,
    /// Distance between the finger pads, fully open (m): how far a closing finger may
    /// travel.
    pub max_opening: f64,
    /// How much farther than the margins the physics engine reports the palm touching
    /// something (m; a pair of shapes reports at the smaller threshold of the two).
    pub palm_threshold: f64,
    /// The same for the fingers (m).
    pub finger_threshold: f64,
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

    /// World z of the box's lowest point, for a TCP-to-world rotation's last row `rz`
    /// and TCP height `tz`.
    #[inline]
    pub fn lowest_z(&self, rz: &[f64; 3], tz: f64) -> f64 {
        tz + (0..3)
            .map(|i| rz[i] * self.centre[i] - rz[i].abs() * self.half[i])
            .sum::<f64>()
    }
}

/// One convex part of the hand: its hull (TCP frame, millimetres), bounding box (m) and
/// contact threshold (m).
#[derive(Debug, Clone)]
pub(crate) struct Part {
    pub hull: ConvexPolyhedron,
    pub bound: TcpBox,
    pub threshold: f64,
}

impl Part {
    fn new(name: &str, vertices: &[f64], threshold: f64) -> Result<Self> {
        let (hull, lo, hi) = convex_hull(name, vertices)?;
        Ok(Self {
            hull,
            bound: TcpBox::from_bounds(lo, hi),
            threshold,
        })
    }

    /// What the part covers moving along +z from `far` back to `near` back of where it
    /// is: the hull of its two copies (a convex set's sweep along a line).
    fn swept_back(
        name: &str,
        vertices: &[f64],
        far: f64,
        near: f64,
        threshold: f64,
    ) -> Result<Self> {
        let copy = |d: f64| {
            vertices
                .chunks_exact(3)
                .flat_map(move |p| [p[0], p[1], p[2] - d])
        };
        let both: Vec<f64> = copy(near).chain(copy(far)).collect();
        Self::new(name, &both, threshold)
    }
}

/// The hand as the labeller queries it.
#[derive(Debug, Clone)]
pub(crate) struct Hand {
    /// Every part (palm, left, right) swept along its approach (see [`Hand::new`]).
    pub swept: Vec<Part>,
    /// The left (+y) and the right (−y) finger's parts.
    pub fingers: [Vec<Part>; 2],
    /// A box around all of `swept`.
    pub bound: TcpBox,
    pub max_opening: f64,
}

impl Hand {
    /// Builds the hulls of `parts`, their approach sweeps from `pregrasp_distance` back
    /// to `lag` back (the hand trails its commanded pose by `lag` while contacts are
    /// checked, and catches up unchecked; `lag` is clamped to the pre-grasp distance).
    ///
    /// # Errors
    /// [`Error::Value`] for a bad `max_opening` or threshold or a finger without parts;
    /// the errors of a bad part's vertices (as [`super::GraspScene::add_object`]),
    /// named `hand.palm[k]`, `hand.left[k]`, `hand.right[k]`.
    pub fn new(parts: &HandParts, pregrasp_distance: f64, lag: f64) -> Result<Self> {
        if !(parts.max_opening > 0.0 && parts.max_opening <= 1.0) {
            return Err(Error::value(
                "hand.max_opening",
                parts.max_opening,
                "must be in (0, 1] m",
            ));
        }
        for (name, t) in [
            ("hand.palm_threshold", parts.palm_threshold),
            ("hand.finger_threshold", parts.finger_threshold),
        ] {
            if !(0.0..=0.05).contains(&t) {
                return Err(Error::value(name, t, "must be in [0, 0.05] m"));
            }
        }
        let lag = lag.min(pregrasp_distance);
        let mut swept = Vec::new();
        let mut fingers = [Vec::new(), Vec::new()];
        for (group, list) in [
            ("palm", &parts.palm),
            ("left", &parts.left),
            ("right", &parts.right),
        ] {
            if group != "palm" && list.is_empty() {
                return Err(Error::value(
                    &format!("hand.{group}"),
                    0,
                    "a finger needs at least 1 part",
                ));
            }
            let threshold = if group == "palm" {
                parts.palm_threshold
            } else {
                parts.finger_threshold
            };
            for (k, v) in list.iter().enumerate() {
                let name = format!("hand.{group}[{k}]");
                swept.push(Part::swept_back(
                    &name,
                    v,
                    pregrasp_distance,
                    lag,
                    threshold,
                )?);
                match group {
                    "left" => fingers[0].push(Part::new(&name, v, threshold)?),
                    "right" => fingers[1].push(Part::new(&name, v, threshold)?),
                    _ => {}
                }
            }
        }
        let bound = swept
            .iter()
            .skip(1)
            .fold(swept[0].bound, |acc, p| acc.union(&p.bound));
        Ok(Self {
            swept,
            fingers,
            bound,
            max_opening: parts.max_opening,
        })
    }
}
