//! Non-maximum suppression of grasp-quality volumes, as in VGN's post-processing
//! (HEAPGrasp §IV-B: after smoothing, grasps are the local maxima above a threshold).
//!
//! # Window convention
//! A window of size `w` around index `i` covers offsets `-(w / 2) ..= w - 1 - w / 2` along
//! each axis (for `w = 4`: `-2..=1`), clipped to the grid. For finite values this equals
//! `scipy.ndimage.maximum_filter(volume, size=w, mode="reflect")`: reflected indices
//! always fall inside the clipped window, so reflection adds no new values.
//!
//! # NaN
//! The maximum ignores NaN (`f32::max` semantics): a window's maximum is the largest
//! non-NaN value in it, and NaN only when every value in it is NaN. NaN voxels are never
//! selected by [`nms3d`].
//!
//! # Algorithm
//! The filter is separable: three 1-D sliding-window maxima, along a, b, then c. Each
//! pass combines whole rows of a grid (elementwise maxima over contiguous memory): a
//! direct loop for windows of up to four, the van Herk / Gil-Werman prefix-suffix scheme
//! (three maxima per value, whatever the window) beyond. The a pass writes a transposed
//! `[b][a][c]` buffer so that both it and the b pass run in disjoint slabs on several
//! threads ([`crate::parallel`]); the result does not depend on the thread count.

use std::cmp::Ordering;

use crate::error::{Error, Result};
use crate::filter::check_cube;
use crate::parallel;

/// Clipped windows of at most this many voxels use the direct loop.
const DIRECT_MAX_WINDOW: usize = 4;

/// Volumes with at least this many voxels per thread are processed in parallel slabs.
const MIN_VOXELS_PER_THREAD: usize = 1 << 17;

/// The maximum over a `window`-sized neighbourhood of every voxel of a cubic `R³`
/// C-order volume: offsets `-(w / 2) ..= w - 1 - w / 2` per axis, clipped to the grid
/// (equal to `scipy.ndimage.maximum_filter(size=w, mode="reflect")` for finite values).
/// NaN values are ignored; a window holding only NaN gives NaN. A window larger than the
/// grid is allowed and simply clipped.
///
/// # Errors
/// [`Error::Value`] naming `resolution` when it is 0; [`Error::Shape`] naming `volume`
/// when `volume.len() != R³`; [`Error::Value`] naming `window` when it is 0.
///
/// # Example
/// ```
/// use heapgrasp_core::nms::maximum_filter3d;
/// let mut v = vec![0.0f32; 27];
/// v[0] = 2.0; // voxel [0, 0, 0] of a 3-cube
/// let m = maximum_filter3d(&v, 3, 3).unwrap();
/// assert_eq!(m[13], 2.0); // [1, 1, 1] sees [0, 0, 0]
/// assert_eq!(m[26], 0.0); // [2, 2, 2] does not
/// ```
pub fn maximum_filter3d(volume: &[f32], resolution: usize, window: usize) -> Result<Vec<f32>> {
    check_cube(volume, resolution)?;
    check_window(window)?;
    let threads = parallel::threads_for(volume.len(), MIN_VOXELS_PER_THREAD, resolution);
    Ok(max_filter_with_threads(volume, resolution, window, threads))
}

/// VGN-style non-maximum suppression: the indices `[a, b, c]` of the voxels whose value
/// is `>= threshold` and equal to the maximum of their window (see
/// [`maximum_filter3d`]), sorted by value descending, ties broken by flat index
/// `(a * R + b) * R + c` ascending (`-0.0` and `0.0` tie).
///
/// Every voxel of a plateau of equal values that is a window maximum is kept (as VGN's
/// `qual == maximum_filter(qual)` test does): NMS does not thin plateaus. NaN voxels are
/// never selected.
///
/// # Errors
/// [`Error::Value`] naming `resolution` when it is 0; [`Error::Shape`] naming `volume`
/// when `volume.len() != R³`; [`Error::Value`] naming `window` when it is 0, or
/// `threshold` when it is NaN.
///
/// # Example
/// ```
/// use heapgrasp_core::nms::nms3d;
/// let mut v = vec![0.0f32; 64];
/// v[(1 * 4 + 2) * 4 + 3] = 0.9;
/// v[(3 * 4 + 0) * 4 + 0] = 0.7;
/// let peaks = nms3d(&v, 4, 0.5, 3).unwrap();
/// assert_eq!(peaks, vec![[1, 2, 3], [3, 0, 0]]);
/// ```
pub fn nms3d(
    volume: &[f32],
    resolution: usize,
    threshold: f32,
    window: usize,
) -> Result<Vec<[usize; 3]>> {
    check_cube(volume, resolution)?;
    check_window(window)?;
    if threshold.is_nan() {
        return Err(Error::value("threshold", threshold, "must not be NaN"));
    }
    let threads = parallel::threads_for(volume.len(), MIN_VOXELS_PER_THREAD, resolution);
    let maxed = max_filter_with_threads(volume, resolution, window, threads);
    let plane = resolution * resolution;
    let mut peaks: Vec<(usize, f32)> = parallel::map_ranges(resolution, threads, |rows| {
        let span = rows.start * plane..rows.end * plane;
        volume[span.clone()]
            .iter()
            .zip(&maxed[span.clone()])
            .zip(span)
            .filter(|((&v, &m), _)| v >= threshold && v == m)
            .map(|((&v, _), i)| (i, v))
            .collect::<Vec<_>>()
    })
    .into_iter()
    .flatten()
    .collect();
    // No NaN is selected (`NaN >= t` is false), so partial_cmp never fails.
    peaks.sort_unstable_by(|x, y| {
        y.1.partial_cmp(&x.1)
            .unwrap_or(Ordering::Equal)
            .then(x.0.cmp(&y.0))
    });
    let r = resolution;
    Ok(peaks
        .into_iter()
        .map(|(i, _)| [i / plane, (i / r) % r, i % r])
        .collect())
}

fn check_window(window: usize) -> Result<()> {
    if window == 0 {
        return Err(Error::value("window", window, "must be >= 1"));
    }
    Ok(())
}

/// The maximum filter with validated inputs and an explicit thread count.
fn max_filter_with_threads(volume: &[f32], r: usize, window: usize, threads: usize) -> Vec<f32> {
    // Offsets beyond the grid add nothing: clip them so scratch stays O(R).
    let lo = (window / 2).min(r - 1);
    let hi = (window - 1 - window / 2).min(r - 1);
    if lo == 0 && hi == 0 {
        return volume.to_vec();
    }
    let plane = r * r;
    // Pass 1, axis a, into a transposed [b][a][c] buffer, in b slabs.
    let mut transposed = vec![0.0f32; volume.len()];
    parallel::for_each_row_chunk(&mut transposed, plane, threads, |rows, chunk| {
        let mut scratch = Scratch::default();
        for (b, dst) in rows.zip(chunk.chunks_exact_mut(plane)) {
            let lines = Lines {
                src: volume,
                first: b * r,
                stride: plane,
                len: r,
            };
            window_max(&lines, r, lo, hi, dst, &mut scratch);
        }
    });
    // Passes 2 and 3, axes b and c, back to [a][b][c], in a slabs.
    let mut out = vec![0.0f32; volume.len()];
    parallel::for_each_row_chunk(&mut out, plane, threads, |rows, chunk| {
        let mut scratch = Scratch::default();
        let mut row_copy = vec![0.0f32; r];
        for (a, dst) in rows.zip(chunk.chunks_exact_mut(plane)) {
            let lines = Lines {
                src: &transposed,
                first: a * r,
                stride: plane,
                len: r,
            };
            window_max(&lines, r, lo, hi, dst, &mut scratch);
            for row in dst.chunks_exact_mut(r) {
                row_copy.copy_from_slice(row);
                let lines = Lines {
                    src: &row_copy,
                    first: 0,
                    stride: 1,
                    len: 1,
                };
                window_max(&lines, r, lo, hi, row, &mut scratch);
            }
        }
    });
    out
}

/// `n` rows of `len` values: row `j` is `src[first + j * stride..][..len]`.
struct Lines<'a> {
    src: &'a [f32],
    first: usize,
    stride: usize,
    len: usize,
}

impl Lines<'_> {
    #[inline(always)]
    fn row(&self, j: usize) -> &[f32] {
        let s = self.first + j * self.stride;
        &self.src[s..s + self.len]
    }
}

/// Prefix and suffix buffers of the van Herk / Gil-Werman scheme, reused across calls.
#[derive(Default)]
struct Scratch {
    prefix: Vec<f32>,
    suffix: Vec<f32>,
}

#[inline(always)]
fn max_into(dst: &mut [f32], src: &[f32]) {
    dst.iter_mut().zip(src).for_each(|(d, &s)| *d = d.max(s));
}

/// Row `i` of `dst` (`n` rows of `lines.len` values) becomes the elementwise maximum
/// of rows `j` of `lines` for `j` in `[i - lo, i + hi] ∩ [0, n)`; `lo, hi < n`.
fn window_max(lines: &Lines, n: usize, lo: usize, hi: usize, dst: &mut [f32], s: &mut Scratch) {
    let len = lines.len;
    let w = lo + hi + 1;
    if w <= DIRECT_MAX_WINDOW {
        for (i, out) in dst.chunks_exact_mut(len).enumerate() {
            let start = i.saturating_sub(lo);
            let end = (i + hi).min(n - 1);
            out.copy_from_slice(lines.row(start));
            for j in start + 1..=end {
                max_into(out, lines.row(j));
            }
        }
        return;
    }
    // Padded index p = j + lo over 0..P, P = n + w - 1; rows outside 0..n are NaN, the
    // identity of f32::max. Blocks of w padded rows start at multiples of w; out[i] is
    // max(suffix[i], prefix[i + w - 1]), which together cover exactly p in i..i + w.
    let padded = n + w - 1;
    let nan_row = |buf: &mut [f32]| buf.fill(f32::NAN);
    s.prefix.resize(padded * len, f32::NAN);
    s.suffix.resize(padded * len, f32::NAN);
    for start in (0..padded).step_by(w) {
        let end = (start + w).min(padded);
        for p in start..end {
            let (before, cur) = s.prefix.split_at_mut(p * len);
            let cur = &mut cur[..len];
            match p.checked_sub(lo).filter(|&j| j < n) {
                Some(j) => cur.copy_from_slice(lines.row(j)),
                None => nan_row(cur),
            }
            if p > start {
                max_into(cur, &before[(p - 1) * len..]);
            }
        }
        for p in (start..end).rev() {
            let (cur, after) = s.suffix.split_at_mut((p + 1) * len);
            let cur = &mut cur[p * len..];
            match p.checked_sub(lo).filter(|&j| j < n) {
                Some(j) => cur.copy_from_slice(lines.row(j)),
                None => nan_row(cur),
            }
            if p + 1 < end {
                max_into(cur, &after[..len]);
            }
        }
    }
    for (i, out) in dst.chunks_exact_mut(len).enumerate() {
        out.copy_from_slice(&s.suffix[i * len..(i + 1) * len]);
        let q = i + w - 1;
        max_into(out, &s.prefix[q * len..(q + 1) * len]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn idx(r: usize, a: usize, b: usize, c: usize) -> usize {
        (a * r + b) * r + c
    }

    /// Brute-force window maximum (NaN ignored) at one voxel.
    fn naive_max(v: &[f32], r: usize, w: usize, p: [usize; 3]) -> f32 {
        let (lo, hi) = ((w / 2) as isize, (w - 1 - w / 2) as isize);
        let range = |x: usize| {
            let x = x as isize;
            ((x - lo).max(0) as usize)..=((x + hi).min(r as isize - 1) as usize)
        };
        let mut m = f32::NAN;
        for a in range(p[0]) {
            for b in range(p[1]) {
                for c in range(p[2]) {
                    m = m.max(v[idx(r, a, b, c)]);
                }
            }
        }
        m
    }

    fn naive_nms(v: &[f32], r: usize, t: f32, w: usize) -> Vec<[usize; 3]> {
        let mut out = Vec::new();
        for a in 0..r {
            for b in 0..r {
                for c in 0..r {
                    let x = v[idx(r, a, b, c)];
                    if x >= t && x == naive_max(v, r, w, [a, b, c]) {
                        out.push([a, b, c]);
                    }
                }
            }
        }
        out
    }

    fn same(x: f32, y: f32) -> bool {
        x == y || (x.is_nan() && y.is_nan())
    }

    #[test]
    fn single_peak_is_found() {
        let r = 6;
        let mut v = vec![0.1f32; r * r * r];
        v[idx(r, 2, 3, 4)] = 0.8;
        assert_eq!(nms3d(&v, r, 0.5, 3).unwrap(), vec![[2, 3, 4]]);
    }

    #[test]
    fn plateau_voxels_are_all_kept() {
        let r = 5;
        let mut v = vec![0.0f32; r * r * r];
        for (a, b) in [(1, 1), (1, 2), (2, 1), (2, 2)] {
            v[idx(r, a, b, 3)] = 0.6;
        }
        assert_eq!(
            nms3d(&v, r, 0.5, 3).unwrap(),
            vec![[1, 1, 3], [1, 2, 3], [2, 1, 3], [2, 2, 3]]
        );
    }

    #[test]
    fn close_peaks_keep_only_the_larger() {
        let r = 8;
        let mut v = vec![0.0f32; r * r * r];
        v[idx(r, 4, 4, 3)] = 0.9;
        v[idx(r, 4, 5, 5)] = 0.8; // 2 voxels away along c: inside a 5-window
        assert_eq!(nms3d(&v, r, 0.5, 5).unwrap(), vec![[4, 4, 3]]);
        // With a 3-window both are local maxima, sorted by value.
        assert_eq!(nms3d(&v, r, 0.5, 3).unwrap(), vec![[4, 4, 3], [4, 5, 5]]);
    }

    #[test]
    fn results_are_sorted_and_thresholded() {
        let r = 9;
        let mut v = vec![0.0f32; r * r * r];
        let peaks = [
            ([0, 0, 0], 0.3),
            ([8, 8, 8], 0.95),
            ([4, 0, 8], 0.7),
            ([0, 8, 4], 0.7),
            ([4, 4, 4], 0.5),
        ];
        for (p, x) in peaks {
            v[idx(r, p[0], p[1], p[2])] = x;
        }
        let got = nms3d(&v, r, 0.5, 3).unwrap();
        assert_eq!(got, vec![[8, 8, 8], [0, 8, 4], [4, 0, 8], [4, 4, 4]]);
        assert_eq!(nms3d(&v, r, 0.96, 3).unwrap(), Vec::<[usize; 3]>::new());
        // Threshold is inclusive.
        assert_eq!(nms3d(&v, r, 0.95, 3).unwrap(), vec![[8, 8, 8]]);
    }

    #[test]
    fn even_window_offsets_are_minus_two_to_plus_one() {
        // Values on one line of each axis: x[1] and x[3]. With w = 4 the window of i is
        // [i - 2, i + 1]: voxel 1 does not see voxel 3, voxel 3 sees voxel 1.
        let r = 6;
        for axis in 0..3 {
            let at = |i: usize| {
                let mut p = [0usize; 3];
                p[axis] = i;
                idx(r, p[0], p[1], p[2])
            };
            let unflat = |i: usize| {
                let mut p = [0usize; 3];
                p[axis] = i;
                p
            };
            let mut v = vec![0.0f32; r * r * r];
            v[at(1)] = 4.0;
            v[at(3)] = 5.0;
            let m = maximum_filter3d(&v, r, 4).unwrap();
            let line: Vec<f32> = (0..r).map(|i| m[at(i)]).collect();
            assert_eq!(line, vec![4.0, 4.0, 5.0, 5.0, 5.0, 5.0], "axis {axis}");
            assert_eq!(nms3d(&v, r, 1.0, 4).unwrap(), vec![unflat(3), unflat(1)]);
            v[at(1)] = 5.0;
            v[at(3)] = 4.0;
            let m = maximum_filter3d(&v, r, 4).unwrap();
            let line: Vec<f32> = (0..r).map(|i| m[at(i)]).collect();
            assert_eq!(line, vec![5.0, 5.0, 5.0, 5.0, 4.0, 4.0], "axis {axis}");
            assert_eq!(nms3d(&v, r, 1.0, 4).unwrap(), vec![unflat(1)]);
        }
    }

    #[test]
    fn filter_matches_brute_force_for_every_window() {
        let r = 7;
        let mut v: Vec<f32> = (0..r * r * r)
            .map(|i| ((i * 2654435761usize) % 97) as f32)
            .collect();
        v[idx(r, 3, 3, 3)] = f32::NAN;
        for w in 1..=16 {
            let one = max_filter_with_threads(&v, r, w, 1);
            let many = max_filter_with_threads(&v, r, w, 3);
            for a in 0..r {
                for b in 0..r {
                    for c in 0..r {
                        let i = idx(r, a, b, c);
                        let e = naive_max(&v, r, w, [a, b, c]);
                        assert!(same(one[i], e), "w {w} at {a} {b} {c}");
                        assert!(same(many[i], e));
                    }
                }
            }
        }
    }

    #[test]
    fn nan_is_never_selected_and_all_nan_windows_stay_nan() {
        let v = vec![f32::NAN; 8];
        assert!(maximum_filter3d(&v, 2, 2)
            .unwrap()
            .iter()
            .all(|x| x.is_nan()));
        assert!(nms3d(&v, 2, f32::NEG_INFINITY, 2).unwrap().is_empty());
        let mut v = vec![f32::NAN; 27];
        v[5] = -1.0;
        assert_eq!(nms3d(&v, 3, f32::NEG_INFINITY, 9).unwrap(), vec![[0, 1, 2]]);
    }

    #[test]
    fn invalid_inputs_are_rejected() {
        let v = vec![0.0f32; 8];
        assert!(matches!(
            nms3d(&v, 2, 0.5, 0),
            Err(Error::Value { ref name, .. }) if name == "window"
        ));
        assert!(matches!(
            maximum_filter3d(&v, 2, 0),
            Err(Error::Value { ref name, .. }) if name == "window"
        ));
        assert!(matches!(
            nms3d(&v, 2, f32::NAN, 3),
            Err(Error::Value { ref name, .. }) if name == "threshold"
        ));
        assert!(matches!(
            nms3d(&v, 3, 0.5, 3),
            Err(Error::Shape { ref name, .. }) if name == "volume"
        ));
        assert!(matches!(
            maximum_filter3d(&[], 0, 3),
            Err(Error::Value { ref name, .. }) if name == "resolution"
        ));
        assert_eq!(maximum_filter3d(&v, 2, 1000).unwrap(), vec![0.0; 8]);
    }

    fn volume_strategy() -> impl Strategy<Value = (usize, Vec<f32>)> {
        (1usize..6).prop_flat_map(|r| {
            let value = prop_oneof![
                8 => (0u8..6).prop_map(|k| f32::from(k) * 0.25),
                1 => Just(f32::NAN),
                2 => -1.0f32..2.0,
            ];
            (Just(r), proptest::collection::vec(value, r * r * r))
        })
    }

    proptest! {
        #[test]
        fn nms_equals_brute_force(
            (r, v) in volume_strategy(),
            w in 1usize..14,
            t in -0.5f32..1.5,
        ) {
            let got = nms3d(&v, r, t, w).unwrap();
            let m = maximum_filter3d(&v, r, w).unwrap();
            for a in 0..r {
                for b in 0..r {
                    for c in 0..r {
                        prop_assert!(same(m[idx(r, a, b, c)], naive_max(&v, r, w, [a, b, c])));
                    }
                }
            }
            for p in &got {
                let x = v[idx(r, p[0], p[1], p[2])];
                prop_assert!(x >= t);
                prop_assert_eq!(x, naive_max(&v, r, w, *p));
            }
            for pair in got.windows(2) {
                let (x, y) = (v[idx(r, pair[0][0], pair[0][1], pair[0][2])],
                              v[idx(r, pair[1][0], pair[1][1], pair[1][2])]);
                let (i, j) = (idx(r, pair[0][0], pair[0][1], pair[0][2]),
                              idx(r, pair[1][0], pair[1][1], pair[1][2]));
                prop_assert!(x > y || (x == y && i < j));
            }
            let mut sorted = got.clone();
            sorted.sort_unstable();
            prop_assert_eq!(sorted, naive_nms(&v, r, t, w));
        }
    }
}
