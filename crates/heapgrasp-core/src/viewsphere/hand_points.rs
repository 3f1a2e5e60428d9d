//! Points inside a parallel-jaw hand: the collision check of Natarajan et al.'s grasp synthesis
//! (§3.3), where the gripper at a candidate pose must hold none of the object's points
//! nor of the unexplored region's (what no view has shown to be empty).
//!
//! The hand is the box model of [`HandGeometry`] (palm and both fingers, the fingers
//! `opening` apart), each box axis-aligned in the TCP frame (z the approach, fingers
//! closing along y). The points are indexed once in a hash grid of cubic cells
//! ([`PointIndex`]); per pose and box, the cells under the box's world bounding box are
//! visited and their points tested in the TCP frame. Poses are checked in parallel over
//! contiguous chunks; each count depends on its pose alone, so the result does not
//! depend on the thread count.

use std::collections::HashMap;

use nalgebra::Point3;

use crate::camera::Pose;
use crate::error::{Error, Result};
use crate::gripper::HandGeometry;
use crate::parallel;

/// Poses per thread below which a call stays on one thread.
const MIN_POSES_PER_THREAD: usize = 16;

/// A box of the hand in the TCP frame: its low and high corners (m).
pub type HandBox = ([f64; 3], [f64; 3]);

/// The hand's boxes in the TCP frame with the finger pads `opening` apart: the palm's two
/// boxes, then each finger's tip and base.
pub fn hand_boxes(hand: &HandGeometry, opening: f64) -> Result<Vec<HandBox>> {
    hand.validate()?;
    if !(opening.is_finite() && opening > 0.0 && opening <= hand.max_opening) {
        return Err(Error::Value {
            name: "opening".into(),
            value: format!("{opening}"),
            reason: format!("expected a value in (0, {}]", hand.max_opening),
        });
    }
    let mut at = hand.clone();
    at.max_opening = opening;
    let parts = at.parts();
    let boxes = parts
        .palm
        .iter()
        .chain(&parts.left)
        .chain(&parts.right)
        .map(|corners| {
            let mut lo = [f64::INFINITY; 3];
            let mut hi = [f64::NEG_INFINITY; 3];
            for v in corners.chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            (lo, hi)
        })
        .collect();
    Ok(boxes)
}

/// Points in a hash grid of cubic cells, for box queries.
#[derive(Debug, Clone)]
pub struct PointIndex {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<[f64; 3]>>,
    len: usize,
}

impl PointIndex {
    /// Indexes `points` (flat `(P, 3)`, world, m) in cells of `cell` metres.
    pub fn new(points: &[f64], cell: f64) -> Result<Self> {
        if !points.len().is_multiple_of(3) {
            return Err(Error::Shape {
                name: "points".into(),
                expected: "(P, 3)".into(),
                got: format!("{} values", points.len()),
            });
        }
        if !(cell.is_finite() && cell > 0.0) {
            return Err(Error::Value {
                name: "cell".into(),
                value: format!("{cell}"),
                reason: "expected a finite value > 0".into(),
            });
        }
        if let Some(k) = points.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                name: "points".into(),
                position: format!("[{}, {}]", k / 3, k % 3),
            });
        }
        let mut cells: HashMap<[i64; 3], Vec<[f64; 3]>> = HashMap::new();
        for p in points.chunks_exact(3) {
            let p = [p[0], p[1], p[2]];
            cells.entry(Self::key(cell, &p)).or_default().push(p);
        }
        Ok(Self {
            cell,
            cells,
            len: points.len() / 3,
        })
    }

    fn key(cell: f64, p: &[f64; 3]) -> [i64; 3] {
        // Saturating casts: points far outside any hand land in far cells.
        p.map(|v| (v / cell).floor() as i64)
    }

    /// Number of points indexed.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Points strictly inside the box `b` (TCP frame) of the hand at `tcp2world`,
    /// counted up to `limit` (the search stops there).
    fn count_in_box(&self, tcp2world: &Pose, world2tcp: &Pose, b: &HandBox, limit: u32) -> u32 {
        let (lo, hi) = b;
        let mut wlo = [f64::INFINITY; 3];
        let mut whi = [f64::NEG_INFINITY; 3];
        for i in 0..8 {
            let c = Point3::new(
                if i & 4 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 1 == 0 { lo[2] } else { hi[2] },
            );
            let w = tcp2world.transform_point(&c);
            for k in 0..3 {
                wlo[k] = wlo[k].min(w[k]);
                whi[k] = whi[k].max(w[k]);
            }
        }
        let klo = Self::key(self.cell, &wlo);
        let khi = Self::key(self.cell, &whi);
        let inside = |points: &[[f64; 3]], most: u32| -> u32 {
            let n = points
                .iter()
                .filter(|p| {
                    let q = world2tcp.transform_point(&Point3::new(p[0], p[1], p[2]));
                    (0..3).all(|k| q[k] > lo[k] && q[k] < hi[k])
                })
                .take(most as usize)
                .count();
            u32::try_from(n).unwrap_or(u32::MAX)
        };
        // Visit the cells under the box, or every occupied cell when there are fewer of
        // those (a tiny cell or a far-off pose): the work stays bounded by the points.
        let span: f64 = (0..3)
            .map(|k| (i128::from(khi[k]) - i128::from(klo[k]) + 1) as f64)
            .product();
        let mut count = 0u32;
        if span > self.cells.len() as f64 {
            for (key, points) in &self.cells {
                if (0..3).all(|k| key[k] >= klo[k] && key[k] <= khi[k]) {
                    count = count.saturating_add(inside(points, limit - count));
                    if count >= limit {
                        return count;
                    }
                }
            }
            return count;
        }
        for x in klo[0]..=khi[0] {
            for y in klo[1]..=khi[1] {
                for z in klo[2]..=khi[2] {
                    if let Some(points) = self.cells.get(&[x, y, z]) {
                        count = count.saturating_add(inside(points, limit - count));
                        if count >= limit {
                            return count;
                        }
                    }
                }
            }
        }
        count
    }
}

/// The hand's boxes at each pose's opening, and the thread count to use; an error when
/// the openings do not match the poses or one is out of the hand's range.
fn prepare(
    hand: &HandGeometry,
    tcp2world: &[Pose],
    openings: &[f64],
    threads: usize,
) -> Result<(Vec<Vec<HandBox>>, usize)> {
    if openings.len() != tcp2world.len() {
        return Err(Error::Shape {
            name: "openings".into(),
            expected: format!("({},)", tcp2world.len()),
            got: format!("({},)", openings.len()),
        });
    }
    let boxes = openings
        .iter()
        .map(|&w| hand_boxes(hand, w))
        .collect::<Result<Vec<_>>>()?;
    let threads = if threads == 0 {
        parallel::num_threads()
    } else {
        threads
    };
    Ok((boxes, threads.max(1)))
}

/// For each pose `tcp2world[i]` with the fingers `openings[i]` apart, how many indexed
/// points lie inside the hand (a point inside two boxes counts twice), on `threads`
/// threads (0: [`parallel::num_threads`]).
pub fn hand_point_counts(
    hand: &HandGeometry,
    tcp2world: &[Pose],
    openings: &[f64],
    index: &PointIndex,
    threads: usize,
) -> Result<Vec<u32>> {
    let (boxes, threads) = prepare(hand, tcp2world, openings, threads)?;
    let parts = threads.min(tcp2world.len() / MIN_POSES_PER_THREAD).max(1);
    let counts = parallel::map_ranges(tcp2world.len(), parts, |range| {
        range
            .map(|i| {
                let pose = &tcp2world[i];
                let inverse = pose.inverse();
                boxes[i]
                    .iter()
                    .map(|b| index.count_in_box(pose, &inverse, b, u32::MAX))
                    .fold(0u32, u32::saturating_add)
            })
            .collect::<Vec<_>>()
    });
    Ok(counts.concat())
}

/// Poses per block of [`first_free`]: the blocks run in parallel, in order, and the
/// search stops after the first block that holds a free pose.
const FREE_BLOCK: usize = 64;

/// The index of the first pose `tcp2world[i]` (fingers `openings[i]` apart) at which the
/// hand holds none of the indexed points, or None: [`hand_point_counts`]` == 0`, with
/// each pose's search stopped at its first point and the poses after the first free one
/// left unchecked, on `threads` threads (0: [`parallel::num_threads`]).
pub fn first_free(
    hand: &HandGeometry,
    tcp2world: &[Pose],
    openings: &[f64],
    index: &PointIndex,
    threads: usize,
) -> Result<Option<usize>> {
    let (boxes, threads) = prepare(hand, tcp2world, openings, threads)?;
    let free = |i: usize| {
        let pose = &tcp2world[i];
        let inverse = pose.inverse();
        boxes[i]
            .iter()
            .all(|b| index.count_in_box(pose, &inverse, b, 1) == 0)
    };
    let mut start = 0;
    while start < tcp2world.len() {
        let end = (start + FREE_BLOCK * threads).min(tcp2world.len());
        let parts = threads.min((end - start).div_ceil(FREE_BLOCK)).max(1);
        let found = parallel::map_ranges(end - start, parts, |range| {
            range.map(|k| start + k).find(|&i| free(i))
        });
        if let Some(i) = found.into_iter().flatten().min() {
            return Ok(Some(i));
        }
        start = end;
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn translation(x: f64, y: f64, z: f64) -> Pose {
        let mut m = [0.0; 16];
        m[0] = 1.0;
        m[5] = 1.0;
        m[10] = 1.0;
        m[15] = 1.0;
        m[3] = x;
        m[7] = y;
        m[11] = z;
        Pose::from_row_major("pose", &m).expect("a rigid transform")
    }

    #[test]
    fn boxes_follow_the_opening() {
        let hand = HandGeometry::panda();
        let boxes = hand_boxes(&hand, 0.04).expect("valid");
        assert_eq!(boxes.len(), 6);
        // The left finger's pads at y = +0.02, the right's at y = -0.02.
        assert!((boxes[2].0[1] - 0.02).abs() < 1e-12);
        assert!((boxes[4].1[1] + 0.02).abs() < 1e-12);
        assert!(hand_boxes(&hand, 0.0).is_err());
        assert!(hand_boxes(&hand, 0.2).is_err());
        assert!(hand_boxes(&hand, f64::NAN).is_err());
    }

    #[test]
    fn points_between_the_fingers_are_free_and_on_them_are_not() {
        let hand = HandGeometry::panda();
        let tip = hand.finger_tip - 0.005; // inside the fingertips' z range
                                           // Between the pads, on the left finger, inside the palm, far away (TCP frame).
        let points = [
            [0.0, 0.0, tip],
            [0.0, 0.045, tip],
            [0.0, 0.0, hand.palm_front - 0.01],
            [1.0, 1.0, 1.0],
        ];
        let at = translation(0.2, -0.1, 0.3);
        let moved: Vec<f64> = points
            .iter()
            .flat_map(|p| [p[0] + 0.2, p[1] - 0.1, p[2] + 0.3])
            .collect();
        let index = PointIndex::new(&moved, 0.01).expect("valid");
        assert_eq!(index.len(), 4);
        let counts = hand_point_counts(&hand, &[at, at], &[0.08, 0.02], &index, 1).expect("valid");
        // Fully open: the left finger's pad is at y = 0.04, so the point at 0.045 is in
        // it; the palm holds one. Closed to 2 cm, the middle point is still free.
        assert_eq!(counts, vec![2, 1]);
    }

    #[test]
    fn thread_count_does_not_change_the_result() {
        let hand = HandGeometry::panda();
        let mut points = Vec::new();
        for i in 0..2000 {
            let t = i as f64 * 0.618_033_988_749_895;
            points.extend([
                (t.sin() * 0.1) % 0.1,
                (t.cos() * 0.1) % 0.1,
                (t * 0.37).fract() * 0.2,
            ]);
        }
        let index = PointIndex::new(&points, 0.0075).expect("valid");
        let poses: Vec<Pose> = (0..100)
            .map(|i| translation(i as f64 * 0.002 - 0.1, 0.0, 0.05 + i as f64 * 0.001))
            .collect();
        let openings = vec![0.06; poses.len()];
        let one = hand_point_counts(&hand, &poses, &openings, &index, 1).expect("valid");
        let four = hand_point_counts(&hand, &poses, &openings, &index, 4).expect("valid");
        assert_eq!(one, four);
        assert!(one.iter().any(|&c| c > 0));
    }

    #[test]
    fn a_tiny_cell_or_a_far_pose_stays_fast_and_agrees() {
        let hand = HandGeometry::panda();
        let points = [0.0, 0.045, 0.0, 0.0, 0.0, -0.05, 0.3, 0.3, 0.3];
        let coarse = PointIndex::new(&points, 0.01).expect("valid");
        let tiny = PointIndex::new(&points, 1e-300).expect("valid");
        let poses = [translation(0.0, 0.0, 0.0), translation(1e300, 0.0, 0.0)];
        let widths = [0.08, 0.08];
        let a = hand_point_counts(&hand, &poses, &widths, &coarse, 1).expect("valid");
        let b = hand_point_counts(&hand, &poses, &widths, &tiny, 1).expect("valid");
        assert_eq!(a, b);
        assert_eq!(a, vec![2, 0]);
    }

    #[test]
    fn the_first_free_pose_is_the_first_zero_count() {
        let hand = HandGeometry::panda();
        let mut points = Vec::new();
        for i in 0..400 {
            let t = i as f64 * 0.618_033_988_749_895;
            points.extend([
                (t * 0.31).fract() * 0.2 - 0.1,
                (t * 0.57).fract() * 0.2 - 0.1,
                0.0,
            ]);
        }
        let index = PointIndex::new(&points, 0.01).expect("valid");
        // Poses over the points' slab, lower and lower: the later ones collide... and
        // then poses far above it, which are free.
        let mut poses: Vec<Pose> = (0..300)
            .map(|i| translation(0.0, 0.0, 0.05 - i as f64 * 1e-4))
            .collect();
        poses.extend((0..10).map(|i| translation(0.0, 0.0, 0.5 + i as f64)));
        let openings = vec![0.08; poses.len()];
        let counts = hand_point_counts(&hand, &poses, &openings, &index, 1).expect("valid");
        let want = counts.iter().position(|&c| c == 0);
        for threads in [1, 2, 5] {
            let got = first_free(&hand, &poses, &openings, &index, threads).expect("valid");
            assert_eq!(got, want);
        }
        assert!(
            want.is_some_and(|w| w > 0),
            "{want:?}: the first poses collide"
        );
        let none = first_free(&hand, &poses[..1], &openings[..1], &index, 1).expect("valid");
        assert_eq!(none, counts[..1].iter().position(|&c| c == 0));
        assert!(first_free(&hand, &poses, &openings[..3], &index, 1).is_err());
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(PointIndex::new(&[0.0, 1.0], 0.01).is_err());
        assert!(PointIndex::new(&[0.0, 1.0, f64::NAN], 0.01).is_err());
        assert!(PointIndex::new(&[0.0, 1.0, 2.0], 0.0).is_err());
        let index = PointIndex::new(&[], 0.01).expect("empty is fine");
        assert!(index.is_empty());
        let hand = HandGeometry::panda();
        let err = hand_point_counts(&hand, &[translation(0.0, 0.0, 0.0)], &[], &index, 1);
        assert!(err.is_err());
    }
}
