//! The Shape-from-Silhouette occupancy grid of HEAPGrasp (eq. 9–10) and its
//! high-confidence form `Ŝ_{≥λ}`.
//!
//! The grid keeps, per voxel, the number of frames in which the voxel centre was
//! *segmented* (`|I_seg|`) and *visible* (`|I_rgb|`, projected inside the image).
//! Occupancy is `segmented / visible` where `visible > 0`, else 0 (eq. 10), computed in
//! f32. Counts saturate at `u32::MAX` instead of wrapping, so a voxel seen in every one
//! of more frames than that keeps occupancy 1. A voxel is *high-confidence* for threshold λ when its occupancy is non-zero and
//! `>= λ` (both sides in f32): that is the set `Ŝ_{≥λ}` counts in eq. 14.

use crate::camera::{PinholeCamera, Pose};
use crate::carve::{carve, carve_with_threads};
use crate::error::{Error, Result};
use crate::grid::GridSpec;

/// Occupancy of a voxel from its counts (eq. 10), in f32.
#[inline(always)]
pub fn occupancy_value(segmented: u32, visible: u32) -> f32 {
    if visible == 0 {
        0.0
    } else {
        segmented as f32 / visible as f32
    }
}

/// Whether a voxel with these counts is in `Ŝ_{≥λ}` (occupancy non-zero and `>= lam`).
#[inline(always)]
pub fn is_high_confidence(segmented: u32, visible: u32, lam: f32) -> bool {
    segmented > 0 && occupancy_value(segmented, visible) >= lam
}

/// [`is_high_confidence`] as a table lookup: `thresholds[v]` is the smallest `s` with
/// `f32(s) / f32(v) >= λ` (or `u32::MAX` when none), built from the very same f32
/// division, so `s > 0 && s >= thresholds[v]` is exactly the same predicate without a
/// division per voxel. Visible counts beyond the table (at most
/// [`HighConfidenceTable::MAX_ROWS`] rows: a remembered grid's counts reach millions)
/// take the division itself.
#[derive(Debug, Clone)]
pub struct HighConfidenceTable {
    thresholds: Vec<u32>,
    lam: f32,
}

impl HighConfidenceTable {
    /// The most visible counts a table holds (`0..MAX_ROWS`).
    pub const MAX_ROWS: u32 = 1 << 16;

    /// A table for visible counts `0..=max_visible` (at most [`Self::MAX_ROWS`] of them;
    /// larger counts are answered by the division) at threshold `lam`.
    pub fn new(lam: f32, max_visible: u32) -> Self {
        let thresholds = (0..=max_visible.min(Self::MAX_ROWS - 1))
            .map(|v| {
                if v == 0 {
                    return u32::MAX;
                }
                // The predicate is monotone in s: start near λ·v and step to the edge.
                let mut s = ((lam as f64) * v as f64).floor().clamp(0.0, v as f64) as u32;
                while s > 0 && occupancy_value(s - 1, v) >= lam {
                    s -= 1;
                }
                while s <= v && occupancy_value(s, v) < lam {
                    s += 1;
                }
                if s > v {
                    u32::MAX
                } else {
                    s
                }
            })
            .collect();
        Self { thresholds, lam }
    }

    /// Whether counts `(s, v)` are high-confidence ([`is_high_confidence`]), for any `v`.
    #[inline(always)]
    pub fn contains(&self, s: u32, v: u32) -> bool {
        match self.thresholds.get(v as usize) {
            Some(&t) => s > 0 && s >= t,
            None => is_high_confidence(s, v, self.lam),
        }
    }
}

/// Validates a confidence threshold λ ∈ [0, 1] and returns it in f32.
///
/// # Errors
/// [`Error::Value`] naming `lam` for NaN or values outside `[0, 1]`.
pub fn check_lambda(lam: f64) -> Result<f32> {
    if !(0.0..=1.0).contains(&lam) {
        return Err(Error::value("lam", lam, "threshold λ must be in [0, 1]"));
    }
    Ok(lam as f32)
}

/// Silhouette counts on a voxel grid.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    spec: GridSpec,
    segmented: Vec<u32>,
    visible: Vec<u32>,
}

impl OccupancyGrid {
    /// An empty grid (all counts 0).
    pub fn new(spec: GridSpec) -> Self {
        let n = spec.voxel_count();
        Self {
            spec,
            segmented: vec![0; n],
            visible: vec![0; n],
        }
    }

    /// A grid from existing counts.
    ///
    /// # Errors
    /// [`Error::Shape`] if a buffer is not R³ long; [`Error::Value`] if some voxel has
    /// `segmented > visible`, which no sequence of frames can produce.
    pub fn from_counts(spec: GridSpec, segmented: Vec<u32>, visible: Vec<u32>) -> Result<Self> {
        spec.check_volume("segmented", segmented.len())?;
        spec.check_volume("visible", visible.len())?;
        if let Some(i) = segmented.iter().zip(&visible).position(|(s, v)| s > v) {
            return Err(Error::value(
                "segmented",
                format!(
                    "{} > visible {} at voxel {:?}",
                    segmented[i],
                    visible[i],
                    spec.unflatten(i)
                ),
                "segmented counts cannot exceed visible counts",
            ));
        }
        Ok(Self {
            spec,
            segmented,
            visible,
        })
    }

    /// The grid geometry.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Per-voxel count of frames in which the voxel was segmented, flat C order.
    pub fn segmented(&self) -> &[u32] {
        &self.segmented
    }

    /// Per-voxel count of frames in which the voxel projected inside the image.
    pub fn visible(&self) -> &[u32] {
        &self.visible
    }

    /// Integrates one silhouette (`mask`: `(height, width)` bytes, nonzero = object).
    ///
    /// # Errors
    /// [`Error::Shape`] when the mask does not match the camera.
    pub fn integrate(
        &mut self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        mask: &[u8],
    ) -> Result<()> {
        self.integrate_many(camera, std::slice::from_ref(cam2world), mask)
    }

    /// Integrates `poses.len()` silhouettes stored back to back in `masks`
    /// (`(N, height, width)` bytes). All frames are validated before any count changes.
    /// Counts saturate at `u32::MAX`.
    ///
    /// # Errors
    /// [`Error::Shape`] when `masks` does not hold one camera-sized mask per pose.
    pub fn integrate_many(
        &mut self,
        camera: &PinholeCamera,
        poses: &[Pose],
        masks: &[u8],
    ) -> Result<()> {
        carve(
            &self.spec,
            camera,
            poses,
            masks,
            &mut self.segmented,
            &mut self.visible,
        )
    }

    /// [`OccupancyGrid::integrate_many`] on exactly `threads` threads (0 counts as 1)
    /// rather than as many as the work is worth: frame-parallel when the grid has at most
    /// 2¹⁸ voxels and there are at least `threads` frames, else in at most R slabs of the
    /// x axis. The counts do not depend on `threads`.
    ///
    /// # Errors
    /// As [`OccupancyGrid::integrate_many`].
    pub fn integrate_many_with_threads(
        &mut self,
        camera: &PinholeCamera,
        poses: &[Pose],
        masks: &[u8],
        threads: usize,
    ) -> Result<()> {
        carve_with_threads(
            &self.spec,
            camera,
            poses,
            masks,
            &mut self.segmented,
            &mut self.visible,
            threads,
        )
    }

    /// Occupancy per voxel (eq. 10), flat C order.
    pub fn occupancy(&self) -> Vec<f32> {
        self.segmented
            .iter()
            .zip(&self.visible)
            .map(|(&s, &v)| occupancy_value(s, v))
            .collect()
    }

    /// The high-confidence grid `Ŝ_{≥λ}`: occupancy with values below `lam` set to 0.
    pub fn high_confidence(&self, lam: f32) -> Vec<f32> {
        self.segmented
            .iter()
            .zip(&self.visible)
            .map(|(&s, &v)| {
                let o = occupancy_value(s, v);
                if o >= lam {
                    o
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// `#Ŝ_{≥λ}`: the number of non-zero voxels of the high-confidence grid.
    pub fn count_high_confidence(&self, lam: f32) -> usize {
        self.segmented
            .iter()
            .zip(&self.visible)
            .filter(|(&s, &v)| is_high_confidence(s, v, lam))
            .count()
    }

    /// Sets every count back to 0.
    pub fn reset(&mut self) {
        self.segmented.fill(0);
        self.visible.fill(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (GridSpec, PinholeCamera, Pose) {
        let grid = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 16).unwrap();
        let cam = PinholeCamera::new(80, 60, 70.0, 70.0, 39.5, 29.5).unwrap();
        let m = [
            1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.8, 0.0, 0.0, 0.0, 1.0,
        ];
        (grid, cam, Pose::from_row_major("cam2world", &m).unwrap())
    }

    #[test]
    fn full_mask_marks_every_visible_voxel_segmented() {
        let (grid, cam, pose) = setup();
        let mut occ = OccupancyGrid::new(grid);
        occ.integrate(&cam, &pose, &vec![1u8; cam.pixel_count()])
            .unwrap();
        assert!(occ.visible().contains(&1));
        assert_eq!(occ.segmented(), occ.visible());
        assert_eq!(
            occ.count_high_confidence(0.9),
            occ.visible().iter().filter(|&&v| v > 0).count()
        );
    }

    #[test]
    fn counts_match_the_scalar_reference() {
        let (grid, cam, pose) = setup();
        let mask: Vec<u8> = (0..cam.pixel_count())
            .map(|i| u8::from((i * 7919) % 3 == 0))
            .collect();
        let mut occ = OccupancyGrid::new(grid);
        occ.integrate_many(&cam, &[pose, pose], &[mask.clone(), mask.clone()].concat())
            .unwrap();
        let w2c = pose.inverse();
        let r = grid.resolution();
        for a in 0..r {
            for b in 0..r {
                for c in 0..r {
                    let i = grid.flat_index(a, b, c);
                    let pc = w2c.transform_point(&grid.voxel_center(a, b, c));
                    let uf = cam.fx * pc.x / pc.z + cam.cx + 0.5;
                    let vf = cam.fy * pc.y / pc.z + cam.cy + 0.5;
                    let tie = |f: f64| (f - f.round()).abs() < 1e-3;
                    if tie(uf) || tie(vf) {
                        continue; // documented tolerance at pixel borders
                    }
                    let px = cam.project(&pc);
                    let (vis, seg) = match px {
                        None => (0, 0),
                        Some((u, v)) => (2, 2 * u32::from(mask[(v * cam.width + u) as usize])),
                    };
                    assert_eq!(
                        (occ.visible()[i], occ.segmented()[i]),
                        (vis, seg),
                        "voxel {a} {b} {c}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_table_answers_beyond_its_rows_as_the_division_does() {
        let table = HighConfidenceTable::new(0.9, u32::MAX);
        for v in [0, 1, 7, 65_535, 65_536, 1 << 24, u32::MAX - 1, u32::MAX] {
            for s in [0, 1, v / 2, (v as f64 * 0.9) as u32, v.saturating_sub(1), v] {
                assert_eq!(
                    table.contains(s, v),
                    is_high_confidence(s, v, 0.9),
                    "{s}/{v}"
                );
            }
        }
    }

    #[test]
    fn counts_saturate_instead_of_wrapping() {
        let (grid, cam, _) = setup();
        // Looking down from beside the grid's centre: it sees part of the grid.
        let m = [
            1.0, 0.0, 0.0, 0.2, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.8, 0.0, 0.0, 0.0, 1.0,
        ];
        let pose = Pose::from_row_major("cam2world", &m).unwrap();
        let n = grid.voxel_count();
        let full = vec![1u8; cam.pixel_count()];
        let empty = vec![0u8; cam.pixel_count()];
        // Three frames that see and segment every visible voxel, then one that sees
        // without segmenting: from MAX - 1 the counts must stop at MAX.
        let poses = [pose; 4];
        let masks = [full.clone(), full.clone(), full.clone(), empty].concat();
        let mut fresh = OccupancyGrid::new(grid);
        fresh.integrate_many(&cam, &poses, &masks).unwrap();
        let seen: Vec<bool> = fresh.visible().iter().map(|&v| v > 0).collect();
        assert!(seen.iter().any(|&s| s) && !seen.iter().all(|&s| s));
        for threads in [1, 2, 3, 4, 5] {
            for start in [u32::MAX, u32::MAX - 1, u32::MAX - 3] {
                let mut occ =
                    OccupancyGrid::from_counts(grid, vec![start; n], vec![start; n]).unwrap();
                occ.integrate_many_with_threads(&cam, &poses, &masks, threads)
                    .unwrap();
                for (i, &seen) in seen.iter().enumerate() {
                    let (s, v) = (occ.segmented()[i], occ.visible()[i]);
                    if seen {
                        assert_eq!(v, u32::MAX, "threads {threads} start {start}");
                        assert_eq!(s, start.saturating_add(3), "threads {threads}");
                    } else {
                        assert_eq!((s, v), (start, start));
                    }
                }
                assert!(
                    occ.occupancy().iter().all(|&o| o == 1.0),
                    "threads {threads}"
                );
                assert_eq!(occ.count_high_confidence(1.0), n);
            }
        }
        // One frame at a time takes the same path as the kernels of a batch.
        let mut occ =
            OccupancyGrid::from_counts(grid, vec![u32::MAX; n], vec![u32::MAX; n]).unwrap();
        occ.integrate(&cam, &pose, &full).unwrap();
        assert!(occ.segmented().iter().all(|&s| s == u32::MAX));
        assert!(occ.occupancy().iter().all(|&o| o == 1.0));
    }

    #[test]
    fn wrong_mask_size_changes_nothing() {
        let (grid, cam, pose) = setup();
        let mut occ = OccupancyGrid::new(grid);
        assert!(matches!(
            occ.integrate(&cam, &pose, &[1u8; 10]),
            Err(Error::Shape { .. })
        ));
        assert!(occ.visible().iter().all(|&v| v == 0));
    }

    #[test]
    fn threshold_table_equals_the_division() {
        for lam in [0.0f32, 0.1, 0.5, 0.9, 0.95, 0.999, 1.0, 1.0 / 3.0] {
            let t = HighConfidenceTable::new(lam, 300);
            for v in 0..=300 {
                for s in 0..=v {
                    assert_eq!(
                        t.contains(s, v),
                        is_high_confidence(s, v, lam),
                        "lam {lam} s {s} v {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn high_confidence_threshold_is_inclusive() {
        let grid = GridSpec::new([0.0; 3], 1.0, 1).unwrap();
        let occ = OccupancyGrid::from_counts(grid, vec![9], vec![10]).unwrap();
        assert_eq!(occ.count_high_confidence(0.9), 1);
        assert_eq!(occ.high_confidence(0.9), vec![0.9]);
        assert_eq!(occ.count_high_confidence(0.91), 0);
        assert!(OccupancyGrid::from_counts(grid, vec![2], vec![1]).is_err());
        assert!(check_lambda(1.5).is_err());
        assert!(check_lambda(f64::NAN).is_err());
    }
}
