//! `keep_silhouettes`.

use heapgrasp_core::roofs::{self, SilhouetteView, VoxelLattice};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;

use crate::camera::PyPinholeCamera;
use crate::convert::{array_arg, detached, poses_arg, shape_str, vec3_arg};
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
    voxel_size: f64,
    cameras: Vec<PyRef<'py, PyPinholeCamera>>,
    poses: &Bound<'py, PyAny>,
    masks: Vec<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let f = array_arg::<bool>(full, "full", "bool", Some(3))?;
    let r = f.shape[0];
    if f.shape != [r, r, r] {
        return Err(ShapeError::new_err(format!(
            "full: expected a cubic (R, R, R) volume, got shape {}",
            shape_str(&f.shape)
        )));
    }
    let t = array_arg::<bool>(trimmed, "trimmed", "bool", Some(3))?;
    if t.shape != f.shape {
        return Err(ShapeError::new_err(format!(
            "trimmed: expected shape {} like full, got {}",
            shape_str(&f.shape),
            shape_str(&t.shape)
        )));
    }
    let lattice = VoxelLattice::new(vec3_arg(origin, "origin")?, voxel_size, r).py()?;
    let poses = poses_arg(poses, "poses")?;
    if cameras.len() != poses.len() || masks.len() != poses.len() {
        return Err(ShapeError::new_err(format!(
            "cameras, poses and masks must have one entry per view, got {}, {} and {}",
            cameras.len(),
            poses.len(),
            masks.len()
        )));
    }
    let masks = masks
        .iter()
        .enumerate()
        .map(|(i, m)| array_arg::<bool>(m, &format!("masks[{i}]"), "bool", Some(2)))
        .collect::<PyResult<Vec<_>>>()?;
    for (i, (m, c)) in masks.iter().zip(&cameras).enumerate() {
        let want = [c.inner.height as usize, c.inner.width as usize];
        if m.shape != want {
            return Err(ShapeError::new_err(format!(
                "masks[{i}]: expected shape ({}, {}) (its camera's height, width), got ({}, {})",
                want[0], want[1], m.shape[0], m.shape[1]
            )));
        }
    }
    let bools: Vec<&[bool]> = masks.iter().map(|m| m.as_slice()).collect();
    let views: Vec<SilhouetteView<'_>> = cameras
        .iter()
        .zip(&poses)
        .zip(&bools)
        .map(|((c, &cam2world), &mask)| SilhouetteView {
            camera: c.inner,
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
