//! Silhouettes of closed meshes filled from their contour edges only.
//!
//! Seen from outside, a closed, consistently oriented mesh covers a pixel centre iff at
//! least one of its front faces does (the first hit of a ray is a front face). The front
//! faces form a 2-chain whose boundary is the *contour*: the edges whose two faces are
//! one front and one not front, each directed as in its front face. On every image row
//! the number of front faces covering a point is the winding number of the contour
//! around it, so the mask row is the set of columns where that count is positive. A
//! contour is typically a tenth of the front faces' edges, so this does much less work
//! per frame than rasterising every front face.
//!
//! # Exactness
//! A contour edge bounds a row at the same column as in the triangle rasteriser
//! (`super::rasterize_triangle`): the edge line `u = p + v·q` is computed with the same
//! floating-point operations from the same camera-frame vertices and the same sign, and
//! is rounded the same way (`ceil` where the front face lies to the right, `floor` where
//! it lies to the left). Edges between two front faces, which cancel here, share
//! bit-identical lines there, so the triangle rasteriser has no cracks along them. The
//! two methods therefore give the same mask, except for pixel centres within rounding of
//! a contour *vertex*: the rows an edge crosses are taken from its projected end points
//! (half-open, `v_min <= v < v_max`, so that every closed contour crosses each row an
//! even number of times), where the triangle rasteriser decides them from the other
//! edges' lines. The Rust tests check equality on random views of the procedural meshes.

use nalgebra::Vector3;

use crate::camera::PinholeCamera;
use crate::rounding::{ceil_fast, floor_fast};

use super::PixelRect;

/// The undirected edges of a closed mesh, each as `[i, j, f_ij, f_ji]`: vertex indices
/// `i < j`, the face holding the directed edge `i → j` and the face holding `j → i`.
pub(super) fn closed_edges(faces: &[[u32; 3]]) -> Option<Vec<[u32; 4]>> {
    use std::collections::HashMap;
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3);
    for (f, t) in faces.iter().enumerate() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if directed.insert((a, b), f as u32).is_some() {
                return None;
            }
        }
    }
    let mut edges = Vec::with_capacity(directed.len() / 2);
    for (&(a, b), &f_ab) in &directed {
        let f_ba = *directed.get(&(b, a))?;
        if a < b {
            edges.push([a, b, f_ab, f_ba]);
        }
    }
    edges.sort_unstable();
    Some(edges)
}

/// Row events of the fill: one per (contour edge, row crossed). `key` sorts by row,
/// then column; the lowest bit is 1 for a +1 (the front side begins at this column) and
/// 0 for a −1 (it ended at the column before).
#[derive(Debug, Default, Clone)]
pub(super) struct Events {
    keys: Vec<u64>,
    /// Scratch of the row bucketing in [`Events::fill`].
    sorted: Vec<u64>,
    starts: Vec<u32>,
}

const ROW_SHIFT: u32 = 33;
const COL_SHIFT: u32 = 1;
const COL_MASK: u64 = (1 << 32) - 1;

impl Events {
    pub(super) fn clear(&mut self) {
        self.keys.clear();
    }

    /// Adds the row crossings of one mesh's contour.
    ///
    /// `cam`/`uv`: the mesh's camera-frame vertices and their projections (every vertex
    /// in front of the camera); `front`: per face, whether it is drawn (non-zero
    /// determinant facing the camera); `s`: the sign of a front face's determinant
    /// (the same for all of them).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn push_contour(
        &mut self,
        camera: &PinholeCamera,
        rect: PixelRect,
        edges: &[[u32; 4]],
        cam: &[[f64; 3]],
        uv: &[[f64; 2]],
        front: &[bool],
        s: f64,
    ) {
        let (inv_fx, inv_fy, cx, cy) = (1.0 / camera.fx, 1.0 / camera.fy, camera.cx, camera.cy);
        let (row_lo, row_hi) = (f64::from(rect.v0), f64::from(rect.v1));
        let (col_lo, col_hi) = (f64::from(rect.u0), f64::from(rect.u1) + 1.0);
        for &[a, b, f_ab, f_ba] in edges {
            let (fa, fb) = (front[f_ab as usize], front[f_ba as usize]);
            if fa == fb {
                continue;
            }
            // Directed as in its front face.
            let (i, j) = if fa {
                (a as usize, b as usize)
            } else {
                (b as usize, a as usize)
            };
            let (vi, vj) = (uv[i][1], uv[j][1]);
            if vi == vj {
                continue; // crosses no row centre line (half-open)
            }
            let (vmin, vmax) = if vi < vj { (vi, vj) } else { (vj, vi) };
            let r0 = ceil_fast(vmin).max(row_lo);
            let r1 = (ceil_fast(vmax) - 1.0).min(row_hi);
            if r0 > r1 {
                continue;
            }
            // +1 where the front face lies to the right of the edge (the triangle
            // rasteriser's "lower" edges, a > 0): for s > 0 those run upward in v.
            let rising = (vj > vi) != (s > 0.0);
            // The line exactly as `rasterize_triangle` computes it.
            let n = Vector3::from(cam[i]).cross(&Vector3::from(cam[j]));
            let alpha = s * n.x * inv_fx;
            let b_y = s * n.y * inv_fy;
            let b0 = s * n.z - b_y * cy - alpha * cx;
            let inv_a = 1.0 / alpha;
            let (p, q) = (-b0 * inv_a, -b_y * inv_a);
            let (ui, uj) = (uv[i][0], uv[j][0]);
            let (umin, umax) = (ui.min(uj) - SLACK, ui.max(uj) + SLACK);
            let slope = (uj - ui) / (vj - vi);
            let mut r = r0;
            while r <= r1 {
                let mut x = p + r * q;
                if !(x >= umin && x <= umax) {
                    // Degenerate line (nearly horizontal, or α = 0): the segment itself.
                    x = (ui + (r - vi) * slope).clamp(umin, umax);
                }
                let col = if rising {
                    ceil_fast(x)
                } else {
                    floor_fast(x) + 1.0
                };
                let col = col.clamp(col_lo, col_hi) as u64;
                self.keys
                    .push(((r as u64) << ROW_SHIFT) | (col << COL_SHIFT) | u64::from(rising));
                r += 1.0;
            }
        }
    }

    /// Sets to 1 the pixels of `out` (a `width`-wide row-major mask) where the count of
    /// the events is positive. Consumes the events.
    pub(super) fn fill(&mut self, width: usize, out: &mut [u8]) {
        self.sort();
        let keys = &self.keys;
        let mut k = 0;
        while k < keys.len() {
            let row = (keys[k] >> ROW_SHIFT) as usize * width;
            let row_key = keys[k] >> ROW_SHIFT;
            let mut count: i32 = 0;
            let mut start = 0usize;
            while k < keys.len() && keys[k] >> ROW_SHIFT == row_key {
                // Row and column together: all the events at one pixel.
                let pixel_key = keys[k] >> COL_SHIFT;
                let col = (pixel_key & COL_MASK) as usize;
                let before = count;
                while k < keys.len() && keys[k] >> COL_SHIFT == pixel_key {
                    count += if keys[k] & 1 == 1 { 1 } else { -1 };
                    k += 1;
                }
                if before <= 0 && count > 0 {
                    start = col;
                } else if before > 0 && count <= 0 {
                    out[row + start..row + col].fill(1);
                }
            }
            debug_assert_eq!(count, 0, "every closed contour crosses a row evenly");
        }
        self.keys.clear();
    }

    /// Sorts the keys: bucketed by row (a counting sort over the rows), then each
    /// row's few events sorted by column.
    fn sort(&mut self) {
        let keys = &self.keys;
        if keys.len() < 64 {
            self.keys.sort_unstable();
            return;
        }
        let (lo, hi) = keys.iter().fold((u64::MAX, 0), |(lo, hi), &k| {
            (lo.min(k >> ROW_SHIFT), hi.max(k >> ROW_SHIFT))
        });
        let rows = (hi - lo) as usize + 1;
        self.starts.clear();
        self.starts.resize(rows + 1, 0);
        for &k in keys {
            self.starts[((k >> ROW_SHIFT) - lo) as usize + 1] += 1;
        }
        for r in 0..rows {
            self.starts[r + 1] += self.starts[r];
        }
        self.sorted.clear();
        self.sorted.resize(keys.len(), 0);
        for &k in keys {
            let slot = &mut self.starts[((k >> ROW_SHIFT) - lo) as usize];
            self.sorted[*slot as usize] = k;
            *slot += 1;
        }
        // `starts[r]` is now the end of row r (the start of row r + 1).
        let mut begin = 0;
        for r in 0..rows {
            let end = self.starts[r] as usize;
            self.sorted[begin..end].sort_unstable();
            begin = end;
        }
        std::mem::swap(&mut self.keys, &mut self.sorted);
    }
}

/// Slack (pixels) of the segment bound on an edge's column.
const SLACK: f64 = 1e-6;

#[cfg(test)]
mod tests {
    use super::super::MeshScene;
    use crate::camera::{PinholeCamera, Pose};
    use crate::primitives::{box_mesh, cylinder, uv_sphere};
    use proptest::prelude::*;

    /// A torus around z (closed, outward CCW): concave, with a hole and folds in most
    /// silhouettes.
    fn torus(big: f64, small: f64, n: u32, m: u32) -> (Vec<f64>, Vec<u32>) {
        let mut v = Vec::new();
        for i in 0..n {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            for j in 0..m {
                let b = std::f64::consts::TAU * f64::from(j) / f64::from(m);
                let r = big + small * b.cos();
                v.extend([r * a.cos(), r * a.sin(), small * b.sin()]);
            }
        }
        let idx = |i: u32, j: u32| (i % n) * m + (j % m);
        let mut f = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (p, q, r, s) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
                f.extend([p, q, r, p, r, s]);
            }
        }
        (v, f)
    }

    /// Two overlapping boxes in one mesh: closed, with front layers counted twice.
    fn two_boxes() -> (Vec<f64>, Vec<u32>) {
        let (mut v, mut f) = box_mesh([0.04, 0.01, 0.02]);
        let (v2, f2) = box_mesh([0.01, 0.04, 0.03]);
        let off = (v.len() / 3) as u32;
        v.extend(
            v2.iter()
                .enumerate()
                .map(|(k, x)| x + if k % 3 == 0 { 0.01 } else { 0.0 }),
        );
        f.extend(f2.iter().map(|i| i + off));
        (v, f)
    }

    fn pose(rot: [f64; 3], t: [f64; 3]) -> Pose {
        let r = nalgebra::Rotation3::from_euler_angles(rot[0], rot[1], rot[2]);
        let m = r.matrix();
        Pose::from_row_major(
            "obj2world",
            &[
                m[(0, 0)],
                m[(0, 1)],
                m[(0, 2)],
                t[0],
                m[(1, 0)],
                m[(1, 1)],
                m[(1, 2)],
                t[1],
                m[(2, 0)],
                m[(2, 1)],
                m[(2, 2)],
                t[2],
                0.0,
                0.0,
                0.0,
                1.0,
            ],
        )
        .unwrap()
    }

    fn scene(rots: &[[f64; 3]; 6]) -> MeshScene {
        let mut s = MeshScene::new();
        let meshes = [
            box_mesh([0.03, 0.02, 0.05]),
            uv_sphere(0.035, 9, 14),
            cylinder(0.025, 0.06, 24),
            torus(0.05, 0.015, 24, 12),
            two_boxes(),
            cylinder(0.04, 0.01, 7),
        ];
        let at = [
            [0.08, 0.10, 0.05],
            [0.20, 0.08, 0.04],
            [0.15, 0.20, 0.06],
            [0.10, 0.22, 0.03],
            [0.22, 0.20, 0.10],
            [0.15, 0.15, 0.02],
        ];
        for (k, (v, f)) in meshes.into_iter().enumerate() {
            let id = s.add_mesh(&v, &f, pose(rots[k], at[k])).unwrap();
            assert!(s.is_closed(id).unwrap(), "mesh {k} must be closed");
        }
        s
    }

    fn view(r: f64, phi: f64, theta: f64) -> Pose {
        let c = [0.15, 0.15, 0.0];
        let eye = [
            c[0] + r * theta.sin() * phi.cos(),
            c[1] + r * theta.sin() * phi.sin(),
            c[2] + r * theta.cos(),
        ];
        Pose::look_at(eye, c, [0.0, 0.0, 1.0]).unwrap()
    }

    fn differing(a: &[u8], b: &[u8]) -> usize {
        a.iter().zip(b).filter(|(x, y)| x != y).count()
    }

    #[test]
    fn contour_fill_equals_the_face_by_face_mask() {
        let cam = PinholeCamera::new(320, 240, 300.0, 300.0, 159.5, 119.5).unwrap();
        let s = scene(&[
            [0.3, 0.2, 0.1],
            [0.0; 3],
            [1.2, 0.3, 0.0],
            [0.4, 0.0, 0.7],
            [0.1, 0.9, 0.2],
            [0.0, 1.4, 0.3],
        ]);
        let mut covered = 0;
        for k in 0..60 {
            let phi = 0.37 * f64::from(k);
            let theta = 0.05 + 0.02 * f64::from(k % 30);
            let r = 0.25 + 0.01 * f64::from(k % 20);
            let p = view(r, phi, theta);
            let mask = s.render_mask(&cam, &p);
            assert_eq!(
                differing(&mask, &s.render_mask_faces(&cam, &p)),
                0,
                "view {k}"
            );
            covered += mask.iter().filter(|&&m| m == 1).count();
        }
        assert!(
            covered > 60 * 2000,
            "the meshes should fill part of every view"
        );
    }

    #[test]
    fn meshes_straddling_the_camera_plane_fall_back_to_faces() {
        // The camera sits beside a long box, part of which is behind it.
        let cam = PinholeCamera::new(64, 48, 40.0, 40.0, 31.5, 23.5).unwrap();
        let mut s = MeshScene::new();
        let (v, f) = box_mesh([0.5, 0.02, 0.02]);
        s.add_mesh(&v, &f, Pose::identity()).unwrap();
        let p = Pose::look_at([0.0, -0.1, 0.0], [0.3, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
        let mask = s.render_mask(&cam, &p);
        assert!(mask.contains(&1));
        assert_eq!(mask, s.render_mask_faces(&cam, &p));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn contour_fill_equals_faces_on_random_views(
            rots in prop::array::uniform6(prop::array::uniform3(-3.2f64..3.2)),
            r in 0.2f64..0.6,
            phi in -3.2f64..3.2,
            theta in 0.0f64..1.2,
        ) {
            let cam = PinholeCamera::new(96, 72, 90.0, 90.0, 47.5, 35.5).unwrap();
            let s = scene(&rots);
            let p = view(r, phi, theta);
            prop_assert_eq!(differing(&s.render_mask(&cam, &p), &s.render_mask_faces(&cam, &p)), 0);
        }
    }
}
