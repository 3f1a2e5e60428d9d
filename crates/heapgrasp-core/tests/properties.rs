//! Cross-module invariants, checked with proptest on random cameras, poses, masks and
//! scenes: carving only ever adds counts (monotone in views), a batch equals the same
//! frames one by one, and re-observing the only view seen so far scores 0 (eq. 14).

// Test code: generators build known-valid values.
#![allow(clippy::unwrap_used)]

use heapgrasp_core::primitives::box_mesh;
use heapgrasp_core::{score::score_views, GridSpec, MeshScene, OccupancyGrid, PinholeCamera, Pose};
use proptest::prelude::*;

prop_compose! {
    fn camera()(w in 8u32..48, h in 8u32..40, f in 15.0f64..120.0, cx in -5.0f64..50.0, cy in -5.0f64..45.0)
        -> PinholeCamera {
        PinholeCamera::new(w, h, f, f * 1.1, cx, cy).unwrap()
    }
}

prop_compose! {
    /// A camera on a sphere around the grid centre, looking at a point near it.
    fn view()(phi in 0.0f64..std::f64::consts::TAU, theta in 0.05f64..1.5, r in 0.3f64..0.9, jx in -0.05f64..0.05, jy in -0.05f64..0.05)
        -> Pose {
        let eye = [0.15 + r * theta.sin() * phi.cos(), 0.15 + r * theta.sin() * phi.sin(), r * theta.cos()];
        Pose::look_at(eye, [0.15 + jx, 0.15 + jy, 0.1], [0.0, 0.0, 1.0]).unwrap()
    }
}

fn random_mask(cam: &PinholeCamera, seed: u64) -> Vec<u8> {
    let mut x = seed | 1;
    (0..cam.pixel_count())
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            u8::from(!x.is_multiple_of(3))
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn carving_is_monotone_and_batches_equal_sequences(
        cam in camera(),
        poses in prop::collection::vec(view(), 1..5),
        seed in any::<u64>(),
        r in 1usize..10,
    ) {
        let spec = GridSpec::new([0.0; 3], 0.3, r).unwrap();
        let masks: Vec<u8> = (0..poses.len()).flat_map(|k| random_mask(&cam, seed.wrapping_add(k as u64))).collect();
        let px = cam.pixel_count();
        let mut batch = OccupancyGrid::new(spec);
        batch.integrate_many(&cam, &poses, &masks).unwrap();
        let mut seq = OccupancyGrid::new(spec);
        for (k, pose) in poses.iter().enumerate() {
            let before = seq.clone();
            seq.integrate(&cam, pose, &masks[k * px..(k + 1) * px]).unwrap();
            for i in 0..spec.voxel_count() {
                let dv = seq.visible()[i] - before.visible()[i];
                let ds = seq.segmented()[i] - before.segmented()[i];
                prop_assert!(dv <= 1 && ds <= dv, "one frame adds at most one view to a voxel");
                prop_assert!(seq.segmented()[i] <= seq.visible()[i]);
            }
        }
        prop_assert_eq!(batch, seq);
    }

    #[test]
    fn re_observing_the_only_seen_view_scores_zero(
        cam in camera(),
        pose in view(),
        hx in 0.01f64..0.06, hy in 0.01f64..0.06, hz in 0.01f64..0.06,
        lam in 0.5f64..1.0,
    ) {
        let mut scene = MeshScene::new();
        let (v, f) = box_mesh([hx, hy, hz]);
        let at = Pose::from_row_major("p", &[1.0, 0.0, 0.0, 0.15, 0.0, 1.0, 0.0, 0.15, 0.0, 0.0, 1.0, hz, 0.0, 0.0, 0.0, 1.0]).unwrap();
        scene.add_mesh(&v, &f, at).unwrap();
        let mut grid = OccupancyGrid::new(GridSpec::new([0.0; 3], 0.3, 12).unwrap());
        grid.integrate(&cam, &pose, &scene.render_mask(&cam, &pose)).unwrap();
        let scores = score_views(&grid, &scene, &cam, &[vec![pose], vec![pose, pose]], lam).unwrap();
        prop_assert_eq!(scores, vec![0.0, 0.0]);
    }
}
