//! Criterion benchmark of the antipodal grasp search (`heapgrasp_core::antipodal`): a
//! pile of five boxes and cylinders in the 40³ workspace grid, every candidate TCP, the
//! planner's 72 orientations (top-down and 30° tilts, 8 azimuths, 8 yaws).

use criterion::{criterion_group, criterion_main, Criterion};
use heapgrasp_core::antipodal::{best_grasps, AntipodalParams, AntipodalScene};

const R: usize = 40;
const V: f64 = 0.30 / R as f64;

/// `grasp_orientations((0, 30°), 8, 8)`: TCP-to-world rotations (columns x, y, z).
fn orientations() -> (Vec<[[f64; 3]; 3]>, Vec<f64>) {
    let (mut rots, mut tilts) = (Vec::new(), Vec::new());
    for t in [0.0f64, 30f64.to_radians()] {
        let azimuths: Vec<f64> = if t == 0.0 {
            vec![0.0]
        } else {
            (0..8)
                .map(|a| std::f64::consts::TAU * a as f64 / 8.0)
                .collect()
        };
        for phi in azimuths {
            let z = [t.sin() * phi.cos(), t.sin() * phi.sin(), -t.cos()];
            let e1 = [-phi.sin(), phi.cos(), 0.0];
            let e2 = cross(z, e1);
            for m in 0..8 {
                let psi = std::f64::consts::PI * m as f64 / 8.0;
                let y: [f64; 3] = std::array::from_fn(|i| psi.cos() * e1[i] + psi.sin() * e2[i]);
                let x = cross(y, z);
                rots.push(std::array::from_fn(|w| [x[w], y[w], z[w]]));
                tilts.push(t);
            }
        }
    }
    (rots, tilts)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Two upright boxes, an upright and a lying cylinder, and a box on top of another.
fn pile() -> Vec<bool> {
    let mut occ = vec![false; R * R * R];
    for a in 0..R {
        for b in 0..R {
            for c in 0..R {
                let [x, y, z] = [a, b, c].map(|i| (i as f64 + 0.5) * V);
                let inside = (((x - 0.08).abs() < 0.02) && ((y - 0.08).abs() < 0.03) && z < 0.06)
                    || (((x - 0.20).abs() < 0.035) && ((y - 0.10).abs() < 0.025) && z < 0.05)
                    || ((x - 0.10).powi(2) + (y - 0.21).powi(2) < 0.03f64.powi(2) && z < 0.08)
                    || (((x - 0.21).abs() < 0.05)
                        && (y - 0.21).powi(2) + (z - 0.025).powi(2) < 0.025f64.powi(2))
                    || (((x - 0.20).abs() < 0.02) && ((y - 0.10).abs() < 0.02) && z < 0.08);
                occ[(a * R + b) * R + c] = inside;
            }
        }
    }
    occ
}

fn search(c: &mut Criterion) {
    let occ = pile();
    let labels: Vec<i32> = occ.iter().map(|&x| i32::from(x)).collect();
    let mut centroid = [0.0; 3];
    let mut count = 0.0;
    let mut cand = Vec::new();
    for a in 0..R {
        for b in 0..R {
            for c in 0..R {
                if occ[(a * R + b) * R + c] {
                    for (s, i) in centroid.iter_mut().zip([a, b, c]) {
                        *s += (i as f64 + 0.5) * V;
                    }
                    count += 1.0;
                }
                // Candidates: occupied voxels and their neighbours above the table.
                let near = (a.saturating_sub(1)..(a + 2).min(R)).any(|i| {
                    (b.saturating_sub(1)..(b + 2).min(R)).any(|j| {
                        (c.saturating_sub(1)..(c + 2).min(R)).any(|k| occ[(i * R + j) * R + k])
                    })
                });
                if near && (c as f64 + 0.5) * V > 0.005 {
                    cand.push([a, b, c]);
                }
            }
        }
    }
    let centroids = [[0.0; 3], centroid.map(|s| s / count)];
    // Central differences of the occupancy stand in for the smoothed gradient.
    let mut gradient = vec![0.0; 3 * R * R * R];
    for a in 1..R - 1 {
        for b in 1..R - 1 {
            for c in 1..R - 1 {
                let at =
                    |i: usize, j: usize, k: usize| f64::from(u8::from(occ[(i * R + j) * R + k]));
                let i = (a * R + b) * R + c;
                gradient[i] = 0.5 * (at(a + 1, b, c) - at(a - 1, b, c));
                gradient[R * R * R + i] = 0.5 * (at(a, b + 1, c) - at(a, b - 1, c));
                gradient[2 * R * R * R + i] = 0.5 * (at(a, b, c + 1) - at(a, b, c - 1));
            }
        }
    }
    let scene = AntipodalScene {
        resolution: R,
        occupied: &occ,
        gradient: &gradient,
        labels: &labels,
        centroids: &centroids,
        candidates: &cand,
    };
    let (rots, tilts) = orientations();
    let params = AntipodalParams::panda(V, 0.0);
    let found = best_grasps(&scene, &params, &rots, &tilts).expect("valid input");
    assert!(
        found.quality.iter().any(|&q| q > 0.0),
        "the fixture has grasps"
    );
    let name = format!("antipodal_40_pile_{}cand_72rot", cand.len());
    c.bench_function(&name, |b| {
        b.iter(|| best_grasps(&scene, &params, &rots, &tilts))
    });
}

criterion_group!(benches, search);
criterion_main!(benches);
