//! The scene of the grasp labeller: rigid objects made of convex pieces, on a table.
//!
//! Each piece is the convex hull of one collision mesh (what a physics engine collides
//! a dynamic mesh shape as); an object is a set of pieces with one `obj2world` pose. The
//! table is the half-space below the plane `z = table_z`.

use nalgebra::Point3;
use parry3d::shape::ConvexPolyhedron;

use super::convex::convex_hull;
use crate::camera::Pose;
use crate::error::{Error, Result};

/// One object: its id, pose and contact threshold.
#[derive(Debug, Clone)]
pub(crate) struct SceneObject {
    pub id: i32,
    pub obj2world: Pose,
    pub threshold: f64,
}

/// One convex piece of an object, in the object's frame (the hull in millimetres).
#[derive(Debug, Clone)]
pub(crate) struct Piece {
    /// Index into [`GraspScene::objects`].
    pub object: usize,
    pub hull: ConvexPolyhedron,
    /// Centre (world frame) and radius of a ball around the piece.
    pub centre: Point3<f64>,
    pub radius: f64,
}

/// Rigid objects of convex pieces on a table.
#[derive(Debug, Clone)]
pub struct GraspScene {
    table_z: f64,
    pub(crate) objects: Vec<SceneObject>,
    pub(crate) pieces: Vec<Piece>,
}

impl GraspScene {
    /// An empty scene on a table whose top is the plane `z = table_z` (world frame).
    ///
    /// # Errors
    /// [`Error::Value`] if `table_z` is not finite.
    pub fn new(table_z: f64) -> Result<Self> {
        if !table_z.is_finite() {
            return Err(Error::value("table_z", table_z, "must be finite"));
        }
        Ok(Self {
            table_z,
            objects: Vec::new(),
            pieces: Vec::new(),
        })
    }

    /// World z of the table's top.
    pub fn table_z(&self) -> f64 {
        self.table_z
    }

    /// Number of objects.
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// Whether the scene holds no object.
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Number of convex pieces over all objects.
    pub fn piece_count(&self) -> usize {
        self.pieces.len()
    }

    /// Adds object `id` at `obj2world` made of `pieces`: each a flat `(V, 3)` array of
    /// vertices in the object frame (metres), collided as its convex hull. `threshold`:
    /// how much farther than the margins the physics engine reports the object touching
    /// something (m; a pair reports at the smaller threshold of the two).
    ///
    /// # Errors
    /// [`Error::Value`] for an id below 0 or already in the scene, no pieces, or a
    /// threshold outside [0, 0.05] m;
    /// [`Error::Shape`] for a piece whose length is not a multiple of 3;
    /// [`Error::NonFinite`] for a NaN or infinite vertex; [`Error::Mesh`] for a piece
    /// whose vertices do not span a volume.
    pub fn add_object(
        &mut self,
        id: i32,
        obj2world: Pose,
        pieces: &[&[f64]],
        threshold: f64,
    ) -> Result<()> {
        if !(0.0..=0.05).contains(&threshold) {
            return Err(Error::value(
                "threshold",
                threshold,
                "must be in [0, 0.05] m",
            ));
        }
        if id < 0 {
            return Err(Error::value("id", id, "must be >= 0"));
        }
        if self.objects.iter().any(|o| o.id == id) {
            return Err(Error::value("id", id, "is already in the scene"));
        }
        if pieces.is_empty() {
            return Err(Error::value(
                "pieces",
                0,
                "an object needs at least 1 piece",
            ));
        }
        let object = self.objects.len();
        let mut built = Vec::with_capacity(pieces.len());
        for (k, &flat) in pieces.iter().enumerate() {
            let name = format!("pieces[{k}]");
            let (hull, lo, hi) = convex_hull(&name, flat)?;
            let centre = Point3::from(std::array::from_fn(|i| 0.5 * (lo[i] + hi[i])));
            let radius = flat
                .chunks_exact(3)
                .map(|p| (Point3::new(p[0], p[1], p[2]) - centre).norm())
                .fold(0.0f64, f64::max);
            built.push(Piece {
                object,
                hull,
                centre: obj2world.transform_point(&centre),
                radius,
            });
        }
        self.objects.push(SceneObject {
            id,
            obj2world,
            threshold,
        });
        self.pieces.extend(built);
        Ok(())
    }
}
