use super::*;

fn params() -> LabelParams {
    LabelParams {
        pregrasp_distance: 0.05,
        friction: 1.0,
        hand_margin: 0.001,
        object_margin: 0.001,
        min_width: 0.004,
        approach_lag: 0.0,
    }
}

const MARGINS: f64 = 0.002;

/// A pose from TCP axes (world columns) and a position.
fn pose(x: [f64; 3], y: [f64; 3], z: [f64; 3], t: [f64; 3]) -> Pose {
    let m = [
        x[0], y[0], z[0], t[0], x[1], y[1], z[1], t[1], x[2], y[2], z[2], t[2], 0.0, 0.0, 0.0, 1.0,
    ];
    Pose::from_row_major("pose", &m).unwrap()
}

fn translation(t: [f64; 3]) -> Pose {
    pose([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], t)
}

/// A top-down grasp (approach −z) with the fingers closing along world ±y.
fn top_down(t: [f64; 3]) -> Pose {
    pose([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0], t)
}

/// Corners of a box of half extents `h` about the origin, flat (8, 3).
fn box_piece(h: [f64; 3]) -> Vec<f64> {
    crate::gripper::box_corners(h.map(|x| -x), h)
}

/// A polyhedral sphere of radius `r` (latitude-longitude vertices, poles included).
fn sphere_piece(r: f64) -> Vec<f64> {
    let mut v = vec![0.0, 0.0, r, 0.0, 0.0, -r];
    for i in 1..24 {
        let theta = std::f64::consts::PI * i as f64 / 24.0;
        for j in 0..48 {
            let phi = std::f64::consts::TAU * j as f64 / 48.0;
            v.extend([
                r * theta.sin() * phi.cos(),
                r * theta.sin() * phi.sin(),
                r * theta.cos(),
            ]);
        }
    }
    v
}

fn labeller(objects: &[(i32, [f64; 3], Vec<f64>)]) -> GraspLabeller {
    let mut l = GraspLabeller::new(
        GraspScene::new(0.0).unwrap(),
        &HandGeometry::panda().parts(),
        params(),
    )
    .unwrap();
    for (id, at, piece) in objects {
        l.add_object(*id, translation(*at), &[piece], 0.0).unwrap();
    }
    l
}

/// A 3 x 5 x 6 cm box standing on the table at the origin.
fn lone_box() -> GraspLabeller {
    labeller(&[(1, [0.0, 0.0, 0.03], box_piece([0.015, 0.025, 0.03]))])
}

#[test]
fn a_box_between_the_fingers_is_held_at_its_width() {
    let l = lone_box();
    let label = l.label_one(&top_down([0.0, 0.0, 0.04]));
    assert_eq!(label.reason, Reason::Success, "{label:?}");
    assert!(label.success);
    assert_eq!(label.object, 1);
    assert!(
        (f64::from(label.width) - (0.05 + 2.0 * MARGINS)).abs() < 1e-4,
        "{label:?}"
    );
}

#[test]
fn a_box_off_centre_is_pushed_between_the_fingers() {
    let l = lone_box();
    let label = l.label_one(&top_down([0.0, 0.012, 0.04]));
    assert_eq!(label.reason, Reason::Success, "{label:?}");
    assert!(
        (f64::from(label.width) - (0.05 + 2.0 * MARGINS)).abs() < 1e-4,
        "{label:?}"
    );
}

#[test]
fn a_box_wider_than_the_opening_collides() {
    let l = labeller(&[(1, [0.0, 0.0, 0.03], box_piece([0.015, 0.045, 0.03]))]);
    let label = l.label_one(&top_down([0.0, 0.0, 0.04]));
    assert_eq!(label.reason, Reason::Collision);
    assert!(!label.success);
    assert_eq!(label.object, -1);
    assert_eq!(label.width, 0.08);
}

#[test]
fn nothing_between_the_fingers_is_empty() {
    let l = lone_box();
    let label = l.label_one(&top_down([0.2, 0.0, 0.04]));
    assert_eq!(label.reason, Reason::Empty);
}

#[test]
fn fingertips_in_the_table_collide() {
    // A 4 cm tall box: the palm's face stays above it with the fingertips this low.
    let l = labeller(&[(1, [0.0, 0.0, 0.02], box_piece([0.015, 0.025, 0.02]))]);
    // Fingertips 0.5 mm above the table: within the hand's 1 mm margin.
    let label = l.label_one(&top_down([0.0, 0.0, 0.0072 + 0.0005]));
    assert_eq!(label.reason, Reason::Collision);
    let label = l.label_one(&top_down([0.0, 0.0, 0.0072 + 0.0015]));
    assert_eq!(label.reason, Reason::Success);
}

#[test]
fn a_side_grasp_whose_palm_hits_the_table_collides() {
    // Approach along world +x, TCP x = world z: the palm reaches 3.2 cm up and down
    // from the TCP, the fingers 1.05 cm.
    let l = labeller(&[(1, [0.1, 0.0, 0.03], box_piece([0.03, 0.025, 0.03]))]);
    let side = |h: f64| {
        pose(
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.1, 0.0, h],
        )
    };
    assert_eq!(l.label_one(&side(0.04)).reason, Reason::Success);
    let low = l.label_one(&side(0.025));
    assert_eq!(low.reason, Reason::Collision, "{low:?}");
    // The table alone: the palm reaches it, while the fingers (1.45 cm up) do not.
    let table = labeller(&[]);
    assert_eq!(table.label_one(&side(0.025)).reason, Reason::Collision);
    assert_eq!(table.label_one(&side(0.04)).reason, Reason::Empty);
}

#[test]
fn contact_thresholds_widen_what_touches() {
    // The side grasp's palm 2 mm above the table.
    let side = pose(
        [0.0, 0.0, 1.0],
        [0.0, -1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.1, 0.0, 0.032 + 0.002],
    );
    assert_eq!(labeller(&[]).label_one(&side).reason, Reason::Empty);
    let mut hand = HandGeometry::panda().parts();
    hand.palm_threshold = 0.0025;
    hand.finger_threshold = 0.0012;
    let l = GraspLabeller::new(GraspScene::new(0.0).unwrap(), &hand, params()).unwrap();
    assert_eq!(l.label_one(&side).reason, Reason::Collision);
    // The fingers have their own: a top-down grasp 2 mm above the table is free.
    let low = top_down([0.0, 0.0, 0.0072 + 0.0025]);
    assert_eq!(l.label_one(&low).reason, Reason::Empty);
    // A pair takes the smaller threshold: a finger whose outer side passes 2.5 mm
    // beside a box touches it only when the box's threshold reaches past the margins too.
    let beside = top_down([0.0, 0.015 + 0.0025 + 0.056, 0.045]);
    for (object, expect) in [(0.0, Reason::Empty), (0.001, Reason::Collision)] {
        let mut l = GraspLabeller::new(GraspScene::new(0.0).unwrap(), &hand, params()).unwrap();
        l.add_object(
            1,
            translation([0.0, 0.0, 0.03]),
            &[&box_piece([0.015, 0.015, 0.03])],
            object,
        )
        .unwrap();
        assert_eq!(
            l.label_one(&beside).reason,
            expect,
            "object threshold {object}"
        );
    }
}

#[test]
fn the_approach_lag_shortens_the_sweep() {
    // Fingertips 0.5 mm into the table's margin at the grasp pose.
    let low = top_down([0.0, 0.0, 0.0072 + 0.0005]);
    assert_eq!(labeller(&[]).label_one(&low).reason, Reason::Collision);
    let mut p = params();
    p.approach_lag = 0.001;
    let l = GraspLabeller::new(
        GraspScene::new(0.0).unwrap(),
        &HandGeometry::panda().parts(),
        p,
    )
    .unwrap();
    assert_eq!(l.label_one(&low).reason, Reason::Empty);
}

#[test]
fn a_sphere_is_held_through_its_centre_and_not_past_the_friction_cone() {
    let r = 0.025;
    let l = labeller(&[(3, [0.0, 0.0, r], sphere_piece(r))]);
    let centre = l.label_one(&top_down([0.0, 0.0, r]));
    assert_eq!(centre.reason, Reason::Success, "{centre:?}");
    assert!((f64::from(centre.width) - (2.0 * r + 2.0 * MARGINS)).abs() < 1e-3);
    // Fingertips above the equator: the tip edge touches where the sphere's normal is
    // tilted by `tilt` from the closing axis (friction 1: the cone is 45°).
    let tip_at = |tilt: f64| top_down([0.0, 0.0, r + r * tilt.to_radians().sin() + 0.0072]);
    let inside = l.label_one(&tip_at(30.0));
    assert_eq!(inside.reason, Reason::Success, "{inside:?}");
    let outside = l.label_one(&tip_at(55.0));
    assert_eq!(outside.reason, Reason::NotAntipodal, "{outside:?}");
    // A larger friction coefficient holds it.
    let mut grippy = params();
    grippy.friction = 2.0;
    let mut l2 = GraspLabeller::new(
        GraspScene::new(0.0).unwrap(),
        &HandGeometry::panda().parts(),
        grippy,
    )
    .unwrap();
    l2.add_object(3, translation([0.0, 0.0, r]), &[&sphere_piece(r)], 0.0)
        .unwrap();
    assert_eq!(l2.label_one(&tip_at(55.0)).reason, Reason::Success);
}

#[test]
fn one_object_per_finger_fails() {
    // Two 1.5 cm thick plates, 2 cm apart, one in front of each finger.
    let plate = box_piece([0.015, 0.0075, 0.03]);
    let l = labeller(&[
        (1, [0.0, 0.0175, 0.03], plate.clone()),
        (2, [0.0, -0.0175, 0.03], plate),
    ]);
    let label = l.label_one(&top_down([0.0, 0.0, 0.04]));
    assert_eq!(label.reason, Reason::TwoObjects, "{label:?}");
}

#[test]
fn a_thin_sheet_closes_too_narrow() {
    let l = labeller(&[(1, [0.0, 0.0, 0.03], box_piece([0.015, 0.0001, 0.03]))]);
    let label = l.label_one(&top_down([0.0, 0.0, 0.04]));
    // 0.2 mm + the margins (4 mm) is 4.2 mm: held; without margins it would not be.
    assert_eq!(label.reason, Reason::Success, "{label:?}");
    let mut p = params();
    p.min_width = 0.005;
    let mut l = GraspLabeller::new(
        GraspScene::new(0.0).unwrap(),
        &HandGeometry::panda().parts(),
        p,
    )
    .unwrap();
    l.add_object(
        1,
        translation([0.0, 0.0, 0.03]),
        &[&box_piece([0.015, 0.0001, 0.03])],
        0.0,
    )
    .unwrap();
    assert_eq!(
        l.label_one(&top_down([0.0, 0.0, 0.04])).reason,
        Reason::Narrow
    );
}

/// Some objects and grasps all over them.
fn clutter() -> (GraspLabeller, Vec<Pose>) {
    let l = labeller(&[
        (1, [0.0, 0.0, 0.03], box_piece([0.015, 0.025, 0.03])),
        (2, [0.06, 0.02, 0.025], sphere_piece(0.025)),
        (5, [0.02, 0.07, 0.02], box_piece([0.04, 0.012, 0.02])),
    ]);
    let mut grasps = Vec::new();
    let mut seed = 12345u64;
    let mut rand = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..400 {
        let t = [
            -0.03 + 0.12 * rand(),
            -0.03 + 0.13 * rand(),
            0.01 + 0.06 * rand(),
        ];
        let tilt = 0.8 * rand();
        let yaw = std::f64::consts::PI * rand();
        let az = std::f64::consts::TAU * rand();
        let z = Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), -tilt.cos());
        let helper = if z.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let x0 = helper.cross(&z).normalize();
        let y0 = z.cross(&x0);
        let x = x0 * yaw.cos() + y0 * yaw.sin();
        let y = z.cross(&x);
        grasps.push(pose(x.into(), y.into(), z.into(), t));
    }
    (l, grasps)
}

#[test]
fn thread_count_does_not_change_labels() {
    let (l, grasps) = clutter();
    let one = l.label(&grasps, 1);
    for threads in [0, 2, 3, 7] {
        assert_eq!(l.label(&grasps, threads), one);
    }
    let per = grasps.iter().map(|g| l.label_one(g)).collect::<Vec<_>>();
    assert_eq!(per, one);
    // The scene exercises more than one outcome.
    let mut seen: Vec<Reason> = one.iter().map(|g| g.reason).collect();
    seen.sort_by_key(|r| *r as u8);
    seen.dedup();
    assert!(seen.len() >= 4, "{seen:?}");
}

#[test]
fn bad_parameters_and_pieces_are_errors() {
    let mut p = params();
    p.friction = f64::NAN;
    assert!(matches!(
        GraspLabeller::new(GraspScene::new(0.0).unwrap(), &HandGeometry::panda().parts(), p),
        Err(Error::Value { name, .. }) if name == "friction"
    ));
    let mut hand = HandGeometry::panda();
    hand.finger_split = 0.01;
    assert!(matches!(
        hand.validate(),
        Err(Error::Value { name, .. }) if name == "hand.finger_split"
    ));
    let mut parts = HandGeometry::panda().parts();
    parts.right.clear();
    assert!(matches!(
        GraspLabeller::new(GraspScene::new(0.0).unwrap(), &parts, params()),
        Err(Error::Value { name, .. }) if name == "hand.right"
    ));
    let mut parts = HandGeometry::panda().parts();
    parts.left[1] = vec![0.0; 12];
    assert!(matches!(
        GraspLabeller::new(GraspScene::new(0.0).unwrap(), &parts, params()),
        Err(Error::Mesh { name, .. }) if name == "hand.left[1]"
    ));
    let mut p = params();
    p.min_width = 0.09;
    assert!(GraspLabeller::new(
        GraspScene::new(0.0).unwrap(),
        &HandGeometry::panda().parts(),
        p
    )
    .is_err());
    assert!(GraspScene::new(f64::INFINITY).is_err());
    let mut s = GraspScene::new(0.0).unwrap();
    let flat = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0];
    assert!(matches!(
        s.add_object(1, Pose::identity(), &[&flat], 0.0),
        Err(Error::Mesh { .. })
    ));
    let mut nan = box_piece([0.01; 3]);
    nan[4] = f64::NAN;
    assert!(matches!(
        s.add_object(1, Pose::identity(), &[&nan], 0.0),
        Err(Error::NonFinite { position, .. }) if position == "[1, 1]"
    ));
    assert!(matches!(
        s.add_object(1, Pose::identity(), &[&[0.0; 7]], 0.0),
        Err(Error::Shape { .. })
    ));
    assert!(s.add_object(1, Pose::identity(), &[], 0.0).is_err());
    let cube = box_piece([0.01; 3]);
    assert!(s.add_object(1, Pose::identity(), &[&cube], -0.001).is_err());
    s.add_object(1, Pose::identity(), &[&cube], 0.0).unwrap();
    assert!(s.add_object(1, Pose::identity(), &[&cube], 0.0).is_err());
    assert!(s.add_object(-2, Pose::identity(), &[&cube], 0.0).is_err());
    assert_eq!((s.len(), s.piece_count()), (1, 1));
}
