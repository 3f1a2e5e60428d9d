//! Natarajan et al.'s heuristic view scores (§4.2.2–4.2.3): which unexplored points could hold
//! a grasp, and which points a next view would see past the object's surface.
//!
//! # The grasp region (the 3D heuristic's "useful" unexplored points)
//! An antipodal grasp closes along a contact's normal, so only space along the visible
//! surface normals can hold the other contact. A target point is in the grasp region
//! when, for some object point `p` with unit normal `n`, `d = q − p` has
//! `|d·n| <= half_length` (the gripper's opening, both sides of the surface) and
//! `|d − (d·n) n| <= radius` (a cylinder about the normal line; the original uses
//! 16 × 3 × 3 cm boxes, whose orientation about the normal it leaves open).
//!
//! # Visibility through a local surface reconstruction
//! Each object point becomes a surfel: a square of half width `radius` centred on the
//! point, across its normal (tangent axes from the normal alone). The surfels are one
//! parry3d [`TriMesh`] (two triangles each) whose BVH answers the rays. A target is
//! visible from an eye when the segment between them meets no surfel (the object's
//! unseen parts occlude nothing: the paper's optimistic estimate). The field of view and
//! the sensor's range are the caller's. Rays are split over threads in contiguous
//! ranges; each answer depends on its ray alone.

use nalgebra::Vector3;
use parry3d::math::Vector as PVec;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;

use crate::error::{Error, Result};
use crate::parallel;
use crate::viewsphere::synthesis::{CloudIndex, Point};

/// Object points per thread below which the grasp region stays on one thread.
const MIN_POINTS_PER_THREAD: usize = 2_000;
/// Rays per thread below which visibility stays on one thread.
const MIN_RAYS_PER_THREAD: usize = 4_000;
/// The most samples the grasp region takes along each side of a normal line
/// (`half_length / radius`): beyond it the work is unbounded for all practical purposes
/// (a radius of 1e-300 m), and the call is refused.
pub const MAX_REGION_SAMPLES: f64 = 10_000.0;

fn threads(n: usize, per_thread: usize, threads: usize) -> usize {
    let t = if threads == 0 {
        parallel::num_threads()
    } else {
        threads
    };
    t.min(n / per_thread).max(1)
}

fn positive(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::value(
            name,
            format!("{value}"),
            "expected a finite value > 0",
        ))
    }
}

/// Unit normals of `normals` (one per point): a shape mismatch or a zero normal is an
/// error naming it.
fn unit_normals(points: &[Point], normals: &[Point]) -> Result<Vec<Vector3<f64>>> {
    if normals.len() != points.len() {
        return Err(Error::Shape {
            name: "normals".into(),
            expected: format!("({}, 3)", points.len()),
            got: format!("({}, 3)", normals.len()),
        });
    }
    normals
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let v = Vector3::from(*n);
            let norm = v.norm();
            if norm > 1e-12 && norm.is_finite() {
                Ok(v / norm)
            } else {
                Err(Error::value(
                    &format!("normals[{i}]"),
                    format!("{n:?}"),
                    "expected a non-zero normal",
                ))
            }
        })
        .collect()
}

/// Whether each target lies in the grasp region of the object points (module doc):
/// within `half_length` along and `radius` across some point's normal line, on
/// `threads` threads (0: all).
pub fn grasp_region(
    points: &[Point],
    normals: &[Point],
    targets: &[Point],
    half_length: f64,
    radius: f64,
    threads: usize,
) -> Result<Vec<bool>> {
    positive("half_length", half_length)?;
    positive("radius", radius)?;
    if half_length / radius > MAX_REGION_SAMPLES {
        return Err(Error::value(
            "radius",
            format!("{radius}"),
            format!(
                "expected half_length / radius <= {MAX_REGION_SAMPLES} (half_length is \
                 {half_length}): the region is sampled every radius along each normal"
            ),
        ));
    }
    let normals = unit_normals(points, normals)?;
    if points.is_empty() || targets.is_empty() {
        return Ok(vec![false; targets.len()]);
    }
    let cell = 2.0 * radius;
    let index = CloudIndex::new(targets, 0..targets.len(), cell);
    // Samples along the normal line every `radius`: every point of the cylinder is
    // within `radius` across and `radius / 2` along of a sample, so within
    // `radius · √(1 + 1/4)` of it.
    let reach = radius * 1.2;
    let samples = (half_length / radius).ceil() as i64;
    let parts = self::threads(points.len(), MIN_POINTS_PER_THREAD, threads);
    let masks = parallel::map_ranges(points.len(), parts, |range| {
        let mut mask = vec![false; targets.len()];
        for i in range {
            let p = Vector3::from(points[i]);
            let n = normals[i];
            for s in -samples..=samples {
                let t = (s as f64 * radius).clamp(-half_length, half_length);
                let c = p + n * t;
                index.near(&[c.x, c.y, c.z], reach, |j| {
                    let j = j as usize;
                    if mask[j] {
                        return;
                    }
                    let d = Vector3::from(targets[j]) - p;
                    let along = d.dot(&n);
                    if along.abs() <= half_length && (d - n * along).norm() <= radius {
                        mask[j] = true;
                    }
                });
            }
        }
        mask
    });
    let mut out = vec![false; targets.len()];
    for mask in masks {
        for (o, m) in out.iter_mut().zip(mask) {
            *o |= m;
        }
    }
    Ok(out)
}

/// Two unit tangents across `n` (any pair; they depend on `n` alone).
fn tangents(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = n.cross(&helper).normalize();
    (u, n.cross(&u))
}

/// The surfels of `points` as one triangle mesh (module doc), or None without points.
fn surfels(points: &[Point], normals: &[Vector3<f64>], radius: f64) -> Result<Option<TriMesh>> {
    if points.is_empty() {
        return Ok(None);
    }
    let mut vertices = Vec::with_capacity(4 * points.len());
    let mut faces = Vec::with_capacity(2 * points.len());
    for (p, n) in points.iter().zip(normals) {
        let (u, v) = tangents(n);
        let c = Vector3::from(*p);
        let k = vertices.len() as u32;
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let q = c + (u * a + v * b) * radius;
            vertices.push(PVec::new(q.x as f32, q.y as f32, q.z as f32));
        }
        faces.push([k, k + 1, k + 2]);
        faces.push([k, k + 2, k + 3]);
    }
    TriMesh::new(vertices, faces)
        .map(Some)
        .map_err(|e| Error::Mesh {
            name: "surfels".into(),
            reason: format!("{e:?}"),
        })
}

/// For every eye and target (row-major `(V, M)`), whether the segment from the eye to
/// the target meets none of the surfels of `points` (module doc), on `threads` threads
/// (0: all). A target at an eye is visible.
pub fn surfel_visibility(
    points: &[Point],
    normals: &[Point],
    radius: f64,
    eyes: &[Point],
    targets: &[Point],
    threads: usize,
) -> Result<Vec<bool>> {
    positive("radius", radius)?;
    let normals = unit_normals(points, normals)?;
    let n_rays = eyes.len() * targets.len();
    let Some(mesh) = surfels(points, &normals, radius)? else {
        return Ok(vec![true; n_rays]);
    };
    let parts = self::threads(n_rays, MIN_RAYS_PER_THREAD, threads);
    let chunks = parallel::map_ranges(n_rays, parts, |range| {
        range
            .map(|k| {
                let (e, q) = (&eyes[k / targets.len()], &targets[k % targets.len()]);
                let d = Vector3::new(q[0] - e[0], q[1] - e[1], q[2] - e[2]);
                let dist = d.norm();
                if !(dist > 0.0) {
                    return true;
                }
                let d = d / dist;
                let ray = Ray::new(
                    PVec::new(e[0] as f32, e[1] as f32, e[2] as f32),
                    PVec::new(d.x as f32, d.y as f32, d.z as f32),
                );
                mesh.cast_local_ray(&ray, dist as f32, false).is_none()
            })
            .collect::<Vec<_>>()
    });
    Ok(chunks.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_radius_tiny_against_half_length_is_refused_not_looped_over() {
        let p = [[0.0, 0.0, 0.0]];
        let n = [[0.0, 0.0, 1.0]];
        let t = [[0.0, 0.0, 0.01]];
        for (half, radius) in [(0.08, 1e-300), (1e300, 0.015), (0.2, 5e-324)] {
            let err = grasp_region(&p, &n, &t, half, radius, 1).unwrap_err();
            assert!(err.to_string().contains("half_length / radius"), "{err}");
        }
        assert_eq!(
            grasp_region(&p, &n, &t, 0.08, 0.08 / MAX_REGION_SAMPLES, 1).unwrap(),
            [true]
        );
    }

    /// A square sheet of points in the plane z = 0 (normals +z), `n × n` at `spacing`.
    fn sheet(n: usize, spacing: f64) -> (Vec<Point>, Vec<Point>) {
        let half = (n as f64 - 1.0) / 2.0;
        let points: Vec<Point> = (0..n * n)
            .map(|k| {
                let (i, j) = ((k / n) as f64, (k % n) as f64);
                [(i - half) * spacing, (j - half) * spacing, 0.0]
            })
            .collect();
        let normals = vec![[0.0, 0.0, 1.0]; points.len()];
        (points, normals)
    }

    #[test]
    fn a_sheet_hides_what_lies_behind_it() {
        let (points, normals) = sheet(21, 0.0075); // 15 cm square
        let eyes = [[0.0, 0.0, 0.4], [0.0, 0.0, -0.4], [0.4, 0.0, 0.0]];
        let targets = [[0.0, 0.0, -0.05], [0.0, 0.0, 0.05], [0.01, 0.02, -0.01]];
        let vis = surfel_visibility(&points, &normals, 0.0075, &eyes, &targets, 1).unwrap();
        // From above: the points below are hidden, the one above is not.
        assert_eq!(&vis[0..3], &[false, true, false]);
        // From below: the reverse.
        assert_eq!(&vis[3..6], &[true, false, true]);
        // From the side, level with the sheet: the rays to the upper target pass above
        // the surfels; those through the sheet's plane below it pass under them.
        assert!(vis[7]);
    }

    #[test]
    fn gaps_wider_than_the_surfels_let_rays_through() {
        let (points, normals) = sheet(5, 0.05); // 5 points 5 cm apart: 2 cm gaps at r = 1.5 cm
        let eye = [[0.025, 0.025, 0.4]];
        let target = [[0.025, 0.025, -0.05]]; // behind the middle of a gap
        let vis = surfel_visibility(&points, &normals, 0.015, &eye, &target, 1).unwrap();
        assert_eq!(vis, vec![true]);
        let vis = surfel_visibility(&points, &normals, 0.03, &eye, &target, 1).unwrap();
        assert_eq!(vis, vec![false]);
    }

    #[test]
    fn threads_do_not_change_visibility() {
        let (points, normals) = sheet(30, 0.005);
        let eyes: Vec<Point> = (0..8)
            .map(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_4;
                [0.3 * a.cos(), 0.3 * a.sin(), 0.2]
            })
            .collect();
        let targets: Vec<Point> = (0..2_000)
            .map(|k| {
                let f = k as f64;
                [
                    0.1 * (f * 0.37).sin(),
                    0.1 * (f * 0.91).cos(),
                    0.05 * (f * 0.13).sin(),
                ]
            })
            .collect();
        let one = surfel_visibility(&points, &normals, 0.004, &eyes, &targets, 1).unwrap();
        let many = surfel_visibility(&points, &normals, 0.004, &eyes, &targets, 4).unwrap();
        assert_eq!(one, many);
        assert!(one.iter().any(|&v| v) && one.iter().any(|&v| !v));
    }

    #[test]
    fn no_points_hide_nothing() {
        let vis = surfel_visibility(&[], &[], 0.01, &[[0.0; 3]], &[[1.0, 0.0, 0.0]], 0).unwrap();
        assert_eq!(vis, vec![true]);
    }

    #[test]
    fn the_grasp_region_is_a_cylinder_about_each_normal() {
        let points = [[0.0, 0.0, 0.0]];
        let normals = [[0.0, 0.0, 2.0]]; // not unit: normalised
        let targets = [
            [0.0, 0.0, -0.079],  // inside, along
            [0.0, 0.0, 0.081],   // beyond the length
            [0.014, 0.0, 0.05],  // inside, across
            [0.011, 0.011, 0.0], // 1.56 cm across: outside
            [0.0, 0.016, -0.02], // outside
        ];
        let mask = grasp_region(&points, &normals, &targets, 0.08, 0.015, 1).unwrap();
        assert_eq!(mask, vec![true, false, true, false, false]);
    }

    #[test]
    fn the_grasp_region_matches_brute_force() {
        let points: Vec<Point> = (0..300)
            .map(|k| {
                let f = k as f64;
                [
                    0.05 * (f * 0.7).sin(),
                    0.05 * (f * 1.3).cos(),
                    0.03 * (f * 0.2).sin(),
                ]
            })
            .collect();
        let normals: Vec<Point> = (0..300)
            .map(|k| {
                let f = k as f64;
                [(f * 0.5).sin(), (f * 0.3).cos(), 0.5 + (f * 0.1).sin()]
            })
            .collect();
        let targets: Vec<Point> = (0..3_000)
            .map(|k| {
                let f = k as f64;
                [
                    0.15 * (f * 0.123).sin(),
                    0.15 * (f * 0.457).cos(),
                    0.1 * (f * 0.789).sin(),
                ]
            })
            .collect();
        let (half_length, radius) = (0.08, 0.012);
        let fast = grasp_region(&points, &normals, &targets, half_length, radius, 2).unwrap();
        let slow: Vec<bool> = targets
            .iter()
            .map(|q| {
                points.iter().zip(&normals).any(|(p, n)| {
                    let n = Vector3::from(*n).normalize();
                    let d = Vector3::from(*q) - Vector3::from(*p);
                    let along = d.dot(&n);
                    along.abs() <= half_length && (d - n * along).norm() <= radius
                })
            })
            .collect();
        assert_eq!(fast, slow);
        assert!(fast.iter().any(|&v| v) && fast.iter().any(|&v| !v));
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = [[0.0; 3]];
        assert!(grasp_region(&p, &[[0.0; 3]], &p, 0.08, 0.01, 0).is_err());
        assert!(grasp_region(&p, &[], &p, 0.08, 0.01, 0).is_err());
        assert!(grasp_region(&p, &[[0.0, 0.0, 1.0]], &p, f64::NAN, 0.01, 0).is_err());
        assert!(surfel_visibility(&p, &[[0.0, 0.0, 1.0]], 0.0, &p, &p, 0).is_err());
    }
}
