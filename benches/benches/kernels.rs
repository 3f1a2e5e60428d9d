//! Criterion benchmarks of the core kernels. Run: `cargo bench -p heapgrasp-benches --bench kernels`.
//! Results and the exact commands are recorded in `docs/benchmarks.md`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use heapgrasp_benches::{
    camera, candidate_trajectories, grid, mesh_scene, ring, sphere_masks, trajectory, view_pose,
    CUBE,
};
use heapgrasp_core::{nms, score, GridSpec, OccupancyGrid};

fn carve(c: &mut Criterion) {
    let mut group = c.benchmark_group("carve_30_views");
    group.sample_size(20);
    for (w, h) in [(320, 240), (640, 480)] {
        let cam = camera(w, h);
        let poses = ring(30);
        let masks = sphere_masks(&cam, &poses);
        for r in [40usize, 80, 160] {
            let spec = grid(r);
            group.throughput(Throughput::Elements(
                (spec.voxel_count() * poses.len()) as u64,
            ));
            group.bench_with_input(BenchmarkId::new(format!("{w}x{h}"), r), &r, |b, _| {
                let mut occ = OccupancyGrid::new(spec);
                b.iter(|| {
                    occ.reset();
                    occ.integrate_many(&cam, &poses, &masks)
                        .expect("valid input");
                });
            });
        }
    }
    group.finish();
}

fn render(c: &mut Criterion) {
    let scene = mesh_scene();
    let mut group = c.benchmark_group("render_mask");
    for (w, h) in [(320, 240), (640, 480)] {
        let cam = camera(w, h);
        let pose = view_pose(0.33, 0.7, 0.5);
        group.bench_function(format!("{w}x{h}_{}tri", scene.triangle_count()), |b| {
            b.iter(|| scene.render_mask(&cam, &pose))
        });
        // The face-by-face reference the contour fill replaced.
        group.bench_function(
            format!("{w}x{h}_{}tri_faces", scene.triangle_count()),
            |b| b.iter(|| scene.render_mask_faces(&cam, &pose)),
        );
    }
    group.finish();
}

/// The grid after the initial view p0 (top, θ = 0), optionally followed by a 10-frame
/// trajectory to a first waypoint.
fn grid_state(mid: bool) -> OccupancyGrid {
    let scene = mesh_scene();
    let cam = camera(320, 240);
    let mut poses = vec![view_pose(0.33, 0.0, 0.0)];
    if mid {
        poses.extend(trajectory(
            0.33,
            (0.0, 0.0),
            (0.0, std::f64::consts::PI / 5.0 * 0.95),
            10,
        ));
    }
    let masks: Vec<u8> = poses
        .iter()
        .flat_map(|p| scene.render_mask(&cam, p))
        .collect();
    let mut occ = OccupancyGrid::new(grid(40));
    occ.integrate_many(&cam, &poses, &masks)
        .expect("valid input");
    occ
}

fn score_views(c: &mut Criterion) {
    let scene = mesh_scene();
    let cam = camera(320, 240);
    let mut group = c.benchmark_group("score_views_800x10_320x240_40");
    group.sample_size(10);
    for (name, mid, from) in [
        ("after_p0", false, (0.0, 0.0)),
        (
            "after_first_waypoint",
            true,
            (0.0, std::f64::consts::PI / 5.0 * 0.95),
        ),
    ] {
        let occ = grid_state(mid);
        let trajectories = candidate_trajectories(from, 10);
        group.bench_function(name, |b| {
            b.iter(|| {
                score::score_views(&occ, &scene, &cam, &trajectories, 0.9).expect("valid input")
            })
        });
        // Eq. 14 counted on the column of radius 0.08 m around the scene centre (the
        // pipeline's target column, `target_radius`).
        let region = column_region(occ.spec(), [CUBE / 2.0, CUBE / 2.0], 0.08);
        group.bench_function(format!("{name}_column_0.08"), |b| {
            b.iter(|| {
                score::score_views_in(&occ, &scene, &cam, &trajectories, 0.9, Some(&region))
                    .expect("valid input")
            })
        });
    }
    group.finish();
}

/// The voxels whose centre lies within `radius` of `xy` in x–y (a vertical column, as
/// `heapgrasp.viewplan.target_region`).
fn column_region(spec: &GridSpec, xy: [f64; 2], radius: f64) -> Vec<bool> {
    (0..spec.voxel_count())
        .map(|i| {
            let [a, b, c] = spec.unflatten(i);
            let p = spec.voxel_center(a, b, c);
            (p.x - xy[0]).hypot(p.y - xy[1]) <= radius
        })
        .collect()
}

fn nms_bench(c: &mut Criterion) {
    let r = 40;
    // A smooth random-ish field with many local maxima.
    let vol: Vec<f32> = (0..r * r * r)
        .map(|i| {
            let (a, b, c) = ((i / (r * r)) as f32, ((i / r) % r) as f32, (i % r) as f32);
            0.5 + 0.25 * (0.7 * a).sin() * (0.9 * b).cos() + 0.25 * (1.3 * c + 0.2 * a).sin()
        })
        .collect();
    c.bench_function("gaussian_filter3d_40_sigma1", |b| {
        b.iter(|| heapgrasp_core::filter::gaussian_filter3d(&vol, r, 1.0).expect("valid"))
    });
    c.bench_function("nms3d_40_window4", |b| {
        b.iter(|| nms::nms3d(&vol, r, 0.8, 4).expect("valid"))
    });
}

criterion_group!(benches, carve, render, score_views, nms_bench);
criterion_main!(benches);
