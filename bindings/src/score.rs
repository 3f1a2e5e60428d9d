//! `score_views`.

use heapgrasp_core::score;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyList;

use crate::camera::PyPinholeCamera;
use crate::convert::{check_tail, detached, mask_arg, poses_arg};
use crate::errors::ShapeError;
use crate::occupancy::PyOccupancyGrid;
use crate::raster::PyMeshScene;

/// Exact eq. 14 view scores, float32 (K,); with `region` ((R, R, R) bool or uint8)
/// both counts are restricted to it.
#[pyfunction]
#[pyo3(signature = (grid, scene, camera, trajectories, lam = 0.9, region = None))]
pub fn score_views<'py>(
    py: Python<'py>,
    grid: &PyOccupancyGrid,
    scene: &PyMeshScene,
    camera: &PyPinholeCamera,
    trajectories: &Bound<'py, PyAny>,
    lam: f64,
    region: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<f32>>> {
    let region: Option<Vec<bool>> = match region {
        None => None,
        Some(obj) => {
            let m = mask_arg(obj, "region", 3)?;
            let r = grid.inner.spec().resolution();
            check_tail("region", m.shape(), &[r, r, r], &format!("({r}, {r}, {r})"))?;
            Some(m.bytes().iter().map(|&b| b != 0).collect())
        }
    };
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
    let scores = detached(py, move || {
        score::score_views_in(g, s, &cam, &trajs, lam, region.as_deref())
    })?;
    Ok(PyArray1::from_vec(py, scores))
}
