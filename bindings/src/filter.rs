//! `gaussian_filter3d`, `maximum_filter3d`, `nms3d`.

use heapgrasp_core::{filter, nms};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{array_arg, detached, int_arg, named, shape_str, ArrayArg};
use crate::errors::ShapeError;
use crate::occupancy::volume as to_volume;

fn cube<'py>(obj: &Bound<'py, PyAny>) -> PyResult<(ArrayArg<'py, f32>, usize)> {
    let v = array_arg::<f32>(obj, "volume", "float32", Some(3))?;
    let r = v.shape[0];
    if v.shape != [r, r, r] || r == 0 {
        return Err(ShapeError::new_err(format!(
            "volume: expected a cubic (R, R, R) array with R >= 1, got shape {}",
            shape_str(&v.shape)
        )));
    }
    Ok((v, r))
}

fn window_arg(window: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    match window {
        None => Ok(4),
        Some(w) => Ok(int_arg(
            w,
            "window",
            1,
            1 << 16,
            "window must be between 1 and 65536 voxels",
        )? as usize),
    }
}

/// 3-D Gaussian smoothing, equal to scipy.ndimage.gaussian_filter(mode="nearest", truncate=4).
#[pyfunction]
pub fn gaussian_filter3d<'py>(
    py: Python<'py>,
    volume: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::sigma)] sigma: f64,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (v, r) = cube(volume)?;
    let data = v.as_slice();
    let out = detached(py, move || filter::gaussian_filter3d(data, r, sigma))?;
    to_volume(py, r, out)
}

/// Sliding-window maximum over offsets [-(w/2), w-1-w/2] clipped to the grid.
#[pyfunction]
#[pyo3(signature = (volume, window = None))]
pub fn maximum_filter3d<'py>(
    py: Python<'py>,
    volume: &Bound<'py, PyAny>,
    window: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let window = window_arg(window)?;
    let (v, r) = cube(volume)?;
    let data = v.as_slice();
    let out = detached(py, move || nms::maximum_filter3d(data, r, window))?;
    to_volume(py, r, out)
}

/// Voxels >= threshold that equal their window maximum, as int64 (K, 3), best first.
#[pyfunction]
#[pyo3(signature = (volume, threshold, window = None))]
pub fn nms3d<'py>(
    py: Python<'py>,
    volume: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::threshold)] threshold: f64,
    window: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<i64>>> {
    let window = window_arg(window)?;
    let (v, r) = cube(volume)?;
    let data = v.as_slice();
    let threshold = threshold as f32;
    let idx = detached(py, move || nms::nms3d(data, r, threshold, window))?;
    let k = idx.len();
    let flat: Vec<i64> = idx.into_iter().flat_map(|p| p.map(|x| x as i64)).collect();
    PyArray1::from_vec(py, flat).reshape([k, 3])
}
