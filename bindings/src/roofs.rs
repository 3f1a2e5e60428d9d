//! `keep_silhouettes`.

use heapgrasp_core::roofs::{self, SilhouetteView, VoxelLattice};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{
    bool_arg, camera_arg, detached, items_arg, named, poses_arg, shape_str, vec3_arg,
};
use crate::errors::{IntoPyResult, ShapeError};

/// The voxels of `full` that trimming cut from `trimmed` and that the silhouettes
/// (`cameras[i]`, `poses[i]`, `masks[i]`) show to be real: bool (R, R, R).
#[pyfunction]
#[pyo3(signature = (full, trimmed, origin, voxel_size, cameras, poses, masks))]
#[allow(clippy::too_many_arguments)]
pub fn keep_silhouettes<'py>(
    py: Python<'py>,
    full: &Bound<'py, PyAny>,
    trimmed: &Bound<'py, PyAny>,
    origin: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::voxel_size)] voxel_size: f64,
    cameras: &Bound<'py, PyAny>,
    poses: &Bound<'py, PyAny>,
    masks: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let f = bool_arg(full, "full", 3)?;
    let r = f.shape()[0];
    if f.shape() != [r, r, r] || r == 0 {
        return Err(ShapeError::new_err(format!(
            "full: expected a cubic (R, R, R) volume with R >= 1, got shape {}",
            shape_str(f.shape())
        )));
    }
    let t = bool_arg(trimmed, "trimmed", 3)?;
    if t.shape() != f.shape() {
        return Err(ShapeError::new_err(format!(
            "trimmed: expected shape {} like full, got {}",
            shape_str(f.shape()),
            shape_str(t.shape())
        )));
    }
    let lattice = VoxelLattice::new(vec3_arg(origin, "origin")?, voxel_size, r).py()?;
    let poses = poses_arg(poses, "poses")?;
    let n = poses.len();
    let per_view = format!("one entry per view ({n} poses)");
    let cameras = items_arg(cameras, "cameras", n, "PinholeCamera", &per_view)?
        .iter()
        .enumerate()
        .map(|(i, c)| camera_arg(c, &format!("cameras[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let masks = items_arg(masks, "masks", n, "(height, width) bool arrays", &per_view)?;
    if cameras.len() != n || masks.len() != n {
        return Err(ShapeError::new_err(format!(
            "cameras, poses and masks must have one entry per view, got {}, {} and {}",
            cameras.len(),
            n,
            masks.len()
        )));
    }
    let masks = masks
        .iter()
        .enumerate()
        .map(|(i, m)| bool_arg(m, &format!("masks[{i}]"), 2))
        .collect::<PyResult<Vec<_>>>()?;
    for (i, (m, c)) in masks.iter().zip(&cameras).enumerate() {
        let want = [c.height as usize, c.width as usize];
        if m.shape() != want {
            return Err(ShapeError::new_err(format!(
                "masks[{i}]: expected shape ({}, {}) (its camera's height, width), got {}",
                want[0],
                want[1],
                shape_str(m.shape())
            )));
        }
    }
    let bools: Vec<&[bool]> = masks.iter().map(|m| m.as_slice()).collect();
    let views: Vec<SilhouetteView<'_>> = cameras
        .iter()
        .zip(&poses)
        .zip(&bools)
        .map(|((&camera, &cam2world), &mask)| SilhouetteView {
            camera,
            cam2world,
            mask,
        })
        .collect();
    let (fs, ts) = (f.as_slice(), t.as_slice());
    let back = detached(py, move || {
        roofs::keep_silhouettes(&lattice, fs, ts, &views)
    })?;
    Ok(PyArray1::from_vec(py, back).reshape([r, r, r])?.into_any())
}
