//! 3-D Gaussian smoothing of grasp-quality volumes (HEAPGrasp §IV-B: "we first smooth
//! the grasp scores with a 3-D Gaussian filter", VGN's post-processing).
//!
//! [`gaussian_filter3d`] reproduces
//! `scipy.ndimage.gaussian_filter(volume, sigma, mode="nearest", truncate=4.0)` on a
//! float32 cubic volume:
//! - kernel radius `r = int(4.0 * sigma + 0.5)`, weights `w[k] = exp(-0.5 / sigma² · k²)`
//!   for `k = -r..=r`, normalised to sum 1, all in f64 ([`gaussian_kernel1d`]);
//! - boundary mode "nearest": an index outside the grid is clamped to `0..R`;
//! - one 1-D pass per axis in scipy's order (a, then b, then c); each pass sums in f64
//!   and rounds its result to f32, exactly like scipy's `correlate1d` writing into a
//!   float32 output between passes. Only the summation order differs, so results agree
//!   with scipy to about one f32 ulp (~1e-7 relative);
//! - `sigma <= 1e-15` filters nothing (scipy skips such axes): the result is a copy.
//!
//! The a pass combines whole b-c planes and the b pass whole c rows (vectorisable
//! multiply-adds over contiguous memory); the c pass walks a clamped, padded copy of each
//! row. Large volumes are processed in slabs of the a axis on several threads
//! ([`crate::parallel`]); the result does not depend on the thread count.

use crate::error::{Error, Result};
use crate::parallel;

/// Kernel half-width in units of sigma (scipy's `truncate`).
pub const TRUNCATE: f64 = 4.0;

/// Largest accepted kernel radius `int(4 sigma + 0.5)`; larger sigmas are rejected.
pub const MAX_RADIUS: usize = 1000;

/// Sigmas at or below this filter nothing (scipy's threshold).
const SIGMA_EPS: f64 = 1e-15;

/// Volumes with at least this many voxels per thread are filtered in parallel slabs.
const MIN_VOXELS_PER_THREAD: usize = 1 << 17;

/// The normalised 1-D Gaussian kernel scipy uses for `sigma`, `truncate = 4.0`:
/// `2r + 1` weights for offsets `-r..=r`, `r = int(4 sigma + 0.5)`, summing to 1.
///
/// # Errors
/// [`Error::Value`] naming `sigma` when sigma is NaN, infinite, negative, or so large
/// that the radius would exceed [`MAX_RADIUS`].
///
/// # Example
/// ```
/// use heapgrasp_core::filter::gaussian_kernel1d;
/// let w = gaussian_kernel1d(1.0).unwrap();
/// assert_eq!(w.len(), 9); // radius int(4.5) = 4
/// assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
/// assert!(gaussian_kernel1d(-1.0).is_err());
/// ```
pub fn gaussian_kernel1d(sigma: f64) -> Result<Vec<f64>> {
    let radius = kernel_radius(sigma)?;
    if sigma <= SIGMA_EPS {
        return Ok(vec![1.0]);
    }
    let sigma2 = sigma * sigma;
    let mut w: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let x = i as f64 - radius as f64;
            (-0.5 / sigma2 * (x * x)).exp()
        })
        .collect();
    let sum: f64 = w.iter().sum();
    w.iter_mut().for_each(|x| *x /= sum);
    Ok(w)
}

/// Validates sigma and returns the kernel radius `int(4 sigma + 0.5)`.
fn kernel_radius(sigma: f64) -> Result<usize> {
    if !(sigma.is_finite() && sigma >= 0.0) {
        return Err(Error::value("sigma", sigma, "must be finite and >= 0"));
    }
    let r = (TRUNCATE * sigma + 0.5).floor();
    if r > MAX_RADIUS as f64 {
        return Err(Error::value(
            "sigma",
            sigma,
            format!("kernel radius int(4 sigma + 0.5) must not exceed {MAX_RADIUS}"),
        ));
    }
    Ok(r as usize)
}

/// Checks that `volume` is a flat cubic `R³` buffer.
pub(crate) fn check_cube(volume: &[f32], resolution: usize) -> Result<()> {
    if resolution == 0 {
        return Err(Error::value("resolution", resolution, "must be >= 1"));
    }
    let expected = resolution
        .checked_mul(resolution)
        .and_then(|x| x.checked_mul(resolution));
    if expected != Some(volume.len()) {
        let r = resolution;
        return Err(Error::shape(
            "volume",
            format!("({r}, {r}, {r})"),
            format!("{} values", volume.len()),
        ));
    }
    Ok(())
}

/// Smooths a cubic `R³` C-order volume with a 3-D Gaussian, like
/// `scipy.ndimage.gaussian_filter(volume, sigma, mode="nearest", truncate=4.0)` on
/// float32 data (see the [module docs](self) for the exact arithmetic).
///
/// Non-finite values are allowed: a NaN or infinity spreads to every voxel within the
/// kernel radius of it along the filtered axes, as in scipy (`inf - inf` gives NaN).
///
/// # Errors
/// [`Error::Value`] naming `resolution` when it is 0; [`Error::Shape`] naming `volume`
/// when `volume.len() != R³`; [`Error::Value`] naming `sigma` when sigma is NaN,
/// infinite, negative, or gives a radius above [`MAX_RADIUS`].
///
/// # Example
/// ```
/// use heapgrasp_core::filter::gaussian_filter3d;
/// let mut v = vec![0.0f32; 27];
/// v[13] = 1.0; // centre of a 3x3x3 volume
/// let s = gaussian_filter3d(&v, 3, 0.5).unwrap();
/// assert!(s[13] < 1.0 && s[0] > 0.0);
/// assert_eq!(s[0], s[26]); // symmetric corners
/// assert_eq!(gaussian_filter3d(&v, 3, 0.0).unwrap(), v);
/// ```
pub fn gaussian_filter3d(volume: &[f32], resolution: usize, sigma: f64) -> Result<Vec<f32>> {
    check_cube(volume, resolution)?;
    let weights = gaussian_kernel1d(sigma)?;
    let threads = parallel::threads_for(volume.len(), MIN_VOXELS_PER_THREAD, resolution);
    Ok(filter_with_threads(volume, resolution, &weights, threads))
}

/// The filter proper, with validated inputs and an explicit thread count.
fn filter_with_threads(volume: &[f32], r: usize, weights: &[f64], threads: usize) -> Vec<f32> {
    if weights.len() == 1 {
        return volume.to_vec();
    }
    let plane = r * r;
    let mut out = vec![0.0f32; volume.len()];
    // Pass 1, axis a: output plane a is the weighted sum of input planes clamp(a + k).
    parallel::for_each_row_chunk(&mut out, plane, threads, |rows, chunk| {
        let mut acc = vec![0.0f64; plane];
        for (a, dst) in rows.zip(chunk.chunks_exact_mut(plane)) {
            weighted_rows(
                |j| &volume[j * plane..(j + 1) * plane],
                a,
                r,
                weights,
                &mut acc,
            );
            dst.iter_mut().zip(&acc).for_each(|(d, &s)| *d = s as f32);
        }
    });
    // Passes 2 and 3, axes b and c, plane by plane in place.
    parallel::for_each_row_chunk(&mut out, plane, threads, |_, chunk| {
        let mut scratch = vec![0.0f32; plane];
        let mut acc = vec![0.0f64; r];
        let radius = weights.len() / 2;
        let mut padded = vec![0.0f64; r + 2 * radius];
        for p in chunk.chunks_exact_mut(plane) {
            scratch.copy_from_slice(p);
            for (b, dst) in p.chunks_exact_mut(r).enumerate() {
                weighted_rows(|j| &scratch[j * r..(j + 1) * r], b, r, weights, &mut acc);
                dst.iter_mut().zip(&acc).for_each(|(d, &s)| *d = s as f32);
            }
            for row in p.chunks_exact_mut(r) {
                filter_row(row, weights, &mut padded);
            }
        }
    });
    out
}

/// `acc = Σ_k weights[k] · row(clamp(i + k - radius, 0, n - 1))`, where `row(j)` gives
/// row `j` of `n` rows, each `acc.len()` long.
#[inline]
fn weighted_rows<'a>(
    row: impl Fn(usize) -> &'a [f32],
    i: usize,
    n: usize,
    weights: &[f64],
    acc: &mut [f64],
) {
    let radius = weights.len() / 2;
    acc.fill(0.0);
    for (k, &w) in weights.iter().enumerate() {
        let j = (i + k).saturating_sub(radius).min(n - 1);
        for (s, &x) in acc.iter_mut().zip(row(j)) {
            *s += w * f64::from(x);
        }
    }
}

/// Filters one contiguous row in place with nearest-boundary padding.
/// `padded` must hold `row.len() + weights.len() - 1` values.
#[inline]
fn filter_row(row: &mut [f32], weights: &[f64], padded: &mut [f64]) {
    let n = row.len();
    let radius = weights.len() / 2;
    let (first, last) = (f64::from(row[0]), f64::from(row[n - 1]));
    padded[..radius].fill(first);
    padded[radius + n..].fill(last);
    for (p, &x) in padded[radius..radius + n].iter_mut().zip(row.iter()) {
        *p = f64::from(x);
    }
    for (c, dst) in row.iter_mut().enumerate() {
        let s: f64 = padded[c..c + weights.len()]
            .iter()
            .zip(weights)
            .map(|(&x, &w)| w * x)
            .sum();
        *dst = s as f32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn idx(r: usize, a: usize, b: usize, c: usize) -> usize {
        (a * r + b) * r + c
    }

    fn close(x: f32, y: f64, rel: f64) -> bool {
        (f64::from(x) - y).abs() <= rel * y.abs().max(1e-30) + 1e-12
    }

    /// Naive scipy-equivalent reference: three f64 passes rounded to f32 in between.
    fn reference(v: &[f32], r: usize, sigma: f64) -> Vec<f32> {
        let w = gaussian_kernel1d(sigma).unwrap();
        let rad = w.len() / 2;
        let clamp = |i: isize| i.clamp(0, r as isize - 1) as usize;
        let mut cur = v.to_vec();
        for axis in 0..3 {
            let mut next = vec![0.0f32; cur.len()];
            for a in 0..r {
                for b in 0..r {
                    for c in 0..r {
                        let mut s = 0.0f64;
                        for (k, &wk) in w.iter().enumerate() {
                            let o = k as isize - rad as isize;
                            let mut p = [a as isize, b as isize, c as isize];
                            p[axis] += o;
                            let j = idx(r, clamp(p[0]), clamp(p[1]), clamp(p[2]));
                            s += wk * f64::from(cur[j]);
                        }
                        next[idx(r, a, b, c)] = s as f32;
                    }
                }
            }
            cur = next;
        }
        cur
    }

    #[test]
    fn kernel_matches_scipy_definition() {
        assert_eq!(gaussian_kernel1d(0.0).unwrap(), vec![1.0]);
        assert_eq!(gaussian_kernel1d(0.1).unwrap().len(), 1); // int(0.9) = 0
        assert_eq!(gaussian_kernel1d(0.125).unwrap().len(), 3); // int(1.0) = 1
        let w = gaussian_kernel1d(2.0).unwrap();
        assert_eq!(w.len(), 17);
        let raw: Vec<f64> = (-8..=8)
            .map(|x: i32| (-0.5 / 4.0 * f64::from(x * x)).exp())
            .collect();
        let s: f64 = raw.iter().sum();
        for (a, b) in w.iter().zip(&raw) {
            assert!((a - b / s).abs() < 1e-16);
        }
    }

    #[test]
    fn constant_volume_stays_constant() {
        let r = 7;
        let v = vec![3.25f32; r * r * r];
        for sigma in [0.5, 1.0, 3.0] {
            let out = gaussian_filter3d(&v, r, sigma).unwrap();
            assert!(
                out.iter().all(|&x| (x - 3.25).abs() < 1e-6),
                "sigma {sigma}"
            );
        }
    }

    #[test]
    fn centred_impulse_gives_the_separable_gaussian() {
        let (r, sigma) = (13, 1.3); // radius int(5.7) = 5 < 6: no boundary effect
        let mut v = vec![0.0f32; r * r * r];
        v[idx(r, 6, 6, 6)] = 1.0;
        let out = gaussian_filter3d(&v, r, sigma).unwrap();
        let w = gaussian_kernel1d(sigma).unwrap();
        let wt = |i: usize| {
            let o = i as isize - 6 + (w.len() / 2) as isize;
            usize::try_from(o)
                .ok()
                .and_then(|o| w.get(o))
                .copied()
                .unwrap_or(0.0)
        };
        for a in 0..r {
            for b in 0..r {
                for c in 0..r {
                    let expected = wt(a) * wt(b) * wt(c);
                    let got = out[idx(r, a, b, c)];
                    assert!(
                        close(got, expected, 1e-6),
                        "{a} {b} {c}: {got} vs {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn sum_is_preserved_away_from_the_boundary() {
        let (r, sigma) = (16, 1.0); // radius 4
        let mut v = vec![0.0f32; r * r * r];
        let mut total = 0.0f64;
        for a in 5..11 {
            for b in 4..12 {
                for c in 6..10 {
                    let x = ((a * 7 + b * 3 + c) % 5) as f32 - 1.5;
                    v[idx(r, a, b, c)] = x;
                    total += f64::from(x);
                }
            }
        }
        let out = gaussian_filter3d(&v, r, sigma).unwrap();
        let sum: f64 = out.iter().map(|&x| f64::from(x)).sum();
        assert!((sum - total).abs() < 1e-4, "{sum} vs {total}");
    }

    #[test]
    fn nearest_boundary_on_a_3_cube() {
        // sigma 0.3: radius int(1.7) = 1, weights (e, 1, e) / (1 + 2e), e = exp(-0.5/0.09).
        let e = (-0.5f64 / 0.09).exp();
        let (w0, w1) = (1.0 / (1.0 + 2.0 * e), e / (1.0 + 2.0 * e));
        // Volume varying along c only: [1, 0, 0]; a and b passes leave it unchanged.
        let mut v = vec![0.0f32; 27];
        for a in 0..3 {
            for b in 0..3 {
                v[idx(3, a, b, 0)] = 1.0;
            }
        }
        let out = gaussian_filter3d(&v, 3, 0.3).unwrap();
        // c = 0 sees x[clamp(-1)] = x[0] = 1, x[0] = 1, x[1] = 0.
        let expected = [w1 + w0, w1, 0.0];
        for a in 0..3 {
            for b in 0..3 {
                for (c, &e) in expected.iter().enumerate() {
                    assert!(close(out[idx(3, a, b, c)], e, 1e-6));
                }
            }
        }
    }

    #[test]
    fn nearest_boundary_on_a_5_cube_corner_impulse() {
        // sigma 0.5: radius int(2.5) = 2, weights w(k) ∝ exp(-2 k²).
        let raw: Vec<f64> = (0..3).map(|k| (-2.0 * f64::from(k * k)).exp()).collect();
        let s = raw[0] + 2.0 * (raw[1] + raw[2]);
        let (w0, w1, w2) = (raw[0] / s, raw[1] / s, raw[2] / s);
        // 1-D response of the impulse at 0 (resp. 4) with indices clamped to 0..5.
        let at0 = [w0 + w1 + w2, w1 + w2, w2, 0.0, 0.0];
        let at1 = [w1, w0, w1, w2, 0.0]; // impulse at 1: only offset +1 reaches it from 0
        let at4 = [0.0, 0.0, w2, w1 + w2, w0 + w1 + w2];
        let mut v = vec![0.0f32; 125];
        v[idx(5, 0, 1, 4)] = 1.0;
        let out = gaussian_filter3d(&v, 5, 0.5).unwrap();
        for a in 0..5 {
            for b in 0..5 {
                for c in 0..5 {
                    let e = at0[a] * at1[b] * at4[c];
                    let got = out[idx(5, a, b, c)];
                    assert!(close(got, e, 1e-6), "{a} {b} {c}: {got} vs {e}");
                }
            }
        }
        // Hand value at the impulse itself.
        assert!(close(
            out[idx(5, 0, 1, 4)],
            (w0 + w1 + w2) * w0 * (w0 + w1 + w2),
            1e-6
        ));
    }

    #[test]
    fn matches_the_naive_reference_and_is_thread_independent() {
        let r = 9;
        let v: Vec<f32> = (0..r * r * r)
            .map(|i| ((i * 2654435761usize) % 1000) as f32 / 100.0 - 3.0)
            .collect();
        for sigma in [0.4, 1.0, 2.6] {
            let w = gaussian_kernel1d(sigma).unwrap();
            let expected = reference(&v, r, sigma);
            let one = filter_with_threads(&v, r, &w, 1);
            let many = filter_with_threads(&v, r, &w, 4);
            assert_eq!(one, many);
            for (x, y) in one.iter().zip(&expected) {
                assert!((x - y).abs() <= 2e-6 * y.abs().max(1.0), "{x} vs {y}");
            }
        }
    }

    #[test]
    fn radius_wider_than_the_grid_clamps() {
        let v: Vec<f32> = (0..8).map(|i| i as f32).collect();
        let out = gaussian_filter3d(&v, 2, 3.0).unwrap(); // radius 12 on a 2-cube
        let expected = reference(&v, 2, 3.0);
        for (x, y) in out.iter().zip(&expected) {
            assert!((x - y).abs() < 1e-6);
        }
    }

    #[test]
    fn zero_sigma_is_identity() {
        let v: Vec<f32> = (0..64).map(|i| (i as f32).sin()).collect();
        assert_eq!(gaussian_filter3d(&v, 4, 0.0).unwrap(), v);
        assert_eq!(gaussian_filter3d(&v, 4, 1e-16).unwrap(), v);
    }

    #[test]
    fn non_finite_values_propagate() {
        let mut v = vec![1.0f32; 125];
        v[idx(5, 2, 2, 2)] = f32::NAN;
        let out = gaussian_filter3d(&v, 5, 0.3).unwrap(); // radius 1
        assert!(out[idx(5, 2, 2, 3)].is_nan());
        assert!(out[idx(5, 3, 3, 3)].is_nan());
        assert!(out[idx(5, 0, 2, 2)].is_finite());
    }

    #[test]
    fn invalid_inputs_are_rejected() {
        let v = vec![0.0f32; 27];
        for sigma in [f64::NAN, -0.5, f64::INFINITY, 1e6, 1e300] {
            assert!(
                matches!(gaussian_filter3d(&v, 3, sigma), Err(Error::Value { ref name, .. }) if name == "sigma"),
                "sigma {sigma}"
            );
        }
        assert!(gaussian_filter3d(&v, 3, 249.0).is_ok()); // radius 996
        assert!(matches!(
            gaussian_filter3d(&v, 4, 1.0),
            Err(Error::Shape { ref name, .. }) if name == "volume"
        ));
        assert!(matches!(
            gaussian_filter3d(&[], 0, 1.0),
            Err(Error::Value { ref name, .. }) if name == "resolution"
        ));
        assert!(matches!(
            gaussian_filter3d(&v, usize::MAX, 1.0),
            Err(Error::Shape { .. })
        ));
    }

    proptest! {
        #[test]
        fn output_stays_within_input_range(
            r in 1usize..6,
            sigma in 0.0f64..3.0,
            seed in proptest::collection::vec(-100.0f32..100.0, 216),
        ) {
            let v = &seed[..r * r * r];
            let out = gaussian_filter3d(v, r, sigma).unwrap();
            let lo = v.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            let tol = 1e-6 * lo.abs().max(hi.abs());
            for &x in &out {
                prop_assert!(x >= lo - tol && x <= hi + tol, "{} not in [{}, {}]", x, lo, hi);
            }
        }
    }
}
