//! Natarajan et al.'s heuristic view scores (`heapgrasp_core::viewsphere::visibility`): the grasp region of
//! the unexplored points and their visibility past a surfel reconstruction.

use heapgrasp_core::viewsphere::visibility;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{detached, float_arg};
use crate::synthesis::{cloud, threads_arg};

/// Whether each target lies within `half_length` along and `radius` across the normal
/// line of some object point (the 3D heuristic's grasp region).
///
/// `points`, `normals` (N, 3) float64 (normals non-zero; normalised here); `targets`
/// (M, 3) float64; `half_length`, `radius` > 0 (m). Returns (M,) bool.
#[pyfunction]
#[pyo3(signature = (points, normals, targets, *, half_length, radius, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn grasp_region<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    normals: &Bound<'py, PyAny>,
    targets: &Bound<'py, PyAny>,
    half_length: &Bound<'py, PyAny>,
    radius: &Bound<'py, PyAny>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let pts = cloud(points, "points")?;
    let nrm = cloud(normals, "normals")?;
    let tgt = cloud(targets, "targets")?;
    let half_length = float_arg(half_length, "half_length")?;
    let radius = float_arg(radius, "radius")?;
    let threads = threads_arg(threads)?;
    let mask = detached(py, || {
        visibility::grasp_region(&pts, &nrm, &tgt, half_length, radius, threads)
    })?;
    Ok(PyArray1::from_vec(py, mask))
}

/// Whether each target is visible from each eye past the surfels of the object points
/// (squares of half width `radius` across their normals).
///
/// `points`, `normals` (N, 3) float64; `eyes` (V, 3), `targets` (M, 3) float64;
/// `radius` > 0 (m). Returns (V, M) bool: the segment from eye to target meets no
/// surfel. The field of view and the sensor's range are not checked.
#[pyfunction]
#[pyo3(signature = (points, normals, eyes, targets, *, radius, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn surfel_visibility<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    normals: &Bound<'py, PyAny>,
    eyes: &Bound<'py, PyAny>,
    targets: &Bound<'py, PyAny>,
    radius: &Bound<'py, PyAny>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<bool>>> {
    let pts = cloud(points, "points")?;
    let nrm = cloud(normals, "normals")?;
    let eye = cloud(eyes, "eyes")?;
    let tgt = cloud(targets, "targets")?;
    let radius = float_arg(radius, "radius")?;
    let threads = threads_arg(threads)?;
    let (v, m) = (eye.len(), tgt.len());
    let vis = detached(py, || {
        visibility::surfel_visibility(&pts, &nrm, radius, &eye, &tgt, threads)
    })?;
    PyArray1::from_vec(py, vis).reshape([v, m])
}
