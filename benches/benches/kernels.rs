//! Criterion benchmarks of the core kernels. Run: `cargo bench -p heapgrasp-benches --bench kernels`.
//! Results and the exact commands are recorded in `docs/benchmarks.md`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use heapgrasp_benches::{
    camera, candidate_trajectories, grid, mesh_scene, ring, sphere_masks, trajectory, view_pose,
    CUBE,
};
use heapgrasp_core::roofs::{keep_silhouettes, SilhouetteView, VoxelLattice};
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
    // A phase begun from a remembered hull (the scene memory): the voxels carved before
    // carry a visible count of 2^24, the pipeline's "carved for good".
    let fresh = grid_state(true);
    let carved: Vec<u32> = fresh
        .segmented()
        .iter()
        .zip(fresh.visible())
        .map(|(&s, &v)| if v > 0 && s == 0 { 1 << 24 } else { v })
        .collect();
    let remembered = OccupancyGrid::from_counts(*fresh.spec(), fresh.segmented().to_vec(), carved)
        .expect("valid counts");
    let trajectories = candidate_trajectories((0.0, std::f64::consts::PI / 5.0 * 0.95), 10);
    group.bench_function("after_first_waypoint_remembered", |b| {
        b.iter(|| {
            score::score_views(&remembered, &scene, &cam, &trajectories, 0.9).expect("valid input")
        })
    });
    group.finish();
}

/// The silhouette check after roof trimming, on the grid a HEAPGrasp phase leaves: the
/// view from above `p0`, 10 frames down to the rim of the sphere, 10 back over the top
/// and 3 more (24 views, the pipeline's `silhouette_views`). The trimming is stood in for
/// by a cut at 4.5 cm, which takes off the hull's roofs and the tops of the taller
/// objects, so that the check has roofs to leave off and real parts to put back.
fn silhouette_check(c: &mut Criterion) {
    let scene = mesh_scene();
    let cam = camera(320, 240);
    let rim = (0.0, std::f64::consts::PI / 5.0 * 0.95);
    let mut poses = vec![view_pose(0.33, 0.0, 0.0)];
    poses.extend(trajectory(0.33, (0.0, 0.0), rim, 10));
    poses.extend(trajectory(0.33, rim, (2.0, 0.05), 10));
    poses.extend(trajectory(0.33, (2.0, 0.05), (2.3, 0.2), 3));
    let masks: Vec<Vec<bool>> = poses
        .iter()
        .map(|p| scene.render_mask(&cam, p).iter().map(|&m| m > 0).collect())
        .collect();
    let spec = grid(40);
    let mut occ = OccupancyGrid::new(spec);
    let flat: Vec<u8> = masks.iter().flatten().map(|&m| u8::from(m)).collect();
    occ.integrate_many(&cam, &poses, &flat)
        .expect("valid input");
    let full: Vec<bool> = occ.high_confidence(0.9).iter().map(|&x| x > 0.0).collect();
    let r = spec.resolution();
    let cut_level = (0.045 / spec.voxel_size()) as usize;
    let trimmed: Vec<bool> = full
        .iter()
        .enumerate()
        .map(|(i, &x)| x && i % r < cut_level)
        .collect();
    let lattice = VoxelLattice::new(spec.origin(), spec.voxel_size(), r).expect("valid grid");
    let views: Vec<SilhouetteView<'_>> = poses
        .iter()
        .zip(&masks)
        .map(|(&cam2world, mask)| SilhouetteView {
            camera: cam,
            cam2world,
            mask,
        })
        .collect();
    let cut = full.iter().zip(&trimmed).filter(|(&f, &t)| f && !t).count();
    let back = keep_silhouettes(&lattice, &full, &trimmed, &views).expect("valid input");
    let restored = back.iter().filter(|&&x| x).count();
    assert!(
        restored > 0 && restored < cut,
        "{restored} of {cut} cut voxels restored"
    );
    println!("keep_silhouettes fixture: {restored} of {cut} cut voxels restored");
    c.bench_function(&format!("keep_silhouettes_24x320x240_40_{cut}cut"), |b| {
        b.iter(|| keep_silhouettes(&lattice, &full, &trimmed, &views).expect("valid input"))
    });
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

criterion_group!(
    benches,
    carve,
    render,
    score_views,
    silhouette_check,
    nms_bench
);
criterion_main!(benches);
