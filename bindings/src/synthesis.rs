//! Natarajan et al.'s grasp synthesis on a point cloud (`heapgrasp_core::viewsphere::synthesis`): normals
//! and curvature, contact patches, antipodal pairs.

use heapgrasp_core::viewsphere::synthesis::{self, Point};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{array_arg, bool_arg, check_tail, detached, float_arg, int_arg};
use crate::errors::IntoPyResult;

pub(crate) fn cloud(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Point>> {
    let arr = array_arg::<f64>(obj, name, "float64", Some(2))?;
    check_tail(name, &arr.shape, &[3], "(N, 3)")?;
    synthesis::points_from_flat(name, arr.as_slice()).py()
}

fn mask(obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<bool>> {
    let arr = bool_arg(obj, name, 1)?;
    check_tail(name, arr.shape(), &[n], &format!("({n},)"))?;
    Ok(arr.as_slice().to_vec())
}

pub(crate) fn threads_arg(threads: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    Ok(match threads {
        None => 0,
        Some(t) => int_arg(t, "threads", 0, 4096, "expected an int in [0, 4096]")? as usize,
    })
}

fn rows<'py>(py: Python<'py>, v: Vec<[f64; 3]>) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = v.len();
    PyArray1::from_vec(py, v.concat()).reshape([n, 3])
}

/// Normals (N, 3) and curvatures (N,).
type NormalArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// Unit normals (away from the cloud's centroid) and curvatures from each point's `k`
/// nearest points.
///
/// `points`: (N, 3) float64 with N >= k; `k`: an int >= 3 (default 10). Returns
/// ((N, 3) normals, (N,) curvatures `λ0 / (λ0 + λ1 + λ2)`).
#[pyfunction]
#[pyo3(signature = (points, *, k = None, threads = None))]
pub fn point_normals<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    k: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<NormalArrays<'py>> {
    let pts = cloud(points, "points")?;
    let k = match k {
        None => 10,
        Some(k) => int_arg(k, "k", 3, 1 << 20, "expected an int in [3, 1048576]")? as usize,
    };
    let threads = threads_arg(threads)?;
    let (normals, curvature) = detached(py, || synthesis::point_normals(&pts, k, threads))?;
    Ok((rows(py, normals)?, PyArray1::from_vec(py, curvature)))
}

/// Whether a finger pad fits on the surface at each point with `candidates` true.
///
/// `points` (N, 3) float64; `normals` (N, 3) float64 unit vectors; `candidates` (N,)
/// bool. Returns (N,) bool, false where not a candidate.
#[pyfunction]
#[pyo3(signature = (points, normals, candidates, *, threads = None))]
pub fn contact_patches<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    normals: &Bound<'py, PyAny>,
    candidates: &Bound<'py, PyAny>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let pts = cloud(points, "points")?;
    let nrm = cloud(normals, "normals")?;
    let candidates = mask(candidates, "candidates", pts.len())?;
    let threads = threads_arg(threads)?;
    let ok = detached(py, || {
        synthesis::contact_patches(&pts, &nrm, &candidates, threads)
    })?;
    Ok(PyArray1::from_vec(py, ok))
}

/// The four arrays of antipodal pairs: first and second contacts, quality, width.
type PairArrays<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

/// Every pair of usable points that fits the opening with quality at least
/// `min_quality` degrees, ordered by (i, j), i < j.
///
/// `points`, `normals` (N, 3) float64; `usable` (N,) bool; `voxel` >= 0 (m, added to
/// the contacts' distance), `max_width` > 0 (m), `min_quality` in [0, 180]. Returns
/// (first, second, quality, width).
#[pyfunction]
#[pyo3(signature = (points, normals, usable, *, voxel, max_width, min_quality, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn antipodal_pairs<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    normals: &Bound<'py, PyAny>,
    usable: &Bound<'py, PyAny>,
    voxel: &Bound<'py, PyAny>,
    max_width: &Bound<'py, PyAny>,
    min_quality: &Bound<'py, PyAny>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<PairArrays<'py>> {
    let pts = cloud(points, "points")?;
    let nrm = cloud(normals, "normals")?;
    let usable = mask(usable, "usable", pts.len())?;
    let voxel = float_arg(voxel, "voxel")?;
    let max_width = float_arg(max_width, "max_width")?;
    let min_quality = float_arg(min_quality, "min_quality")?;
    let threads = threads_arg(threads)?;
    let pairs = detached(py, || {
        synthesis::antipodal_pairs(&pts, &nrm, &usable, voxel, max_width, min_quality, threads)
    })?;
    let index = |v: Vec<u32>| PyArray1::from_vec(py, v.into_iter().map(i64::from).collect());
    Ok((
        index(pairs.first),
        index(pairs.second),
        PyArray1::from_vec(py, pairs.quality),
        PyArray1::from_vec(py, pairs.width),
    ))
}
