//! Closed triangle meshes of simple solids (outward, counter-clockwise faces), as flat
//! `(vertices, faces)` buffers ready for [`crate::MeshScene::add_mesh`]. Used by tests,
//! benchmarks and procedural scenes.

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MeshScene, Pose};

    #[test]
    fn primitives_are_closed_and_outward() {
        let mut s = MeshScene::new();
        for (v, f) in [
            box_mesh([0.1, 0.2, 0.3]),
            uv_sphere(0.1, 8, 12),
            cylinder(0.05, 0.1, 16),
        ] {
            let id = s.add_mesh(&v, &f, Pose::identity()).unwrap();
            assert!(s.is_closed(id).unwrap());
        }
    }
}
