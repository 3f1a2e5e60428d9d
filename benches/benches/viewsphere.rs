//! Criterion benchmarks of Natarajan et al.'s cloud and view-scoring kernels
//! (`heapgrasp_core::viewsphere::clouds`, `heapgrasp_core::viewsphere::visibility`): a 640 × 480 depth view of a
//! box on a table down-sampled to 7.5 mm voxels, and the 3D heuristic's scoring of 8
//! next views (1,000 useful points past a box's surfels) and its grasp region.

use criterion::{criterion_group, criterion_main, Criterion};
use heapgrasp_core::viewsphere::clouds::depth_voxels;
use heapgrasp_core::viewsphere::visibility::{grasp_region, surfel_visibility};
use heapgrasp_core::{PinholeCamera, Pose};

/// The visible faces of a 6 × 10 × 12 cm box standing on the origin, sampled at 7.5 mm,
/// with outward normals.
fn box_points() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (hx, hy, h) = (0.03, 0.05, 0.12);
    let step = 0.0075;
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    let n = |a: f64, b: f64| ((b - a) / step).round() as usize + 1;
    let at = |a: f64, k: usize| a + k as f64 * step;
    for i in 0..n(-hx, hx) {
        for j in 0..n(-hy, hy) {
            points.push([at(-hx, i), at(-hy, j), h]);
            normals.push([0.0, 0.0, 1.0]);
        }
    }
    for j in 0..n(-hy, hy) {
        for k in 0..n(0.0, h) {
            points.push([-hx, at(-hy, j), at(0.0, k)]);
            normals.push([-1.0, 0.0, 0.0]);
        }
    }
    (points, normals)
}

/// A 7.5 mm lattice over ±0.15 m × ±0.15 m × 0–0.3 m.
fn lattice() -> Vec<[f64; 3]> {
    let n = 40;
    (0..n * n * n)
        .map(|k| {
            let (i, j, l) = (k / (n * n), (k / n) % n, k % n);
            [
                -0.15 + 0.0075 * i as f64,
                -0.15 + 0.0075 * j as f64,
                0.0075 * l as f64,
            ]
        })
        .collect()
}

fn eyes() -> Vec<[f64; 3]> {
    (0..8)
        .map(|k| {
            let a = std::f64::consts::FRAC_PI_4 * k as f64;
            [0.4 * 0.7 * a.cos(), 0.4 * 0.7 * a.sin(), 0.4 * 0.71]
        })
        .collect()
}

fn kernels(c: &mut Criterion) {
    let (points, normals) = box_points();
    let targets = lattice();
    let useful: Vec<[f64; 3]> = targets.iter().step_by(64).copied().take(1000).collect();
    let eyes = eyes();
    c.bench_function(
        &format!("surfel_visibility_{}pts_8x{}", points.len(), useful.len()),
        |b| b.iter(|| surfel_visibility(&points, &normals, 0.0075, &eyes, &useful, 0)),
    );
    c.bench_function(
        &format!("grasp_region_{}pts_{}targets", points.len(), targets.len()),
        |b| b.iter(|| grasp_region(&points, &normals, &targets, 0.08, 0.015, 0)),
    );
    // A view from the start pose (azimuth π, polar π/7) of the table plane z = 0.
    let camera = PinholeCamera::new(640, 480, 554.2547, 554.2547, 320.5, 240.5).expect("valid");
    let (az, polar) = (std::f64::consts::PI, std::f64::consts::PI / 7.0);
    let eye = [
        0.4 * polar.sin() * az.cos(),
        0.4 * polar.sin() * az.sin(),
        0.4 * polar.cos(),
    ];
    let pose = Pose::look_at(eye, [0.0; 3], [0.0, 0.0, 1.0]).expect("valid");
    let depth: Vec<f32> = (0..640 * 480)
        .map(|k| {
            let (u, v) = ((k % 640) as f64, (k / 640) as f64);
            let ray = [(u - 320.5) / 554.2547, (v - 240.5) / 554.2547, 1.0];
            // The depth along the optical axis where the ray meets z = 0.
            let r = pose.rotation();
            let dz = r[(2, 0)] * ray[0] + r[(2, 1)] * ray[1] + r[(2, 2)] * ray[2];
            (-eye[2] / dz) as f32
        })
        .collect();
    c.bench_function("depth_voxels_640x480_7.5mm", |b| {
        b.iter(|| depth_voxels(&depth, &camera, &pose, 0.1, 3.0, 0.0075))
    });
}

criterion_group!(benches, kernels);
criterion_main!(benches);
