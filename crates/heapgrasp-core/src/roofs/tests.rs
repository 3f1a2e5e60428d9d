//! Tests of the silhouette check on rendered boxes and hand-made images.

use super::*;
use crate::primitives::box_mesh;
use crate::MeshScene;
use proptest::prelude::*;

const R: usize = 20;
const V: f64 = 0.01;

fn at(a: usize, b: usize, c: usize) -> usize {
    (a * R + b) * R + c
}

fn lattice() -> VoxelLattice {
    VoxelLattice::new([-0.1, -0.1, 0.0], V, R).unwrap()
}

fn camera() -> PinholeCamera {
    PinholeCamera::new(320, 240, 300.0, 300.0, 159.5, 119.5).unwrap()
}

/// A box of half extents `h` centred at `centre` (axis-aligned).
fn add_box(scene: &mut MeshScene, h: [f64; 3], centre: [f64; 3]) {
    let (vertices, faces) = box_mesh(h);
    let mut m = [0.0; 16];
    for i in 0..3 {
        m[i * 5] = 1.0;
        m[i * 4 + 3] = centre[i];
    }
    m[15] = 1.0;
    let pose = Pose::from_row_major("obj2world", &m).unwrap();
    scene.add_mesh(&vertices, &faces, pose).unwrap();
}

/// Views from four sides and above, at 36° from the vertical like HEAPGrasp's.
fn poses() -> Vec<Pose> {
    let mut out = Vec::new();
    for k in 0..4 {
        let phi = k as f64 * std::f64::consts::FRAC_PI_2 + 0.3;
        let (s, c) = (0.33 * 0.59, 0.33 * 0.81);
        let eye = [s * phi.cos(), s * phi.sin(), c];
        out.push(Pose::look_at(eye, [0.0, 0.0, 0.02], [0.0, 0.0, 1.0]).unwrap());
    }
    out
}

fn masks(scene: &MeshScene, poses: &[Pose]) -> Vec<Vec<bool>> {
    poses
        .iter()
        .map(|p| {
            scene
                .render_mask(&camera(), p)
                .iter()
                .map(|&m| m > 0)
                .collect()
        })
        .collect()
}

fn views<'a>(poses: &[Pose], masks: &'a [Vec<bool>]) -> Vec<SilhouetteView<'a>> {
    poses
        .iter()
        .zip(masks)
        .map(|(&cam2world, mask)| SilhouetteView {
            camera: camera(),
            cam2world,
            mask,
        })
        .collect()
}

/// The hull of a 4 cm cube on the floor (voxels 8..12 × 8..12 × 0..4) with a roof
/// `roof` voxels high on it, and the same hull with the roof cut.
fn cube_with_roof(roof: usize) -> (Vec<bool>, Vec<bool>) {
    let mut full = vec![false; R * R * R];
    let mut trimmed = full.clone();
    for a in 8..12 {
        for b in 8..12 {
            for c in 0..4 + roof {
                full[at(a, b, c)] = true;
                trimmed[at(a, b, c)] = c < 4;
            }
        }
    }
    (full, trimmed)
}

#[test]
fn a_roof_over_a_real_cube_is_explained() {
    let mut scene = MeshScene::new();
    add_box(&mut scene, [0.02, 0.02, 0.02], [0.0, 0.0, 0.02]);
    let p = poses();
    let m = masks(&scene, &p);
    let (full, trimmed) = cube_with_roof(3);
    let back = keep_silhouettes(&lattice(), &full, &trimmed, &views(&p, &m)).unwrap();
    assert!(!back.contains(&true));
}

#[test]
fn a_real_part_that_was_cut_comes_back_whole() {
    // A 2 × 2 × 8 cm pillar stands against the 4 cm cube (voxels 12..14 × 9..11 × 0..8),
    // and their hull merged; the trimming cut the pillar above the cube with the roof.
    let mut scene = MeshScene::new();
    add_box(&mut scene, [0.02, 0.02, 0.02], [0.0, 0.0, 0.02]);
    add_box(&mut scene, [0.01, 0.01, 0.04], [0.03, 0.0, 0.04]);
    let p = poses();
    let m = masks(&scene, &p);
    let (mut full, mut trimmed) = cube_with_roof(2);
    for a in 12..14 {
        for b in 9..11 {
            for c in 0..8 {
                full[at(a, b, c)] = true;
                trimmed[at(a, b, c)] = c < 4;
            }
        }
    }
    let back = keep_silhouettes(&lattice(), &full, &trimmed, &views(&p, &m)).unwrap();
    for a in 12..14 {
        for b in 9..11 {
            for c in 4..8 {
                assert!(back[at(a, b, c)], "voxel {:?} of the pillar", [a, b, c]);
            }
        }
    }
    // Whatever comes back was cut, and columns come back from the trimmed top up.
    for a in 0..R {
        for b in 0..R {
            for c in 0..R {
                let i = at(a, b, c);
                assert!(
                    !back[i] || (full[i] && !trimmed[i]),
                    "voxel {:?}",
                    [a, b, c]
                );
                if back[i] && c > 4 {
                    assert!(back[at(a, b, c - 1)], "column {a}, {b} has a gap below {c}");
                }
            }
        }
    }
    // The roof's far corner, away from the pillar, stays cut.
    assert!(!back[at(8, 8, 4)] && !back[at(8, 11, 5)]);
}

#[test]
fn levels_go_from_the_bottom_so_real_parts_explain_roofs_above_them() {
    // A 2 × 2 × 3 cm block (voxels 9..11 × 9..11 × 0..3) under a roof 3 voxels high,
    // all cut down to the bottom layer: the block's own voxels come back first and
    // explain the pixels the roof would otherwise claim, so the roof's top stays off.
    let mut scene = MeshScene::new();
    add_box(&mut scene, [0.01, 0.01, 0.015], [0.0, 0.0, 0.015]);
    let p = poses();
    let m = masks(&scene, &p);
    let mut full = vec![false; R * R * R];
    let mut trimmed = full.clone();
    for a in 9..11 {
        for b in 9..11 {
            for c in 0..6 {
                full[at(a, b, c)] = true;
                trimmed[at(a, b, c)] = c == 0;
            }
        }
    }
    let back = keep_silhouettes(&lattice(), &full, &trimmed, &views(&p, &m)).unwrap();
    for a in 9..11 {
        for b in 9..11 {
            assert!(back[at(a, b, 1)] && back[at(a, b, 2)], "column {a}, {b}");
            assert!(!back[at(a, b, 5)], "roof top of column {a}, {b}");
        }
    }
}

#[test]
fn without_cut_voxels_or_views_nothing_comes_back() {
    let mut scene = MeshScene::new();
    add_box(&mut scene, [0.01, 0.01, 0.01], [0.0, 0.0, 0.05]);
    let p = poses();
    let m = masks(&scene, &p);
    let (full, _) = cube_with_roof(4);
    let none = keep_silhouettes(&lattice(), &full, &full, &views(&p, &m)).unwrap();
    assert!(!none.contains(&true));
    let (full, trimmed) = cube_with_roof(4);
    let none = keep_silhouettes(&lattice(), &full, &trimmed, &[]).unwrap();
    assert!(!none.contains(&true));
}

#[test]
fn the_result_does_not_depend_on_the_views_order() {
    let mut scene = MeshScene::new();
    add_box(&mut scene, [0.02, 0.02, 0.02], [0.0, 0.0, 0.02]);
    add_box(&mut scene, [0.01, 0.005, 0.015], [0.01, 0.0, 0.055]);
    let mut p = poses();
    let m = masks(&scene, &p);
    let (full, trimmed) = cube_with_roof(5);
    let a = keep_silhouettes(&lattice(), &full, &trimmed, &views(&p, &m)).unwrap();
    assert!(a.contains(&true));
    p.reverse();
    let mut m = m;
    m.reverse();
    let b = keep_silhouettes(&lattice(), &full, &trimmed, &views(&p, &m)).unwrap();
    assert_eq!(a, b);
}

#[test]
fn bad_shapes_name_the_argument() {
    let (full, trimmed) = cube_with_roof(2);
    let mask = vec![false; 10];
    let v = [SilhouetteView {
        camera: camera(),
        cam2world: poses()[0],
        mask: &mask,
    }];
    let err = keep_silhouettes(&lattice(), &full, &trimmed, &v).unwrap_err();
    assert!(
        matches!(err, Error::Shape { ref name, .. } if name == "masks[0]"),
        "{err}"
    );
    let err = keep_silhouettes(&lattice(), &full[1..], &trimmed, &[]).unwrap_err();
    assert!(
        matches!(err, Error::Shape { ref name, .. } if name == "full"),
        "{err}"
    );
    let err = keep_silhouettes(&lattice(), &full, &trimmed[1..], &[]).unwrap_err();
    assert!(
        matches!(err, Error::Shape { ref name, .. } if name == "trimmed"),
        "{err}"
    );
    assert!(VoxelLattice::new([0.0, f64::NAN, 0.0], V, R).is_err());
    assert!(VoxelLattice::new([0.0; 3], 0.0, R).is_err());
    assert!(VoxelLattice::new([0.0; 3], V, 0).is_err());
}

#[test]
fn a_voxel_size_whose_grid_side_overflows_is_named() {
    // 1e308 per voxel is finite, but 2 voxels are not: the error names voxel_size (the
    // argument), not the grid's side.
    let err = VoxelLattice::new([0.0; 3], 1e308, 2).unwrap_err();
    assert!(
        matches!(err, Error::Value { ref name, .. } if name == "voxel_size"),
        "{err}"
    );
    assert!(VoxelLattice::new([0.0; 3], 1e308, 1).is_ok());
}

#[test]
fn footprints_cover_the_projected_sphere() {
    let cam = camera();
    let p = poses()[1];
    let mask = vec![false; cam.pixel_count()];
    let view = SilhouetteView {
        camera: cam,
        cam2world: p,
        mask: &mask,
    };
    let world2cam = p.inverse();
    let rho = 0.5 * 3.0f64.sqrt() * V;
    for c in [[0.0, 0.0, 0.02], [0.03, -0.02, 0.05], [-0.05, 0.04, 0.0]] {
        let b = footprint(&view, V, c).unwrap();
        // Points on the sphere project inside the box (to within half a pixel).
        for k in 0..64 {
            let (t, s) = (k as f64 * 0.7, k as f64 * 1.3);
            let d = [t.cos() * s.sin(), t.sin() * s.sin(), s.cos()];
            let q = nalgebra::Point3::new(c[0] + rho * d[0], c[1] + rho * d[1], c[2] + rho * d[2]);
            let q = world2cam.transform_point(&q);
            let u = cam.fx * q.x / q.z + cam.cx;
            let v = cam.fy * q.y / q.z + cam.cy;
            let slack = 0.5 + 0.05 * (b.u1 - b.u0) as f64;
            assert!(
                u >= b.u0 as f64 - slack && u <= b.u1 as f64 + slack,
                "u {u} {b:?}"
            );
            assert!(
                v >= b.v0 as f64 - slack && v <= b.v1 as f64 + slack,
                "v {v} {b:?}"
            );
        }
    }
    // Behind the camera, or off the image: no box.
    let eye = p.translation();
    assert!(footprint(&view, V, [2.0 * eye.x, 2.0 * eye.y, 2.0 * eye.z]).is_none());
    assert!(footprint(&view, V, [5.0, 5.0, 0.0]).is_none());
}

#[test]
fn opening_drops_slivers_and_the_border() {
    let (w, h) = (12, 9);
    let mut img = vec![false; w * h];
    let mut set = |u0: usize, u1: usize, v0: usize, v1: usize| {
        for v in v0..=v1 {
            for u in u0..=u1 {
                img[v * w + u] = true;
            }
        }
    };
    set(1, 3, 1, 3); // a 3 × 3 block: kept
    set(6, 7, 1, 7); // a sliver two pixels wide: dropped
                     // Two columns on the image's edge: dropped, because outside counts as unset (with
                     // outside set they would be the edge of a wider block and stay).
    set(10, 11, 3, 8);
    let out = binary_opening_3x3(&img, w, h);
    for v in 0..h {
        for u in 0..w {
            let want = (1..=3).contains(&u) && (1..=3).contains(&v);
            assert_eq!(out[v * w + u], want, "pixel ({u}, {v})");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn paint_is_the_union_of_the_boxes(
        boxes in proptest::collection::vec((0usize..16, 0usize..16, 0usize..11, 0usize..11), 0..12)
    ) {
        let (w, h) = (16, 11);
        let boxes: Vec<PixelBox> = boxes
            .into_iter()
            .map(|(a, b, c, d)| PixelBox { u0: a.min(b), u1: a.max(b), v0: c.min(d), v1: c.max(d) })
            .collect();
        let got = paint(w, h, boxes.iter().copied());
        for v in 0..h {
            for u in 0..w {
                let want = boxes.iter().any(|b| (b.u0..=b.u1).contains(&u) && (b.v0..=b.v1).contains(&v));
                prop_assert_eq!(got[v * w + u], want);
            }
        }
    }

    #[test]
    fn opening_is_erosion_then_dilation(
        dense in proptest::collection::vec(any::<bool>(), 110),
        sparse in proptest::collection::vec(proptest::bool::weighted(0.12), 110),
    ) {
        // Dense images fill the image; sparse ones leave a small window of set pixels
        // somewhere in it, which is all the opening visits.
        for bits in [dense, sparse] {
            let (w, h) = (11usize, 10usize);
            let get = |img: &[bool], u: isize, v: isize| {
                u >= 0 && v >= 0 && (u as usize) < w && (v as usize) < h && img[v as usize * w + u as usize]
            };
            let mut eroded = vec![false; w * h];
            for v in 0..h as isize {
                for u in 0..w as isize {
                    eroded[v as usize * w + u as usize] =
                        (-1..=1).all(|dv| (-1..=1).all(|du| get(&bits, u + du, v + dv)));
                }
            }
            let out = binary_opening_3x3(&bits, w, h);
            for v in 0..h as isize {
                for u in 0..w as isize {
                    let want = (-1..=1).any(|dv| (-1..=1).any(|du| get(&eroded, u + du, v + dv)));
                    prop_assert_eq!(out[v as usize * w + u as usize], want);
                }
            }
        }
    }
}
