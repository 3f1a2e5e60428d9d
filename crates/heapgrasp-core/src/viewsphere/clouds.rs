//! Natarajan et al.'s point clouds (§3.2): voxel down-sampling of the fused views, and which
//! points of the unexplored region a depth view shows to be empty.
//!
//! A point is *seen empty* by a view when it lies in front of the camera, projects into
//! the image ([`PinholeCamera::project`]'s convention), the table does not hide it
//! (`z >= floor_z`), and the depth measured at its pixel is missing (not finite or
//! outside `[min_range, max_range]`: the ray met nothing there) or farther than
//! `occlusion ×` the point's own depth (the ray passed it). Points off the image stay
//! unexplored (the public code's bug, removing them, is not repeated). Points are split
//! over threads in contiguous ranges; each answer depends on its point alone.

use std::collections::HashMap;

use nalgebra::Point3;

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::parallel;
use crate::viewsphere::synthesis::check_flat_points;

/// Points per thread below which a call stays on one thread.
const MIN_POINTS_PER_THREAD: usize = 20_000;

/// The view's settings: the sensor's range (m), the occlusion factor and the table's
/// height (world z) below which points stay unexplored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeenParams {
    /// Nearest measured depth (m).
    pub min_range: f64,
    /// Farthest measured depth (m).
    pub max_range: f64,
    /// A point is passed by the ray when the measured depth exceeds this times its own.
    pub occlusion: f64,
    /// World z below which points are never seen.
    pub floor_z: f64,
}

impl SeenParams {
    fn validate(&self) -> Result<()> {
        let bad = |name: &str, value: f64, reason: &str| Error::Value {
            name: name.into(),
            value: format!("{value}"),
            reason: reason.into(),
        };
        if !(self.min_range.is_finite() && self.min_range >= 0.0) {
            return Err(bad(
                "min_range",
                self.min_range,
                "expected a finite value >= 0",
            ));
        }
        if !(self.max_range.is_finite() && self.max_range > self.min_range) {
            return Err(bad(
                "max_range",
                self.max_range,
                "expected a finite value > min_range",
            ));
        }
        if !(self.occlusion.is_finite() && self.occlusion > 0.0) {
            return Err(bad(
                "occlusion",
                self.occlusion,
                "expected a finite value > 0",
            ));
        }
        if self.floor_z.is_nan() {
            return Err(bad("floor_z", self.floor_z, "expected a number"));
        }
        Ok(())
    }
}

/// For each world point (flat `(N, 3)`), whether the view (`depth`, row-major
/// `height × width`, metres along the optical axis, from `camera` at `cam2world`) shows
/// it to be empty (module doc), on `threads` threads (0: [`parallel::num_threads`]).
pub fn seen_empty(
    points: &[f64],
    depth: &[f32],
    camera: &PinholeCamera,
    cam2world: &Pose,
    params: &SeenParams,
    threads: usize,
) -> Result<Vec<bool>> {
    check_flat_points("points", points)?;
    camera.check_image("depth", depth.len())?;
    params.validate()?;
    let world2cam = cam2world.inverse();
    let n = points.len() / 3;
    let threads = if threads == 0 {
        parallel::num_threads()
    } else {
        threads
    };
    let parts = threads.min(n / MIN_POINTS_PER_THREAD).max(1);
    let width = camera.width as usize;
    let chunks = parallel::map_ranges(n, parts, |range| {
        range
            .map(|i| {
                let p = &points[3 * i..3 * i + 3];
                if p[2] < params.floor_z {
                    return false;
                }
                let c = world2cam.transform_point(&Point3::new(p[0], p[1], p[2]));
                let Some((u, v)) = camera.project(&c) else {
                    return false;
                };
                let d = f64::from(depth[v as usize * width + u as usize]);
                let valid = d.is_finite() && d >= params.min_range && d <= params.max_range;
                !valid || d > params.occlusion * c.z
            })
            .collect::<Vec<_>>()
    });
    Ok(chunks.concat())
}

/// The largest cell index magnitude voxel down-sampling accepts (2⁶²).
const LARGEST_CELL: f64 = 4_611_686_018_427_387_904.0;

/// Centroids of points per cell of a lattice anchored at the origin, summed in the order
/// the points come.
struct Voxels {
    voxel: f64,
    /// The last point's cell and slot: neighbouring pixels mostly share a cell.
    last: Option<([i64; 3], usize)>,
    cells: HashMap<[i64; 3], usize>,
    keys: Vec<[i64; 3]>,
    sums: Vec<[f64; 4]>,
}

impl Voxels {
    fn new(voxel: f64) -> Result<Self> {
        if !(voxel.is_finite() && voxel > 0.0) {
            return Err(Error::value("voxel", voxel, "expected a finite value > 0"));
        }
        Ok(Self {
            voxel,
            last: None,
            cells: HashMap::new(),
            keys: Vec::new(),
            sums: Vec::new(),
        })
    }

    /// Adds a point; an error when its cell's index does not fit an `i64` comfortably
    /// (|p / voxel| ≥ 2⁶²: coordinates far beyond any scene).
    fn add(&mut self, p: [f64; 3]) -> Result<()> {
        let cell = p.map(|v| (v / self.voxel).floor());
        if cell.iter().any(|c| !(c.abs() < LARGEST_CELL)) {
            return Err(Error::value(
                "points",
                format!("{p:?}"),
                format!("too far from the origin for {} m voxels", self.voxel),
            ));
        }
        let key = cell.map(|c| c as i64);
        let slot = match self.last {
            Some((k, slot)) if k == key => slot,
            _ => {
                let (keys, sums) = (&mut self.keys, &mut self.sums);
                let slot = *self.cells.entry(key).or_insert_with(|| {
                    keys.push(key);
                    sums.push([0.0; 4]);
                    keys.len() - 1
                });
                self.last = Some((key, slot));
                slot
            }
        };
        let sum = &mut self.sums[slot];
        sum[0] += p[0];
        sum[1] += p[1];
        sum[2] += p[2];
        sum[3] += 1.0;
        Ok(())
    }

    /// The centroids, cells in lexicographic order of their index.
    fn centroids(self) -> Vec<[f64; 3]> {
        let mut order: Vec<usize> = (0..self.keys.len()).collect();
        order.sort_unstable_by_key(|&i| self.keys[i]);
        order
            .into_iter()
            .map(|i| {
                let s = self.sums[i];
                [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
            })
            .collect()
    }
}

/// One point per occupied `voxel`-sized cell of a lattice anchored at the origin (flat
/// `(N, 3)` points): the centroid of the cell's points (summed in the points' order),
/// cells in lexicographic order of their index `⌊p / voxel⌋`.
pub fn voxel_downsample(points: &[f64], voxel: f64) -> Result<Vec<[f64; 3]>> {
    let mut voxels = Voxels::new(voxel)?;
    check_flat_points("points", points)?;
    for p in points.chunks_exact(3) {
        voxels.add([p[0], p[1], p[2]])?;
    }
    Ok(voxels.centroids())
}

/// The world points of a depth image (row-major `height × width`, metres along the
/// optical axis, from `camera` at `cam2world`) whose depth lies in `[min_range,
/// max_range]`, down-sampled as [`voxel_downsample`] does (pixels in row-major order):
/// pixel `(u, v)` lies on the ray `((u − cx) / fx, (v − cy) / fy, 1)`.
pub fn depth_voxels(
    depth: &[f32],
    camera: &PinholeCamera,
    cam2world: &Pose,
    min_range: f64,
    max_range: f64,
    voxel: f64,
) -> Result<Vec<[f64; 3]>> {
    camera.check_image("depth", depth.len())?;
    if !(min_range.is_finite() && min_range >= 0.0) {
        return Err(Error::value(
            "min_range",
            min_range,
            "expected a finite value >= 0",
        ));
    }
    if !(max_range.is_finite() && max_range > min_range) {
        return Err(Error::value(
            "max_range",
            max_range,
            "expected a finite value > min_range",
        ));
    }
    let mut voxels = Voxels::new(voxel)?;
    let width = camera.width as usize;
    for (k, &d) in depth.iter().enumerate() {
        let z = f64::from(d);
        if !(z.is_finite() && z >= min_range && z <= max_range) {
            continue;
        }
        let (u, v) = ((k % width) as f64, (k / width) as f64);
        let c = Point3::new(
            (u - camera.cx) / camera.fx * z,
            (v - camera.cy) / camera.fy * z,
            z,
        );
        let w = cam2world.transform_point(&c);
        voxels.add([w.x, w.y, w.z])?;
    }
    Ok(voxels.centroids())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_depth_view_gives_the_plane_in_its_range() {
        let (camera, pose) = above();
        // 1 m everywhere (the plane z = 0), nothing measured in the first row, too near
        // in the second.
        let mut depth = vec![1.0f32; 64 * 48];
        depth[..64].fill(0.0);
        depth[64..128].fill(0.05);
        let out = depth_voxels(&depth, &camera, &pose, 0.1, 3.0, 0.01).expect("valid");
        assert!(!out.is_empty());
        assert!(out.iter().all(|p| p[2].abs() < 1e-12));
        // The plane seen: x in ±0.63 m, y within the rows measured.
        let (lo, hi) = out
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
        assert!(lo > -0.64 && hi < 0.65 && hi - lo > 1.2);
        // As many cells as the points' centroids fall in distinct keys, sorted.
        let keys: Vec<[i64; 3]> = out
            .iter()
            .map(|p| p.map(|v| (v / 0.01).floor() as i64))
            .collect();
        assert!(keys.windows(2).all(|w| w[0] < w[1]));
        assert!(depth_voxels(&depth[1..], &camera, &pose, 0.1, 3.0, 0.01).is_err());
        assert!(depth_voxels(&depth, &camera, &pose, 0.5, 0.4, 0.01).is_err());
        assert!(depth_voxels(&depth, &camera, &pose, 0.1, 3.0, -1.0).is_err());
    }

    #[test]
    fn voxels_hold_their_points_centroid_in_key_order() {
        let points = [
            0.012, 0.0, 0.0, // cell (1, 0, 0)
            0.001, 0.002, 0.0, // cell (0, 0, 0)
            0.003, 0.004, 0.0, // cell (0, 0, 0)
            -0.001, 0.0, 0.0, // cell (-1, 0, 0)
        ];
        let out = voxel_downsample(&points, 0.01).expect("valid");
        assert_eq!(out.len(), 3);
        assert_eq!(out[0], [-0.001, 0.0, 0.0]);
        assert!((out[1][0] - 0.002).abs() < 1e-15 && (out[1][1] - 0.003).abs() < 1e-15);
        assert_eq!(out[2], [0.012, 0.0, 0.0]);
        assert!(voxel_downsample(&[], 0.01).expect("valid").is_empty());
        assert!(voxel_downsample(&points, 0.0).is_err());
        assert!(voxel_downsample(&points[..4], 0.01).is_err());
        assert!(voxel_downsample(&[f64::NAN, 0.0, 0.0], 0.01).is_err());
        assert!(voxel_downsample(&[1e300, 0.0, 0.0], 0.01).is_err());
    }

    fn params() -> SeenParams {
        SeenParams {
            min_range: 0.1,
            max_range: 3.0,
            occlusion: 0.99,
            floor_z: -0.01,
        }
    }

    /// A camera 1 m above the origin looking straight down.
    fn above() -> (PinholeCamera, Pose) {
        let camera = PinholeCamera::new(64, 48, 50.0, 50.0, 31.5, 23.5).expect("valid");
        let pose = Pose::look_at([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).expect("valid");
        (camera, pose)
    }

    #[test]
    fn points_before_the_surface_are_seen_and_behind_it_are_not() {
        let (camera, pose) = above();
        // The table at z = 0 measured everywhere (depth 1 m), a hole in one corner.
        let mut depth = vec![1.0f32; 64 * 48];
        depth[0] = 0.0;
        let points = [
            0.0, 0.0, 0.5, // in front of the table: seen
            0.0, 0.0, -0.005, // 5 mm behind the surface, within the 1 % margin: seen
            0.0, 0.0, -0.05, // 5 cm behind it: hidden (and below the floor)
            5.0, 0.0, 0.5, // off the image: stays
            0.0, 0.0, 2.0, // behind the camera: stays
        ];
        let seen = seen_empty(&points, &depth, &camera, &pose, &params(), 1).expect("valid");
        assert_eq!(seen, vec![true, true, false, false, false]);
        // Without the floor, 5 cm behind the surface is still hidden; 5 mm, with no
        // margin (occlusion 1), too.
        let open = SeenParams {
            floor_z: -1.0,
            occlusion: 1.0,
            ..params()
        };
        let seen = seen_empty(&points[..9], &depth, &camera, &pose, &open, 1).expect("valid");
        assert_eq!(seen, vec![true, false, false]);
        // A point projecting into the hole: nothing measured, so the ray met nothing.
        let corner = pose.transform_point(&Point3::new(-0.63 * 0.8, -0.47 * 0.8, 0.8));
        let hole = [corner.x, corner.y, corner.z];
        let seen = seen_empty(&hole, &depth, &camera, &pose, &params(), 1).expect("valid");
        assert_eq!(seen, vec![true]);
    }

    #[test]
    fn thread_count_does_not_change_the_answer() {
        let (camera, pose) = above();
        let depth: Vec<f32> = (0..64 * 48).map(|k| 0.5 + (k % 7) as f32 * 0.1).collect();
        let points: Vec<f64> = (0..150_000)
            .flat_map(|i| {
                let t = i as f64 * 0.618_033_988_749_895;
                [
                    (t * 0.3).fract() - 0.5,
                    (t * 0.7).fract() - 0.5,
                    (t * 0.11).fract() * 0.8,
                ]
            })
            .collect();
        let one = seen_empty(&points, &depth, &camera, &pose, &params(), 1).expect("valid");
        let four = seen_empty(&points, &depth, &camera, &pose, &params(), 4).expect("valid");
        assert_eq!(one, four);
        assert!(one.iter().any(|&s| s) && one.iter().any(|&s| !s));
    }

    #[test]
    fn bad_input_is_an_error() {
        let (camera, pose) = above();
        let depth = vec![1.0f32; 64 * 48];
        assert!(seen_empty(&[0.0, 1.0], &depth, &camera, &pose, &params(), 1).is_err());
        let nan = [0.0, f64::NAN, 0.0];
        assert!(seen_empty(&nan, &depth, &camera, &pose, &params(), 1).is_err());
        assert!(seen_empty(&[0.0; 3], &depth[1..], &camera, &pose, &params(), 1).is_err());
        for p in [
            SeenParams {
                min_range: -1.0,
                ..params()
            },
            SeenParams {
                max_range: 0.05,
                ..params()
            },
            SeenParams {
                occlusion: 0.0,
                ..params()
            },
            SeenParams {
                floor_z: f64::NAN,
                ..params()
            },
        ] {
            assert!(seen_empty(&[0.0; 3], &depth, &camera, &pose, &p, 1).is_err());
        }
    }
}
