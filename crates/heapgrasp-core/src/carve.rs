//! Shape-from-Silhouette counting (HEAPGrasp §IV-A, the counts behind eq. 10).
//!
//! For every frame and every voxel, the voxel centre is projected into the frame: if it
//! lands inside the image the voxel's *visible* count `|I_rgb|` grows by one, and if the
//! pixel is set in the silhouette mask its *segmented* count `|I_seg|` grows too.
//!
//! The kernel walks grid columns `(a, b, ·)` (contiguous in memory) and, for each
//! column, all frames, so the column's counters stay in L1; masks are bit-packed so a
//! 320×240 frame takes 9.6 kB. Slabs of the x axis run on separate threads. A runtime
//! dispatch picks the AVX-512 (16 lanes) or AVX2 (8 lanes) loop where the CPU has one,
//! and the portable loop elsewhere (aarch64 included: the compiler's NEON code for it);
//! `HEAPGRASP_KERNEL` forces a level the CPU has ([`kernel_level`]).
//!
//! The file runs past 800 lines only because its unit tests sit beside the code (the
//! crate's rule, from `mod tests` on); the kernel itself is under 800.

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::grid::GridSpec;
use crate::parallel;
use crate::projector::{mask_bit, pack_mask, Column, Intrinsics32, VoxelProjector};

/// One frame prepared for carving: its projector and packed mask.
pub(crate) struct PreparedFrame {
    pub projector: VoxelProjector,
    pub words: Vec<u32>,
}

impl PreparedFrame {
    pub(crate) fn new(grid: &GridSpec, camera: &PinholeCamera, pose: &Pose, mask: &[u8]) -> Self {
        let mut words = Vec::with_capacity(mask.len().div_ceil(32));
        pack_mask(mask, &mut words);
        Self {
            projector: VoxelProjector::new(grid, camera, pose),
            words,
        }
    }
}

/// Grids up to this many voxels are carved frame-parallel (each thread owns private
/// counts for a subset of frames, summed at the end); larger ones slab-parallel.
const FRAME_PARALLEL_MAX_VOXELS: usize = 1 << 18;

/// Adds the silhouettes `masks` (`poses.len()` camera-sized masks back to back) into the
/// counts of `grid` (`segmented`, `visible`: flat R³ buffers), on as many threads as the
/// work is worth (at most [`parallel::num_threads`]). Counts saturate at `u32::MAX`.
///
/// # Errors
/// [`Error::Shape`] when `masks` does not hold one camera-sized mask per pose; nothing is
/// counted then.
pub(crate) fn carve(
    grid: &GridSpec,
    camera: &PinholeCamera,
    poses: &[Pose],
    masks: &[u8],
    segmented: &mut [u32],
    visible: &mut [u32],
) -> Result<()> {
    let threads = parallel::threads_for(grid.voxel_count() * poses.len(), 1 << 18, usize::MAX);
    let prep_threads = parallel::threads_for(masks.len(), 1 << 20, poses.len());
    carve_split(
        grid,
        camera,
        poses,
        masks,
        (segmented, visible),
        threads,
        prep_threads,
    )
}

/// How [`carve_with_threads`] splits the work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CarvePlan {
    /// One thread carves every frame over the whole grid.
    Serial,
    /// This many threads each carve a share of the frames into private counts, summed at
    /// the end (small grids, at least as many frames as threads).
    Frames(usize),
    /// This many threads each carve every frame over a slab of the x axis.
    Slabs(usize),
}

impl CarvePlan {
    /// The split for `frames` frames over a grid of resolution `r` on `threads` threads.
    pub(crate) fn new(r: usize, frames: usize, threads: usize) -> Self {
        let voxels = r * r * r;
        if threads <= 1 || frames == 0 {
            Self::Serial
        } else if voxels <= FRAME_PARALLEL_MAX_VOXELS && frames >= threads {
            Self::Frames(threads)
        } else if threads.min(r) > 1 {
            Self::Slabs(threads.min(r))
        } else {
            Self::Serial
        }
    }
}

/// [`carve`] on exactly `threads` threads (`0` counts as 1; the slab path uses at most R
/// of them). The counts do not depend on `threads`.
///
/// # Errors
/// As [`carve`].
pub(crate) fn carve_with_threads(
    grid: &GridSpec,
    camera: &PinholeCamera,
    poses: &[Pose],
    masks: &[u8],
    segmented: &mut [u32],
    visible: &mut [u32],
    threads: usize,
) -> Result<()> {
    let prep_threads = parallel::threads_for(masks.len(), 1 << 20, poses.len());
    carve_split(
        grid,
        camera,
        poses,
        masks,
        (segmented, visible),
        threads,
        prep_threads.min(threads.max(1)),
    )
}

/// [`carve`] with `threads` carving as [`CarvePlan`] says, the frames prepared on
/// `prep_threads` threads when the plan is not frame-parallel.
fn carve_split(
    grid: &GridSpec,
    camera: &PinholeCamera,
    poses: &[Pose],
    masks: &[u8],
    (segmented, visible): (&mut [u32], &mut [u32]),
    threads: usize,
    prep_threads: usize,
) -> Result<()> {
    let px = camera.pixel_count();
    if masks.len() != poses.len() * px {
        return Err(Error::shape(
            "masks",
            format!("({}, {}, {})", poses.len(), camera.height, camera.width),
            format!("{} values", masks.len()),
        ));
    }
    let n = poses.len();
    if n == 0 {
        return Ok(());
    }
    let voxels = grid.voxel_count();
    let r = grid.resolution();
    let frame =
        |k: usize| PreparedFrame::new(grid, camera, &poses[k], &masks[k * px..(k + 1) * px]);
    match CarvePlan::new(r, n, threads) {
        CarvePlan::Frames(threads) => {
            // The calling thread carves the first share of frames straight into the grid;
            // each other thread into private counts, summed at the end. (Fresh buffers
            // cost page faults, so only the extra threads allocate.)
            let ranges = parallel::split_range(n, threads);
            let partial = std::thread::scope(|s| {
                let handles: Vec<_> = ranges[1..]
                    .iter()
                    .cloned()
                    .map(|range| {
                        let frame = &frame;
                        s.spawn(move || {
                            let mut seg = vec![0u32; voxels];
                            let mut vis = vec![0u32; voxels];
                            let frames: Vec<_> = range.map(frame).collect();
                            carve_slab(grid, 0..r, &frames, &mut seg, &mut vis);
                            (seg, vis)
                        })
                    })
                    .collect();
                let own: Vec<_> = ranges[0].clone().map(&frame).collect();
                carve_slab(grid, 0..r, &own, segmented, visible);
                handles
                    .into_iter()
                    .map(|h| match h.join() {
                        Ok(v) => v,
                        Err(payload) => std::panic::resume_unwind(payload),
                    })
                    .collect::<Vec<_>>()
            });
            // Every addend is non-negative, so the saturated total is min(MAX, sum) in
            // any order: the same counts as one thread.
            for (seg, vis) in partial {
                segmented
                    .iter_mut()
                    .zip(&seg)
                    .for_each(|(d, s)| *d = d.saturating_add(*s));
                visible
                    .iter_mut()
                    .zip(&vis)
                    .for_each(|(d, s)| *d = d.saturating_add(*s));
            }
        }
        plan => {
            let slabs = match plan {
                CarvePlan::Slabs(k) => k,
                _ => 1,
            };
            let frames: Vec<_> =
                parallel::map_ranges(n, prep_threads, |r| r.map(frame).collect::<Vec<_>>())
                    .into_iter()
                    .flatten()
                    .collect();
            parallel::for_each_row_chunk_pair(
                segmented,
                visible,
                r * r,
                slabs,
                |rows, seg, vis| carve_slab(grid, rows, &frames, seg, vis),
            );
        }
    }
    Ok(())
}

/// Adds one prepared frame over the whole grid, single-threaded (callers parallelise
/// over something else, e.g. view candidates).
pub(crate) fn carve_one(grid: &GridSpec, frame: &PreparedFrame, seg: &mut [u32], vis: &mut [u32]) {
    carve_slab(
        grid,
        0..grid.resolution(),
        std::slice::from_ref(frame),
        seg,
        vis,
    );
}

/// Adds one prepared frame to the listed column prefixes only: for each `(a, b, len)`,
/// the voxels `(a, b, 0..len)` (`seg`, `vis`: flat buffers of the whole grid; the other
/// voxels are left as they are). Each voxel gets exactly the counts [`carve_one`] gives
/// it: the column loop computes every voxel from its own index, so a shorter column
/// changes nothing for the voxels it keeps.
pub(crate) fn carve_columns(
    grid: &GridSpec,
    frame: &PreparedFrame,
    columns: &[(u32, u32, u32)],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    let r = grid.resolution();
    for &(a, b, len) in columns {
        let (a, b, len) = (a as usize, b as usize, len as usize);
        let off = (a * r + b) * r;
        let col = frame.projector.column(a, b);
        carve_column_at(
            Kernel::selected(),
            &col,
            &frame.projector.intr,
            &frame.words,
            &mut seg[off..off + len],
            &mut vis[off..off + len],
        );
    }
}

/// Carves the x-slab `rows` of the grid; `seg` and `vis` hold exactly those rows.
fn carve_slab(
    grid: &GridSpec,
    rows: std::ops::Range<usize>,
    frames: &[PreparedFrame],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    carve_slab_at(Kernel::selected(), grid, rows, frames, seg, vis);
}

/// [`carve_slab`] with the column loop of `kernel`. The SIMD builds dispatch once per
/// slab into a loop compiled with their features, so each column's loop is inlined there
/// (a call per column and frame, each re-broadcasting its constants, cost the AVX2 build
/// a third of its speed on 40-voxel columns).
#[inline]
fn carve_slab_at(
    kernel: Kernel,
    grid: &GridSpec,
    rows: std::ops::Range<usize>,
    frames: &[PreparedFrame],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    match kernel.0 {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a Kernel holds Avx512 only when the CPU has every enabled feature.
        KernelLevel::Avx512 => unsafe { carve_slab_avx512(grid, rows, frames, seg, vis) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, for the AVX2 feature set.
        KernelLevel::Avx2 => unsafe { carve_slab_avx2(grid, rows, frames, seg, vis) },
        _ => carve_slab_with(grid, rows, frames, seg, vis, carve_column_generic),
    }
}

/// The slab loop (rows of the x axis, every column, every frame) around `column`.
#[inline(always)]
fn carve_slab_with(
    grid: &GridSpec,
    rows: std::ops::Range<usize>,
    frames: &[PreparedFrame],
    seg: &mut [u32],
    vis: &mut [u32],
    mut column: impl FnMut(&Column, &Intrinsics32, &[u32], &mut [u32], &mut [u32]),
) {
    let r = grid.resolution();
    for (local, a) in rows.enumerate() {
        for first in (0..r).step_by(TILE_COLUMNS) {
            let tile = first..(first + TILE_COLUMNS).min(r);
            for f in frames {
                for b in tile.clone() {
                    let off = (local * r + b) * r;
                    let col = f.projector.column(a, b);
                    let (seg_col, vis_col) = (&mut seg[off..off + r], &mut vis[off..off + r]);
                    column(&col, &f.projector.intr, &f.words, seg_col, vis_col);
                }
            }
        }
    }
}

/// Neighbouring columns carved together, frame by frame: their counts stay in L1 (16
/// columns of 80 voxels: 10 kB), and one frame's mask is read where they project, close
/// together, before the next frame's. Column by column, every frame's mask was read in
/// turn (30 frames of 640 × 480: 1.1 MB), missing L1 on most gathers.
const TILE_COLUMNS: usize = 16;

/// [`carve_slab_with`] compiled for AVX-512, its column loop inlined.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,bmi2")]
fn carve_slab_avx512(
    grid: &GridSpec,
    rows: std::ops::Range<usize>,
    frames: &[PreparedFrame],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    carve_slab_with(grid, rows, frames, seg, vis, |c, i, w, s, v| {
        carve_column_avx512(c, i, w, s, v)
    });
}

/// [`carve_slab_with`] compiled for AVX2, its column loop inlined.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi2")]
fn carve_slab_avx2(
    grid: &GridSpec,
    rows: std::ops::Range<usize>,
    frames: &[PreparedFrame],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    carve_slab_with(grid, rows, frames, seg, vis, |c, i, w, s, v| {
        carve_column_avx2(c, i, w, s, v)
    });
}

/// The inner loop over one column: vectorisable, branch-free. Counts saturate at
/// `u32::MAX` (a segmented voxel adds to both counts, so `seg <= vis` still holds).
#[inline(always)]
fn carve_column_generic(
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    let n = seg.len().min(vis.len());
    let (seg, vis) = (&mut seg[..n], &mut vis[..n]);
    for c in 0..n {
        let cf = c as f32;
        let x = col.base[0] + cf * col.step[0];
        let y = col.base[1] + cf * col.step[1];
        let z = col.base[2] + cf * col.step[2];
        let (inside, idx) = intr.pixel_masked(x, y, z);
        let inside = u32::from(inside);
        vis[c] = vis[c].saturating_add(inside);
        seg[c] = seg[c].saturating_add(mask_bit(words, idx) & inside);
    }
}

/// AVX-512 column loop: 16 voxels per step, a masked gather from the packed mask, and
/// `rcp14` refined by one Newton step in place of a divide (relative error ~1e-7, inside
/// the tolerance documented in [`crate::projector`]). Counts saturate at `u32::MAX` like
/// [`carve_column_generic`]'s.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,bmi2")]
#[inline]
fn carve_column_avx512(
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    use std::arch::x86_64::*;
    let n = seg.len().min(vis.len());
    let lane = _mm512_setr_ps(
        0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0,
    );
    let (bx, by, bz) = (
        _mm512_set1_ps(col.base[0]),
        _mm512_set1_ps(col.base[1]),
        _mm512_set1_ps(col.base[2]),
    );
    let (sx, sy, sz) = (
        _mm512_set1_ps(col.step[0]),
        _mm512_set1_ps(col.step[1]),
        _mm512_set1_ps(col.step[2]),
    );
    let (fx, fy) = (_mm512_set1_ps(intr.fx), _mm512_set1_ps(intr.fy));
    let (cxh, cyh) = (_mm512_set1_ps(intr.cx_half), _mm512_set1_ps(intr.cy_half));
    let (wi, hi) = (
        _mm512_set1_epi32(intr.width as i32),
        _mm512_set1_epi32(intr.height_f as i32),
    );
    let zero = _mm512_setzero_ps();
    let two = _mm512_set1_ps(2.0);
    let one = _mm512_set1_epi32(1);
    let low5 = _mm512_set1_epi32(31);
    let mut c0 = 0usize;
    while c0 < n {
        let k = (n - c0).min(16);
        let live: __mmask16 = if k == 16 { 0xffff } else { (1u16 << k) - 1 };
        let cf = _mm512_add_ps(lane, _mm512_set1_ps(c0 as f32));
        let x = _mm512_fmadd_ps(cf, sx, bx);
        let y = _mm512_fmadd_ps(cf, sy, by);
        let z = _mm512_fmadd_ps(cf, sz, bz);
        let r0 = _mm512_rcp14_ps(z);
        let inv = _mm512_mul_ps(r0, _mm512_fnmadd_ps(z, r0, two));
        let uf = _mm512_fmadd_ps(_mm512_mul_ps(fx, x), inv, cxh);
        let vf = _mm512_fmadd_ps(_mm512_mul_ps(fy, y), inv, cyh);
        // floor() to i32; NaN and out-of-range values become i32::MIN, which the
        // unsigned compares below reject like any negative pixel.
        let ui = _mm512_cvt_roundps_epi32::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(uf);
        let vi = _mm512_cvt_roundps_epi32::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(vf);
        let mut inside = _mm512_mask_cmp_ps_mask::<_CMP_GT_OQ>(live, z, zero);
        inside = _mm512_mask_cmplt_epu32_mask(inside, ui, wi);
        inside = _mm512_mask_cmplt_epu32_mask(inside, vi, hi);
        let idx = _mm512_add_epi32(_mm512_mullo_epi32(vi, wi), ui);
        // SAFETY: only lanes in `inside` are gathered; their pixel index is < width *
        // height, so idx / 32 < words.len() (ceil(width * height / 32) words).
        let w = unsafe {
            _mm512_mask_i32gather_epi32::<4>(
                _mm512_setzero_si512(),
                inside,
                _mm512_srli_epi32::<5>(idx),
                words.as_ptr().cast(),
            )
        };
        let bit = _mm512_and_si512(_mm512_srlv_epi32(w, _mm512_and_si512(idx, low5)), one);
        // SAFETY: lanes in `live` address c0..c0 + k <= n, inside both slices.
        unsafe {
            let vp = vis.as_mut_ptr().add(c0);
            let sp = seg.as_mut_ptr().add(c0);
            let v_old = _mm512_maskz_loadu_epi32(live, vp.cast());
            let s_old = _mm512_maskz_loadu_epi32(live, sp.cast());
            // Adding 0 or 1 wraps only MAX, to 0: the unsigned max keeps MAX there.
            let v_new = _mm512_mask_add_epi32(v_old, inside, v_old, one);
            let s_new = _mm512_add_epi32(s_old, bit);
            _mm512_mask_storeu_epi32(vp.cast(), live, _mm512_max_epu32(v_new, v_old));
            _mm512_mask_storeu_epi32(sp.cast(), live, _mm512_max_epu32(s_new, s_old));
        }
        c0 += 16;
    }
}

/// AVX2 column loop: 8 voxels per step, the same arithmetic as [`carve_column_avx512`]
/// but with an exact divide (AVX2's 12-bit `rcp` refined once is not close enough to the
/// portable loop's `1 / z`), unsigned bounds as `min_epu32` compares, a masked gather from
/// the packed mask, and masked loads and stores for the column's tail. Counts saturate at
/// `u32::MAX` like [`carve_column_generic`]'s.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi2")]
#[inline]
fn carve_column_avx2(
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    use std::arch::x86_64::*;
    let n = seg.len().min(vis.len());
    let lane = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
    let lane_i = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let (bx, by, bz) = (
        _mm256_set1_ps(col.base[0]),
        _mm256_set1_ps(col.base[1]),
        _mm256_set1_ps(col.base[2]),
    );
    let (sx, sy, sz) = (
        _mm256_set1_ps(col.step[0]),
        _mm256_set1_ps(col.step[1]),
        _mm256_set1_ps(col.step[2]),
    );
    let (fx, fy) = (_mm256_set1_ps(intr.fx), _mm256_set1_ps(intr.fy));
    let (cxh, cyh) = (_mm256_set1_ps(intr.cx_half), _mm256_set1_ps(intr.cy_half));
    let wi = _mm256_set1_epi32(intr.width as i32);
    // the largest valid column and row, for `x <= max` as an unsigned compare
    let (umax, vmax) = (
        _mm256_set1_epi32(intr.width as i32 - 1),
        _mm256_set1_epi32(intr.height_f as i32 - 1),
    );
    let zero = _mm256_setzero_ps();
    let one_f = _mm256_set1_ps(1.0);
    let one = _mm256_set1_epi32(1);
    let low5 = _mm256_set1_epi32(31);
    let mut c0 = 0usize;
    while c0 < n {
        let k = (n - c0).min(8);
        let live = _mm256_cmpgt_epi32(_mm256_set1_epi32(k as i32), lane_i);
        let cf = _mm256_add_ps(lane, _mm256_set1_ps(c0 as f32));
        let x = _mm256_fmadd_ps(cf, sx, bx);
        let y = _mm256_fmadd_ps(cf, sy, by);
        let z = _mm256_fmadd_ps(cf, sz, bz);
        let inv = _mm256_div_ps(one_f, z);
        let uf = _mm256_fmadd_ps(_mm256_mul_ps(fx, x), inv, cxh);
        let vf = _mm256_fmadd_ps(_mm256_mul_ps(fy, y), inv, cyh);
        // floor, then to i32: NaN and out-of-range values become i32::MIN, which the
        // unsigned compares below reject like any negative pixel.
        let ui = _mm256_cvttps_epi32(_mm256_floor_ps(uf));
        let vi = _mm256_cvttps_epi32(_mm256_floor_ps(vf));
        let in_u = _mm256_cmpeq_epi32(_mm256_min_epu32(ui, umax), ui);
        let in_v = _mm256_cmpeq_epi32(_mm256_min_epu32(vi, vmax), vi);
        let in_front = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(z, zero));
        let inside = _mm256_and_si256(
            _mm256_and_si256(in_u, in_v),
            _mm256_and_si256(in_front, live),
        );
        let idx = _mm256_add_epi32(_mm256_mullo_epi32(vi, wi), ui);
        // SAFETY: only lanes in `inside` are gathered; their pixel index is < width *
        // height, so idx / 32 < words.len() (ceil(width * height / 32) words).
        let w = unsafe {
            _mm256_mask_i32gather_epi32::<4>(
                _mm256_setzero_si256(),
                words.as_ptr().cast(),
                _mm256_srli_epi32::<5>(idx),
                inside,
            )
        };
        let bit = _mm256_and_si256(_mm256_srlv_epi32(w, _mm256_and_si256(idx, low5)), one);
        let step = _mm256_and_si256(inside, one);
        // SAFETY: lanes in `live` address c0..c0 + k <= n, inside both slices; the masked
        // loads and stores touch no other lane.
        unsafe {
            let vp = vis.as_mut_ptr().add(c0).cast::<i32>();
            let sp = seg.as_mut_ptr().add(c0).cast::<i32>();
            let v_old = _mm256_maskload_epi32(vp, live);
            let s_old = _mm256_maskload_epi32(sp, live);
            // Adding 0 or 1 wraps only MAX, to 0: the unsigned max keeps MAX there.
            let v_new = _mm256_max_epu32(_mm256_add_epi32(v_old, step), v_old);
            let s_new = _mm256_max_epu32(_mm256_add_epi32(s_old, bit), s_old);
            _mm256_maskstore_epi32(vp, live, v_new);
            _mm256_maskstore_epi32(sp, live, s_new);
        }
        c0 += 8;
    }
}

/// Which build of the column loop this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelLevel {
    /// AVX-512 (F, BW, VL, DQ) with FMA.
    Avx512,
    /// AVX2 with FMA.
    Avx2,
    /// Whatever the compilation target allows.
    Baseline,
}

/// The kernel build selected at run time (cached): the level `HEAPGRASP_KERNEL` asks for
/// (`avx512`, `avx2` or `baseline`) where the CPU has it; else `Baseline` where
/// `HEAPGRASP_NO_SIMD` is set (a synonym of `HEAPGRASP_KERNEL=baseline`); else
/// [`cpu_kernel_level`]. A request the CPU cannot honour, or an unknown value, is ignored
/// here and named by [`kernel_request`] (the Python package warns with it).
pub fn kernel_level() -> KernelLevel {
    use std::sync::OnceLock;
    static LEVEL: OnceLock<KernelLevel> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        if let Ok(Some(level)) = kernel_request() {
            return level;
        }
        if std::env::var_os("HEAPGRASP_NO_SIMD").is_some() {
            return KernelLevel::Baseline;
        }
        cpu_kernel_level()
    })
}

impl KernelLevel {
    /// The level's name: `avx512`, `avx2` or `baseline` (`HEAPGRASP_KERNEL`'s values).
    pub fn name(self) -> &'static str {
        match self {
            KernelLevel::Avx512 => "avx512",
            KernelLevel::Avx2 => "avx2",
            KernelLevel::Baseline => "baseline",
        }
    }
}

/// The level `HEAPGRASP_KERNEL` asks for: `Ok(None)` where it is unset or empty,
/// `Ok(Some(level))` where the CPU has that level, and `Err` with a message naming the
/// value where it is not one of `avx512`, `avx2`, `baseline` or the CPU lacks it.
pub fn kernel_request() -> std::result::Result<Option<KernelLevel>, String> {
    let Some(raw) = std::env::var_os("HEAPGRASP_KERNEL") else {
        return Ok(None);
    };
    let value = raw.to_string_lossy().trim().to_ascii_lowercase();
    let level = match value.as_str() {
        "" => return Ok(None),
        "avx512" => KernelLevel::Avx512,
        "avx2" => KernelLevel::Avx2,
        "baseline" => KernelLevel::Baseline,
        _ => {
            return Err(format!(
                "HEAPGRASP_KERNEL={:?} is not one of avx512, avx2, baseline",
                raw.to_string_lossy()
            ))
        }
    };
    if Kernel::supported(level).is_none() {
        return Err(format!(
            "HEAPGRASP_KERNEL={value}: this CPU cannot run the {value} kernel (its best is {})",
            cpu_kernel_level().name()
        ));
    }
    Ok(Some(level))
}

/// The best kernel build this CPU supports, whatever the environment says.
pub fn cpu_kernel_level() -> KernelLevel {
    if has_avx512() {
        KernelLevel::Avx512
    } else if has_avx2() {
        KernelLevel::Avx2
    } else {
        KernelLevel::Baseline
    }
}

/// Whether the CPU has every feature `carve_column_avx512` is built with.
#[cfg(target_arch = "x86_64")]
fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("bmi2")
}

/// Whether the CPU has every feature `carve_column_avx2` is built with.
#[cfg(target_arch = "x86_64")]
fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("bmi2")
}

/// No x86 SIMD build off x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn has_avx512() -> bool {
    false
}

/// No x86 SIMD build off x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn has_avx2() -> bool {
    false
}

/// A build of the column loop that this CPU supports: only [`Kernel::selected`] and
/// [`Kernel::supported`] make one, so running it is sound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Kernel(KernelLevel);

impl Kernel {
    /// The build [`kernel_level`] selects.
    fn selected() -> Self {
        Self(kernel_level())
    }

    /// The build `level`, if this CPU can run it.
    fn supported(level: KernelLevel) -> Option<Self> {
        let ok = match level {
            KernelLevel::Avx512 => has_avx512(),
            KernelLevel::Avx2 => has_avx2(),
            KernelLevel::Baseline => true,
        };
        ok.then_some(Self(level))
    }
}

/// One frame over one column with the column loop of `kernel`.
#[inline]
fn carve_column_at(
    kernel: Kernel,
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    match kernel.0 {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a Kernel holds Avx512 only when the CPU has every enabled feature.
        KernelLevel::Avx512 => unsafe { carve_column_avx512(col, intr, words, seg, vis) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, for the AVX2 feature set.
        KernelLevel::Avx2 => unsafe { carve_column_avx2(col, intr, words, seg, vis) },
        _ => carve_column_generic(col, intr, words, seg, vis),
    }
}

#[cfg(test)]
mod tests {
    //! The column loops against each other and against an f64 scalar reference, and the
    //! threaded paths against one thread, on random grids, cameras, poses, masks and
    //! starting counts (some at the top of the u32 range, to check the saturation).

    // Test code: generators build known-valid values.
    #![allow(clippy::unwrap_used)]

    use super::*;
    use proptest::prelude::*;

    /// Random inputs: the frames, and starting counts (`seg <= vis`).
    #[derive(Debug)]
    struct Case {
        grid: GridSpec,
        camera: PinholeCamera,
        poses: Vec<Pose>,
        masks: Vec<u8>,
        seg: Vec<u32>,
        vis: Vec<u32>,
    }

    fn xorshift(x: &mut u64) -> u64 {
        *x ^= *x << 13;
        *x ^= *x >> 7;
        *x ^= *x << 17;
        *x
    }

    prop_compose! {
        fn camera()(w in 1u32..64, h in 1u32..48, f in 5.0f64..150.0, aspect in 0.7f64..1.4,
                    cx in -10.0f64..70.0, cy in -10.0f64..55.0) -> PinholeCamera {
            PinholeCamera::new(w, h, f, f * aspect, cx, cy).unwrap()
        }
    }

    prop_compose! {
        /// Resolutions 1..=40 cover every tail length of the 16-lane AVX-512 loop.
        fn grid()(ox in -0.3f64..0.3, oy in -0.3f64..0.3, oz in -0.3f64..0.3,
                  size in 0.05f64..0.6, r in 1usize..=40) -> GridSpec {
            GridSpec::new([ox, oy, oz], size, r).unwrap()
        }
    }

    prop_compose! {
        /// Any eye (also inside the grid, with voxels behind the camera), any target and
        /// roll.
        fn pose()(eye in prop::array::uniform3(-1.0f64..1.0),
                  target in prop::array::uniform3(-0.4f64..0.4),
                  up in prop::array::uniform3(-1.0f64..1.0)) -> Pose {
            Pose::look_at(eye, target, up).unwrap_or_else(|_| Pose::identity())
        }
    }

    prop_compose! {
        fn case()(grid in grid(), camera in camera(),
                  poses in prop::collection::vec(pose(), 1..6),
                  density in 0u64..=4, counts in 0u8..4, seed in any::<u64>()) -> Case {
            let mut x = seed | 1;
            let masks = (0..poses.len() * camera.pixel_count())
                .map(|_| u8::from(xorshift(&mut x) % 4 < density))
                .collect();
            let n = grid.voxel_count();
            let (mut seg, mut vis) = (vec![0u32; n], vec![0u32; n]);
            for i in 0..n {
                let v = match counts {
                    0 => 0,
                    1 => (xorshift(&mut x) % 8) as u32,
                    // At or just below the top: the frames push some voxels over it.
                    _ => u32::MAX - (xorshift(&mut x) % 8) as u32,
                };
                let s = v - (xorshift(&mut x) % (u64::from(v.min(3)) + 1)) as u32;
                (seg[i], vis[i]) = (s, v);
            }
            Case { grid, camera, poses, masks, seg, vis }
        }
    }

    /// Counts of `case` after carving all its frames over the whole grid with `kernel`.
    fn carve_with(kernel: Kernel, case: &Case) -> Counts {
        let px = case.camera.pixel_count();
        let frames: Vec<_> = (0..case.poses.len())
            .map(|k| {
                let mask = &case.masks[k * px..(k + 1) * px];
                PreparedFrame::new(&case.grid, &case.camera, &case.poses[k], mask)
            })
            .collect();
        let (mut seg, mut vis) = (case.seg.clone(), case.vis.clone());
        let r = case.grid.resolution();
        carve_slab_at(kernel, &case.grid, 0..r, &frames, &mut seg, &mut vis);
        (seg, vis)
    }

    /// The f64 reference (the projection of [`PinholeCamera::project`], saturating
    /// adds), and per voxel whether some frame puts its centre so close to a pixel border
    /// (or to the image plane) that f32 kernels may round it to the other side.
    fn reference(case: &Case) -> (Vec<u32>, Vec<u32>, Vec<bool>) {
        let (grid, cam) = (&case.grid, &case.camera);
        let (mut seg, mut vis) = (case.seg.clone(), case.vis.clone());
        let mut tie = vec![false; grid.voxel_count()];
        let px = cam.pixel_count();
        for (k, pose) in case.poses.iter().enumerate() {
            let w2c = pose.inverse();
            let mask = &case.masks[k * px..(k + 1) * px];
            for i in 0..grid.voxel_count() {
                let [a, b, c] = grid.unflatten(i);
                let p = w2c.transform_point(&grid.voxel_center(a, b, c));
                let scale = p.x.abs() + p.y.abs() + p.z.abs() + 1.0;
                if p.z.abs() < 1e-4 * scale {
                    tie[i] = true;
                    continue;
                }
                if p.z > 0.0 {
                    let uf = cam.fx * p.x / p.z + cam.cx + 0.5;
                    let vf = cam.fy * p.y / p.z + cam.cy + 0.5;
                    // f32 rounding of the coordinates and of 1/z, scaled to pixels.
                    let tol =
                        1e-4 + 4e-6 * (cam.fx.max(cam.fy) * scale / p.z + uf.abs() + vf.abs());
                    let near = |f: f64| (f - f.round()).abs() < tol;
                    if near(uf) || near(vf) {
                        tie[i] = true;
                    }
                }
                if let Some((u, v)) = cam.project(&p) {
                    vis[i] = vis[i].saturating_add(1);
                    let set = mask[(v * cam.width + u) as usize] != 0;
                    seg[i] = seg[i].saturating_add(u32::from(set));
                }
            }
        }
        (seg, vis, tie)
    }

    /// `(segmented, visible)` of every voxel.
    type Counts = (Vec<u32>, Vec<u32>);

    /// Up to 5 voxels where two count pairs differ, tie voxels left out, as `(voxel,
    /// (seg, vis) of x, (seg, vis) of y)`.
    fn differing(x: &Counts, y: &Counts, tie: &[bool]) -> Vec<(usize, [u32; 2], [u32; 2])> {
        (0..tie.len())
            .filter(|&i| !tie[i] && (x.0[i] != y.0[i] || x.1[i] != y.1[i]))
            .map(|i| (i, [x.0[i], x.1[i]], [y.0[i], y.1[i]]))
            .take(5)
            .collect()
    }

    fn announce_avx512_skip() {
        use std::sync::Once;
        static ONCE: Once = Once::new();
        ONCE.call_once(|| {
            eprintln!(
                "carve: this CPU lacks AVX-512 (F, BW, VL, DQ with AVX2, FMA, BMI2): the \
                 AVX-512-vs-portable comparison is skipped; portable-vs-scalar still runs"
            );
        });
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn simd_and_portable_kernels_agree_with_the_scalar_reference(case in case()) {
            let (rseg, rvis, tie) = reference(&case);
            let reference = (rseg, rvis);
            let portable = carve_with(Kernel::supported(KernelLevel::Baseline).unwrap(), &case);
            let bad = differing(&portable, &reference, &tie);
            prop_assert!(bad.is_empty(), "portable vs scalar (voxel, portable, scalar): {bad:?}");
            for i in 0..tie.len() {
                prop_assert!(portable.0[i] <= portable.1[i], "segmented > visible at {i}");
            }
            match Kernel::supported(KernelLevel::Avx512) {
                Some(k) => {
                    let avx512 = carve_with(k, &case);
                    let bad = differing(&avx512, &portable, &tie);
                    prop_assert!(bad.is_empty(), "AVX-512 vs portable (voxel, avx512, portable): {bad:?}");
                }
                None => announce_avx512_skip(),
            }
            if let Some(k) = Kernel::supported(KernelLevel::Avx2) {
                let avx2 = carve_with(k, &case);
                let bad = differing(&avx2, &portable, &tie);
                prop_assert!(bad.is_empty(), "AVX2 vs portable (voxel, avx2, portable): {bad:?}");
                for i in 0..tie.len() {
                    prop_assert!(avx2.0[i] <= avx2.1[i], "AVX2: segmented > visible at {i}");
                }
            }
        }

        #[test]
        fn thread_count_does_not_change_the_counts(case in case(), threads in 2usize..7) {
            let run = |threads: usize| {
                let (mut seg, mut vis) = (case.seg.clone(), case.vis.clone());
                carve_with_threads(
                    &case.grid, &case.camera, &case.poses, &case.masks, &mut seg, &mut vis, threads,
                )
                .unwrap();
                (seg, vis)
            };
            prop_assert_eq!(run(threads), run(1));
        }
    }

    #[test]
    fn plans_split_as_documented() {
        // A small grid with at least as many frames as threads: frame-parallel.
        assert_eq!(CarvePlan::new(48, 3, 3), CarvePlan::Frames(3));
        assert_eq!(CarvePlan::new(48, 6, 2), CarvePlan::Frames(2));
        // Fewer frames than threads, or more than 2^18 voxels: slabs, at most R.
        assert_eq!(CarvePlan::new(48, 3, 4), CarvePlan::Slabs(4));
        assert_eq!(CarvePlan::new(65, 30, 2), CarvePlan::Slabs(2));
        assert_eq!(CarvePlan::new(3, 1, 8), CarvePlan::Slabs(3));
        // One thread, one voxel per axis or no frames: serial.
        assert_eq!(CarvePlan::new(48, 3, 1), CarvePlan::Serial);
        assert_eq!(CarvePlan::new(48, 3, 0), CarvePlan::Serial);
        assert_eq!(CarvePlan::new(1, 1, 4), CarvePlan::Serial);
        assert_eq!(CarvePlan::new(48, 0, 4), CarvePlan::Serial);
    }

    #[test]
    fn large_grids_carve_the_same_in_slabs() {
        // 65³ > 2^18 voxels: the slab path even with more frames than threads.
        let grid = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 65).unwrap();
        let camera = PinholeCamera::new(40, 30, 45.0, 47.0, 19.3, 14.6).unwrap();
        let poses: Vec<Pose> = (0..3)
            .map(|k| {
                let a = 0.1 + 2.1 * k as f64;
                Pose::look_at(
                    [0.7 * a.cos(), 0.7 * a.sin(), 0.35],
                    [0.0, 0.0, 0.15],
                    [0.0, 0.0, 1.0],
                )
                .unwrap()
            })
            .collect();
        let mut x = 7u64;
        let masks: Vec<u8> = (0..3 * camera.pixel_count())
            .map(|_| u8::from(xorshift(&mut x).is_multiple_of(2)))
            .collect();
        let n = grid.voxel_count();
        let run = |threads: usize| {
            let (mut seg, mut vis) = (vec![0u32; n], vec![0u32; n]);
            carve_with_threads(&grid, &camera, &poses, &masks, &mut seg, &mut vis, threads)
                .unwrap();
            (seg, vis)
        };
        let one = run(1);
        assert!(one.1.iter().filter(|&&v| v > 0).count() > n / 10);
        for threads in [2, 3, 4] {
            assert_eq!(CarvePlan::new(65, 3, threads), CarvePlan::Slabs(threads));
            assert!(run(threads) == one, "{threads} threads");
        }
    }
}
