//! Truncated signed distance fusion of depth images, the scene representation of the
//! VGN baseline (Breyer et al., CoRL 2020) that HEAPGrasp compares against, built on the
//! projection kernel of [`crate::projector`].
//!
//! # Semantics (the contract a NumPy reference re-implements)
//! The volume holds, per voxel of a [`GridSpec`], a value `tsdf` and a weight `w`, both
//! f32 and initially 0. Integrating a depth image `depth_m` (metres, `(height, width)`
//! row-major, indexed `[v, u]`) seen by `camera` at `cam2world` updates each voxel as
//! follows:
//! 1. `(x, y, z)` = the voxel centre `origin + ([a, b, c] + 0.5) · size / R` in the camera
//!    frame (`world2cam = cam2world⁻¹`);
//! 2. the voxel is skipped unless it projects into the image by the crate convention:
//!    `z > 0`, `u = floor(fx·x/z + cx + 0.5)`, `v = floor(fy·y/z + cy + 0.5)`,
//!    `0 <= u < width`, `0 <= v < height`;
//! 3. `d = depth_m[v, u]`; the voxel is skipped when `d` is not finite or `d <= 0`
//!    (missing depth);
//! 4. `sdf = d - z` (positive in front of the surface); the voxel is skipped when
//!    `sdf < -truncation` (occluded, behind the surface by more than the truncation);
//! 5. `obs = min(1, sdf / truncation)`, so `obs ∈ [-1, 1]`;
//! 6. running mean with observation weight 1: `tsdf = (tsdf · w + obs) / (w + 1)`, then
//!    `w = w + 1`.
//!
//! Voxels never updated keep `tsdf = 0`, `w = 0`; `w` counts the frames that observed a
//! voxel (exact up to 2²⁴).
//!
//! # Precision
//! Steps 1–6 run in f32, the camera coordinates coming from [`VoxelProjector`] (affine
//! in the voxel index, precomputed in f64 per view). Against an f64 evaluation, `z`
//! differs by ~1e-7 relative, so `obs` agrees to ~1e-6 absolute for truncations of a
//! few voxels, and a voxel whose f64 pixel coordinate lies within ~1e-4 px of a pixel
//! border may read the neighbouring pixel (see [`crate::projector`]).
//!
//! # Layout and threads
//! Values and weights are flat C-order `R³` buffers (`(a·R + b)·R + c`). The kernel walks
//! grid columns `(a, b, ·)` and runs slabs of the a axis on several threads for large
//! grids; the result does not depend on the thread count.

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::grid::GridSpec;
use crate::parallel;
use crate::projector::{Column, Intrinsics32, VoxelProjector};

/// Grids with at least this many voxels per thread are integrated in parallel slabs.
const MIN_VOXELS_PER_THREAD: usize = 1 << 17;

/// A TSDF volume on a cubic grid (see the [module docs](self) for the update rule).
#[derive(Debug, Clone, PartialEq)]
pub struct TsdfVolume {
    spec: GridSpec,
    truncation: f64,
    tsdf: Vec<f32>,
    weight: Vec<f32>,
}

impl TsdfVolume {
    /// An empty volume (every value and weight 0) with truncation distance
    /// `truncation` metres.
    ///
    /// # Errors
    /// [`Error::Value`] naming `truncation` unless it is finite and > 0.
    ///
    /// # Example
    /// ```
    /// use heapgrasp_core::{tsdf::TsdfVolume, GridSpec};
    /// let spec = GridSpec::new([0.0; 3], 0.3, 40).unwrap();
    /// let tsdf = TsdfVolume::new(spec, 4.0 * spec.voxel_size()).unwrap();
    /// assert!(tsdf.weights().iter().all(|&w| w == 0.0));
    /// assert!(TsdfVolume::new(spec, 0.0).is_err());
    /// ```
    pub fn new(spec: GridSpec, truncation: f64) -> Result<Self> {
        if !(truncation.is_finite() && truncation > 0.0) {
            return Err(Error::value(
                "truncation",
                truncation,
                "must be finite and > 0 metres",
            ));
        }
        let n = spec.voxel_count();
        Ok(Self {
            spec,
            truncation,
            tsdf: vec![0.0; n],
            weight: vec![0.0; n],
        })
    }

    /// The grid geometry.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The truncation distance, metres.
    pub fn truncation(&self) -> f64 {
        self.truncation
    }

    /// Fuses one depth image (`depth_m`: `(height, width)` metres, row-major; 0 or
    /// non-finite = missing) taken by `camera` at `cam2world`.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `depth_m` when its length is not `width * height`; the
    /// volume is left unchanged then.
    pub fn integrate(
        &mut self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        depth_m: &[f32],
    ) -> Result<()> {
        camera.check_image("depth_m", depth_m.len())?;
        let r = self.spec.resolution();
        let threads = parallel::threads_for(self.tsdf.len(), MIN_VOXELS_PER_THREAD, r);
        self.integrate_with_threads(camera, cam2world, depth_m, threads);
        Ok(())
    }

    /// The update proper, on a validated depth image, with an explicit thread count.
    fn integrate_with_threads(
        &mut self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        depth_m: &[f32],
        threads: usize,
    ) {
        let projector = VoxelProjector::new(&self.spec, camera, cam2world);
        let trunc = self.truncation as f32;
        let r = self.spec.resolution();
        parallel::for_each_row_chunk_pair(
            &mut self.tsdf,
            &mut self.weight,
            r * r,
            threads,
            |rows, tsdf, weight| {
                for (local, a) in rows.enumerate() {
                    for b in 0..r {
                        let off = (local * r + b) * r;
                        integrate_column(
                            &projector.column(a, b),
                            &projector.intr,
                            depth_m,
                            trunc,
                            &mut tsdf[off..off + r],
                            &mut weight[off..off + r],
                        );
                    }
                }
            },
        );
    }

    /// TSDF values in `[-1, 1]`, flat C order (0 where the weight is 0).
    pub fn values(&self) -> &[f32] {
        &self.tsdf
    }

    /// Per-voxel weights: the number of frames that observed each voxel.
    pub fn weights(&self) -> &[f32] {
        &self.weight
    }

    /// Sets every value and weight back to 0.
    pub fn reset(&mut self) {
        self.tsdf.fill(0.0);
        self.weight.fill(0.0);
    }
}

/// Updates one grid column `(a, b, ·)` (steps 2–6 of the module docs).
#[inline]
fn integrate_column(
    col: &Column,
    intr: &Intrinsics32,
    depth: &[f32],
    trunc: f32,
    tsdf: &mut [f32],
    weight: &mut [f32],
) {
    for (c, (t, w)) in tsdf.iter_mut().zip(weight.iter_mut()).enumerate() {
        let cf = c as f32;
        let x = col.base[0] + cf * col.step[0];
        let y = col.base[1] + cf * col.step[1];
        let z = col.base[2] + cf * col.step[2];
        let Some(px) = intr.pixel(x, y, z) else {
            continue;
        };
        let Some(&d) = depth.get(px as usize) else {
            continue;
        };
        if !(d.is_finite() && d > 0.0) {
            continue;
        }
        let sdf = d - z;
        if sdf < -trunc {
            continue;
        }
        let obs = (sdf / trunc).min(1.0);
        *t = (*t * *w + obs) / (*w + 1.0);
        *w += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRUNC: f64 = 0.04;

    /// A 16³ grid over [-0.15, 0.15]² x [0, 0.3] and a camera 0.8 m above looking down.
    fn setup() -> (GridSpec, PinholeCamera, Pose) {
        let grid = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 16).unwrap();
        let cam = PinholeCamera::new(80, 60, 70.0, 70.0, 39.5, 29.5).unwrap();
        let m = [
            1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.8, 0.0, 0.0, 0.0, 1.0,
        ];
        (grid, cam, Pose::from_row_major("cam2world", &m).unwrap())
    }

    /// Direct f64 evaluation of one observation: `None` when the voxel is skipped, and
    /// whether the voxel sits within 1e-3 px of a pixel border (tolerated difference).
    fn expected_obs(
        grid: &GridSpec,
        cam: &PinholeCamera,
        pose: &Pose,
        depth: &[f32],
        [a, b, c]: [usize; 3],
    ) -> (Option<f64>, bool) {
        let pc = pose.inverse().transform_point(&grid.voxel_center(a, b, c));
        let uf = cam.fx * pc.x / pc.z + cam.cx + 0.5;
        let vf = cam.fy * pc.y / pc.z + cam.cy + 0.5;
        let tie = (uf - uf.round()).abs() < 1e-3 || (vf - vf.round()).abs() < 1e-3;
        let obs = cam.project(&pc).and_then(|(u, v)| {
            let d = f64::from(depth[(v * cam.width + u) as usize]);
            let sdf = d - pc.z;
            (d.is_finite() && d > 0.0 && sdf >= -TRUNC).then(|| (sdf / TRUNC).min(1.0))
        });
        (obs, tie)
    }

    fn all_voxels(r: usize) -> impl Iterator<Item = [usize; 3]> {
        (0..r * r * r).map(move |i| [i / (r * r), (i / r) % r, i % r])
    }

    #[test]
    fn fronto_parallel_plane_gives_the_clamped_distance() {
        let (grid, cam, pose) = setup();
        // Depth 0.7 everywhere: a plane at world z = 0.1 seen from z = 0.8.
        let depth = vec![0.7f32; cam.pixel_count()];
        let mut tsdf = TsdfVolume::new(grid, TRUNC).unwrap();
        tsdf.integrate(&cam, &pose, &depth).unwrap();
        let (mut observed, mut occluded, mut partial) = (0, 0, 0);
        for p in all_voxels(16) {
            let i = grid.flat_index(p[0], p[1], p[2]);
            let (obs, tie) = expected_obs(&grid, &cam, &pose, &depth, p);
            if tie {
                continue;
            }
            match obs {
                Some(o) => {
                    observed += 1;
                    assert_eq!(tsdf.weights()[i], 1.0, "{p:?}");
                    assert!((f64::from(tsdf.values()[i]) - o).abs() < 1e-5, "{p:?}");
                    // Plane geometry: sdf = world z - 0.1 (depth 0.7 is rounded to f32).
                    let zc = grid.voxel_center(p[0], p[1], p[2]).z;
                    assert!((o - ((zc - 0.1) / TRUNC).min(1.0)).abs() < 1e-6);
                    partial += usize::from(o.abs() < 1.0);
                }
                None => {
                    assert_eq!((tsdf.weights()[i], tsdf.values()[i]), (0.0, 0.0), "{p:?}");
                    let pc = pose
                        .inverse()
                        .transform_point(&grid.voxel_center(p[0], p[1], p[2]));
                    occluded += usize::from(cam.project(&pc).is_some());
                }
            }
        }
        assert!(observed > 1000 && occluded > 500 && partial > 100);
        // Voxel [8, 8, 0] (world z ≈ 0.009) lies 0.09 m behind the plane: unobserved.
        assert_eq!(tsdf.weights()[grid.flat_index(8, 8, 0)], 0.0);
        // Voxel [8, 8, 5] (world z = 0.103125) lies 3.125 mm in front: 0.078125.
        let v = tsdf.values()[grid.flat_index(8, 8, 5)];
        assert!((v - 0.078125).abs() < 1e-5, "{v}");
    }

    #[test]
    fn missing_depth_leaves_voxels_untouched() {
        let (grid, cam, pose) = setup();
        let mut tsdf = TsdfVolume::new(grid, TRUNC).unwrap();
        tsdf.integrate(&cam, &pose, &vec![0.0f32; cam.pixel_count()])
            .unwrap();
        assert!(tsdf.weights().iter().all(|&w| w == 0.0));
        // Left half NaN, bottom rows 0 (or negative): only the rest is observed.
        let mut depth = vec![0.7f32; cam.pixel_count()];
        for v in 0..cam.height {
            for u in 0..cam.width {
                let i = (v * cam.width + u) as usize;
                if u < cam.width / 2 {
                    depth[i] = f32::NAN;
                } else if v >= 50 {
                    depth[i] = if u % 2 == 0 { 0.0 } else { -1.0 };
                } else if v < 3 {
                    depth[i] = f32::INFINITY;
                }
            }
        }
        tsdf.integrate(&cam, &pose, &depth).unwrap();
        let mut seen = 0;
        for p in all_voxels(16) {
            let (obs, tie) = expected_obs(&grid, &cam, &pose, &depth, p);
            if tie {
                continue;
            }
            let w = tsdf.weights()[grid.flat_index(p[0], p[1], p[2])];
            assert_eq!(w, if obs.is_some() { 1.0 } else { 0.0 }, "{p:?}");
            seen += usize::from(obs.is_some());
        }
        assert!(seen > 100);
    }

    #[test]
    fn two_integrations_average() {
        let (grid, cam, pose) = setup();
        let d1 = vec![0.7f32; cam.pixel_count()];
        let d2 = vec![0.72f32; cam.pixel_count()];
        let mut tsdf = TsdfVolume::new(grid, TRUNC).unwrap();
        tsdf.integrate(&cam, &pose, &d1).unwrap();
        tsdf.integrate(&cam, &pose, &d2).unwrap();
        let (mut both, mut second_only) = (0, 0);
        for p in all_voxels(16) {
            let (o1, t1) = expected_obs(&grid, &cam, &pose, &d1, p);
            let (o2, _) = expected_obs(&grid, &cam, &pose, &d2, p);
            if t1 {
                continue;
            }
            let i = grid.flat_index(p[0], p[1], p[2]);
            let (v, w) = (f64::from(tsdf.values()[i]), tsdf.weights()[i]);
            match (o1, o2) {
                (Some(a), Some(b)) => {
                    both += 1;
                    assert_eq!(w, 2.0);
                    assert!((v - (a + b) / 2.0).abs() < 1e-5, "{p:?}");
                }
                (None, Some(b)) => {
                    second_only += 1;
                    assert_eq!(w, 1.0);
                    assert!((v - b).abs() < 1e-5);
                }
                (Some(_), None) => unreachable!("a deeper surface observes more"),
                (None, None) => assert_eq!(w, 0.0),
            }
        }
        assert!(both > 1000 && second_only > 50);
    }

    #[test]
    fn thread_count_does_not_change_the_result() {
        let (_, cam, pose) = setup();
        let grid = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 24).unwrap();
        let depth: Vec<f32> = (0..cam.pixel_count())
            .map(|i| 0.62 + 0.002 * (i % 37) as f32)
            .collect();
        let mut one = TsdfVolume::new(grid, TRUNC).unwrap();
        let mut many = one.clone();
        one.integrate_with_threads(&cam, &pose, &depth, 1);
        many.integrate_with_threads(&cam, &pose, &depth, 5);
        assert_eq!(one, many);
        assert!(one.weights().iter().any(|&w| w > 0.0));
    }

    #[test]
    fn wrong_depth_size_errors_and_changes_nothing() {
        let (grid, cam, pose) = setup();
        let mut tsdf = TsdfVolume::new(grid, TRUNC).unwrap();
        tsdf.integrate(&cam, &pose, &vec![0.7f32; cam.pixel_count()])
            .unwrap();
        let before = tsdf.clone();
        let err = tsdf.integrate(&cam, &pose, &[0.7f32; 10]).unwrap_err();
        assert!(matches!(err, Error::Shape { ref name, .. } if name == "depth_m"));
        assert_eq!(tsdf, before);
        tsdf.reset();
        assert!(tsdf
            .weights()
            .iter()
            .chain(tsdf.values())
            .all(|&x| x == 0.0));
    }

    #[test]
    fn invalid_truncation_is_rejected() {
        let (grid, _, _) = setup();
        for t in [0.0, -0.01, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                TsdfVolume::new(grid, t),
                Err(Error::Value { ref name, .. }) if name == "truncation"
            ));
        }
        let tsdf = TsdfVolume::new(grid, 0.02).unwrap();
        assert_eq!(tsdf.truncation(), 0.02);
        assert_eq!(tsdf.spec(), &grid);
        assert_eq!(tsdf.values().len(), 4096);
    }
}
