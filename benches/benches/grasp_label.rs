//! Criterion benchmark of the exact-geometry grasp labeller (`heapgrasp_core::grasp_label`):
//! five objects with the piece counts of the simulator's (a 16-piece cup, a 3-piece
//! bottle, a box, a 64-vertex cylinder and a 300-vertex blob), the Panda hand's boxes, and
//! VGN's grasps: 120 surface points × 6 yaws (720 grasps), labelled on 1 and 2 threads.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use heapgrasp_core::grasp_label::{GraspLabeller, GraspScene, HandGeometry, LabelParams};
use heapgrasp_core::gripper::box_corners;
use heapgrasp_core::Pose;

/// A ring of `n` points of radius `r` at height `z`, starting at angle `a0`, spanning `da`.
fn ring(r: f64, z: f64, n: usize, a0: f64, da: f64) -> Vec<f64> {
    (0..n)
        .flat_map(|k| {
            let a = a0 + da * k as f64 / (n - 1).max(1) as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

fn cylinder(r: f64, h: f64) -> Vec<f64> {
    let full = std::f64::consts::TAU * 31.0 / 32.0;
    [
        ring(r, -h / 2.0, 32, 0.0, full),
        ring(r, h / 2.0, 32, 0.0, full),
    ]
    .concat()
}

/// A cup: 15 wall wedges and a base, as `sim/objects.py` decomposes it.
fn cup() -> Vec<Vec<f64>> {
    let step = std::f64::consts::TAU / 15.0;
    let mut pieces: Vec<Vec<f64>> = (0..15)
        .map(|k| {
            let a = k as f64 * step;
            [
                ring(0.034, -0.045, 2, a, step),
                ring(0.040, -0.045, 2, a, step),
                ring(0.037, 0.045, 2, a, step),
                ring(0.043, 0.045, 2, a, step),
            ]
            .concat()
        })
        .collect();
    pieces.push(
        cylinder(0.034, 0.006)
            .iter()
            .enumerate()
            .map(|(i, &v)| if i % 3 == 2 { v - 0.042 } else { v })
            .collect(),
    );
    pieces
}

/// A bottle: body, shoulder and neck.
fn bottle() -> Vec<Vec<f64>> {
    let full = std::f64::consts::TAU * 31.0 / 32.0;
    vec![
        [
            ring(0.03, -0.06, 32, 0.0, full),
            ring(0.03, 0.02, 32, 0.0, full),
        ]
        .concat(),
        [
            ring(0.03, 0.02, 32, 0.0, full),
            ring(0.012, 0.045, 32, 0.0, full),
        ]
        .concat(),
        [
            ring(0.012, 0.045, 32, 0.0, full),
            ring(0.012, 0.07, 32, 0.0, full),
        ]
        .concat(),
    ]
}

/// A box of half extents `h` about the origin.
fn cuboid(h: [f64; 3]) -> Vec<f64> {
    box_corners(h.map(|x| -x), h)
}

/// A lumpy blob of 300 vertices (the random_urdfs meshes are a few hundred).
fn blob(rand: &mut impl FnMut() -> f64) -> Vec<f64> {
    (0..300)
        .flat_map(|_| {
            let z = 2.0 * rand() - 1.0;
            let a = std::f64::consts::TAU * rand();
            let s = (1.0 - z * z).sqrt();
            let r = 0.03 * (1.0 + 0.15 * rand());
            [r * s * a.cos(), 1.4 * r * s * a.sin(), 0.8 * r * z]
        })
        .collect()
}

fn translation(t: [f64; 3]) -> Pose {
    let m = [
        1.0, 0.0, 0.0, t[0], 0.0, 1.0, 0.0, t[1], 0.0, 0.0, 1.0, t[2], 0.0, 0.0, 0.0, 1.0,
    ];
    Pose::from_row_major("obj2world", &m).expect("rigid")
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|x| x / n)
}

/// VGN's grasps: points on each object's bounding ball (its centre `c`, radius `r`)
/// with outward normal n_z > -0.1, depth U[-0.1, 1.1] finger depths in front of the
/// palm, z = -normal, 6 yaws in [0, π).
fn grasps(objects: &[([f64; 3], f64)], rand: &mut impl FnMut() -> f64) -> Vec<Pose> {
    let hand = HandGeometry::panda();
    let mut out = Vec::new();
    while out.len() < 720 {
        let (c, r) = objects[(rand() * objects.len() as f64) as usize % objects.len()];
        let n = unit([2.0 * rand() - 1.0, 2.0 * rand() - 1.0, 2.0 * rand() - 1.0]);
        if n[2] <= -0.1 || c[2] + r * n[2] < 0.0 {
            continue;
        }
        let depth = (-0.1 + 1.2 * rand()) * hand.finger_depth() + hand.palm_front;
        let t: [f64; 3] = std::array::from_fn(|i| c[i] + n[i] * (r + depth));
        let z = n.map(|x| -x);
        let helper = if z[0].abs() > 0.9999 {
            [0.0, 1.0, 0.0]
        } else {
            [1.0, 0.0, 0.0]
        };
        let y0 = unit(cross(z, helper));
        let x0 = cross(y0, z);
        for k in 0..6 {
            let a = std::f64::consts::PI * k as f64 / 6.0;
            let x: [f64; 3] = std::array::from_fn(|i| a.cos() * x0[i] + a.sin() * y0[i]);
            let y = cross(z, x);
            let m = [
                x[0], y[0], z[0], t[0], x[1], y[1], z[1], t[1], x[2], y[2], z[2], t[2], 0.0, 0.0,
                0.0, 1.0,
            ];
            out.push(Pose::from_row_major("tcp2world", &m).expect("rigid"));
        }
    }
    out
}

fn label(c: &mut Criterion) {
    let mut seed = 38u64;
    let mut rand = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let params = LabelParams {
        pregrasp_distance: 0.05,
        friction: 1.0,
        hand_margin: 0.001,
        object_margin: 0.001,
        min_width: 0.004,
        approach_lag: 0.0015,
    };
    let mut parts = HandGeometry::panda().parts();
    (parts.palm_threshold, parts.finger_threshold) = (0.0027, 0.0012);
    let mut labeller =
        GraspLabeller::new(GraspScene::new(0.0).expect("table"), &parts, params).expect("valid");
    let blob = blob(&mut rand);
    let objects: [(Vec<Vec<f64>>, [f64; 3], f64); 5] = [
        (cup(), [0.09, 0.10, 0.045], 0.065),
        (bottle(), [0.20, 0.09, 0.06], 0.075),
        (vec![cuboid([0.025, 0.02, 0.03])], [0.15, 0.18, 0.03], 0.045),
        (vec![cylinder(0.025, 0.08)], [0.22, 0.21, 0.04], 0.05),
        (vec![blob], [0.08, 0.21, 0.025], 0.05),
    ];
    for (id, (pieces, at, _)) in objects.iter().enumerate() {
        let slices: Vec<&[f64]> = pieces.iter().map(Vec::as_slice).collect();
        labeller
            .add_object(id as i32 + 1, translation(*at), &slices, 0.0015)
            .expect("valid object");
    }
    let balls: Vec<([f64; 3], f64)> = objects.iter().map(|(_, at, r)| (*at, *r)).collect();
    let poses = grasps(&balls, &mut rand);
    let labels = labeller.label(&poses, 1);
    assert!(
        labels.iter().any(|l| l.success),
        "the fixture has successes"
    );
    let mut group = c.benchmark_group("grasp_label");
    group.throughput(Throughput::Elements(poses.len() as u64));
    for threads in [1, 2] {
        group.bench_function(
            format!(
                "5_objects_{}_pieces_720_grasps_{threads}t",
                labeller.scene().piece_count()
            ),
            |b| b.iter(|| labeller.label(&poses, threads)),
        );
    }
    group.finish();
}

criterion_group!(benches, label);
criterion_main!(benches);
