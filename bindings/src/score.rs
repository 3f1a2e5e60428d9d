//! `score_views`.

use heapgrasp_core::score;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::camera::PyPinholeCamera;
use crate::convert::{detached, poses_arg};
use crate::errors::ShapeError;
use crate::occupancy::PyOccupancyGrid;
use crate::raster::PyMeshScene;

/// Exact eq. 14 view scores, float32 (K,).
#[pyfunction]
#[pyo3(signature = (grid, scene, camera, trajectories, lam = 0.9))]
pub fn score_views<'py>(
    py: Python<'py>,
    grid: &PyOccupancyGrid,
    scene: &PyMeshScene,
    camera: &PyPinholeCamera,
    trajectories: &Bound<'py, PyAny>,
    lam: f64,
) -> PyResult<Bound<'py, PyArray1<f32>>> {
    let items: Vec<Bound<'py, PyAny>> = match trajectories.cast::<PyList>() {
        Ok(list) => list.iter().collect(),
        Err(_) => trajectories
            .try_iter()
            .map_err(|_| {
                ShapeError::new_err("trajectories: expected a sequence of (M, 4, 4) float64 arrays")
            })?
            .collect::<PyResult<_>>()?,
    };
    let trajs = items
        .iter()
        .enumerate()
        .map(|(k, t)| poses_arg(t, &format!("trajectories[{k}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let (g, s, cam) = (&grid.inner, &scene.inner, camera.inner);
    let scores = detached(py, move || score::score_views(g, s, &cam, &trajs, lam))?;
    Ok(PyArray1::from_vec(py, scores))
}
