//! Exact-geometry grasp labels: whether a parallel-jaw grasp executed as VGN executes it
//! in physics would hold an object, decided on the true collision geometry instead of
//! simulated (issue 38 §1; the labels of VGN's data set that HEAPGrasp §V trains on).
//!
//! The execution it mirrors (`heapgrasp.robot.grasping.execute_grasp` with the simulated
//! Panda hand): the hand, fingers at the widest opening, is placed at the pre-grasp pose
//! `pregrasp_distance` back along the grasp's z, moves straight to the grasp pose and
//! stops at any contact; then the fingers close, force-limited, the hand lifts and shakes,
//! and the grasp holds if both fingers touch one object. Here, per grasp:
//!
//! 1. **approach** — each convex part of the hand ([`HandParts`]: the boxes of a
//!    [`HandGeometry`] or a simulator's collision hulls), swept from the pre-grasp pose
//!    to the grasp pose (a translation along its own z: the swept volume is the hull of
//!    the part and its translate), must stay more than the contact margin from every
//!    convex piece of every object and from the table, else [`Reason::Collision`];
//! 2. **closing** — each finger's parts are shape-cast inward along ∓y across the whole
//!    opening; the first contact is what that finger closes on, and the closest points
//!    there give the contact normal as the physics engine computes it. The fingers are
//!    coupled, so a finger that meets a free object first pushes it toward the other
//!    finger: the closed width is the opening minus both fingers' travels, wherever the
//!    object started between them. Both fingers must meet the same object
//!    ([`Reason::Empty`], [`Reason::TwoObjects`]), the width must reach the minimum the
//!    simulator counts as holding ([`Reason::Narrow`]), and each contact normal must lie
//!    within the friction cone about the closing direction ([`Reason::NotAntipodal`]).
//!    A closing finger never meets the table: what it sweeps lies between the two
//!    fingers, inside their convex hull, and step 1 put both above the table.
//!
//! **Margins.** PyBullet reports a contact as soon as two shapes come within their
//! collision margins (a convex mesh shape has one of 1 mm; a box primitive such as the
//! table none): the hand counts as touching an object closer than `hand_margin +
//! object_margin` and the table closer than `hand_margin`, and a finger closing on an
//! object stops that far from it, so widths include the margins as the simulator's do.
//! Bullet also reports a contact between shapes up to its contact-breaking threshold
//! apart (2 % of a shape's size; of a pair, the smaller shape's): each hand part and
//! object adds its `threshold`. While approaching, the hand trails its commanded pose by
//! `approach_lag` and contacts are checked only on the way, so the sweep ends that much
//! short of the grasp pose.

//!
//! Grasps are labelled in parallel over contiguous chunks; each label depends on its
//! grasp alone, so results do not depend on the thread count.

mod convex;
mod hand;
mod scene;
#[cfg(test)]
mod tests;

pub use crate::gripper::HandGeometry;
pub use convex::MAX_PIECE_VERTICES;
pub use hand::HandParts;
pub use scene::GraspScene;

use nalgebra::{Matrix3, Vector3};
use parry3d::math::{Mat3, Pose as PPose, Rot3, Vector as PVec};
use parry3d::query::details::{
    cast_shapes_support_map_support_map, closest_points_support_map_support_map,
    contact_support_map_support_map,
};
use parry3d::query::{ClosestPoints, ShapeCastOptions};
use parry3d::shape::SupportMap;

use crate::camera::Pose;
use crate::error::{Error, Result};
use crate::parallel;
use hand::Hand;

/// How a grasp was judged ([`GraspLabel::reason`]); the `u8` codes cross to Python.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Reason {
    /// Both fingers hold one object with antipodal contacts.
    Success = 0,
    /// The open hand touches an object or the table at the pre-grasp pose or on the
    /// approach to the grasp pose.
    Collision = 1,
    /// A finger closes on nothing.
    Empty = 2,
    /// The fingers close on two different objects.
    TwoObjects = 3,
    /// A contact normal lies outside the friction cone about the closing direction.
    NotAntipodal = 4,
    /// The fingers close narrower than the minimum width (the simulator takes it for
    /// shut).
    Narrow = 5,
}

impl Reason {
    /// Every reason, in code order.
    pub const ALL: [Reason; 6] = [
        Reason::Success,
        Reason::Collision,
        Reason::Empty,
        Reason::TwoObjects,
        Reason::NotAntipodal,
        Reason::Narrow,
    ];

    /// The reason's name (`"collision"`, `"not-antipodal"`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Reason::Success => "success",
            Reason::Collision => "collision",
            Reason::Empty => "empty",
            Reason::TwoObjects => "two-objects",
            Reason::NotAntipodal => "not-antipodal",
            Reason::Narrow => "narrow",
        }
    }
}

/// The label of one grasp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspLabel {
    /// Whether the grasp holds an object.
    pub success: bool,
    /// Distance between the finger pads once closed (m); the widest opening when the
    /// grasp fails.
    pub width: f32,
    /// Id of the object held, or -1.
    pub object: i32,
    /// Why.
    pub reason: Reason,
}

/// The execution the grasps are labelled for.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelParams {
    /// Distance of the pre-grasp pose back along the grasp's z (m).
    pub pregrasp_distance: f64,
    /// Coulomb friction coefficient between fingers and objects: the friction cone's
    /// half-angle is `atan(friction)`.
    pub friction: f64,
    /// Collision margin of the hand's shapes (m).
    pub hand_margin: f64,
    /// Collision margin of the objects' convex pieces (m); the table has none.
    pub object_margin: f64,
    /// Smallest closed width that holds an object (m).
    pub min_width: f64,
    /// How far the hand trails its commanded pose while it approaches (m).
    pub approach_lag: f64,
}

impl LabelParams {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::Value`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let checks = [
            ("pregrasp_distance", self.pregrasp_distance, 0.0, 1.0),
            ("hand_margin", self.hand_margin, 0.0, 0.05),
            ("approach_lag", self.approach_lag, 0.0, 0.05),
            ("object_margin", self.object_margin, 0.0, 0.05),
            ("min_width", self.min_width, 0.0, 1.0),
        ];
        for (name, v, lo, hi) in checks {
            if !(v >= lo && v <= hi) {
                return Err(Error::value(name, v, format!("must be in [{lo}, {hi}] m")));
            }
        }
        if !(self.friction > 0.0 && self.friction.is_finite()) {
            return Err(Error::value(
                "friction",
                self.friction,
                "must be finite and > 0",
            ));
        }
        Ok(())
    }
}

/// Labels grasps of a hand ([`HandParts`]) on a [`GraspScene`].
#[derive(Debug, Clone)]
pub struct GraspLabeller {
    scene: GraspScene,
    params: LabelParams,
    hand: Hand,
    cos_cone: f64,
    /// The largest contact threshold of any hand part or object.
    max_threshold: f64,
}

/// What a closing finger meets first: the object's index and the contact normal out of
/// the finger (TCP axes).
type Closure = Option<(usize, [f32; 3])>;

/// A piece near the hand, with its object's pose in the TCP frame.
struct Near {
    piece: usize,
    /// The ball centre in the TCP frame.
    centre: [f64; 3],
    rotation: Rot3,
    translation: Vector3<f64>,
}

impl Near {
    /// The piece's object pose in the TCP frame moved to `at` (TCP axes), in
    /// millimetres.
    fn pose_from(&self, at: &[f64; 3]) -> PPose {
        let t = (self.translation - Vector3::from(*at)) * MM;
        PPose::from_parts(PVec::new(t.x as f32, t.y as f32, t.z as f32), self.rotation)
    }
}

fn rot_to_parry(r: &Matrix3<f64>) -> Rot3 {
    let col = |j: usize| PVec::new(r[(0, j)] as f32, r[(1, j)] as f32, r[(2, j)] as f32);
    Rot3::from_mat3(&Mat3::from_cols(col(0), col(1), col(2))).normalize()
}

/// parry's queries run in millimetres: its GJK tolerances are absolute, and in f32 on
/// centimetre-sized shapes expressed in metres its distances and casts come out
/// millimetres wrong (a 2.5 cm ball 4 mm from a box measured 7.8 mm away); from
/// centimetres up they agree with the exact values to the polyhedra's own precision.
pub(crate) const MM: f64 = 1000.0;

fn hand_threshold(hand: &Hand) -> f64 {
    hand.swept.iter().map(|p| p.threshold).fold(0.0, f64::max)
}

fn scene_threshold(scene: &GraspScene) -> f64 {
    scene
        .objects
        .iter()
        .map(|o| o.threshold)
        .fold(0.0, f64::max)
}

/// Fewest grasps worth a thread of their own.
const MIN_GRASPS_PER_THREAD: usize = 32;

impl GraspLabeller {
    /// A labeller for `hand` executing grasps as `params` says on `scene`.
    ///
    /// # Errors
    /// As [`LabelParams::validate`]; [`Error::Value`] for a `min_width` beyond
    /// `hand.max_opening`; a bad hand part as [`GraspScene::add_object`] a bad piece,
    /// named `hand.left[k]` etc.
    pub fn new(scene: GraspScene, hand: &HandParts, params: LabelParams) -> Result<Self> {
        params.validate()?;
        let hand = Hand::new(hand, params.pregrasp_distance, params.approach_lag)?;
        if params.min_width > hand.max_opening {
            return Err(Error::value(
                "min_width",
                params.min_width,
                format!(
                    "must be at most the hand's max_opening {}",
                    hand.max_opening
                ),
            ));
        }
        let max_threshold = hand_threshold(&hand).max(scene_threshold(&scene));
        Ok(Self {
            scene,
            hand,
            cos_cone: params.friction.atan().cos(),
            params,
            max_threshold,
        })
    }

    /// The scene.
    pub fn scene(&self) -> &GraspScene {
        &self.scene
    }

    /// The parameters.
    pub fn params(&self) -> &LabelParams {
        &self.params
    }

    /// Adds an object to the scene ([`GraspScene::add_object`]).
    ///
    /// # Errors
    /// As [`GraspScene::add_object`].
    pub fn add_object(
        &mut self,
        id: i32,
        obj2world: Pose,
        pieces: &[&[f64]],
        threshold: f64,
    ) -> Result<()> {
        self.scene.add_object(id, obj2world, pieces, threshold)?;
        self.max_threshold = self.max_threshold.max(threshold);
        Ok(())
    }

    /// Labels grasps given as TCP poses (`tcp2world`: z the approach, fingers closing
    /// along y), on `threads` threads (0: [`parallel::num_threads`]).
    pub fn label(&self, tcp2world: &[Pose], threads: usize) -> Vec<GraspLabel> {
        let threads = if threads == 0 {
            parallel::num_threads()
        } else {
            threads
        };
        let parts = threads.min(tcp2world.len() / MIN_GRASPS_PER_THREAD).max(1);
        parallel::map_ranges(tcp2world.len(), parts, |range| {
            tcp2world[range]
                .iter()
                .map(|p| self.label_one(p))
                .collect::<Vec<_>>()
        })
        .concat()
    }

    /// Labels one grasp (see the module documentation).
    pub fn label_one(&self, tcp2world: &Pose) -> GraspLabel {
        let opening = self.hand.max_opening;
        let fail = |reason| GraspLabel {
            success: false,
            width: opening as f32,
            object: -1,
            reason,
        };
        let p = &self.params;
        if self.touches_table(tcp2world) {
            return fail(Reason::Collision);
        }
        let margin = p.hand_margin + p.object_margin;
        let reach = margin + self.max_threshold;
        let near = self.near_pieces(tcp2world, reach);
        for n in &near {
            let piece = &self.scene.pieces[n.piece];
            let object_threshold = self.scene.objects[piece.object].threshold;
            let pos12 = n.pose_from(&[0.0; 3]);
            for part in &self.hand.swept {
                if !part.bound.near(&n.centre, piece.radius + reach) {
                    continue;
                }
                let pair = margin + part.threshold.min(object_threshold);
                let touching = closest_points_support_map_support_map(
                    &pos12,
                    &part.hull,
                    &piece.hull,
                    (pair * MM) as f32,
                );
                if !matches!(touching, ClosestPoints::Disjoint) {
                    return fail(Reason::Collision);
                }
            }
        }
        let [(left, d_left), (right, d_right)] =
            [0, 1].map(|side| self.closure(&near, side, margin));
        let (Some((a, n_left)), Some((b, n_right))) = (left, right) else {
            return fail(Reason::Empty);
        };
        if a != b {
            return fail(Reason::TwoObjects);
        }
        let width = (opening - d_left - d_right).max(0.0);
        if width < p.min_width {
            return fail(Reason::Narrow);
        }
        // The left finger closes along −y, the right one along +y.
        if -f64::from(n_left[1]) < self.cos_cone || f64::from(n_right[1]) < self.cos_cone {
            return fail(Reason::NotAntipodal);
        }
        GraspLabel {
            success: true,
            width: width as f32,
            object: self.scene.objects[a].id,
            reason: Reason::Success,
        }
    }

    /// Whether a swept part of the hand comes within its margin and threshold of the
    /// table (a box shape: no margin of its own, and larger than any hand part).
    fn touches_table(&self, tcp2world: &Pose) -> bool {
        let r = tcp2world.rotation();
        let rz = [r[(2, 0)], r[(2, 1)], r[(2, 2)]];
        let tz = tcp2world.translation().z;
        let table = self.scene.table_z() + self.params.hand_margin;
        // World −z in the TCP frame: the direction of each part's lowest point.
        let down = PVec::new(-rz[0] as f32, -rz[1] as f32, -rz[2] as f32);
        self.hand.swept.iter().any(|part| {
            let limit = table + part.threshold;
            if part.bound.lowest_z(&rz, tz) >= limit {
                return false;
            }
            let low = part.hull.local_support_point(down);
            let z = (0..3).map(|i| rz[i] * f64::from(low[i])).sum::<f64>() / MM + tz;
            z < limit
        })
    }

    /// The pieces whose bounding ball comes within `margin` of the hand's reach.
    fn near_pieces(&self, tcp2world: &Pose, margin: f64) -> Vec<Near> {
        let world2tcp = tcp2world.inverse();
        let mut near = Vec::new();
        let mut object_pose: Option<(usize, Rot3, Vector3<f64>)> = None;
        for (k, piece) in self.scene.pieces.iter().enumerate() {
            let c = world2tcp.transform_point(&piece.centre);
            let centre = [c.x, c.y, c.z];
            if !self.hand.bound.near(&centre, piece.radius + margin) {
                continue;
            }
            // Pieces of one object are stored together: convert its pose once.
            let (rotation, translation) = match object_pose {
                Some((o, r, t)) if o == piece.object => (r, t),
                _ => {
                    let obj2tcp = world2tcp.compose(&self.scene.objects[piece.object].obj2world);
                    let r = rot_to_parry(obj2tcp.rotation());
                    let t = *obj2tcp.translation();
                    object_pose = Some((piece.object, r, t));
                    (r, t)
                }
            };
            near.push(Near {
                piece: k,
                centre,
                rotation,
                translation,
            });
        }
        near
    }

    /// What finger `side` (0: left, +y, closing along −y; 1: right) meets first over
    /// the whole opening, and how far it travels to get there.
    fn closure(&self, near: &[Near], side: usize, margin: f64) -> (Closure, f64) {
        let dir = if side == 0 { -1.0 } else { 1.0 };
        let reach = self.hand.max_opening;
        let mut best = reach;
        let mut first: Option<(usize, usize)> = None;
        let vel12 = PVec::new(0.0, -dir as f32, 0.0);
        let options = ShapeCastOptions {
            max_time_of_impact: (reach * MM) as f32,
            target_distance: (margin * MM) as f32,
            stop_at_penetration: true,
            compute_impact_geometry_on_penetration: false,
        };
        for (j, part) in self.hand.fingers[side].iter().enumerate() {
            let swept = part.bound.swept(1, dir * reach);
            for (k, n) in near.iter().enumerate() {
                let piece = &self.scene.pieces[n.piece];
                if !swept.near(&n.centre, piece.radius + margin) {
                    continue;
                }
                let hit = cast_shapes_support_map_support_map(
                    &n.pose_from(&[0.0; 3]),
                    vel12,
                    &part.hull,
                    &piece.hull,
                    options,
                );
                if let Some(hit) = hit {
                    let travel = f64::from(hit.time_of_impact) / MM;
                    if travel < best {
                        (best, first) = (travel, Some((j, k)));
                    }
                }
            }
        }
        let Some((j, k)) = first else {
            return (None, best);
        };
        // The cast's own normal is the last direction its ray advanced along, not the
        // contact normal; the closest points of the finger where it stops and the piece
        // give the normal as the physics engine computes it.
        let n = &near[k];
        let piece = &self.scene.pieces[n.piece];
        let normal = contact_support_map_support_map(
            &n.pose_from(&[0.0, dir * best, 0.0]),
            &self.hand.fingers[side][j].hull,
            &piece.hull,
            ((2.0 * margin + 1e-3) * MM) as f32,
        )
        .map_or([0.0, dir as f32, 0.0], |c| {
            [c.normal1.x, c.normal1.y, c.normal1.z]
        });
        (Some((piece.object, normal)), best)
    }
}
