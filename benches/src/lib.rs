//! Fixtures shared by the criterion benchmarks: a ring of cameras around the VGN
//! workspace and analytic silhouettes of a few spheres.

use heapgrasp_core::primitives::{box_mesh, cylinder, uv_sphere};
use heapgrasp_core::{GridSpec, PinholeCamera, Pose};

/// Side of the VGN workspace cube, metres.
pub const CUBE: f64 = 0.30;

/// The workspace grid at resolution `r`, origin at the world origin.
pub fn grid(r: usize) -> GridSpec {
    GridSpec::new([0.0; 3], CUBE, r).expect("valid grid")
}

/// VGN's camera scaled to `width × height` (fx = fy = 540 at 640×480).
pub fn camera(width: u32, height: u32) -> PinholeCamera {
    let s = width as f64 / 640.0;
    PinholeCamera::new(
        width,
        height,
        540.0 * s,
        540.0 * s,
        width as f64 / 2.0 - 0.5,
        height as f64 / 2.0 - 0.5,
    )
    .expect("valid camera")
}

/// `n` cameras on a circle of radius 0.45 m, 0.35 m above the table, looking at the cube centre.
pub fn ring(n: usize) -> Vec<Pose> {
    let c = CUBE / 2.0;
    (0..n)
        .map(|k| {
            let phi = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            Pose::look_at(
                [c + 0.45 * phi.cos(), c + 0.45 * phi.sin(), 0.35],
                [c, c, 0.05],
                [0.0, 0.0, 1.0],
            )
            .expect("valid pose")
        })
        .collect()
}

/// Spheres (centre, radius) standing on the table inside the cube.
pub fn spheres() -> Vec<([f64; 3], f64)> {
    vec![
        ([0.10, 0.12, 0.04], 0.04),
        ([0.19, 0.17, 0.03], 0.03),
        ([0.15, 0.08, 0.035], 0.035),
    ]
}

/// Exact silhouette masks of [`spheres`] (pixel set iff the ray through its centre hits a sphere).
pub fn sphere_masks(cam: &PinholeCamera, poses: &[Pose]) -> Vec<u8> {
    let mut out = Vec::with_capacity(poses.len() * cam.pixel_count());
    for pose in poses {
        let w2c = pose.inverse();
        let centres: Vec<_> = spheres()
            .into_iter()
            .map(|(c, r)| (w2c.transform_point(&c.into()), r))
            .collect();
        for v in 0..cam.height {
            for u in 0..cam.width {
                let d = cam.pixel_ray(u as f64, v as f64).normalize();
                let hit = centres.iter().any(|(c, r)| {
                    let t = d.dot(&c.coords);
                    t > 0.0 && (c.coords - d * t).norm_squared() <= r * r
                });
                out.push(u8::from(hit));
            }
        }
    }
    out
}

fn at(x: f64, y: f64, z: f64) -> Pose {
    Pose::from_row_major(
        "obj2world",
        &[
            1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, z, 0.0, 0.0, 0.0, 1.0,
        ],
    )
    .expect("valid pose")
}

/// Five objects on the table of the workspace (≈ 1.2 k triangles): two spheres, two
/// boxes, a cylinder.
pub fn mesh_scene() -> heapgrasp_core::MeshScene {
    let mut s = heapgrasp_core::MeshScene::new();
    let mut add = |(v, f): (Vec<f64>, Vec<u32>), p: Pose| {
        s.add_mesh(&v, &f, p).expect("valid mesh");
    };
    add(uv_sphere(0.035, 16, 24), at(0.10, 0.11, 0.035));
    add(uv_sphere(0.025, 12, 18), at(0.20, 0.19, 0.025));
    add(box_mesh([0.03, 0.02, 0.04]), at(0.18, 0.09, 0.04));
    add(box_mesh([0.025, 0.025, 0.02]), at(0.09, 0.21, 0.02));
    add(cylinder(0.025, 0.05, 32), at(0.15, 0.15, 0.05));
    s
}

/// View-waypoint candidate (HEAPGrasp eq. 12) at spherical indices: radius `r` around
/// the bottom centre of the cube, azimuth φ = 2π u / U, polar θ = θmax v / V, looking at
/// the cube centre.
pub fn view_pose(r: f64, phi: f64, theta: f64) -> Pose {
    let c = CUBE / 2.0;
    let eye = [
        c + r * theta.sin() * phi.cos(),
        c + r * theta.sin() * phi.sin(),
        r * theta.cos(),
    ];
    Pose::look_at(eye, [c, c, c], [0.0, 0.0, 1.0]).expect("valid pose")
}

/// `m` frames from spherical `(φ0, θ0)` to `(φ1, θ1)`, interpolating the angles linearly
/// (the shorter way around in φ), excluding the start.
pub fn trajectory(r: f64, from: (f64, f64), to: (f64, f64), m: usize) -> Vec<Pose> {
    let tau = 2.0 * std::f64::consts::PI;
    let mut dphi = (to.0 - from.0).rem_euclid(tau);
    if dphi > std::f64::consts::PI {
        dphi -= tau;
    }
    (1..=m)
        .map(|k| {
            let s = k as f64 / m as f64;
            view_pose(r, from.0 + s * dphi, from.1 + s * (to.1 - from.1))
        })
        .collect()
}

/// The paper's 40 × 20 candidates (r = 0.33 m, θmax = π/5) as `m`-frame trajectories
/// from `from`.
pub fn candidate_trajectories(from: (f64, f64), m: usize) -> Vec<Vec<Pose>> {
    let (u_n, v_n, theta_max) = (40, 20, std::f64::consts::PI / 5.0);
    let mut out = Vec::with_capacity(u_n * v_n);
    for u in 0..u_n {
        for v in 0..v_n {
            let to = (
                2.0 * std::f64::consts::PI * u as f64 / u_n as f64,
                theta_max * v as f64 / v_n as f64,
            );
            out.push(trajectory(0.33, from, to, m));
        }
    }
    out
}
