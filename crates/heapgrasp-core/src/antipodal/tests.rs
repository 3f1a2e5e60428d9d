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

/// `run` with other planner parameters and tilts.
fn run_with(
    b: &Box,
    params: &AntipodalParams,
    rots: &[[[f64; 3]; 3]],
    tilts: &[f64],
) -> Result<BestGrasps> {
    let grad = vec![0.0; 3 * R * R * R];
    let centroids = [[0.0; 3], b.centroid];
    let scene = AntipodalScene {
        resolution: R,
        occupied: &b.occ,
        gradient: &grad,
        labels: &b.labels,
        centroids: &centroids,
        candidates: &[[10, 10, 4]],
    };
    best_grasps(&scene, params, rots, tilts)
}

/// Found by fuzzing the bindings (issue 36): a gripper length of 1e300 m, or a voxel of
/// 1e-300 m, overflowed the lattice offsets (index out of bounds, a panic), and a palm
/// 1e298 m deep looped for ever. Lengths beyond MAX_GRIPPER_CELLS voxels are refused.
#[test]
fn extreme_gripper_lengths_are_refused_not_a_panic_or_a_hang() {
    let b = boxed([8, 7, 0], [12, 13, 6]);
    type Change = fn(&mut AntipodalParams);
    let cases: [(&str, Change); 5] = [
        ("tip_thickness", |p| p.hand.tip_thickness *= 1e300),
        ("base_thickness", |p| p.hand.base_thickness *= 1e300),
        ("palm_front", |p| p.hand.palm_front *= 1e300),
        ("finger_width", |p| p.hand.finger_width *= 1e300),
        ("max_opening", |p| p.voxel_size *= 1e-300), // the first length checked
    ];
    for (name, change) in cases {
        let mut p = AntipodalParams::panda(V, 0.0);
        change(&mut p);
        let err = run_with(&b, &p, &[top_down()], &[0.0]).expect_err(name);
        assert!(
            matches!(err, Error::Value { name: ref n, .. } if n == name),
            "{name}: {err}"
        );
    }
    let mut p = AntipodalParams::panda(V, 0.0);
    p.min_patch = i64::MAX;
    let err = run_with(&b, &p, &[top_down()], &[0.0]).expect_err("min_patch");
    assert!(err.to_string().contains("min_patch"), "{err}");
}

/// A gripper far longer than the lattice (but within the limit) costs the lattice's
/// cells, not the gripper's: the pad scans are clipped to the lattice.
#[test]
fn a_gripper_much_longer_than_the_lattice_is_scanned_quickly() {
    let b = boxed([8, 7, 0], [12, 13, 6]);
    let mut p = AntipodalParams::panda(V, 0.0);
    let far = 0.9 * MAX_GRIPPER_CELLS as f64 * V;
    (p.hand.palm_front, p.hand.finger_width) = (-far, far);
    let start = std::time::Instant::now();
    let best = run_with(&b, &p, &[top_down()], &[0.0]).expect("valid input");
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
    assert!((0.0..=1.0).contains(&best.quality[0]));
}

/// Found by fuzzing the bindings: a finite matrix that is not a rotation (entries of
/// 1e300) sized the lattice from its stretched extent (a huge allocation); a NaN tilt
/// gave a NaN quality. Both are refused.
#[test]
fn non_rotations_and_non_finite_tilts_are_refused() {
    let b = boxed([8, 7, 0], [12, 13, 6]);
    let p = AntipodalParams::panda(V, 0.0);
    let mut stretched = top_down();
    stretched[0][0] = 1e300;
    let err = run_with(&b, &p, &[top_down(), stretched], &[0.0, 0.0]).expect_err("stretched");
    assert!(
        matches!(err, Error::NotRigid { ref name, .. } if name == "rotations[1]"),
        "{err}"
    );
    let mut reflected = top_down();
    reflected[0][0] = 1.0;
    let err = run_with(&b, &p, &[reflected], &[0.0]).expect_err("reflection");
    assert!(matches!(err, Error::NotRigid { .. }), "{err}");
    for t in [f64::NAN, f64::INFINITY] {
        let err = run_with(&b, &p, &[top_down()], &[t]).expect_err("tilt");
        assert!(
            matches!(err, Error::NonFinite { ref name, .. } if name == "tilts"),
            "{err}"
        );
    }
}
