//! Exact view scores of HEAPGrasp eq. 14 for every candidate trajectory.
//!
//! For candidate `k` with trajectory poses `P_k` (the interpolated frames of
//! `f(p̄^ℓ, p̄^{u,v})`), the hypothetical silhouettes are rendered from the true scene,
//! added to a copy of the grid's counts, and
//! `s_k = 1 − #Ŝ_{≥λ}(after) / #Ŝ_{≥λ}(before)`.
//! When the current grid has no high-confidence voxel, eq. 14 is undefined; every score
//! is then 0 (no candidate can be ranked by measurement gain).
//!
//! [`score_views_in`] restricts both counts to a region of interest `R` (e.g. the column
//! around HEAPGrasp's target grasp): `s_k = 1 − #(Ŝ_{≥λ} ∩ R)(after) / #(Ŝ_{≥λ} ∩ R)(before)`,
//! the share of the region's measured volume a candidate would carve. With `R` the whole
//! grid it is eq. 14.
//!
//! # Why it is fast, and still exact
//! - A voxel with counts `(s, v)` can end high-confidence after `M` more frames only if
//!   `(s + M) / (v + M) >= λ` (occupancy can at best rise to that), so only those voxels
//!   are tracked; every other voxel contributes 0 to the "after" count.
//! - The far end of the trajectory (the candidate view, the most informative frame) is
//!   carved first with the SIMD kernel of [`crate::carve`]. When more than a quarter of
//!   the grid is tracked, densely over the whole grid, the silhouette rasterised over the
//!   grid's pixels. Otherwise (a small region `R`, or a well-observed grid) only over the
//!   grid columns `(a, b, ·)` holding tracked voxels, up to the highest one, with the
//!   silhouette rasterised only inside the pixels of the tracked voxels' bounding box:
//!   the same kernel computes every voxel from its own index, so each tracked voxel gets
//!   exactly the counts of the dense carve, and the scores do not depend on the path.
//!   A voxel that can then no longer reach λ, even if every remaining frame segments it,
//!   is dropped; the `(s, v) -> high-confidence` test is a table lookup
//!   ([`HighConfidenceTable`]) rather than a division.
//! - If the first frame was dense and more than a quarter of the grid is still
//!   undecided (typically voxels no view has seen yet, which only a frame that sees them
//!   can decide), the remaining frames are carved densely too. Otherwise each remaining
//!   frame visits only the surviving voxels, drops the ones that can no longer reach λ,
//!   and rasterises its silhouette only inside the bounding box of their pixels
//!   ([`MeshScene::render_mask_into`]; a pixel's value does not depend on the rectangle
//!   rendered).
//!
//! Candidates run in parallel (`std::thread::scope`). Voxel centres are projected with
//! the f32 kernel of [`crate::projector`], so results equal integrating the rendered
//! masks with [`OccupancyGrid::integrate_many`] except for voxels within ~1e-4 px of a
//! pixel border.
//!
//! The file runs past 800 lines only because its unit tests sit beside the code (the
//! crate's rule, from `mod tests` on); the kernel itself is under 800.

use crate::camera::{PinholeCamera, Pose};
use crate::carve::{carve_columns, carve_one, PreparedFrame};
use crate::error::{Error, Result};
use crate::occupancy::{HighConfidenceTable, OccupancyGrid};
use crate::parallel;
use crate::projector::VoxelProjector;
use crate::raster::{MeshScene, PixelRect, RasterScratch};

/// Largest accepted trajectory length (frames per candidate): counts are kept in u16.
pub const MAX_TRAJECTORY_FRAMES: usize = 4096;

/// The voxels that can still end high-confidence, with their grid index and counts.
struct Tracked {
    flat: Vec<u32>,
    abc: Vec<[f32; 3]>,
    seg: Vec<u32>,
    vis: Vec<u32>,
    /// The grid columns holding tracked voxels, as `(a, b, len)`: every tracked voxel of
    /// column `(a, b)` lies in `(a, b, 0..len)`.
    columns: Vec<(u32, u32, u32)>,
    /// Smallest and largest voxel index of the tracked voxels on each axis.
    lo: [usize; 3],
    hi: [usize; 3],
}

impl Tracked {
    /// The voxels of `region` (`None`: all) that can end high-confidence after `max_m`
    /// more frames.
    fn collect(
        grid: &OccupancyGrid,
        region: Option<&[bool]>,
        table: &HighConfidenceTable,
        max_m: u32,
    ) -> Self {
        let mut tracked = Self {
            flat: Vec::new(),
            abc: Vec::new(),
            seg: Vec::new(),
            vis: Vec::new(),
            columns: Vec::new(),
            lo: [usize::MAX; 3],
            hi: [0; 3],
        };
        let spec = grid.spec();
        for (i, (&s, &v)) in grid.segmented().iter().zip(grid.visible()).enumerate() {
            if region.is_none_or(|r| r[i]) && may_end_high(table, s, v, max_m) {
                tracked.push(i, spec.unflatten(i), s, v);
            }
        }
        tracked
    }

    /// Appends voxel `i` = `[a, b, c]` with counts `(s, v)`; voxels come in increasing
    /// flat order, so those of one column are consecutive.
    fn push(&mut self, i: usize, [a, b, c]: [usize; 3], s: u32, v: u32) {
        self.flat.push(i as u32);
        self.abc.push([a as f32, b as f32, c as f32]);
        self.seg.push(s);
        self.vis.push(v);
        let (a32, b32, len) = (a as u32, b as u32, c as u32 + 1);
        match self.columns.last_mut() {
            Some(col) if col.0 == a32 && col.1 == b32 => col.2 = len,
            _ => self.columns.push((a32, b32, len)),
        }
        for (axis, x) in [a, b, c].into_iter().enumerate() {
            self.lo[axis] = self.lo[axis].min(x);
            self.hi[axis] = self.hi[axis].max(x);
        }
    }
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
    score_views_in(grid, scene, camera, trajectories, lam, None)
}

/// Eq. 14 with both counts restricted to `region` (one flag per voxel, in the grid's
/// flat order; `None`: the whole grid, i.e. [`score_views`]). All zeros when the region
/// holds no high-confidence voxel.
///
/// # Errors
/// As [`score_views`], and [`Error::Shape`] for a region whose length is not the grid's
/// voxel count.
pub fn score_views_in(
    grid: &OccupancyGrid,
    scene: &MeshScene,
    camera: &PinholeCamera,
    trajectories: &[Vec<Pose>],
    lam: f64,
    region: Option<&[bool]>,
) -> Result<Vec<f32>> {
    let lam = crate::occupancy::check_lambda(lam)?;
    if let Some(r) = region {
        let n = grid.spec().voxel_count();
        if r.len() != n {
            return Err(Error::shape(
                "region",
                format!("{n} voxels"),
                format!("{} voxels", r.len()),
            ));
        }
    }
    for (k, t) in trajectories.iter().enumerate() {
        if t.is_empty() || t.len() > MAX_TRAJECTORY_FRAMES {
            return Err(Error::value(
                &format!("trajectories[{k}]"),
                format!("{} frames", t.len()),
                format!("a trajectory needs 1 to {MAX_TRAJECTORY_FRAMES} poses"),
            ));
        }
    }
    let max_m = trajectories.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let max_v = grid.visible().iter().copied().max().unwrap_or(0);
    let table = HighConfidenceTable::new(lam, max_v.saturating_add(max_m));
    let before = match region {
        None => grid.count_high_confidence(lam),
        Some(r) => grid
            .segmented()
            .iter()
            .zip(grid.visible())
            .zip(r)
            .filter(|&((&s, &v), &inside)| inside && table.contains(s, v))
            .count(),
    };
    if before == 0 || trajectories.is_empty() {
        return Ok(vec![0.0; trajectories.len()]);
    }
    let spec = grid.spec();
    let tracked = Tracked::collect(grid, region, &table, max_m);
    let dense_first = tracked.flat.len() * DENSE_FRACTION > spec.voxel_count();
    let work: usize = trajectories.iter().map(Vec::len).sum::<usize>() * tracked.flat.len().max(1);
    let threads = parallel::threads_for(work, 1 << 16, trajectories.len());
    let before = before as f32;
    let scores = parallel::map_ranges(trajectories.len(), threads, |range| {
        let mut ws = Workspace::new(grid, camera);
        range
            .map(|k| {
                let after = ws.count_after(
                    grid,
                    scene,
                    camera,
                    &tracked,
                    &table,
                    &trajectories[k],
                    dense_first,
                );
                1.0 - after as f32 / before
            })
            .collect::<Vec<_>>()
    });
    Ok(scores.into_iter().flatten().collect())
}

/// Counts from which f32 no longer holds every integer (`f32(2^24 + 1) = 2^24`).
const F32_EXACT: u32 = 1 << 24;

/// Whether a voxel with counts `(s, v)` can be in `Ŝ_{≥λ}` after at most `more` further
/// frames (each adds 1 to `v` if it sees the voxel, and then 0 or 1 to `s`): the test
/// that prunes voxels, so it must never say no to a voxel that can end high-confidence.
///
/// The f32 predicate only grows with `s` and only shrinks with `v` (integer-to-f32
/// rounding and division are monotone), so the best case adds `a` to both, for some
/// `a <= more`. While `v + more < 2^24`, f32 holds every count exactly and
/// `(s + a) / (v + a)` rounds to values non-decreasing in `a` (`s <= v`): `a = more` is
/// the best case. Beyond, rounding can make fewer frames better (found by fuzzing the
/// bindings: `s = 15099494`, `v = 2^24`, one frame seeing the voxel without segmenting
/// it keeps it at `f32(2^24 + 1) / ... >= 0.9`, while `(s + 1) / (v + 2)` rounds below
/// 0.9), so such a voxel is kept and its final counts decide.
#[inline]
fn may_end_high(table: &HighConfidenceTable, s: u32, v: u32, more: u32) -> bool {
    v.saturating_add(more) >= F32_EXACT
        || table.contains(s.saturating_add(more), v.saturating_add(more))
}

/// Per-thread buffers reused across candidates.
struct Workspace {
    /// (index into `Tracked`, added segmented count, added visible count)
    alive: Vec<(u32, u16, u16)>,
    pixels: Vec<u32>,
    mask: Vec<u8>,
    scratch: RasterScratch,
    seg0: Vec<u32>,
    vis0: Vec<u32>,
}

const OUTSIDE: u32 = u32::MAX;

/// Above 1/DENSE_FRACTION of the grid tracked, the first frame is carved densely over
/// the whole grid (else only over the tracked voxels' columns); above 1/DENSE_FRACTION
/// of the grid still undecided after the first frame, the remaining frames are too.
const DENSE_FRACTION: usize = 4;

impl Workspace {
    fn new(grid: &OccupancyGrid, camera: &PinholeCamera) -> Self {
        let n = grid.spec().voxel_count();
        Self {
            alive: Vec::new(),
            pixels: Vec::new(),
            mask: vec![0; camera.pixel_count()],
            scratch: RasterScratch::default(),
            seg0: vec![0; n],
            vis0: vec![0; n],
        }
    }

    /// `#Ŝ_{≥λ}` over the tracked voxels after adding the rendered silhouettes of `poses`
    /// (eq. 14's "after" count). `dense_first`: carve the first frame over the whole grid
    /// rather than over the tracked voxels' columns (the same count either way).
    #[allow(clippy::too_many_arguments)]
    fn count_after(
        &mut self,
        grid: &OccupancyGrid,
        scene: &MeshScene,
        camera: &PinholeCamera,
        tracked: &Tracked,
        table: &HighConfidenceTable,
        poses: &[Pose],
        dense_first: bool,
    ) -> usize {
        if tracked.flat.is_empty() {
            return 0;
        }
        let m = poses.len() as u32;
        let spec = grid.spec();
        // The far end of the trajectory first, with the carving kernel: it is the most
        // informative frame and removes most tracked voxels.
        let last = &poses[poses.len() - 1];
        if dense_first {
            // Over the whole grid.
            let rect = grid_rect(spec, camera, last);
            scene.render_mask_into(camera, last, rect, &mut self.mask, &mut self.scratch);
            let frame = PreparedFrame::new(spec, camera, last, &self.mask);
            self.seg0.fill(0);
            self.vis0.fill(0);
            carve_one(spec, &frame, &mut self.seg0, &mut self.vis0);
        } else {
            // Few tracked voxels (e.g. a small region): only the columns holding them,
            // with the mask rendered only inside the pixels of their bounding box. The
            // same kernel on the same columns: every tracked voxel gets the counts the
            // dense carve gives it. (`seg0`, `vis0` are valid only on those columns.)
            let rect = box_rect(spec, camera, last, tracked.lo, tracked.hi);
            scene.render_mask_into(camera, last, rect, &mut self.mask, &mut self.scratch);
            let frame = PreparedFrame::new(spec, camera, last, &self.mask);
            let r = spec.resolution();
            for &(a, b, len) in &tracked.columns {
                let off = (a as usize * r + b as usize) * r;
                self.seg0[off..off + len as usize].fill(0);
                self.vis0[off..off + len as usize].fill(0);
            }
            carve_columns(
                spec,
                &frame,
                &tracked.columns,
                &mut self.seg0,
                &mut self.vis0,
            );
        }
        let remaining = m - 1;
        self.alive.clear();
        for (k, &i) in tracked.flat.iter().enumerate() {
            let (ds, dv) = (self.seg0[i as usize], self.vis0[i as usize]);
            if may_end_high(
                table,
                tracked.seg[k].saturating_add(ds),
                tracked.vis[k].saturating_add(dv),
                remaining,
            ) {
                self.alive.push((k as u32, ds as u16, dv as u16));
            }
        }
        let rest = &poses[..poses.len() - 1];
        // (Never after a sparse first frame: fewer voxels are alive than tracked.)
        if dense_first && self.alive.len() * DENSE_FRACTION > spec.voxel_count() {
            // Many voxels still undecided (typically ones no view has seen yet): carving
            // the whole grid per frame with the SIMD kernel beats visiting them one by one.
            for pose in rest {
                let rect = grid_rect(spec, camera, pose);
                scene.render_mask_into(camera, pose, rect, &mut self.mask, &mut self.scratch);
                let frame = PreparedFrame::new(spec, camera, pose, &self.mask);
                carve_one(spec, &frame, &mut self.seg0, &mut self.vis0);
            }
            return tracked
                .flat
                .iter()
                .enumerate()
                .filter(|&(k, &i)| {
                    table.contains(
                        tracked.seg[k].saturating_add(self.seg0[i as usize]),
                        tracked.vis[k].saturating_add(self.vis0[i as usize]),
                    )
                })
                .count();
        }
        let width = camera.width;
        for (done, pose) in rest.iter().rev().enumerate() {
            if self.alive.is_empty() {
                break;
            }
            let remaining = m - done as u32 - 2;
            let proj = VoxelProjector::new(spec, camera, pose);
            let intr = proj.intr;
            let [p0, ea, eb, ec] = proj.affine_f32();
            // Project every surviving voxel and find the bounding box of their pixels.
            self.pixels.clear();
            let (mut u0, mut u1, mut v0, mut v1) = (u32::MAX, 0u32, u32::MAX, 0u32);
            for &(k, _, _) in &self.alive {
                let [a, b, c] = tracked.abc[k as usize];
                let p: [f32; 3] =
                    std::array::from_fn(|j| p0[j] + a * ea[j] + b * eb[j] + c * ec[j]);
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
            let mut j = 0;
            self.alive.retain_mut(|(k, ds, dv)| {
                let px = pixels[j];
                j += 1;
                if px != OUTSIDE {
                    *dv += 1;
                    *ds += u16::from(mask[px as usize] != 0);
                }
                let k = *k as usize;
                may_end_high(
                    table,
                    tracked.seg[k].saturating_add(u32::from(*ds)),
                    tracked.vis[k].saturating_add(u32::from(*dv)),
                    remaining,
                )
            });
        }
        self.alive
            .iter()
            .filter(|&&(k, ds, dv)| {
                let k = k as usize;
                table.contains(
                    tracked.seg[k].saturating_add(u32::from(ds)),
                    tracked.vis[k].saturating_add(u32::from(dv)),
                )
            })
            .count()
    }
}

/// The pixels the grid's voxel centres can project to: the box of the projected corners
/// of the cube (all voxel centres lie in their convex hull) when all are in front of the
/// camera, else the whole image.
fn grid_rect(spec: &crate::grid::GridSpec, camera: &PinholeCamera, cam2world: &Pose) -> PixelRect {
    let o = spec.origin();
    let far = o.map(|x| x + spec.size());
    world_box_rect(camera, cam2world, o, far)
}

/// The pixels the centres of voxels `lo..=hi` (per axis) can project to: as
/// [`grid_rect`], for the box of those voxels.
fn box_rect(
    spec: &crate::grid::GridSpec,
    camera: &PinholeCamera,
    cam2world: &Pose,
    lo: [usize; 3],
    hi: [usize; 3],
) -> PixelRect {
    let (o, h) = (spec.origin(), spec.voxel_size());
    let near = std::array::from_fn(|k| o[k] + lo[k] as f64 * h);
    let far = std::array::from_fn(|k| o[k] + (hi[k] + 1) as f64 * h);
    world_box_rect(camera, cam2world, near, far)
}

/// The box of the projected corners of the world box `[near, far]`, one pixel wider on
/// each side, when all corners are in front of the camera; else the whole image.
fn world_box_rect(
    camera: &PinholeCamera,
    cam2world: &Pose,
    near: [f64; 3],
    far: [f64; 3],
) -> PixelRect {
    let full = PixelRect::full(camera);
    let w2c = cam2world.inverse();
    let (mut umin, mut umax, mut vmin, mut vmax) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for k in 0..8 {
        let corner = nalgebra::Point3::new(
            if k & 1 == 0 { near[0] } else { far[0] },
            if k & 2 == 0 { near[1] } else { far[1] },
            if k & 4 == 0 { near[2] } else { far[2] },
        );
        let p = w2c.transform_point(&corner);
        if !(p.z > 1e-9) {
            return full;
        }
        let (u, v) = (
            camera.fx * p.x / p.z + camera.cx,
            camera.fy * p.y / p.z + camera.cy,
        );
        umin = umin.min(u);
        umax = umax.max(u);
        vmin = vmin.min(v);
        vmax = vmax.max(v);
    }
    // One pixel of margin on each side covers the +0.5 rounding of the convention.
    let clamp = |x: f64, hi: u32| x.clamp(0.0, hi as f64) as u32;
    PixelRect {
        u0: clamp((umin - 1.0).floor(), full.u1),
        u1: clamp((umax + 1.0).ceil(), full.u1),
        v0: clamp((vmin - 1.0).floor(), full.v1),
        v1: clamp((vmax + 1.0).ceil(), full.v1),
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

    /// A copy of `grid` with the rendered silhouettes of `poses` integrated.
    fn integrated(
        grid: &OccupancyGrid,
        scene: &MeshScene,
        cam: &PinholeCamera,
        poses: &[Pose],
    ) -> OccupancyGrid {
        let mut g = grid.clone();
        let masks: Vec<u8> = poses
            .iter()
            .flat_map(|p| scene.render_mask(cam, p))
            .collect();
        g.integrate_many(cam, poses, &masks).unwrap();
        g
    }

    /// The definition: render, integrate into a copy, count.
    fn reference(
        grid: &OccupancyGrid,
        scene: &MeshScene,
        cam: &PinholeCamera,
        poses: &[Pose],
        lam: f32,
    ) -> f32 {
        let g = integrated(grid, scene, cam, poses);
        1.0 - g.count_high_confidence(lam) as f32 / grid.count_high_confidence(lam) as f32
    }

    /// Ten 4-frame rings, lower and closer to the scene than the views already seen.
    fn low_rings() -> Vec<Vec<Pose>> {
        (0..10)
            .map(|k| {
                ring(
                    4,
                    0.25 + 0.02 * k as f64,
                    0.15 + 0.03 * k as f64,
                    0.5 * k as f64,
                )
            })
            .collect()
    }

    /// `score_views` over `trajectories`, each score checked against the definition.
    fn scores_as_defined(
        grid: &OccupancyGrid,
        scene: &MeshScene,
        cam: &PinholeCamera,
        trajectories: &[Vec<Pose>],
    ) -> Vec<f32> {
        let scores = score_views(grid, scene, cam, trajectories, 0.9).unwrap();
        for (k, t) in trajectories.iter().enumerate() {
            assert_eq!(
                scores[k],
                reference(grid, scene, cam, t, 0.9),
                "candidate {k}"
            );
        }
        scores
    }

    #[test]
    fn scores_equal_render_integrate_count() {
        let (grid, scene, cam) = setup();
        let trajectories: Vec<Vec<Pose>> = (0..12)
            .map(|k| ring(5, 0.3 + 0.01 * k as f64, 0.2 + 0.02 * k as f64, k as f64))
            .collect();
        let scores = scores_as_defined(&grid, &scene, &cam, &trajectories);
        assert!(
            scores.iter().any(|&s| s > 0.1),
            "new views must carve something: {scores:?}"
        );
    }

    #[test]
    fn paths_from_the_only_view_so_far_score_as_defined() {
        // HEAPGrasp's first waypoint: one view from above, then 10-frame paths that start
        // next to it and end on the view sphere. Most of the grid was carved by that one
        // view and is still undecided after the far end, so every frame is carved densely.
        let cam = PinholeCamera::new(80, 60, 75.0, 75.0, 39.5, 29.5).unwrap();
        let (_, scene, _) = setup();
        let top = Pose::look_at([0.15, 0.15, 0.6], [0.15, 0.15, 0.0], [0.0, 1.0, 0.0]).unwrap();
        let mut grid = OccupancyGrid::new(GridSpec::new([0.0; 3], 0.3, 20).unwrap());
        grid.integrate(&cam, &top, &scene.render_mask(&cam, &top))
            .unwrap();
        let trajectories: Vec<Vec<Pose>> = (0..8)
            .map(|k| {
                let phi = std::f64::consts::TAU * k as f64 / 8.0;
                (1..=10)
                    .map(|j| {
                        let s = j as f64 / 10.0;
                        let (r, theta) = (0.6 - 0.27 * s, 0.6 * s);
                        let eye = [
                            0.15 + r * theta.sin() * phi.cos(),
                            0.15 + r * theta.sin() * phi.sin(),
                            r * theta.cos(),
                        ];
                        Pose::look_at(eye, [0.15, 0.15, 0.15], [0.0, 1.0, 0.0]).unwrap()
                    })
                    .collect()
            })
            .collect();
        let scores = scores_as_defined(&grid, &scene, &cam, &trajectories);
        assert!(scores.iter().all(|&s| s > 0.1), "{scores:?}");
    }

    #[test]
    fn narrow_views_that_leave_most_voxels_unseen_score_as_defined() {
        // A long lens sees a tenth of the cube: the voxels no frame sees stay undecided
        // through every frame, so all of them are carved densely.
        let cam = PinholeCamera::new(80, 60, 320.0, 320.0, 39.5, 29.5).unwrap();
        let (_, scene, _) = setup();
        let mut grid = OccupancyGrid::new(GridSpec::new([0.0; 3], 0.3, 20).unwrap());
        let first = ring(1, 0.4, 0.35, 0.3);
        grid.integrate(&cam, &first[0], &scene.render_mask(&cam, &first[0]))
            .unwrap();
        let trajectories: Vec<Vec<Pose>> = (0..6)
            .map(|k| ring(6, 0.35 + 0.01 * k as f64, 0.3, 0.3 + 0.05 * k as f64))
            .collect();
        scores_as_defined(&grid, &scene, &cam, &trajectories);
    }

    #[test]
    fn scores_equal_the_definition_on_a_well_observed_grid() {
        // Many frames already integrated: few voxels stay undecided, so the sparse path
        // (per-voxel visits after the first frame) runs instead of the dense one.
        let (mut grid, scene, cam) = setup();
        let seen = ring(24, 0.35, 0.3, 0.1);
        let masks: Vec<u8> = seen
            .iter()
            .flat_map(|p| scene.render_mask(&cam, p))
            .collect();
        grid.integrate_many(&cam, &seen, &masks).unwrap();
        let trajectories = low_rings();
        scores_as_defined(&grid, &scene, &cam, &trajectories);
    }

    /// The region's definition: high-confidence voxels inside it, before and after.
    fn reference_in(
        grid: &OccupancyGrid,
        scene: &MeshScene,
        cam: &PinholeCamera,
        poses: &[Pose],
        lam: f32,
        region: &[bool],
    ) -> f32 {
        let count = |g: &OccupancyGrid| {
            let table = HighConfidenceTable::new(lam, 1 << 12);
            g.segmented()
                .iter()
                .zip(g.visible())
                .zip(region)
                .filter(|&((&s, &v), &r)| r && table.contains(s, v))
                .count() as f32
        };
        1.0 - count(&integrated(grid, scene, cam, poses)) / count(grid)
    }

    #[test]
    fn region_scores_count_only_the_region() {
        let (grid, scene, cam) = setup();
        let spec = grid.spec();
        let trajectories: Vec<Vec<Pose>> = (0..8)
            .map(|k| ring(4, 0.3 + 0.01 * k as f64, 0.2 + 0.02 * k as f64, k as f64))
            .collect();
        let all = vec![true; spec.voxel_count()];
        assert_eq!(
            score_views_in(&grid, &scene, &cam, &trajectories, 0.9, Some(&all)).unwrap(),
            score_views(&grid, &scene, &cam, &trajectories, 0.9).unwrap()
        );
        // The upper half of the grid: the region above the box, where the first view
        // leaves most of its volume.
        let upper: Vec<bool> = (0..spec.voxel_count())
            .map(|i| spec.unflatten(i)[2] >= 2)
            .collect();
        let scores = score_views_in(&grid, &scene, &cam, &trajectories, 0.9, Some(&upper)).unwrap();
        for (k, t) in trajectories.iter().enumerate() {
            assert_eq!(
                scores[k],
                reference_in(&grid, &scene, &cam, t, 0.9, &upper),
                "candidate {k}"
            );
        }
        let whole = score_views(&grid, &scene, &cam, &trajectories, 0.9).unwrap();
        assert_ne!(scores, whole, "a region must change the scores");
        // A region without measured volume scores zero; a wrong length is an error.
        let none = vec![false; spec.voxel_count()];
        assert_eq!(
            score_views_in(&grid, &scene, &cam, &trajectories, 0.9, Some(&none)).unwrap(),
            vec![0.0; trajectories.len()]
        );
        assert!(score_views_in(&grid, &scene, &cam, &trajectories, 0.9, Some(&none[1..])).is_err());
    }

    /// The voxels whose centre lies within `radius` of `xy` in x–y: a vertical column
    /// like the pipeline's target region.
    fn column(spec: &GridSpec, xy: [f64; 2], radius: f64) -> Vec<bool> {
        (0..spec.voxel_count())
            .map(|i| {
                let [a, b, c] = spec.unflatten(i);
                let p = spec.voxel_center(a, b, c);
                (p.x - xy[0]).hypot(p.y - xy[1]) <= radius
            })
            .collect()
    }

    /// A grid seen from one view, and the same after a ring of 24 more.
    fn grids() -> (OccupancyGrid, OccupancyGrid, MeshScene, PinholeCamera) {
        let (grid, scene, cam) = setup();
        let seen = ring(24, 0.35, 0.3, 0.1);
        let well_observed = integrated(&grid, &scene, &cam, &seen);
        (grid, well_observed, scene, cam)
    }

    #[test]
    fn small_region_scores_equal_the_definition() {
        // A column around the box: few tracked voxels, so the first frame is carved only
        // over their columns (the sparse first frame), on a grid seen once (many voxels
        // undecided) and on a well-observed one.
        let (once, well, scene, cam) = grids();
        let trajectories = low_rings();
        for grid in [&once, &well] {
            let spec = grid.spec();
            let region = column(spec, [0.15, 0.13], 0.05);
            let table = HighConfidenceTable::new(0.9, 1 << 12);
            let tracked = Tracked::collect(grid, Some(&region), &table, 4);
            assert!(!tracked.flat.is_empty());
            assert!(
                tracked.flat.len() * DENSE_FRACTION <= spec.voxel_count(),
                "the sparse first frame must run: {} tracked",
                tracked.flat.len()
            );
            let scores =
                score_views_in(grid, &scene, &cam, &trajectories, 0.9, Some(&region)).unwrap();
            for (k, t) in trajectories.iter().enumerate() {
                assert_eq!(
                    scores[k],
                    reference_in(grid, &scene, &cam, t, 0.9, &region),
                    "candidate {k}"
                );
            }
            assert!(
                scores.iter().any(|&s| s > 0.0),
                "new views must carve something in the column: {scores:?}"
            );
        }
    }

    #[test]
    fn sparse_first_frame_counts_equal_the_dense_one() {
        // Same tracked voxels, first frame carved over the whole grid or only over their
        // columns: the same kernel on the same voxels, so the counts are identical
        // (not only up to voxels on a pixel border), for columns anywhere in the grid and
        // for trajectories whose far end sees the grid only in part or from inside its
        // box (the whole-image rect).
        let (once, well, scene, cam) = grids();
        let mut trajectories: Vec<Vec<Pose>> = (0..24)
            .map(|k| {
                ring(
                    1 + k % 5,
                    0.12 + 0.02 * k as f64,
                    0.05 + 0.025 * k as f64,
                    0.7 * k as f64,
                )
            })
            .collect();
        // A camera inside the grid's box, looking sideways: some corners behind it.
        trajectories.push(vec![Pose::look_at(
            [0.05, 0.05, 0.1],
            [0.3, 0.25, 0.02],
            [0.0, 0.0, 1.0],
        )
        .unwrap()]);
        for grid in [&once, &well] {
            let spec = grid.spec();
            let max_m = trajectories.iter().map(Vec::len).max().unwrap() as u32;
            let table = HighConfidenceTable::new(0.9, 1 << 12);
            for (xy, radius) in [
                ([0.15, 0.13], 0.05),
                ([0.15, 0.15], 0.08),
                ([0.0, 0.0], 0.06),
                ([0.3, 0.12], 0.03),
                ([0.11, 0.2], 0.02),
            ] {
                let region = column(spec, xy, radius);
                let tracked = Tracked::collect(grid, Some(&region), &table, max_m);
                assert!(tracked.flat.len() * DENSE_FRACTION <= spec.voxel_count());
                let mut ws = Workspace::new(grid, &cam);
                let mut ws_sparse = Workspace::new(grid, &cam);
                for (k, t) in trajectories.iter().enumerate() {
                    let dense = ws.count_after(grid, &scene, &cam, &tracked, &table, t, true);
                    // Stale buffers must not matter: pixels outside the rendered rect
                    // and counts outside the carved columns are never read.
                    ws_sparse.mask.fill(1);
                    ws_sparse.seg0.fill(7);
                    ws_sparse.vis0.fill(3);
                    let sparse =
                        ws_sparse.count_after(grid, &scene, &cam, &tracked, &table, t, false);
                    assert_eq!(sparse, dense, "column {xy:?} r {radius}, candidate {k}");
                }
            }
        }
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

    /// Found by fuzzing the bindings (issue 36): counts beyond 2^24, where f32 cannot
    /// hold every integer, broke the pruning's assumption that the best case of the
    /// remaining frames is all of them segmenting the voxel. With `s = 15099494` and
    /// `v = 2^24` (occupancy 0.9000000358), a frame that sees the voxel without segmenting
    /// it leaves it high-confidence (`f32(2^24 + 1) = 2^24`), but the pruning tried
    /// `(s + 1) / (v + 2)`, which rounds below 0.9, and dropped it: score 1 instead of 0.
    #[test]
    fn counts_beyond_f32_integers_are_scored_by_the_definition() {
        let cam = PinholeCamera::new(1, 1, 2.0, 2.0, 0.0, 0.0).unwrap();
        let scene = MeshScene::new(); // nothing is ever segmented
        let spec = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 1).unwrap();
        let eye = [0.1857, -0.1238, 0.707];
        let sees = Pose::look_at(eye, [0.0, 0.0, 0.15], [0.0, 0.0, 1.0]).unwrap();
        let away = Pose::look_at(eye, [eye[0], eye[1], 2.0], [0.0, 1.0, 0.0]).unwrap();
        let trajectories = vec![
            vec![away, sees],
            vec![sees],
            vec![sees, sees],
            vec![away, sees, sees],
            vec![sees, away, away],
        ];
        let mut checked = 0;
        for v in [
            (1 << 24) - 2,
            (1 << 24) - 1,
            1 << 24,
            (1 << 24) + 1,
            (1 << 24) + 2,
        ] {
            for s in (v as f64 * 0.9) as u32 - 3..=(v as f64 * 0.9) as u32 + 3 {
                let grid = OccupancyGrid::from_counts(spec, vec![s], vec![v]).unwrap();
                if grid.count_high_confidence(0.9) == 0 {
                    continue;
                }
                let got = score_views(&grid, &scene, &cam, &trajectories, 0.9).unwrap();
                for (t, g) in trajectories.iter().zip(&got) {
                    let want = reference(&grid, &scene, &cam, t, 0.9);
                    assert_eq!(*g, want, "s = {s}, v = {v}, {} frames", t.len());
                    checked += 1;
                }
            }
        }
        assert!(checked > 50, "{checked}");
        // The case the fuzzer found.
        let grid = OccupancyGrid::from_counts(spec, vec![15_099_494], vec![1 << 24]).unwrap();
        let got = score_views(&grid, &scene, &cam, &[vec![away, sees]], 0.9).unwrap();
        assert_eq!(got, vec![0.0]);
    }
}
