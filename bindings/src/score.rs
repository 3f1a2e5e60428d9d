//! `score_views`.

use heapgrasp_core::{score, PinholeCamera};
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::convert::{check_tail, detached, instance_arg, items_arg, mask_arg, named, poses_arg};
use crate::occupancy::PyOccupancyGrid;
use crate::raster::PyMeshScene;

/// Most trajectories one call scores (a lazy iterable beyond it is refused, not drained).
pub const MAX_TRAJECTORIES: usize = 1 << 16;

/// Exact eq. 14 view scores, float32 (K,); with `region` ((R, R, R) bool or uint8)
/// both counts are restricted to it.
#[pyfunction]
#[pyo3(signature = (grid, scene, camera, trajectories, lam = 0.9, region = None))]
pub fn score_views<'py>(
    py: Python<'py>,
    grid: &Bound<'py, PyAny>,
    scene: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
    trajectories: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::lam)] lam: f64,
    region: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<f32>>> {
    let grid = instance_arg::<PyOccupancyGrid>(grid, "grid", "an OccupancyGrid")?;
    let scene = instance_arg::<PyMeshScene>(scene, "scene", "a MeshScene")?;
    let region: Option<Vec<bool>> = match region {
        None => None,
        Some(obj) => {
            let m = mask_arg(obj, "region", 3)?;
            let r = grid.inner.spec().resolution();
            check_tail("region", m.shape(), &[r, r, r], &format!("({r}, {r}, {r})"))?;
            Some(m.bytes().iter().map(|&b| b != 0).collect())
        }
    };
    let items = items_arg(
        trajectories,
        "trajectories",
        MAX_TRAJECTORIES,
        "(M, 4, 4) float64 arrays",
        &format!("at most {MAX_TRAJECTORIES} trajectories"),
    )?;
    let trajs = items
        .iter()
        .enumerate()
        .map(|(k, t)| poses_arg(t, &format!("trajectories[{k}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let (g, s, cam) = (&grid.inner, &scene.inner, camera);
    let scores = detached(py, move || {
        score::score_views_in(g, s, &cam, &trajs, lam, region.as_deref())
    })?;
    Ok(PyArray1::from_vec(py, scores))
}
