//! `seen_empty`: which points of Natarajan et al.'s unexplored region a depth view shows to be
//! empty (`heapgrasp_core::viewsphere::clouds`).

use heapgrasp_core::viewsphere::clouds::{self, SeenParams};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use heapgrasp_core::{PinholeCamera, Pose};

use crate::convert::{
    array_arg, camera_arg, check_tail, detached, float_arg, int_arg, pose_arg, ArrayArg,
};

/// A depth view's arguments: the camera, the `(H, W)` float32 depth of its size and the
/// rigid `cam2world`.
fn depth_view<'py>(
    depth: &Bound<'py, PyAny>,
    camera: &Bound<'py, PyAny>,
    cam2world: &Bound<'py, PyAny>,
) -> PyResult<(PinholeCamera, ArrayArg<'py, f32>, Pose)> {
    let cam = camera_arg(camera, "camera")?;
    let d = array_arg::<f32>(depth, "depth", "float32", Some(2))?;
    let want = [cam.height as usize, cam.width as usize];
    check_tail(
        "depth",
        &d.shape,
        &want,
        &format!("({}, {})", want[0], want[1]),
    )?;
    Ok((cam, d, pose_arg(cam2world, "cam2world")?))
}

/// Whether each world point is shown empty by a depth view.
///
/// `points` (N, 3) float64 (world); `depth` (H, W) float32 (m along the optical axis,
/// the camera's size); `camera` a PinholeCamera at `cam2world`. A point is seen empty
/// when it projects into the image in front of the camera, `z >= floor_z`, and the depth
/// at its pixel is missing (not in [min_range, max_range]) or beyond `occlusion` times
/// its own. Returns (N,) bool.
#[pyfunction]
#[pyo3(signature = (
    points, depth, camera, cam2world, *, min_range, max_range, occlusion, floor_z, threads = None
))]
#[allow(clippy::too_many_arguments)]
pub fn seen_empty<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    camera: &Bound<'py, PyAny>,
    cam2world: &Bound<'py, PyAny>,
    min_range: &Bound<'py, PyAny>,
    max_range: &Bound<'py, PyAny>,
    occlusion: &Bound<'py, PyAny>,
    floor_z: &Bound<'py, PyAny>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let pts = array_arg::<f64>(points, "points", "float64", Some(2))?;
    check_tail("points", &pts.shape, &[3], "(N, 3)")?;
    let (cam, d, pose) = depth_view(depth, camera, cam2world)?;
    let params = SeenParams {
        min_range: float_arg(min_range, "min_range")?,
        max_range: float_arg(max_range, "max_range")?,
        occlusion: float_arg(occlusion, "occlusion")?,
        floor_z: float_arg(floor_z, "floor_z")?,
    };
    let threads = match threads {
        None => 0,
        Some(t) => int_arg(t, "threads", 0, 4096, "expected an int in [0, 4096]")? as usize,
    };
    let (p, dd) = (pts.as_slice(), d.as_slice());
    let seen = detached(py, || {
        clouds::seen_empty(p, dd, &cam, &pose, &params, threads)
    })?;
    Ok(PyArray1::from_vec(py, seen))
}

/// One point per occupied `voxel` cell (a lattice anchored at the origin): the centroid
/// of the cell's points, cells in lexicographic order of their index.
///
/// `points` (N, 3) float64 finite; `voxel` > 0 (m). Returns (M, 3) float64.
#[pyfunction]
pub fn voxel_downsample<'py>(
    py: Python<'py>,
    points: &Bound<'py, PyAny>,
    voxel: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let pts = array_arg::<f64>(points, "points", "float64", Some(2))?;
    check_tail("points", &pts.shape, &[3], "(N, 3)")?;
    let voxel = float_arg(voxel, "voxel")?;
    let flat = pts.as_slice();
    let out = detached(py, || clouds::voxel_downsample(flat, voxel))?;
    let n = out.len();
    PyArray1::from_vec(py, out.concat()).reshape([n, 3])
}

/// The world points of a depth view with depth in [min_range, max_range], down-sampled
/// to one centroid per `voxel` cell (cells in lexicographic order).
///
/// `depth` (H, W) float32 (m along the optical axis, the camera's size); `camera` a
/// PinholeCamera at `cam2world`. Returns (M, 3) float64.
#[pyfunction]
#[pyo3(signature = (depth, camera, cam2world, *, min_range, max_range, voxel))]
pub fn depth_voxels<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: &Bound<'py, PyAny>,
    cam2world: &Bound<'py, PyAny>,
    min_range: &Bound<'py, PyAny>,
    max_range: &Bound<'py, PyAny>,
    voxel: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (cam, d, pose) = depth_view(depth, camera, cam2world)?;
    let (lo, hi) = (
        float_arg(min_range, "min_range")?,
        float_arg(max_range, "max_range")?,
    );
    let voxel = float_arg(voxel, "voxel")?;
    let dd = d.as_slice();
    let out = detached(py, || clouds::depth_voxels(dd, &cam, &pose, lo, hi, voxel))?;
    let n = out.len();
    PyArray1::from_vec(py, out.concat()).reshape([n, 3])
}
