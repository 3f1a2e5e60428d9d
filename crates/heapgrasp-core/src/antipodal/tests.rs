//! Tests of the antipodal search on hand-made grids.

use super::*;

const R: usize = 20;
const V: f64 = 0.0075;

#[test]
fn the_panda_hand_on_7_5_mm_cells() {
    // `AntipodalPlanner()._cells(0.0075)` in the Python package.
    let cells = GripperCells::from_params(&AntipodalParams::panda(V, 0.0));
    let want = GripperCells {
        x_pad: (-1, 1),
        x_clear: (-1, 1),
        x_fit: (-2, 2),
        z_contact: (-5, 0),
        z_thin: (-2, 1),
        z_thick: (-13, -3),
        n_thin: 2,
        n_thick: 3,
        palm: [
            [(-3, 3), (-13, 13), (-10, -5)],
            [(-4, 4), (-14, 14), (-24, -10)],
        ],
    };
    assert_eq!(cells, want);
}

/// Top-down TCP (z down), closing along world y.
fn top_down() -> [[f64; 3]; 3] {
    // Columns: TCP x = (−1, 0, 0)... x = y × z with y = (0, 1, 0), z = (0, 0, −1).
    [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]
}

struct Box {
    occ: Vec<bool>,
    labels: Vec<i32>,
    centroid: [f64; 3],
}

/// A box of voxels `[lo, hi)` per axis.
fn boxed(lo: [usize; 3], hi: [usize; 3]) -> Box {
    let mut occ = vec![false; R * R * R];
    let mut sum = [0.0; 3];
    let mut n = 0.0;
    for a in lo[0]..hi[0] {
        for b in lo[1]..hi[1] {
            for c in lo[2]..hi[2] {
                occ[(a * R + b) * R + c] = true;
                sum[0] += (a as f64 + 0.5) * V;
                sum[1] += (b as f64 + 0.5) * V;
                sum[2] += (c as f64 + 0.5) * V;
                n += 1.0;
            }
        }
    }
    let labels = occ.iter().map(|&x| i32::from(x)).collect();
    Box {
        occ,
        labels,
        centroid: sum.map(|s| s / n),
    }
}

fn run(b: &Box, cand: &[[usize; 3]], rots: &[[[f64; 3]; 3]]) -> Result<BestGrasps> {
    let grad = vec![0.0; 3 * R * R * R];
    let centroids = [[0.0; 3], b.centroid];
    let scene = AntipodalScene {
        resolution: R,
        occupied: &b.occ,
        gradient: &grad,
        labels: &b.labels,
        centroids: &centroids,
        candidates: cand,
    };
    let tilts = vec![0.0; rots.len()];
    best_grasps(&scene, &AntipodalParams::panda(V, 0.0), rots, &tilts)
}

#[test]
fn a_box_narrower_than_the_opening_is_grasped_from_above() {
    // 4.5 cm (6 voxels) along y, 3 cm along x, 4.5 cm high, in the middle of the grid.
    let b = boxed([8, 7, 0], [12, 13, 6]);
    // The TCP at the box's centre line, 1.5 cm below its top.
    let best = run(&b, &[[10, 10, 4]], &[top_down()]).expect("valid input");
    assert!(best.quality[0] > 0.5, "{best:?}");
    // Opening: twice the farther contact (3 voxels from the TCP's voxel centre, which
    // is half a voxel off the box's middle) plus the clearance.
    let want = 2.0 * (3.5 * V + 0.003);
    assert!((best.width[0] - want).abs() < 1e-12, "{}", best.width[0]);
}

#[test]
fn a_box_wider_than_the_opening_is_not() {
    // 12 cm along y and along x: no closing direction fits in 8 cm.
    let b = boxed([2, 2, 0], [18, 18, 6]);
    let mut yawed = top_down();
    // Closing along world x as well.
    yawed[0] = [0.0, 1.0, 0.0];
    yawed[1] = [1.0, 0.0, 0.0];
    let best = run(&b, &[[10, 10, 4]], &[top_down(), yawed]).expect("valid input");
    assert_eq!(best.quality[0], 0.0);
}

#[test]
fn a_tcp_away_from_every_object_has_no_grasp() {
    let b = boxed([8, 7, 0], [12, 13, 6]);
    let best = run(&b, &[[2, 2, 4]], &[top_down()]).expect("valid input");
    assert_eq!(best.quality[0], 0.0);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let b = boxed([8, 7, 0], [12, 13, 6]);
    let err = run(&b, &[[10, 10, R]], &[top_down()]).expect_err("index out of range");
    assert!(err.to_string().contains("candidates"), "{err}");
    let mut bad = b;
    bad.labels[0] = 5;
    let err = run(&bad, &[[10, 10, 4]], &[top_down()]).expect_err("label out of range");
    assert!(err.to_string().contains("labels"), "{err}");
    let mut nan = top_down();
    nan[0][0] = f64::NAN;
    let b = boxed([8, 7, 0], [12, 13, 6]);
    let err = run(&b, &[[10, 10, 4]], &[nan]).expect_err("NaN rotation");
    assert!(err.to_string().contains("rotations"), "{err}");
}
