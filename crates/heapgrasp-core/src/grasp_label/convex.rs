//! Convex hulls of vertex arrays for the grasp labeller, in parry's units (mm).

use nalgebra::Point3;
use parry3d::math::Vector as PVec;
use parry3d::shape::ConvexPolyhedron;

use super::MM;
use crate::error::{Error, Result};

/// Most vertices one convex piece may have (a collision mesh is a few thousand at most).
pub const MAX_PIECE_VERTICES: usize = 1 << 20;

/// The convex hull (millimetres) of a flat `(V, 3)` vertex array in metres, and the
/// array's bounding box (metres).
///
/// # Errors
/// [`Error::Shape`] for a length that is not a positive multiple of 3 or too many
/// vertices; [`Error::NonFinite`] for a NaN or infinite coordinate; [`Error::Mesh`] for
/// vertices that do not span a volume.
pub(crate) fn convex_hull(
    name: &str,
    flat: &[f64],
) -> Result<(ConvexPolyhedron, [f64; 3], [f64; 3])> {
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
    let size = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
    let flat_piece = || Error::Mesh {
        name: name.to_owned(),
        reason: "the vertices of a piece must span a volume (not all on one plane)".into(),
    };
    if !spans_volume(&pts, size) {
        return Err(flat_piece());
    }
    // Pieces are given in frames centred near them (an object's, the TCP's), so f32 keeps
    // their millimetre coordinates to well under a micrometre.
    let mm: Vec<PVec> = pts
        .iter()
        .map(|p| PVec::new((p.x * MM) as f32, (p.y * MM) as f32, (p.z * MM) as f32))
        .collect();
    // parry's quickhull has panicked on near-degenerate inputs in the past; a panic here
    // must not take the caller down with a valid-looking mesh.
    let hull = std::panic::catch_unwind(|| ConvexPolyhedron::from_convex_hull(&mm))
        .ok()
        .flatten()
        .ok_or_else(flat_piece)?;
    Ok((hull, lo, hi))
}

/// Whether points span a volume: four of them make a tetrahedron thicker than a
/// millionth of the points' size.
fn spans_volume(pts: &[Point3<f64>], size: f64) -> bool {
    if pts.len() < 4 || !(size > 1e-9) {
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
    if !(n.norm() > 1e-12 * size * size) {
        return false;
    }
    let n = n.normalize();
    let thickness = pts
        .iter()
        .map(|p| n.dot(&(p - a)).abs())
        .fold(0.0, f64::max);
    thickness > 1e-6 * size.max(1e-3)
}
