use super::*;
use proptest::prelude::*;

/// Points of a `nx × ny` lattice of `step` metres in the plane `z = height`.
fn plate(nx: usize, ny: usize, step: f64, height: f64) -> Vec<Point> {
    let mut points = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            points.push([i as f64 * step, j as f64 * step, height]);
        }
    }
    points
}

/// Points on a sphere of `radius` (a Fibonacci lattice).
fn sphere(n: usize, radius: f64) -> Vec<Point> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            [radius * r * t.cos(), radius * r * t.sin(), radius * z]
        })
        .collect()
}

fn brute_nearest(points: &[Point], i: usize, k: usize) -> Vec<u32> {
    let mut d: Vec<(f64, u32)> = points
        .iter()
        .enumerate()
        .map(|(j, q)| (sub(q, &points[i]).norm_squared(), j as u32))
        .collect();
    d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    d.into_iter().take(k).map(|(_, j)| j).collect()
}

fn brute_max_distance_sq(image: &[bool], side: usize) -> i64 {
    let mut best = 0;
    for a in 0..side * side {
        if !image[a] {
            continue;
        }
        let nearest = (0..side * side)
            .filter(|&b| !image[b])
            .map(|b| {
                let (dr, dc) = (
                    (a / side) as i64 - (b / side) as i64,
                    (a % side) as i64 - (b % side) as i64,
                );
                dr * dr + dc * dc
            })
            .min()
            .unwrap_or(0);
        best = best.max(nearest);
    }
    best
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn the_grid_finds_the_true_nearest_points(
        cloud in prop::collection::vec(prop::array::uniform3(-0.2f64..0.2), 12..200),
        k in 3usize..12,
    ) {
        let index = CloudIndex::new(&cloud, 0..cloud.len(), neighbour_cell(&cloud));
        let k = k.min(cloud.len());
        for i in 0..cloud.len() {
            prop_assert_eq!(nearest(&cloud, &index, i, k), brute_nearest(&cloud, i, k));
        }
    }

    #[test]
    fn the_distance_transform_is_exact(bits in prop::collection::vec(any::<bool>(), 81)) {
        let side = 9;
        let mut image = bits;
        for k in 0..side {
            // A false border, as the patch image has.
            image[k] = false;
            image[(side - 1) * side + k] = false;
            image[k * side] = false;
            image[k * side + side - 1] = false;
        }
        prop_assert_eq!(max_distance_sq(&image, side), brute_max_distance_sq(&image, side));
    }
}

#[test]
fn a_plate_has_vertical_normals_and_no_curvature() {
    let points = plate(12, 12, 0.0075, 0.1);
    let (normals, curvature) = point_normals(&points, 10, 1).expect("valid");
    for (n, c) in normals.iter().zip(&curvature) {
        assert!((n[2].abs() - 1.0).abs() < 1e-9, "{n:?}");
        assert!(c.abs() < 1e-9);
    }
}

#[test]
fn a_sphere_has_outward_normals() {
    let points = sphere(600, 0.05);
    let (normals, curvature) = point_normals(&points, 10, 2).expect("valid");
    for (p, n) in points.iter().zip(&normals) {
        let radial = Vector3::from(*p).normalize();
        assert!(radial.dot(&Vector3::from(*n)) > 0.98);
    }
    assert!(curvature
        .iter()
        .all(|&c| (0.0..1.0 / 3.0 + 1e-12).contains(&c)));
}

#[test]
fn hulls_drop_collinear_points() {
    let square = convex_hull(vec![(0, 0), (2, 0), (2, 2), (0, 2), (1, 1), (1, 0)]);
    assert_eq!(square, vec![(0, 0), (2, 0), (2, 2), (0, 2)]);
    assert!(convex_hull(vec![(0, 0), (1, 1), (2, 2), (3, 3)]).len() < 3);
    assert!(inside_hull(&square, (1, 0)) && inside_hull(&square, (1, 1)));
    assert!(!inside_hull(&square, (3, 1)));
}

#[test]
fn a_wide_plate_holds_a_pad_and_a_strip_does_not() {
    // 9 × 9 cm at 7.5 mm: the patch fills the disc. 1.5 cm wide: too narrow for 26 px.
    let wide = plate(13, 13, 0.0075, 0.0);
    let up = vec![[0.0, 0.0, 1.0]; wide.len()];
    let centre = 6 * 13 + 6;
    let mut only = vec![false; wide.len()];
    only[centre] = true;
    let ok = contact_patches(&wide, &up, &only, 1).expect("valid");
    assert!(ok[centre]);
    assert_eq!(ok.iter().filter(|&&v| v).count(), 1);
    let strip = plate(13, 3, 0.0075, 0.0);
    let up = vec![[0.0, 0.0, 1.0]; strip.len()];
    let all = vec![true; strip.len()];
    assert!(!contact_patches(&strip, &up, &all, 1)
        .expect("valid")
        .iter()
        .any(|&v| v));
}

#[test]
fn facing_plates_make_antipodal_pairs() {
    // Two 3 × 3 plates 5 cm apart, normals facing away from each other.
    let mut points = plate(3, 3, 0.0075, 0.0);
    points.extend(plate(3, 3, 0.0075, 0.05));
    let normals: Vec<Point> = (0..points.len())
        .map(|i| {
            if i < 9 {
                [0.0, 0.0, -1.0]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect();
    let usable = vec![true; points.len()];
    let pairs = antipodal_pairs(&points, &normals, &usable, 0.0075, 0.08, 150.0, 1).expect("valid");
    // Every bottom point pairs with the top points within 15° of straight across.
    assert!(pairs.first.iter().all(|&i| i < 9) && pairs.second.iter().all(|&j| j >= 9));
    let straight = (0..pairs.first.len()).filter(|&k| pairs.second[k] == pairs.first[k] + 9);
    assert_eq!(straight.clone().count(), 9);
    for k in straight {
        assert!((pairs.quality[k] - 180.0).abs() < 1e-9);
        assert!((pairs.width[k] - 0.0575).abs() < 1e-12);
    }
    let sorted = pairs.first.windows(2).all(|w| w[0] <= w[1]);
    assert!(sorted);
    let four = antipodal_pairs(&points, &normals, &usable, 0.0075, 0.08, 150.0, 4).expect("valid");
    assert_eq!(pairs, four);
    // Too wide for a 5 cm opening.
    let none = antipodal_pairs(&points, &normals, &usable, 0.0075, 0.05, 150.0, 1).expect("valid");
    assert!(none.first.is_empty());
}

#[test]
fn thread_count_does_not_change_normals_or_patches() {
    let points = sphere(900, 0.04);
    let (n1, c1) = point_normals(&points, 10, 1).expect("valid");
    let (n4, c4) = point_normals(&points, 10, 4).expect("valid");
    assert_eq!((n1.clone(), c1), (n4, c4));
    let all = vec![true; points.len()];
    let p1 = contact_patches(&points, &n1, &all, 1).expect("valid");
    let p4 = contact_patches(&points, &n1, &all, 4).expect("valid");
    assert_eq!(p1, p4);
}

#[test]
fn bad_input_is_an_error() {
    assert!(points_from_flat("points", &[0.0, 1.0]).is_err());
    assert!(points_from_flat("points", &[0.0, 1.0, f64::NAN]).is_err());
    let points = plate(4, 4, 0.01, 0.0);
    assert!(point_normals(&points, 2, 1).is_err());
    assert!(point_normals(&points[..5], 10, 1).is_err());
    let up = vec![[0.0, 0.0, 1.0]; points.len()];
    let all = vec![true; points.len()];
    assert!(contact_patches(&points, &up[..3], &all, 1).is_err());
    assert!(contact_patches(&points, &vec![[0.0, 0.0, 2.0]; 16], &all, 1).is_err());
    assert!(contact_patches(&points, &up, &all[..3], 1).is_err());
    for (voxel, width, quality) in [
        (-1.0, 0.08, 150.0),
        (0.0, f64::NAN, 150.0),
        (0.0, 0.08, 181.0),
    ] {
        assert!(antipodal_pairs(&points, &up, &all, voxel, width, quality, 1).is_err());
    }
}

#[test]
fn extreme_coordinates_end() {
    // A far outlier, coordinates near the float range's ends, all points at one place.
    let mut points = sphere(50, 0.05);
    points.push([1e9, 0.0, 0.0]);
    let (normals, _) = point_normals(&points, 10, 1).expect("valid");
    assert_eq!(normals.len(), 51);
    let wild = vec![
        [1.7e308, 0.0, 0.0],
        [-1.7e308, 1.0, 0.0],
        [0.0, 1e300, -1e300],
        [5e-324, 0.0, 0.0],
    ];
    assert_eq!(point_normals(&wild, 3, 1).expect("valid").0.len(), 4);
    let same = vec![[0.3, 0.3, 0.3]; 12];
    let (normals, curvature) = point_normals(&same, 10, 1).expect("valid");
    assert!(normals.iter().all(|n| n.iter().all(|v| v.is_finite())));
    assert!(curvature.iter().all(|c| c.is_finite()));
    let up = vec![[0.0, 0.0, 1.0]; wild.len()];
    let all = vec![true; wild.len()];
    assert!(contact_patches(&wild, &up, &all, 1).is_ok());
    assert!(antipodal_pairs(&wild, &up, &all, 0.0, 1.7e308, 0.0, 1).is_ok());
}
