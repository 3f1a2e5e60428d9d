//! Fixtures shared by the criterion benchmarks: a ring of cameras around the VGN
//! workspace and analytic silhouettes of a few spheres.

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

/// A closed box mesh (half extents), outward CCW faces: (vertices, faces) flat.
pub fn box_mesh(h: [f64; 3]) -> (Vec<f64>, Vec<u32>) {
    let mut v = Vec::new();
    for i in 0..8 {
        v.extend([
            if i & 1 == 0 { -h[0] } else { h[0] },
            if i & 2 == 0 { -h[1] } else { h[1] },
            if i & 4 == 0 { -h[2] } else { h[2] },
        ]);
    }
    let f = vec![
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    (v, f)
}

/// A closed UV sphere with `rings` × `segments` quads (poles as triangle fans).
pub fn uv_sphere(radius: f64, rings: u32, segments: u32) -> (Vec<f64>, Vec<u32>) {
    let mut v = vec![0.0, 0.0, radius];
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            v.extend([
                radius * th.sin() * ph.cos(),
                radius * th.sin() * ph.sin(),
                radius * th.cos(),
            ]);
        }
    }
    v.extend([0.0, 0.0, -radius]);
    let south = 1 + (rings - 1) * segments;
    let idx = |i: u32, j: u32| 1 + (i - 1) * segments + (j % segments);
    let mut f = Vec::new();
    for j in 0..segments {
        f.extend([0, idx(1, j), idx(1, j + 1)]);
        f.extend([south, idx(rings - 1, j + 1), idx(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            f.extend([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
            f.extend([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
        }
    }
    (v, f)
}

/// A closed cylinder along z centred at the origin.
pub fn cylinder(radius: f64, half_height: f64, segments: u32) -> (Vec<f64>, Vec<u32>) {
    let mut v = Vec::new();
    for z in [-half_height, half_height] {
        for j in 0..segments {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            v.extend([radius * ph.cos(), radius * ph.sin(), z]);
        }
    }
    v.extend([0.0, 0.0, -half_height, 0.0, 0.0, half_height]);
    let (bot, top) = (2 * segments, 2 * segments + 1);
    let mut f = Vec::new();
    for j in 0..segments {
        let k = (j + 1) % segments;
        f.extend([j, k, segments + k, j, segments + k, segments + j]);
        f.extend([bot, k, j, top, segments + j, segments + k]);
    }
    (v, f)
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
