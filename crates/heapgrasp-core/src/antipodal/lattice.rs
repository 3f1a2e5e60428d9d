//! The occupancy grid resampled on a lattice aligned with one TCP orientation, and the
//! row and box operations the antipodal tests are made of.
//!
//! Lattice axes: 0 = TCP x (across the fingers), 1 = TCP y (the closing axis, "rows"),
//! 2 = TCP z (the approach). Every gripper part is then an axis-aligned box, and every
//! test a box sum or a scan along a row.

use crate::rounding::floor_fast;

/// Tolerance (voxels) under which a lattice cell aligned with a voxel overlaps only it.
pub(crate) const ALIGN_TOL: f64 = 0.05;
/// Slack of floor/ceil conversions from metres to cells.
pub(crate) const EPS: f64 = 1e-9;

/// A dense 3-D array in C order (`[i, j, k]` at `(i * b + j) * c + k`).
#[derive(Debug, Clone)]
pub(crate) struct Vol<T> {
    pub a: usize,
    pub b: usize,
    pub c: usize,
    pub data: Vec<T>,
}

impl<T: Copy> Vol<T> {
    pub fn filled(a: usize, b: usize, c: usize, value: T) -> Self {
        Self {
            a,
            b,
            c,
            data: vec![value; a * b * c],
        }
    }

    #[inline(always)]
    pub fn idx(&self, i: usize, j: usize, k: usize) -> usize {
        (i * self.b + j) * self.c + k
    }

    #[inline(always)]
    pub fn at(&self, i: usize, j: usize, k: usize) -> T {
        self.data[self.idx(i, j, k)]
    }
}

#[inline(always)]
pub(crate) fn clampi(x: i64, lo: i64, hi: i64) -> i64 {
    x.max(lo).min(hi)
}

/// What every orientation shares: the padded occupancy (two empty layers around), and
/// the voxel centres of the occupied voxels and of the candidate TCPs (relative to the
/// grid origin).
pub(crate) struct Shared {
    pub r: usize,
    pub v: f64,
    /// Side of the padded grid: `r + 4`.
    pub n: usize,
    pub padded: Vec<bool>,
    /// Occupied voxels on the grid's four side faces, padded; `None` if there are none.
    pub side: Option<Vec<bool>>,
    pub occ_centres: Vec<[f64; 3]>,
    pub cand_centres: Vec<[f64; 3]>,
}

impl Shared {
    pub fn new(occ: &[bool], r: usize, v: f64, cand: &[[usize; 3]]) -> Self {
        let n = r + 4;
        let pidx = |a: usize, b: usize, c: usize| (a * n + b) * n + c;
        let mut padded = vec![false; n * n * n];
        let mut side = vec![false; n * n * n];
        let mut any_side = false;
        let mut occ_centres = Vec::new();
        for a in 0..r {
            for b in 0..r {
                for c in 0..r {
                    if occ[(a * r + b) * r + c] {
                        padded[pidx(a + 2, b + 2, c + 2)] = true;
                        occ_centres.push([
                            (a as f64 + 0.5) * v,
                            (b as f64 + 0.5) * v,
                            (c as f64 + 0.5) * v,
                        ]);
                        if a == 0 || a == r - 1 || b == 0 || b == r - 1 {
                            side[pidx(a + 2, b + 2, c + 2)] = true;
                            any_side = true;
                        }
                    }
                }
            }
        }
        let cand_centres = cand
            .iter()
            .map(|p| p.map(|x| (x as f64 + 0.5) * v))
            .collect();
        Self {
            r,
            v,
            n,
            padded,
            side: any_side.then_some(side),
            occ_centres,
            cand_centres,
        }
    }
}

/// `p @ rot`: a point in grid axes to TCP-aligned axes.
#[inline(always)]
pub(crate) fn to_tcp(p: &[f64; 3], rot: &[[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|j| p[0] * rot[0][j] + p[1] * rot[1][j] + p[2] * rot[2][j])
}

/// `u @ rot.T`: TCP-aligned axes back to grid axes.
#[inline(always)]
pub(crate) fn to_grid(u: &[f64; 3], rot: &[[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|w| u[0] * rot[w][0] + u[1] * rot[w][1] + u[2] * rot[w][2])
}

/// The grid resampled along one TCP orientation.
pub(crate) struct Lattice {
    /// Centre of cell (0, 0, 0) in TCP-aligned coordinates relative to the grid origin.
    pub lo: [f64; 3],
    /// Occupied when the cell's cube overlaps an occupied voxel (conservative).
    pub q: Vol<bool>,
    /// Occupied when the cell's centre lies in an occupied voxel.
    pub q_nn: Vol<bool>,
    /// Like `q_nn` for the occupied voxels on the grid's side faces.
    pub side: Option<Vol<bool>>,
}

impl Lattice {
    /// Resamples the grid on a lattice along the TCP axes covering every occupied voxel
    /// and candidate, with one cell of margin.
    pub fn new(sh: &Shared, rot: &[[f64; 3]; 3]) -> Self {
        let v = sh.v;
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in sh.occ_centres.iter().chain(&sh.cand_centres) {
            let u = to_tcp(p, rot);
            for d in 0..3 {
                lo[d] = lo[d].min(u[d]);
                hi[d] = hi[d].max(u[d]);
            }
        }
        for d in 0..3 {
            lo[d] -= v;
            hi[d] += v;
        }
        let dims: [usize; 3] =
            std::array::from_fn(|d| floor_fast((hi[d] - lo[d]) / v + EPS).max(0.0) as usize + 1);
        let [a, b, c] = dims;
        // Voxel coordinate of each cell centre along grid axis w (voxel centres at
        // integers): (A_w[i] + B_w[j]) + C_w[k].
        let axis = |d: usize, w: usize, len: usize, shift: f64| -> Vec<f64> {
            (0..len)
                .map(|i| (lo[d] + v * i as f64) * (rot[w][d] / v) - shift)
                .collect()
        };
        let ax: Vec<[Vec<f64>; 3]> = (0..3)
            .map(|w| [axis(0, w, a, 0.0), axis(1, w, b, 0.0), axis(2, w, c, 0.5)])
            .collect();
        let n = sh.n as i64;
        let mut q = Vol::filled(a, b, c, false);
        let mut q_nn = Vol::filled(a, b, c, false);
        let mut side = sh.side.as_ref().map(|_| Vol::filled(a, b, c, false));
        let mut t = 0;
        for i in 0..a {
            for j in 0..b {
                for k in 0..c {
                    // Per grid axis: the lowest padded index of the voxels the cell's cube
                    // overlaps, how many more it overlaps (0 or 1; one voxel when the cell
                    // is within ALIGN_TOL of being aligned with it), and the voxel holding
                    // the cell's centre.
                    let mut lower = [0i64; 3];
                    let mut span = [0i64; 3];
                    let mut flat_nn = 0i64;
                    for (w, axw) in ax.iter().enumerate() {
                        let x = (axw[0][i] + axw[1][j]) + axw[2][k];
                        let lo_w = floor_fast(x + ALIGN_TOL) as i64;
                        let hi_w = floor_fast(x + (1.0 - ALIGN_TOL)) as i64;
                        lower[w] = clampi(lo_w + 2, 0, n - 1);
                        span[w] = hi_w - lo_w;
                        flat_nn = flat_nn * n + clampi(floor_fast(x + 0.5) as i64 + 2, 0, n - 1);
                    }
                    q.data[t] = overlaps(&sh.padded, sh.n, lower, span);
                    q_nn.data[t] = sh.padded[flat_nn as usize];
                    if let (Some(s), Some(src)) = (side.as_mut(), sh.side.as_ref()) {
                        s.data[t] = src[flat_nn as usize];
                    }
                    t += 1;
                }
            }
        }
        Self { lo, q, q_nn, side }
    }
}

/// Whether any padded voxel in `lower .. lower + span` (per axis, indices past the
/// grid's end ignored) is occupied.
#[inline(always)]
fn overlaps(padded: &[bool], n: usize, lower: [i64; 3], span: [i64; 3]) -> bool {
    let n_i = n as i64;
    for da in 0..=span[0] {
        let x = lower[0] + da;
        if x >= n_i {
            break;
        }
        for db in 0..=span[1] {
            let y = lower[1] + db;
            if y >= n_i {
                break;
            }
            let row = (x as usize * n + y as usize) * n;
            for dc in 0..=span[2] {
                let z = lower[2] + dc;
                if z >= n_i {
                    break;
                }
                if padded[row + z as usize] {
                    return true;
                }
            }
        }
    }
    false
}

/// 2-D integral over axes 0 and 2 with a leading zero plane: `(a + 1, b, c + 1)`.
pub(crate) fn integral_xz(q: &Vol<bool>) -> Vol<i32> {
    let (a, b, c) = (q.a, q.b, q.c);
    let mut s = Vol::filled(a + 1, b, c + 1, 0i32);
    for i in 0..a {
        for j in 0..b {
            for k in 0..c {
                let val = i32::from(q.at(i, j, k)) + s.at(i, j, k + 1) + s.at(i + 1, j, k)
                    - s.at(i, j, k);
                let t = s.idx(i + 1, j, k + 1);
                s.data[t] = val;
            }
        }
    }
    s
}

/// Whether the window `[di.0, di.1] × [dk.0, dk.1]` (axes 0 and 2) around each cell
/// holds an occupied cell; `s2` is [`integral_xz`].
pub(crate) fn band_any(s2: &Vol<i32>, di: (i64, i64), dk: (i64, i64)) -> Vol<bool> {
    let (a, b, c) = (s2.a - 1, s2.b, s2.c - 1);
    let mut out = Vol::filled(a, b, c, false);
    let kr: Vec<(usize, usize)> = (0..c as i64)
        .map(|k| {
            (
                clampi(k + dk.1 + 1, 0, c as i64) as usize,
                clampi(k + dk.0, 0, c as i64) as usize,
            )
        })
        .collect();
    for i in 0..a as i64 {
        let ih = clampi(i + di.1 + 1, 0, a as i64) as usize;
        let il = clampi(i + di.0, 0, a as i64) as usize;
        for j in 0..b {
            let sh = &s2.data[s2.idx(ih, j, 0)..][..c + 1];
            let sl = &s2.data[s2.idx(il, j, 0)..][..c + 1];
            let o = out.idx(i as usize, j, 0);
            for (k, &(kh, kl)) in kr.iter().enumerate() {
                out.data[o + k] = sh[kh] - sl[kh] - sh[kl] + sl[kl] > 0;
            }
        }
    }
    out
}

/// Cumulative count along axis 1 with a leading zero plane: `(a, b + 1, c)`.
pub(crate) fn cumsum_j(q: &Vol<bool>) -> Vol<i32> {
    let (a, b, c) = (q.a, q.b, q.c);
    let mut out = Vol::filled(a, b + 1, c, 0i32);
    for i in 0..a {
        for j in 0..b {
            for k in 0..c {
                let t = out.idx(i, j + 1, k);
                out.data[t] = out.at(i, j, k) + i32::from(q.at(i, j, k));
            }
        }
    }
    out
}

/// Rows `j` such that rows `j .. j + n - 1` are free (beyond the lattice is).
pub(crate) fn free_from(cum: &Vol<i32>, n: i64) -> Vol<bool> {
    let (a, b, c) = (cum.a, cum.b - 1, cum.c);
    let mut out = Vol::filled(a, b, c, false);
    for i in 0..a {
        for j in 0..b {
            let j2 = (j as i64 + n).min(b as i64) as usize;
            for k in 0..c {
                let t = out.idx(i, j, k);
                out.data[t] = cum.at(i, j2, k) == cum.at(i, j, k);
            }
        }
    }
    out
}

/// Rows `j` such that rows `j - n + 1 .. j` are free.
pub(crate) fn free_to(cum: &Vol<i32>, n: i64) -> Vol<bool> {
    let (a, b, c) = (cum.a, cum.b - 1, cum.c);
    let mut out = Vol::filled(a, b, c, false);
    for i in 0..a {
        for j in 0..b {
            let j0 = (j as i64 - n + 1).max(0) as usize;
            for k in 0..c {
                let t = out.idx(i, j, k);
                out.data[t] = cum.at(i, j + 1, k) == cum.at(i, j0, k);
            }
        }
    }
    out
}

/// Element-wise `x & y`.
pub(crate) fn and(x: &Vol<bool>, y: &Vol<bool>) -> Vol<bool> {
    Vol {
        a: x.a,
        b: x.b,
        c: x.c,
        data: x.data.iter().zip(&y.data).map(|(&p, &q)| p && q).collect(),
    }
}

/// Per cell, the first row `>= j` where `mask` holds (`b` if none).
pub(crate) fn next_true(mask: &Vol<bool>) -> Vol<i32> {
    let (a, b, c) = (mask.a, mask.b, mask.c);
    let mut out = Vol::filled(a, b, c, b as i32);
    for i in 0..a {
        for k in 0..c {
            let mut cur = b as i32;
            for j in (0..b).rev() {
                if mask.at(i, j, k) {
                    cur = j as i32;
                }
                let t = out.idx(i, j, k);
                out.data[t] = cur;
            }
        }
    }
    out
}

/// Per cell, the last row `<= j` where `mask` holds (-1 if none).
pub(crate) fn prev_true(mask: &Vol<bool>) -> Vol<i32> {
    let (a, b, c) = (mask.a, mask.b, mask.c);
    let mut out = Vol::filled(a, b, c, -1);
    for i in 0..a {
        for k in 0..c {
            let mut cur = -1;
            for j in 0..b {
                if mask.at(i, j, k) {
                    cur = j as i32;
                }
                let t = out.idx(i, j, k);
                out.data[t] = cur;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vol(a: usize, b: usize, c: usize, set: &[[usize; 3]]) -> Vol<bool> {
        let mut q = Vol::filled(a, b, c, false);
        for p in set {
            let t = q.idx(p[0], p[1], p[2]);
            q.data[t] = true;
        }
        q
    }

    #[test]
    fn band_any_finds_cells_in_the_window() {
        let q = vol(5, 3, 6, &[[2, 1, 3]]);
        let s2 = integral_xz(&q);
        let band = band_any(&s2, (-1, 1), (0, 2));
        for i in 0..5 {
            for j in 0..3 {
                for k in 0..6 {
                    let want = j == 1 && (1..=3).contains(&i) && (1..=3).contains(&k);
                    assert_eq!(band.at(i, j, k), want, "{i} {j} {k}");
                }
            }
        }
    }

    #[test]
    fn row_scans() {
        let q = vol(1, 6, 1, &[[0, 1, 0], [0, 4, 0]]);
        let next: Vec<i32> = next_true(&q).data;
        let prev: Vec<i32> = prev_true(&q).data;
        assert_eq!(next, vec![1, 1, 4, 4, 4, 6]);
        assert_eq!(prev, vec![-1, 1, 1, 1, 4, 4]);
        let cum = cumsum_j(&q);
        assert_eq!(cum.data, vec![0, 0, 1, 1, 1, 2, 2]);
        // Two free rows from j: rows 2-3 are; from 5 only one row is left, and beyond
        // the lattice counts as free.
        let ff: Vec<bool> = free_from(&cum, 2).data;
        assert_eq!(ff, vec![false, false, true, false, false, true]);
        let ft: Vec<bool> = free_to(&cum, 2).data;
        assert_eq!(ft, vec![true, false, false, true, false, false]);
    }

    #[test]
    fn an_axis_aligned_lattice_reproduces_the_grid() {
        let r = 6;
        let mut occ = vec![false; r * r * r];
        occ[(2 * r + 3) * r + 1] = true;
        occ[(3 * r + 3) * r + 1] = true;
        let sh = Shared::new(&occ, r, 0.01, &[[2, 3, 2]]);
        let eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let lat = Lattice::new(&sh, &eye);
        // lo is one cell below the lowest centre: voxel (2, 3, 1) is cell (1, 1, 1).
        let count = lat.q_nn.data.iter().filter(|&&x| x).count();
        assert_eq!(count, 2);
        assert!(lat.q_nn.at(1, 1, 1) && lat.q_nn.at(2, 1, 1));
        // Aligned cells overlap their own voxel only.
        assert_eq!(lat.q.data, lat.q_nn.data);
        assert!(lat.side.is_none());
    }
}
