//! Contact geometry of one candidate grasp on the nearest-voxel lattice (the
//! conservative one blurs flat tops and faces by half a voxel): engagement, ledge,
//! contact patches and normals (Natarajan et al. §3.3's patch and friction-cone constraints),
//! and the quality factors.

use super::lattice::{band_any, clampi, cumsum_j, integral_xz, next_true, prev_true, to_grid, Vol};
use super::{ramp, GripperCells, Orientation};
use crate::antipodal::lattice::{Lattice, EPS};
use crate::rounding::{ceil_fast, floor_fast};

/// Ridge (cells²) on the slopes of the contact-plane fit: a patch one voxel high is
/// taken as parallel to the approach.
const RIDGE: f64 = 1.0;
/// The plane is fitted over the columns whose extreme lies within this many cells of
/// the contact.
const FIT_ROWS: i64 = 3;
/// Levels below the fingertips searched for a ledge.
const LEDGE_LEVELS: i64 = 2;
/// Contact levels of a flat contact.
const FLAT_LEVELS: i64 = 2;

/// Whole-lattice tables of the nearest-voxel lattice.
pub(super) struct NearestTables {
    band_next: Vol<i32>,
    band_prev: Vol<i32>,
    /// Cumulative count along rows of "the pad's x band holds object".
    c_x: Vol<i32>,
    /// Last / first occupied row `<= j` / `>= j`.
    last: Vol<i32>,
    first: Vol<i32>,
}

impl NearestTables {
    pub fn new(q_nn: &Vol<bool>, cells: &GripperCells) -> Self {
        let band = band_any(&integral_xz(q_nn), cells.x_pad, cells.z_contact);
        let (a, b, c) = (q_nn.a, q_nn.b, q_nn.c);
        // s1[i + 1] = Σ_{i' <= i} q_nn[i'].
        let mut s1 = Vol::filled(a + 1, b, c, 0i32);
        for i in 0..a {
            for j in 0..b {
                for k in 0..c {
                    let t = s1.idx(i + 1, j, k);
                    s1.data[t] = s1.at(i, j, k) + i32::from(q_nn.at(i, j, k));
                }
            }
        }
        let mut band_x = Vol::filled(a, b, c, false);
        for i in 0..a as i64 {
            let ih = clampi(i + cells.x_pad.1 + 1, 0, a as i64) as usize;
            let il = clampi(i + cells.x_pad.0, 0, a as i64) as usize;
            for j in 0..b {
                for k in 0..c {
                    let t = band_x.idx(i as usize, j, k);
                    band_x.data[t] = s1.at(ih, j, k) - s1.at(il, j, k) > 0;
                }
            }
        }
        Self {
            band_next: next_true(&band),
            band_prev: prev_true(&band),
            c_x: cumsum_j(&band_x),
            last: prev_true(q_nn),
            first: next_true(q_nn),
        }
    }
}

/// A candidate that passed the closing and approach tests.
pub(super) struct Candidate {
    pub ic: i64,
    pub jc: i64,
    pub kc: i64,
    pub hi_row: i64,
    pub lo_row: i64,
    /// Half the executed opening (m).
    pub h_act: f64,
}

/// Quality in [0, 1] without the centring factor, or `None` if the contacts fail.
pub(super) fn quality(
    o: &Orientation<'_>,
    lat: &Lattice,
    t: &NearestTables,
    cand: &Candidate,
) -> Option<f64> {
    let p = o.p;
    let cells = o.cells;
    let v = p.voxel_size;
    let (a, b, c) = (lat.q_nn.a as i64, lat.q_nn.b as i64, lat.q_nn.c as i64);
    let Candidate {
        ic,
        jc,
        kc,
        hi_row,
        lo_row,
        h_act,
    } = *cand;
    let (icu, kcu) = (ic as usize, kc as usize);
    let y_hi = i64::from(t.band_prev.at(icu, clampi(hi_row, 0, b - 1) as usize, kcu));
    let y_lo = i64::from(t.band_next.at(icu, clampi(lo_row, 0, b - 1) as usize, kcu));
    if !(y_hi >= lo_row && y_lo <= hi_row) {
        return None;
    }

    // Engagement: levels of the pad holding object between the contacts.
    let hi1 = clampi(y_hi + 1, 0, b) as usize;
    let mut levels = 0i64;
    // Only the levels inside the lattice count: scan just those (a gripper can be far
    // longer than the lattice).
    for dk in cells.z_contact.0.max(-kc)..=cells.z_contact.1.min(c - 1 - kc) {
        let k = (kc + dk) as usize;
        if t.c_x.at(icu, hi1, k) > t.c_x.at(icu, y_lo as usize, k) {
            levels += 1;
        }
    }
    let depth = levels as f64 * v;
    if !(depth >= p.min_depth - EPS) {
        return None;
    }

    // Ledge below the fingertips, under the fingers or between them and the contacts.
    let out_rows = ceil_fast((h_act + p.hand.base_thickness) / v) as i64;
    let (hi_a, hi_b) = (clampi(y_hi + 1, 0, b), clampi(jc + out_rows + 1, 0, b));
    let (lo_a, lo_b) = (clampi(jc - out_rows, 0, b), clampi(y_lo, 0, b));
    let mut ledge = false;
    for dk in cells.z_contact.1 + 1..cells.z_contact.1 + 1 + LEDGE_LEVELS {
        let k = kc + dk;
        if k < 0 || k >= c {
            continue;
        }
        let k = k as usize;
        let above = t.c_x.at(icu, hi_a.max(hi_b) as usize, k) > t.c_x.at(icu, hi_a as usize, k);
        let below = t.c_x.at(icu, lo_a.max(lo_b) as usize, k) > t.c_x.at(icu, lo_a as usize, k);
        ledge |= above || below;
    }

    // Contact patches and normals of both fingers.
    let rot = o.rot;
    let yw = [rot[0][1], rot[1][1], rot[2][1]];
    let xw = [rot[0][0], rot[1][0], rot[2][0]];
    let r = o.sh.r as i64;
    let nk = (cells.z_contact.1 - cells.z_contact.0 + 1).max(0) as usize;
    let mut n_patch = [0i64; 2];
    let mut levels_side = [0i64; 2];
    let mut cos_side = [0.0f64; 2];
    for (side, (sgn, ext, table)) in [(1i64, y_hi, &t.last), (-1, y_lo, &t.first)]
        .into_iter()
        .enumerate()
    {
        let (mut sw, mut sx, mut sz, mut sxx, mut szz, mut sxz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut r0, mut r1, mut r2) = (0.0, 0.0, 0.0);
        let mut gsum = [0.0f64; 3];
        let mut level_hit = vec![false; nk];
        // The cells of the pad inside the lattice (the others hold nothing).
        for di in cells.x_fit.0.max(-ic)..=cells.x_fit.1.min(a - 1 - ic) {
            let on_pad = di >= cells.x_pad.0 && di <= cells.x_pad.1;
            let i3 = ic + di;
            for dk in cells.z_contact.0.max(-kc)..=cells.z_contact.1.min(c - 1 - kc) {
                let kn = (dk - cells.z_contact.0) as usize;
                let k3 = kc + dk;
                let (iu, ku) = (i3 as usize, k3 as usize);
                let row = i64::from(table.at(iu, ext as usize, ku));
                let depth_in = sgn * (row - ext);
                if on_pad && depth_in >= -1 {
                    n_patch[side] += 1;
                    // Tilt across the finger: occupancy gradients on the patch.
                    let u: [f64; 3] = std::array::from_fn(|d| {
                        let idx = [i3, row, k3][d] as f64;
                        lat.lo[d] + v * idx
                    });
                    let w = to_grid(&u, rot);
                    let vox = w.map(|x| clampi(floor_fast(x / v) as i64, 0, r - 1) as usize);
                    let r3 = o.sh.r * o.sh.r * o.sh.r;
                    let flat = (vox[0] * o.sh.r + vox[1]) * o.sh.r + vox[2];
                    for (d, g) in gsum.iter_mut().enumerate() {
                        *g += o.scene.gradient[d * r3 + flat];
                    }
                }
                if on_pad && depth_in == 0 {
                    level_hit[kn] = true;
                }
                if depth_in >= -FIT_ROWS {
                    // Plane fitted to the extremes (all sums are of small integers).
                    let (x, z, rr) = (di as f64, dk as f64, depth_in as f64);
                    sw += 1.0;
                    sx += x;
                    sz += z;
                    sxx += x * x;
                    szz += z * z;
                    sxz += x * z;
                    r0 += rr;
                    r1 += x * rr;
                    r2 += z * rr;
                }
            }
        }
        levels_side[side] = level_hit.iter().filter(|&&h| h).count() as i64;
        let coef = solve3(
            [
                [sw + 1e-9, sx, sz],
                [sx, sxx + RIDGE, sxz],
                [sz, sxz, szz + RIDGE],
            ],
            [r0, r1, r2],
        );
        let gx = (gsum[0] * xw[0] + gsum[1] * xw[1] + gsum[2] * xw[2]).abs();
        let gy = (gsum[0] * yw[0] + gsum[1] * yw[1] + gsum[2] * yw[2]).abs();
        let tan_x = (gx / gy.max(1e-12)).max(coef[1].abs());
        cos_side[side] = 1.0 / (1.0 + tan_x * tan_x + coef[2] * coef[2]).sqrt();
    }
    let patch = n_patch[0].min(n_patch[1]);
    if patch < p.min_patch {
        return None;
    }
    let min_levels = ((p.min_contact_height / v).round_ties_even() as i64).max(1);
    let flat_levels = levels_side[0].min(levels_side[1]);
    if flat_levels < min_levels {
        return None;
    }
    let cos_min = cos_side[0].min(cos_side[1]);
    if !(cos_min >= p.friction_angle.cos() - 1e-12) {
        return None;
    }

    // Quality: 1 for a clean grasp; minor weaknesses cost a few percent, risky ones
    // (shallow, above a ledge, contacts one voxel high) more.
    let cone = p.friction_angle;
    let ang = cos_min.clamp(-1.0, 1.0).acos();
    let mut q = ramp(ang, 0.3 * cone, cone, 1.0, 0.85);
    q *= ramp(depth, p.min_depth, p.target_depth, 0.7, 1.0);
    q *= ramp(
        patch as f64,
        p.min_patch as f64,
        (p.min_patch + 2) as f64,
        0.9,
        1.0,
    );
    q *= if flat_levels >= FLAT_LEVELS {
        1.0
    } else {
        0.85
    };
    q *= if ledge { p.ledge_factor } else { 1.0 };
    q *= 1.0 - 0.1 * (o.tilt / (std::f64::consts::PI / 4.0)).min(1.0);
    // Closing line near the centroid of the grasped blob (Natarajan et al.: line of gravity).
    let mid = [ic, (y_hi + y_lo).div_euclid(2), kc];
    let um: [f64; 3] = std::array::from_fn(|d| lat.lo[d] + v * mid[d] as f64);
    let vox = to_grid(&um, rot).map(|x| clampi(floor_fast(x / v) as i64, 0, r - 1) as usize);
    let ru = o.sh.r;
    let lab = o.scene.labels[(vox[0] * ru + vox[1]) * ru + vox[2]];
    let factor = if lab > 0 {
        let uc: [f64; 3] = std::array::from_fn(|d| lat.lo[d] + v * [ic, jc, kc][d] as f64);
        let tcp = to_grid(&uc, rot);
        let cen = o.scene.centroids[lab as usize];
        let to_c: [f64; 3] = std::array::from_fn(|d| cen[d] - tcp[d]);
        let along = to_c[0] * yw[0] + to_c[1] * yw[1] + to_c[2] * yw[2];
        let off: [f64; 3] = std::array::from_fn(|d| to_c[d] - along * yw[d]);
        let dist = (off[0] * off[0] + off[1] * off[1] + off[2] * off[2]).sqrt();
        ramp(dist, 0.03, 0.08, 1.0, 0.9)
    } else {
        0.9
    };
    q *= factor;
    Some(q.clamp(0.0, 1.0))
}

/// Solves a 3 × 3 system by Gaussian elimination with partial pivoting (the matrices
/// here are symmetric positive definite thanks to the ridge).
fn solve3(mut m: [[f64; 3]; 3], mut rhs: [f64; 3]) -> [f64; 3] {
    for col in 0..3 {
        let mut piv = col;
        for row in col + 1..3 {
            if m[row][col].abs() > m[piv][col].abs() {
                piv = row;
            }
        }
        m.swap(col, piv);
        rhs.swap(col, piv);
        let inv = 1.0 / m[col][col];
        for row in col + 1..3 {
            let l = m[row][col] * inv;
            let pivot = m[col];
            for (x, &p) in m[row].iter_mut().zip(&pivot).skip(col) {
                *x -= l * p;
            }
            rhs[row] -= l * rhs[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let mut s = rhs[row];
        for k in row + 1..3 {
            s -= m[row][k] * x[k];
        }
        x[row] = s / m[row][row];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::solve3;

    #[test]
    fn solve3_solves() {
        let m = [[4.0, 1.0, 2.0], [1.0, 5.0, 0.5], [2.0, 0.5, 6.0]];
        let x = [0.3, -1.2, 2.5];
        let b: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| m[i][j] * x[j]).sum());
        let got = solve3(m, b);
        for i in 0..3 {
            assert!((got[i] - x[i]).abs() < 1e-12, "{got:?}");
        }
    }
}
