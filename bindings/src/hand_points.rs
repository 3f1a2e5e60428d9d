//! `hand_point_counts`, `first_free_pose`: points inside the hand at grasp poses
//! (`heapgrasp_core::viewsphere::hand_points`).

use heapgrasp_core::viewsphere::hand_points::{self, PointIndex};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyMapping;

use crate::convert::{
    array_arg, check_tail, detached, float_arg, floats_arg, int_arg, mapping_item, poses_arg,
    type_name, ArrayArg,
};
use crate::errors::InvalidValueError;
use crate::gripper::hand_geometry;

/// The index's default cell size (m).
const DEFAULT_CELL: f64 = 0.01;

/// The validated arguments both functions share.
struct Args<'py> {
    geometry: heapgrasp_core::gripper::HandGeometry,
    poses: Vec<heapgrasp_core::Pose>,
    openings: ArrayArg<'py, f64>,
    points: ArrayArg<'py, f64>,
    cell: f64,
    threads: usize,
}

impl<'py> Args<'py> {
    fn parse(
        hand: &Bound<'py, PyAny>,
        tcp2world: &Bound<'py, PyAny>,
        openings: &Bound<'py, PyAny>,
        points: &Bound<'py, PyAny>,
        cell: Option<&Bound<'py, PyAny>>,
        threads: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        let d = hand.cast::<PyMapping>().map_err(|_| {
            InvalidValueError::new_err(format!(
                "hand: expected a mapping of GripperGeometry's fields, got {}",
                type_name(hand)
            ))
        })?;
        let f = |k: &str| float_arg(&mapping_item(d, "hand", k)?, &format!("hand[{k:?}]"));
        let pair = |k: &str| floats_arg::<2>(&mapping_item(d, "hand", k)?, &format!("hand[{k:?}]"));
        let geometry = hand_geometry(f, pair, None)?;
        let poses = poses_arg(tcp2world, "tcp2world")?;
        let openings = array_arg::<f64>(openings, "openings", "float64", Some(1))?;
        let points = array_arg::<f64>(points, "points", "float64", Some(2))?;
        check_tail("points", &points.shape, &[3], "(P, 3)")?;
        let cell = cell.map_or(Ok(DEFAULT_CELL), |c| float_arg(c, "cell"))?;
        let threads = match threads {
            None => 0,
            Some(t) => int_arg(t, "threads", 0, 4096, "expected an int in [0, 4096]")? as usize,
        };
        Ok(Self {
            geometry,
            poses,
            openings,
            points,
            cell,
            threads,
        })
    }
}

/// How many of `points` lie inside the hand at each pose.
///
/// `hand`: a mapping of `GripperGeometry`'s fields; `tcp2world`: (N, 4, 4) float64 TCP
/// poses (z the approach, fingers closing along y); `openings`: (N,) float64 distance
/// between the finger pads (m), in (0, hand["max_opening"]]; `points`: (P, 3) float64
/// world points; `cell`: the index's cell size (m, default 0.01). Returns (N,) uint32 counts (a point
/// inside two of the hand's boxes counts twice). Runs on `threads` threads (0: all)
/// with the GIL released.
#[pyfunction]
#[pyo3(signature = (hand, tcp2world, openings, points, *, cell = None, threads = None))]
pub fn hand_point_counts<'py>(
    py: Python<'py>,
    hand: &Bound<'py, PyAny>,
    tcp2world: &Bound<'py, PyAny>,
    openings: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    cell: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<u32>>> {
    let args = Args::parse(hand, tcp2world, openings, points, cell, threads)?;
    let (geometry, poses, cell, threads) = (&args.geometry, &args.poses, args.cell, args.threads);
    let (openings, points) = (args.openings.as_slice(), args.points.as_slice());
    let counts = detached(py, || {
        let index = PointIndex::new(points, cell)?;
        hand_points::hand_point_counts(geometry, poses, openings, &index, threads)
    })?;
    Ok(PyArray1::from_vec(py, counts))
}

/// The index of the first pose at which the hand holds none of `points`, or None.
///
/// The arguments are `hand_point_counts`'; the result is the first `i` with
/// `hand_point_counts(...)[i] == 0`, found with each pose's search stopped at its first
/// point and the poses after the answer left unchecked.
#[pyfunction]
#[pyo3(signature = (hand, tcp2world, openings, points, *, cell = None, threads = None))]
pub fn first_free_pose<'py>(
    py: Python<'py>,
    hand: &Bound<'py, PyAny>,
    tcp2world: &Bound<'py, PyAny>,
    openings: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    cell: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Option<usize>> {
    let args = Args::parse(hand, tcp2world, openings, points, cell, threads)?;
    let (geometry, poses, cell, threads) = (&args.geometry, &args.poses, args.cell, args.threads);
    let (openings, points) = (args.openings.as_slice(), args.points.as_slice());
    detached(py, || {
        let index = PointIndex::new(points, cell)?;
        hand_points::first_free(geometry, poses, openings, &index, threads)
    })
}
