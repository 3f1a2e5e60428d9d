//! Shape-from-Silhouette counting (HEAPGrasp §IV-A, the counts behind eq. 10).
//!
//! For every frame and every voxel, the voxel centre is projected into the frame: if it
//! lands inside the image the voxel's *visible* count `|I_rgb|` grows by one, and if the
//! pixel is set in the silhouette mask its *segmented* count `|I_seg|` grows too.
//!
//! The kernel walks grid columns `(a, b, ·)` (contiguous in memory) and, for each
//! column, all frames, so the column's counters stay in L1; masks are bit-packed so a
//! 320×240 frame takes 9.6 kB. Slabs of the x axis run on separate threads. A runtime
//! dispatch picks an AVX-512 or AVX2 build of the same loop where the CPU has one.

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
/// counts of `grid` (`segmented`, `visible`: flat R³ buffers).
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
    let threads = parallel::threads_for(voxels * n, 1 << 18, usize::MAX);
    let frame =
        |k: usize| PreparedFrame::new(grid, camera, &poses[k], &masks[k * px..(k + 1) * px]);
    if voxels <= FRAME_PARALLEL_MAX_VOXELS && n >= threads && threads > 1 {
        // The calling thread carves the first share of frames straight into the grid;
        // each other thread into private counts, summed at the end. (Fresh buffers cost
        // page faults, so only the extra threads allocate.)
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
                        carve_slab(grid, 0..grid.resolution(), &frames, &mut seg, &mut vis);
                        (seg, vis)
                    })
                })
                .collect();
            let own: Vec<_> = ranges[0].clone().map(&frame).collect();
            carve_slab(grid, 0..grid.resolution(), &own, segmented, visible);
            handles
                .into_iter()
                .map(|h| match h.join() {
                    Ok(v) => v,
                    Err(payload) => std::panic::resume_unwind(payload),
                })
                .collect::<Vec<_>>()
        });
        for (seg, vis) in partial {
            segmented.iter_mut().zip(&seg).for_each(|(d, s)| *d += s);
            visible.iter_mut().zip(&vis).for_each(|(d, s)| *d += s);
        }
    } else {
        let prep_threads = parallel::threads_for(masks.len(), 1 << 20, n);
        let frames: Vec<_> =
            parallel::map_ranges(n, prep_threads, |r| r.map(frame).collect::<Vec<_>>())
                .into_iter()
                .flatten()
                .collect();
        let r = grid.resolution();
        let slabs = threads.min(r);
        parallel::for_each_row_chunk_pair(segmented, visible, r * r, slabs, |rows, seg, vis| {
            carve_slab(grid, rows, &frames, seg, vis)
        });
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
        carve_column(
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
    let r = grid.resolution();
    for (local, a) in rows.enumerate() {
        for b in 0..r {
            let off = (local * r + b) * r;
            let seg_col = &mut seg[off..off + r];
            let vis_col = &mut vis[off..off + r];
            for f in frames {
                let col = f.projector.column(a, b);
                carve_column(&col, &f.projector.intr, &f.words, seg_col, vis_col);
            }
        }
    }
}

/// The inner loop over one column: vectorisable, branch-free.
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
        vis[c] += inside;
        seg[c] += mask_bit(words, idx) & inside;
    }
}

/// AVX-512 column loop: 16 voxels per step, a masked gather from the packed mask, and
/// `rcp14` refined by one Newton step in place of a divide (relative error ~1e-7, inside
/// the tolerance documented in [`crate::projector`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,bmi2")]
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
            _mm512_mask_storeu_epi32(
                vp.cast(),
                live,
                _mm512_mask_add_epi32(v_old, inside, v_old, one),
            );
            _mm512_mask_storeu_epi32(sp.cast(), live, _mm512_add_epi32(s_old, bit));
        }
        c0 += 16;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi2")]
fn carve_column_avx2(
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    carve_column_generic(col, intr, words, seg, vis)
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

/// The kernel build selected at run time (cached).
pub fn kernel_level() -> KernelLevel {
    use std::sync::OnceLock;
    static LEVEL: OnceLock<KernelLevel> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        if std::env::var_os("HEAPGRASP_NO_SIMD").is_some() {
            return KernelLevel::Baseline;
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512dq")
                && std::arch::is_x86_feature_detected!("fma")
                && std::arch::is_x86_feature_detected!("bmi2")
            {
                return KernelLevel::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::arch::is_x86_feature_detected!("bmi2")
            {
                return KernelLevel::Avx2;
            }
        }
        KernelLevel::Baseline
    })
}

#[inline]
fn carve_column(
    col: &Column,
    intr: &Intrinsics32,
    words: &[u32],
    seg: &mut [u32],
    vis: &mut [u32],
) {
    match kernel_level() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: kernel_level() returns Avx512 only when the CPU has every enabled feature.
        KernelLevel::Avx512 => unsafe { carve_column_avx512(col, intr, words, seg, vis) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, for the AVX2 feature set.
        KernelLevel::Avx2 => unsafe { carve_column_avx2(col, intr, words, seg, vis) },
        _ => carve_column_generic(col, intr, words, seg, vis),
    }
}
