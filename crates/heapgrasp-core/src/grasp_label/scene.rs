//! The scene of the grasp labeller: rigid objects made of convex pieces, on a table.
//!
//! Each piece is the convex hull of one collision mesh (what a physics engine collides
//! a dynamic mesh shape as); an object is a set of pieces with one `obj2world` pose. The
//! table is the half-space below the plane `z = table_z`.

use nalgebra::Point3;
use parry3d::math::Vector as PVec;
use parry3d::shape::ConvexPolyhedron;

use super::MM;
use crate::camera::Pose;
use crate::error::{Error, Result};

/// Most vertices one piece may have (a collision mesh is a few thousand at most).
pub const MAX_PIECE_VERTICES: usize = 1 << 20;

/// One object: its id and pose.
#[derive(Debug, Clone)]
pub(crate) struct SceneObject {
    pub id: i32,
    pub obj2world: Pose,
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
    /// vertices in the object frame (metres), collided as its convex hull.
    ///
    /// # Errors
    /// [`Error::Value`] for an id below 0 or already in the scene, or no pieces;
    /// [`Error::Shape`] for a piece whose length is not a multiple of 3;
    /// [`Error::NonFinite`] for a NaN or infinite vertex; [`Error::Mesh`] for a piece
    /// whose vertices do not span a volume.
    pub fn add_object(&mut self, id: i32, obj2world: Pose, pieces: &[&[f64]]) -> Result<()> {
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
            let (hull, centre, radius) = hull_of(&name, flat)?;
            built.push(Piece {
                object,
                hull,
                centre: obj2world.transform_point(&centre),
                radius,
            });
        }
        self.objects.push(SceneObject { id, obj2world });
        self.pieces.extend(built);
        Ok(())
    }
}

/// The convex hull of a flat `(V, 3)` vertex array, with a ball around it (centre in
/// the array's frame, radius).
fn hull_of(name: &str, flat: &[f64]) -> Result<(ConvexPolyhedron, Point3<f64>, f64)> {
    if !flat.len().is_multiple_of(3) || flat.is_empty() {
        return Err(Error::shape(
            name,
            "(V, 3) with V >= 4",
            format!("{} values", flat.len()),
        ));
    }
    if flat.len() / 3 > MAX_PIECE_VERTICES {
        return Err(Error::shape(
            name,
            format!("(V, 3) with V <= {MAX_PIECE_VERTICES}"),
            format!("({}, 3)", flat.len() / 3),
        ));
    }
    if let Some(i) = flat.iter().position(|x| !x.is_finite()) {
        return Err(Error::NonFinite {
            name: name.to_owned(),
            position: format!("[{}, {}]", i / 3, i % 3),
        });
    }
    let pts: Vec<Point3<f64>> = flat
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let (lo, hi) = pts.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                std::array::from_fn(|i| lo[i].min(p[i])),
                std::array::from_fn(|i| hi[i].max(p[i])),
            )
        },
    );
    let centre = Point3::from(std::array::from_fn(|i| 0.5 * (lo[i] + hi[i])));
    let radius = pts
        .iter()
        .map(|p| (p - centre).norm())
        .fold(0.0f64, f64::max);
    let flat_piece = || Error::Mesh {
        name: name.to_owned(),
        reason: "the vertices of a piece must span a volume (not all on one plane)".into(),
    };
    if !spans_volume(&pts, radius) {
        return Err(flat_piece());
    }
    // In millimetres (see `MM`); object frames are centred on the object
    // (sim/objects.py), so f32 keeps these coordinates to well under a micrometre.
    let local: Vec<PVec> = pts
        .iter()
        .map(|p| PVec::new((p.x * MM) as f32, (p.y * MM) as f32, (p.z * MM) as f32))
        .collect();
    // parry's quickhull has panicked on near-degenerate inputs in the past; a panic here
    // must not take the caller down with a valid-looking mesh.
    let hull = std::panic::catch_unwind(|| ConvexPolyhedron::from_convex_hull(&local))
        .ok()
        .flatten()
        .ok_or_else(flat_piece)?;
    Ok((hull, centre, radius))
}

/// Whether points span a volume: the largest tetrahedron on four extreme points is
/// thicker than a micrometre relative to the points' size.
fn spans_volume(pts: &[Point3<f64>], radius: f64) -> bool {
    if pts.len() < 4 || !(radius > 1e-9) {
        return false;
    }
    let a = pts[0];
    let Some(b) = pts
        .iter()
        .max_by(|p, q| (*p - a).norm_squared().total_cmp(&(*q - a).norm_squared()))
    else {
        return false;
    };
    let ab = b - a;
    let Some(c) = pts.iter().max_by(|p, q| {
        ab.cross(&(*p - a))
            .norm_squared()
            .total_cmp(&ab.cross(&(*q - a)).norm_squared())
    }) else {
        return false;
    };
    let n = ab.cross(&(c - a));
    if !(n.norm() > 1e-12 * radius * radius) {
        return false;
    }
    let n = n.normalize();
    let thickness = pts
        .iter()
        .map(|p| n.dot(&(p - a)).abs())
        .fold(0.0, f64::max);
    thickness > 1e-6 * radius.max(1e-3)
}
