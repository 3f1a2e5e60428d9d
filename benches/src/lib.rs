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
