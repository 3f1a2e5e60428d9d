//! Natarajan et al.'s grasp synthesis on a fused object point cloud (§3.3): the hot loops of
//! `heapgrasp.planning.synthesis`.
//!
//! 1. [`point_normals`]: each point's normal and curvature from its `k` nearest points
//!    (itself included; PCL's `NormalEstimation`): the covariance's eigenvector of the
//!    smallest eigenvalue `λ0`, oriented away from the cloud's centroid, and the
//!    curvature `λ0 / (λ0 + λ1 + λ2)`.
//! 2. [`contact_patches`]: whether a finger pad fits on the surface at a point (the
//!    public code's `isContactPatchOk`): the points within ±5 mm along the normal and
//!    ±30 mm across it are projected onto the tangent plane at 1 px/mm; their convex
//!    hull, masked by a disc of 18 px radius, must hold a pixel 13.68 px (26 / 1.9) from
//!    its edge (the exact Euclidean distance transform's maximum).
//! 3. [`antipodal_pairs`]: every pair of usable points whose distance plus a voxel fits
//!    the opening, with quality `180° − (A + B)` at least the minimum, `A` and `B` the
//!    angles between the contact line and each normal (either way along the line).
//!
//! Neighbours come from a hash grid of point indices ([`CloudIndex`]). Work is split over
//! contiguous ranges of points and merged in order, so no result depends on the thread
//! count. The NumPy reference these follow step by step lives in the Python tests.

use std::collections::HashMap;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::error::{Error, Result};
use crate::parallel;

/// Points per thread below which a call stays on one thread.
const MIN_POINTS_PER_THREAD: usize = 64;

/// The contact patch's slab: half thickness along the normal and half width across (m).
const PATCH_ALONG: f64 = 0.005;
const PATCH_ACROSS: f64 = 0.03;
/// The patch image: 1 px/mm, 101 px wide with the contact at pixel 50.
const PATCH_CENTRE: i64 = 50;
/// The finger pad: 26 px; the mask is a disc of `⌊13 √2⌋ = 18` px radius, and a pixel
/// `26 / 1.9` px from the edge must exist.
const PAD_PX: f64 = 26.0;
const DISC_RADIUS: i64 = 18;

/// A 3-D point.
pub type Point = [f64; 3];

/// Checks a flat `(N, 3)` buffer of finite coordinates and returns its points.
pub fn points_from_flat(name: &str, flat: &[f64]) -> Result<Vec<Point>> {
    check_flat_points(name, flat)?;
    Ok(flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
}

/// Checks that `flat` is an `(N, 3)` buffer of finite coordinates (errors name `name`).
pub fn check_flat_points(name: &str, flat: &[f64]) -> Result<()> {
    if !flat.len().is_multiple_of(3) {
        return Err(Error::Shape {
            name: name.into(),
            expected: "(N, 3)".into(),
            got: format!("{} values", flat.len()),
        });
    }
    if let Some(k) = flat.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            name: name.into(),
            position: format!("[{}, {}]", k / 3, k % 3),
        });
    }
    Ok(())
}

/// Point indices in a hash grid of cubic cells.
#[derive(Debug, Clone)]
pub struct CloudIndex {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
    /// The occupied keys' bounds, which bound every search.
    lo: [i64; 3],
    hi: [i64; 3],
    len: usize,
}

impl CloudIndex {
    /// Indexes the points `points[i]` for `i` in `members` in cells of `cell` metres.
    pub(crate) fn new(points: &[Point], members: impl Iterator<Item = usize>, cell: f64) -> Self {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        let mut len = 0;
        for i in members {
            len += 1;
            let key = Self::key(cell, &points[i]);
            for k in 0..3 {
                lo[k] = lo[k].min(key[k]);
                hi[k] = hi[k].max(key[k]);
            }
            cells.entry(key).or_default().push(i as u32);
        }
        Self {
            cell,
            cells,
            lo,
            hi,
            len,
        }
    }

    fn key(cell: f64, p: &Point) -> [i64; 3] {
        p.map(|v| (v / cell).floor() as i64)
    }

    /// Calls `f` with every indexed point in the cells that meet the cube of half width
    /// `radius` around `p` (a superset of the ball).
    pub(crate) fn near(&self, p: &Point, radius: f64, mut f: impl FnMut(u32)) {
        let a = Self::key(self.cell, &p.map(|v| v - radius));
        let b = Self::key(self.cell, &p.map(|v| v + radius));
        let (a, b) = (
            [0, 1, 2].map(|k| a[k].max(self.lo[k])),
            [0, 1, 2].map(|k| b[k].min(self.hi[k])),
        );
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                for z in a[2]..=b[2] {
                    if let Some(members) = self.cells.get(&[x, y, z]) {
                        members.iter().for_each(|&i| f(i));
                    }
                }
            }
        }
    }

    /// Calls `f` with every indexed point in the cells at Chebyshev distance `ring` from
    /// `centre`'s cell; false when rings `0..=ring` have covered every occupied cell.
    fn ring(&self, centre: [i64; 3], ring: i64, mut f: impl FnMut(u32)) -> bool {
        let a = [0, 1, 2].map(|k| centre[k].saturating_sub(ring));
        let b = [0, 1, 2].map(|k| centre[k].saturating_add(ring));
        let mut visit = |key: [i64; 3]| {
            if let Some(members) = self.cells.get(&key) {
                members.iter().for_each(|&i| f(i));
            }
        };
        for x in a[0].max(self.lo[0])..=b[0].min(self.hi[0]) {
            for y in a[1].max(self.lo[1])..=b[1].min(self.hi[1]) {
                if x == a[0] || x == b[0] || y == a[1] || y == b[1] {
                    for z in a[2].max(self.lo[2])..=b[2].min(self.hi[2]) {
                        visit([x, y, z]);
                    }
                } else {
                    visit([x, y, a[2]]);
                    if ring > 0 {
                        visit([x, y, b[2]]);
                    }
                }
            }
        }
        !(0..3).all(|k| a[k] <= self.lo[k] && b[k] >= self.hi[k])
    }
}

fn sub(a: &Point, b: &Point) -> Vector3<f64> {
    Vector3::new(a[0] - b[0], a[1] - b[1], a[2] - b[2])
}

fn threads(n: usize, threads: usize) -> usize {
    let t = if threads == 0 {
        parallel::num_threads()
    } else {
        threads
    };
    t.min(n / MIN_POINTS_PER_THREAD).max(1)
}

/// The `k` nearest indexed points to `points[i]` (itself included), nearest first, ties
/// by index.
fn nearest(points: &[Point], index: &CloudIndex, i: usize, k: usize) -> Vec<u32> {
    let p = &points[i];
    let centre = CloudIndex::key(index.cell, p);
    let mut found: Vec<(f64, u32)> = Vec::new();
    let mut ring = 0i64;
    loop {
        let more = index.ring(centre, ring, |j| {
            found.push((sub(&points[j as usize], p).norm_squared(), j));
        });
        // Any point outside rings 0..=ring is at least `ring` cells away.
        let reach = ring as f64 * index.cell;
        if found.len() >= k {
            found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            if found[k - 1].0 <= reach * reach || !more || found.len() == index.len {
                found.truncate(k);
                return found.into_iter().map(|(_, j)| j).collect();
            }
        }
        if !more || found.len() == index.len {
            found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            return found.into_iter().map(|(_, j)| j).collect();
        }
        ring += 1;
    }
}

/// A cell size for neighbour searches: about twice the mean spacing of a surface
/// sampled by `n` points over the cloud's extent, and at least 1/64 of the extent, so a
/// search visits at most 65 rings whatever the cloud (a far outlier costs speed, not
/// termination).
fn neighbour_cell(points: &[Point]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let cell = (2.0 * extent / (points.len() as f64).sqrt()).max(extent / 64.0);
    if !cell.is_finite() {
        f64::MAX // the extent overflowed: coordinates beyond ±f64::MAX / 2
    } else if cell > 1e-300 {
        cell
    } else {
        1.0 // every point at one place
    }
}

/// Unit normals (away from the centroid) and curvatures of `points` from each point's
/// `k` nearest points (module doc, step 1), on `threads` threads (0: all).
pub fn point_normals(
    points: &[Point],
    k: usize,
    threads: usize,
) -> Result<(Vec<[f64; 3]>, Vec<f64>)> {
    if k < 3 {
        return Err(Error::Value {
            name: "k".into(),
            value: format!("{k}"),
            reason: "expected at least 3 neighbours".into(),
        });
    }
    if points.len() < k {
        return Err(Error::Value {
            name: "points".into(),
            value: format!("{} points", points.len()),
            reason: format!("normals from {k} neighbours need at least {k} points"),
        });
    }
    let index = CloudIndex::new(points, 0..points.len(), neighbour_cell(points));
    let n = points.len() as f64;
    let centroid = (0..3).map(|c| points.iter().map(|p| p[c]).sum::<f64>() / n);
    let centroid: Vec<f64> = centroid.collect();
    let parts = self::threads(points.len(), threads);
    let chunks = parallel::map_ranges(points.len(), parts, |range| {
        range
            .map(|i| {
                let nbrs = nearest(points, &index, i, k);
                let m = nbrs.len() as f64;
                let mut mean = Vector3::zeros();
                for &j in &nbrs {
                    let q = &points[j as usize];
                    mean += Vector3::new(q[0], q[1], q[2]);
                }
                mean /= m;
                let mut cov = Matrix3::zeros();
                for &j in &nbrs {
                    let q = &points[j as usize];
                    let d = Vector3::new(q[0], q[1], q[2]) - mean;
                    cov += d * d.transpose();
                }
                cov /= m;
                let eig = SymmetricEigen::new(cov);
                let (mut smallest, mut total) = (0, 0.0);
                for e in 0..3 {
                    total += eig.eigenvalues[e];
                    if eig.eigenvalues[e] < eig.eigenvalues[smallest] {
                        smallest = e;
                    }
                }
                let mut normal: Vector3<f64> = eig.eigenvectors.column(smallest).into();
                let p = &points[i];
                let out = Vector3::new(p[0] - centroid[0], p[1] - centroid[1], p[2] - centroid[2]);
                if normal.dot(&out) < 0.0 {
                    normal = -normal;
                }
                let curvature = if total > 0.0 {
                    eig.eigenvalues[smallest] / total
                } else {
                    0.0
                };
                ([normal.x, normal.y, normal.z], curvature)
            })
            .collect::<Vec<_>>()
    });
    Ok(chunks.into_iter().flatten().unzip())
}

fn check_normals(points: &[Point], normals: &[Point]) -> Result<()> {
    if normals.len() != points.len() {
        return Err(Error::Shape {
            name: "normals".into(),
            expected: format!("({}, 3)", points.len()),
            got: format!("({}, 3)", normals.len()),
        });
    }
    if let Some(i) = normals
        .iter()
        .position(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() > 1e-6)
    {
        return Err(Error::Value {
            name: "normals".into(),
            value: format!("{:?} at row {i}", normals[i]),
            reason: "expected unit vectors".into(),
        });
    }
    Ok(())
}

fn check_mask(points: &[Point], mask: &[bool], name: &str) -> Result<()> {
    if mask.len() != points.len() {
        return Err(Error::Shape {
            name: name.into(),
            expected: format!("({},)", points.len()),
            got: format!("({},)", mask.len()),
        });
    }
    Ok(())
}

/// Tangent axes at `n`, as the public code builds them: `y = n × ẑ` (normalised),
/// `z = n × y`.
fn tangent_frame(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let mut y = n.cross(&Vector3::z());
    if y.norm() < 1e-12 {
        y = if n.x.abs() > 1e-12 {
            Vector3::new(n.x, 0.0, 0.0)
        } else {
            Vector3::x()
        };
    }
    y /= y.norm();
    (y, n.cross(&y))
}

/// Whether `cloud[i]`'s contact patch fits a finger pad (module doc, step 2).
fn patch_ok(points: &[Point], index: &CloudIndex, i: usize, normal: &Point) -> bool {
    let p = &points[i];
    let n = Vector3::new(normal[0], normal[1], normal[2]);
    let (y, z) = tangent_frame(&n);
    let mut pixels: Vec<(i64, i64)> = Vec::new();
    let reach = (PATCH_ALONG * PATCH_ALONG + 2.0 * PATCH_ACROSS * PATCH_ACROSS).sqrt();
    index.near(p, reach, |j| {
        let rel = sub(&points[j as usize], p);
        let (along, across_y, across_z) = (rel.dot(&n), rel.dot(&y), rel.dot(&z));
        if along.abs() <= PATCH_ALONG
            && across_y.abs() <= PATCH_ACROSS
            && across_z.abs() <= PATCH_ACROSS
        {
            let px = |v: f64| (v * 1000.0 + PATCH_CENTRE as f64) as i64;
            pixels.push((px(across_y), px(across_z)));
        }
    });
    let hull = convex_hull(pixels);
    if hull.len() < 3 {
        return false;
    }
    // The disc and a ring of background around it: the nearest background pixel of any
    // pixel in the disc lies in this window.
    let half = DISC_RADIUS + 1;
    let side = (2 * half + 1) as usize;
    let mut surface = vec![false; side * side];
    for (r, row) in surface.chunks_exact_mut(side).enumerate() {
        for (c, cell) in row.iter_mut().enumerate() {
            let (dr, dc) = (r as i64 - half, c as i64 - half);
            if dr * dr + dc * dc > DISC_RADIUS * DISC_RADIUS {
                continue;
            }
            let q = (PATCH_CENTRE + dr, PATCH_CENTRE + dc);
            *cell = inside_hull(&hull, q);
        }
    }
    let deepest = max_distance_sq(&surface, side);
    (deepest as f64).sqrt() >= PAD_PX / 1.9
}

/// The convex hull of integer pixels, counter-clockwise, without collinear vertices
/// (Andrew's monotone chain); fewer than 3 vertices when the pixels have no area.
fn convex_hull(mut pixels: Vec<(i64, i64)>) -> Vec<(i64, i64)> {
    pixels.sort_unstable();
    pixels.dedup();
    if pixels.len() < 3 {
        return pixels;
    }
    fn chain(hull: &mut Vec<(i64, i64)>, ordered: impl Iterator<Item = (i64, i64)>) {
        let start = hull.len();
        let turn = |o: (i64, i64), a: (i64, i64), b: (i64, i64)| {
            (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
        };
        for q in ordered {
            while hull.len() >= start + 2
                && turn(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop(); // the next chain starts there
    }
    let mut hull = Vec::with_capacity(pixels.len() + 1);
    chain(&mut hull, pixels.iter().copied());
    chain(&mut hull, pixels.iter().rev().copied());
    hull
}

/// Whether pixel `q` lies in the counter-clockwise hull (its edges included).
fn inside_hull(hull: &[(i64, i64)], q: (i64, i64)) -> bool {
    (0..hull.len()).all(|e| {
        let (a, b) = (hull[e], hull[(e + 1) % hull.len()]);
        (b.0 - a.0) * (q.1 - a.1) - (b.1 - a.1) * (q.0 - a.0) >= 0
    })
}

/// The largest squared Euclidean distance from a true pixel of the `side × side` image
/// to the nearest false pixel (Felzenszwalb and Huttenlocher's separable transform; the
/// image's border is false).
fn max_distance_sq(image: &[bool], side: usize) -> i64 {
    const FAR: i64 = i64::MAX / 4;
    let mut d: Vec<i64> = image.iter().map(|&on| if on { FAR } else { 0 }).collect();
    let mut line = vec![0i64; side];
    let mut out = vec![0i64; side];
    for axis in 0..2 {
        for fixed in 0..side {
            let at = |k: usize| {
                if axis == 0 {
                    k * side + fixed
                } else {
                    fixed * side + k
                }
            };
            for (k, v) in line.iter_mut().enumerate() {
                *v = d[at(k)];
            }
            lower_envelope(&line, &mut out);
            for (k, v) in out.iter().enumerate() {
                d[at(k)] = *v;
            }
        }
    }
    d.into_iter().max().unwrap_or(0)
}

/// One dimension of the squared distance transform: `out[q] = min_p (q − p)² + f[p]`
/// over the finite `f[p]` (the lower envelope of parabolas).
fn lower_envelope(f: &[i64], out: &mut [i64]) {
    const FAR: i64 = i64::MAX / 4;
    let sources: Vec<usize> = (0..f.len()).filter(|&p| f[p] < FAR).collect();
    let Some((&first, rest)) = sources.split_first() else {
        out.iter_mut().for_each(|v| *v = FAR);
        return;
    };
    // Where the parabolas of p and q (p < q) cross.
    let meet = |p: usize, q: usize| -> f64 {
        let (fp, fq) = (f[p] as f64, f[q] as f64);
        let (p, q) = (p as f64, q as f64);
        ((fq + q * q) - (fp + p * p)) / (2.0 * (q - p))
    };
    let mut v = vec![first];
    let mut z = vec![f64::NEG_INFINITY];
    for &q in rest {
        let mut s = meet(v[v.len() - 1], q);
        while s <= z[z.len() - 1] {
            v.pop();
            z.pop();
            s = meet(v[v.len() - 1], q);
        }
        v.push(q);
        z.push(s);
    }
    let mut k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while k + 1 < v.len() && z[k + 1] < q as f64 {
            k += 1;
        }
        let dq = q as i64 - v[k] as i64;
        *o = dq * dq + f[v[k]];
    }
}

/// For each point with `candidates[i]` true, whether a finger pad fits on the surface
/// there (module doc, step 2); false elsewhere. On `threads` threads (0: all).
pub fn contact_patches(
    points: &[Point],
    normals: &[Point],
    candidates: &[bool],
    threads: usize,
) -> Result<Vec<bool>> {
    check_normals(points, normals)?;
    check_mask(points, candidates, "candidates")?;
    let reach = (PATCH_ALONG * PATCH_ALONG + 2.0 * PATCH_ACROSS * PATCH_ACROSS).sqrt();
    let index = CloudIndex::new(points, 0..points.len(), reach);
    let wanted: Vec<usize> = (0..points.len()).filter(|&i| candidates[i]).collect();
    let parts = self::threads(wanted.len(), threads);
    let found = parallel::map_ranges(wanted.len(), parts, |range| {
        range
            .map(|w| {
                let i = wanted[w];
                patch_ok(points, &index, i, &normals[i])
            })
            .collect::<Vec<_>>()
    });
    let mut ok = vec![false; points.len()];
    for (&i, f) in wanted.iter().zip(found.into_iter().flatten()) {
        ok[i] = f;
    }
    Ok(ok)
}

/// Antipodal contact pairs: `(i, j)` with `i < j`, the quality (degrees) and the opening
/// the pair needs (m).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Pairs {
    /// First contacts (point indices).
    pub first: Vec<u32>,
    /// Second contacts.
    pub second: Vec<u32>,
    /// `180° − (A + B)` (degrees).
    pub quality: Vec<f64>,
    /// The contacts' distance plus a voxel (m).
    pub width: Vec<f64>,
}

/// Every pair of `usable` points whose distance plus `voxel` is at most `max_width`,
/// with quality at least `min_quality` (module doc, step 3), ordered by `(i, j)`. On
/// `threads` threads (0: all).
pub fn antipodal_pairs(
    points: &[Point],
    normals: &[Point],
    usable: &[bool],
    voxel: f64,
    max_width: f64,
    min_quality: f64,
    threads: usize,
) -> Result<Pairs> {
    check_normals(points, normals)?;
    check_mask(points, usable, "usable")?;
    for (name, value, ok) in [
        ("voxel", voxel, voxel.is_finite() && voxel >= 0.0),
        (
            "max_width",
            max_width,
            max_width.is_finite() && max_width > 0.0,
        ),
        (
            "min_quality",
            min_quality,
            (0.0..=180.0).contains(&min_quality),
        ),
    ] {
        if !ok {
            return Err(Error::Value {
                name: name.into(),
                value: format!("{value}"),
                reason: match name {
                    "min_quality" => "expected degrees in [0, 180]".into(),
                    "voxel" => "expected a finite value >= 0".into(),
                    _ => "expected a finite value > 0".into(),
                },
            });
        }
    }
    let reach = max_width - voxel;
    let members: Vec<usize> = (0..points.len()).filter(|&i| usable[i]).collect();
    if reach <= 0.0 || members.len() < 2 {
        return Ok(Pairs::default());
    }
    let index = CloudIndex::new(points, members.iter().copied(), reach);
    let parts = self::threads(members.len(), threads);
    let chunks = parallel::map_ranges(members.len(), parts, |range| {
        let mut out = Pairs::default();
        for m in range {
            let i = members[m];
            let (p, ni) = (&points[i], Vector3::from(normals[i]));
            let mut js: Vec<u32> = Vec::new();
            index.near(p, reach, |j| {
                if j as usize > i {
                    js.push(j);
                }
            });
            js.sort_unstable();
            for j in js {
                let line = sub(&points[j as usize], p);
                let dist = line.norm();
                let width = dist + voxel;
                if !(width <= max_width && dist > 0.0) {
                    continue;
                }
                let unit = line / dist;
                let nj = Vector3::from(normals[j as usize]);
                let a = unit.dot(&ni).abs().clamp(0.0, 1.0).acos().to_degrees();
                let b = unit.dot(&nj).abs().clamp(0.0, 1.0).acos().to_degrees();
                let quality = 180.0 - (a + b);
                if quality >= min_quality {
                    out.first.push(i as u32);
                    out.second.push(j);
                    out.quality.push(quality);
                    out.width.push(width);
                }
            }
        }
        out
    });
    let mut all = Pairs::default();
    for c in chunks {
        all.first.extend(c.first);
        all.second.extend(c.second);
        all.quality.extend(c.quality);
        all.width.extend(c.width);
    }
    Ok(all)
}

#[cfg(test)]
mod tests;
