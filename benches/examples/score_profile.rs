//! Prints the sizes behind `score_views` for the benchmark scene and times its parts.
//! Run: `cargo run --release -p heapgrasp-benches --example score_profile`.

use heapgrasp_benches::{camera, candidate_trajectories, grid, mesh_scene, trajectory, view_pose};
use heapgrasp_core::occupancy::is_high_confidence;
use heapgrasp_core::{score, OccupancyGrid};
use std::time::Instant;

fn main() {
    let scene = mesh_scene();
    let cam = camera(320, 240);
    for mid in [false, true] {
        let mut poses = vec![view_pose(0.33, 0.0, 0.0)];
        let from = if mid {
            poses.extend(trajectory(
                0.33,
                (0.0, 0.0),
                (0.0, std::f64::consts::PI / 5.0 * 0.95),
                10,
            ));
            (0.0, std::f64::consts::PI / 5.0 * 0.95)
        } else {
            (0.0, 0.0)
        };
        let masks: Vec<u8> = poses
            .iter()
            .flat_map(|p| scene.render_mask(&cam, p))
            .collect();
        let mut occ = OccupancyGrid::new(grid(40));
        occ.integrate_many(&cam, &poses, &masks).expect("valid");
        let tracked = occ
            .segmented()
            .iter()
            .zip(occ.visible())
            .filter(|(&s, &v)| is_high_confidence(s + 10, v + 10, 0.9))
            .count();
        let trajs = candidate_trajectories(from, 10);
        let t = Instant::now();
        let s = score::score_views(&occ, &scene, &cam, &trajs, 0.9).expect("valid");
        let dt = t.elapsed();

        let t = Instant::now();
        let mut m = vec![0u8; cam.pixel_count()];
        let mut n = 0;
        for tr in &trajs {
            for p in tr {
                m = scene.render_mask(&cam, p);
                n += 1;
            }
        }
        let dr = t.elapsed();
        println!(
            "mid={mid}: high-conf={} tracked={tracked} score_views={:.1} ms (max {:.3}); {n} full renders 1 thread = {:.1} ms ({})",
            occ.count_high_confidence(0.9),
            dt.as_secs_f64() * 1e3,
            s.iter().cloned().fold(f32::MIN, f32::max),
            dr.as_secs_f64() * 1e3,
            m.len()
        );
    }
}
