//! Exact view scores of HEAPGrasp eq. 14 for every candidate trajectory.
//!
//! For candidate `k` with trajectory poses `P_k` (the interpolated frames of
//! `f(p̄^ℓ, p̄^{u,v})`), the hypothetical silhouettes are rendered from the true scene,
//! added to a copy of the grid's counts, and
//! `s_k = 1 − #Ŝ_{≥λ}(after) / #Ŝ_{≥λ}(before)`.
//! When the current grid has no high-confidence voxel, eq. 14 is undefined; every score
//! is then 0 (no candidate can be ranked by measurement gain).
//!
//! # Why it is fast, and still exact
//! - A voxel with counts `(s, v)` can end high-confidence after `M` more frames only if
//!   `(s + M) / (v + M) >= λ` (occupancy can at best rise to that), so only those voxels
//!   are tracked; every other voxel contributes 0 to the "after" count.
//! - Frames are processed from the far end of the trajectory (the candidate view, the
//!   most informative) backwards; after each frame a voxel that can no longer reach λ
//!   even if all remaining frames segment it is dropped. Empty space seen as background
//!   leaves after one or two frames, so most frames touch only voxels near the objects.
//! - Each frame's silhouette is rasterised only inside the bounding box of the pixels the
//!   surviving voxels project to ([`MeshScene::render_mask_into`]).
//!
//! Candidates run in parallel (`std::thread::scope`). Voxel centres are projected with
//! the f32 kernel of [`crate::projector`], so results equal integrating the rendered
//! masks with [`OccupancyGrid::integrate_many`] except for voxels within ~1e-4 px of a
//! pixel border.

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::occupancy::{is_high_confidence, OccupancyGrid};
use crate::parallel;
use crate::projector::VoxelProjector;
use crate::raster::{MeshScene, PixelRect};

/// Largest accepted trajectory length (frames per candidate): counts are kept in u16.
pub const MAX_TRAJECTORY_FRAMES: usize = 4096;

/// A tracked voxel: grid index (as f32 for the projection) and current counts.
#[derive(Clone, Copy)]
struct Tracked {
    abc: [f32; 3],
    seg: u32,
    vis: u32,
}

/// Scores every candidate trajectory by eq. 14 (see the module docs).
///
/// # Errors
/// [`Error::Value`] for `lam` outside `[0, 1]`, an empty trajectory, or one longer than
/// [`MAX_TRAJECTORY_FRAMES`].
pub fn score_views(
    grid: &OccupancyGrid,
    scene: &MeshScene,
    camera: &PinholeCamera,
    trajectories: &[Vec<Pose>],
    lam: f64,
) -> Result<Vec<f32>> {
    let lam = crate::occupancy::check_lambda(lam)?;
    for (k, t) in trajectories.iter().enumerate() {
        if t.is_empty() || t.len() > MAX_TRAJECTORY_FRAMES {
            return Err(Error::value(
                &format!("trajectories[{k}]"),
                format!("{} frames", t.len()),
                format!("a trajectory needs 1 to {MAX_TRAJECTORY_FRAMES} poses"),
            ));
        }
    }
    let before = grid.count_high_confidence(lam);
    if before == 0 || trajectories.is_empty() {
        return Ok(vec![0.0; trajectories.len()]);
    }
    let max_m = trajectories.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let spec = grid.spec();
    let tracked: Vec<Tracked> = grid
        .segmented()
        .iter()
        .zip(grid.visible())
        .enumerate()
        .filter(|(_, (&s, &v))| is_high_confidence(s + max_m, v + max_m, lam))
        .map(|(i, (&s, &v))| {
            let [a, b, c] = spec.unflatten(i);
            Tracked {
                abc: [a as f32, b as f32, c as f32],
                seg: s,
                vis: v,
            }
        })
        .collect();
    let work: usize = trajectories.iter().map(Vec::len).sum::<usize>() * tracked.len().max(1);
    let threads = parallel::threads_for(work, 1 << 16, trajectories.len());
    let before = before as f32;
    let scores = parallel::map_ranges(trajectories.len(), threads, |range| {
        let mut ws = Workspace::new(camera);
        range
            .map(|k| {
                let after = ws.count_after(grid, scene, camera, &tracked, &trajectories[k], lam);
                1.0 - after as f32 / before
            })
            .collect::<Vec<_>>()
    });
    Ok(scores.into_iter().flatten().collect())
}

/// Per-thread buffers reused across candidates.
struct Workspace {
    alive: Vec<(u32, u16, u16)>,
    pixels: Vec<u32>,
    mask: Vec<u8>,
    scratch: Vec<[f64; 3]>,
}

const OUTSIDE: u32 = u32::MAX;

impl Workspace {
    fn new(camera: &PinholeCamera) -> Self {
        Self {
            alive: Vec::new(),
            pixels: Vec::new(),
            mask: vec![0; camera.pixel_count()],
            scratch: Vec::new(),
        }
    }

    /// `#Ŝ_{≥λ}` after adding the rendered silhouettes of `poses`.
    fn count_after(
        &mut self,
        grid: &OccupancyGrid,
        scene: &MeshScene,
        camera: &PinholeCamera,
        tracked: &[Tracked],
        poses: &[Pose],
        lam: f32,
    ) -> usize {
        let m = poses.len() as u32;
        // (index into `tracked`, added segmented count, added visible count)
        self.alive.clear();
        self.alive.extend(
            tracked
                .iter()
                .enumerate()
                .filter(|(_, t)| is_high_confidence(t.seg + m, t.vis + m, lam))
                .map(|(i, _)| (i as u32, 0u16, 0u16)),
        );
        let width = camera.width;
        for (done, pose) in poses.iter().rev().enumerate() {
            if self.alive.is_empty() {
                break;
            }
            let remaining = m - done as u32 - 1;
            let proj = VoxelProjector::new(grid.spec(), camera, pose);
            let intr = proj.intr;
            let [p0, ea, eb, ec] = proj.affine_f32();
            // Project every surviving voxel and find the bounding box of their pixels.
            self.pixels.clear();
            let (mut u0, mut u1, mut v0, mut v1) = (u32::MAX, 0u32, u32::MAX, 0u32);
            for &(i, _, _) in &self.alive {
                let [a, b, c] = tracked[i as usize].abc;
                let p: [f32; 3] =
                    std::array::from_fn(|k| p0[k] + a * ea[k] + b * eb[k] + c * ec[k]);
                match intr.pixel(p[0], p[1], p[2]) {
                    Some(px) => {
                        let (u, v) = (px % width, px / width);
                        u0 = u0.min(u);
                        u1 = u1.max(u);
                        v0 = v0.min(v);
                        v1 = v1.max(v);
                        self.pixels.push(px);
                    }
                    None => self.pixels.push(OUTSIDE),
                }
            }
            if u0 <= u1 {
                let rect = PixelRect { u0, u1, v0, v1 };
                scene.render_mask_into(camera, pose, rect, &mut self.mask, &mut self.scratch);
            }
            let mask = &self.mask;
            let pixels = &self.pixels;
            let mut k = 0;
            self.alive.retain_mut(|(i, ds, dv)| {
                let px = pixels[k];
                k += 1;
                if px != OUTSIDE {
                    *dv += 1;
                    *ds += u16::from(mask[px as usize] != 0);
                }
                let t = &tracked[*i as usize];
                is_high_confidence(
                    t.seg + u32::from(*ds) + remaining,
                    t.vis + u32::from(*dv) + remaining,
                    lam,
                )
            });
        }
        self.alive
            .iter()
            .filter(|&&(i, ds, dv)| {
                let t = &tracked[i as usize];
                is_high_confidence(t.seg + u32::from(ds), t.vis + u32::from(dv), lam)
            })
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;
    use crate::raster::tests::box_mesh;

    fn ring(n: usize, radius: f64, height: f64, phase: f64) -> Vec<Pose> {
        (0..n)
            .map(|k| {
                let phi = phase + 2.0 * std::f64::consts::PI * k as f64 / n as f64;
                Pose::look_at(
                    [0.15 + radius * phi.cos(), 0.15 + radius * phi.sin(), height],
                    [0.15, 0.15, 0.04],
                    [0.0, 0.0, 1.0],
                )
                .unwrap()
            })
            .collect()
    }

    fn setup() -> (OccupancyGrid, MeshScene, PinholeCamera) {
        let cam = PinholeCamera::new(80, 60, 75.0, 75.0, 39.5, 29.5).unwrap();
        let mut scene = MeshScene::new();
        let (v, f) = box_mesh(0.04, 0.025, 0.04);
        let pose = Pose::from_row_major(
            "p",
            &[
                1.0, 0.0, 0.0, 0.15, 0.0, 1.0, 0.0, 0.13, 0.0, 0.0, 1.0, 0.04, 0.0, 0.0, 0.0, 1.0,
            ],
        )
        .unwrap();
        scene.add_mesh(&v, &f, pose).unwrap();
        let mut grid = OccupancyGrid::new(GridSpec::new([0.0; 3], 0.3, 20).unwrap());
        let first = ring(1, 0.4, 0.35, 0.3);
        let masks: Vec<u8> = first
            .iter()
            .flat_map(|p| scene.render_mask(&cam, p))
            .collect();
        grid.integrate_many(&cam, &first, &masks).unwrap();
        (grid, scene, cam)
    }

    /// The definition: render, integrate into a copy, count.
    fn reference(
        grid: &OccupancyGrid,
        scene: &MeshScene,
        cam: &PinholeCamera,
        poses: &[Pose],
        lam: f32,
    ) -> f32 {
        let mut g = grid.clone();
        let masks: Vec<u8> = poses
            .iter()
            .flat_map(|p| scene.render_mask(cam, p))
            .collect();
        g.integrate_many(cam, poses, &masks).unwrap();
        1.0 - g.count_high_confidence(lam) as f32 / grid.count_high_confidence(lam) as f32
    }

    #[test]
    fn scores_equal_render_integrate_count() {
        let (grid, scene, cam) = setup();
        let trajectories: Vec<Vec<Pose>> = (0..12)
            .map(|k| ring(5, 0.3 + 0.01 * k as f64, 0.2 + 0.02 * k as f64, k as f64))
            .collect();
        let scores = score_views(&grid, &scene, &cam, &trajectories, 0.9).unwrap();
        for (k, t) in trajectories.iter().enumerate() {
            assert_eq!(
                scores[k],
                reference(&grid, &scene, &cam, t, 0.9),
                "candidate {k}"
            );
        }
        assert!(
            scores.iter().any(|&s| s > 0.1),
            "new views must carve something: {scores:?}"
        );
    }

    #[test]
    fn repeating_the_seen_view_scores_zero() {
        let (grid, scene, cam) = setup();
        let same = vec![ring(1, 0.4, 0.35, 0.3)];
        assert_eq!(
            score_views(&grid, &scene, &cam, &same, 0.9).unwrap(),
            vec![0.0]
        );
    }

    #[test]
    fn empty_grid_scores_zero_and_bad_input_errors() {
        let (_, scene, cam) = setup();
        let empty = OccupancyGrid::new(GridSpec::new([0.0; 3], 0.3, 8).unwrap());
        let t = vec![ring(3, 0.4, 0.3, 0.0)];
        assert_eq!(
            score_views(&empty, &scene, &cam, &t, 0.9).unwrap(),
            vec![0.0]
        );
        assert!(score_views(&empty, &scene, &cam, &[vec![]], 0.9).is_err());
        assert!(score_views(&empty, &scene, &cam, &t, 1.5).is_err());
    }
}
