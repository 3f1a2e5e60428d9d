//! `OccupancyGrid`.

use heapgrasp_core::occupancy::check_lambda;
use heapgrasp_core::{GridSpec, OccupancyGrid, PinholeCamera};
use numpy::{PyArray1, PyArray3, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{
    array_arg, check_tail, detached, int_arg, mask_arg, named, pose_arg, poses_arg, shape_str,
    vec3_arg,
};
use crate::errors::{IntoPyResult, InvalidValueError, ShapeError};

/// `(segmented, visible)` count volumes.
type CountArrays<'py> = (Bound<'py, PyArray3<u32>>, Bound<'py, PyArray3<u32>>);

/// Silhouette counts on a cubic voxel grid (HEAPGrasp eq. 9–10).
#[pyclass(name = "OccupancyGrid", module = "heapgrasp._core")]
pub struct PyOccupancyGrid {
    pub inner: OccupancyGrid,
}

/// Largest explicit thread count of `integrate_many`.
const MAX_CARVE_THREADS: i64 = 256;

/// Voxels per axis when none is given (HEAPGrasp Table I).
const DEFAULT_RESOLUTION: usize = 40;

pub(crate) fn spec_args(
    origin: &Bound<'_, PyAny>,
    size: f64,
    resolution: Option<&Bound<'_, PyAny>>,
) -> PyResult<GridSpec> {
    let origin = vec3_arg(origin, "origin")?;
    let max = heapgrasp_core::grid::MAX_RESOLUTION as i64;
    let what = format!("must be between 1 and {max} voxels per axis");
    let r = match resolution {
        None => DEFAULT_RESOLUTION,
        Some(obj) => int_arg(obj, "resolution", 1, max, &what)? as usize,
    };
    GridSpec::new(origin, size, r).py()
}

pub(crate) fn volume<'py, T: numpy::Element>(
    py: Python<'py>,
    r: usize,
    data: Vec<T>,
) -> PyResult<Bound<'py, PyArray3<T>>> {
    PyArray1::from_vec(py, data).reshape([r, r, r])
}

#[pymethods]
impl PyOccupancyGrid {
    #[new]
    #[pyo3(signature = (origin, size = 0.30, resolution = None))]
    fn new(
        origin: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::size)] size: f64,
        resolution: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: OccupancyGrid::new(spec_args(origin, size, resolution)?),
        })
    }

    /// Minimum corner of the cube (world frame, metres).
    #[getter]
    fn origin(&self) -> (f64, f64, f64) {
        let o = self.inner.spec().origin();
        (o[0], o[1], o[2])
    }
    /// Side of the cube (metres).
    #[getter]
    fn size(&self) -> f64 {
        self.inner.spec().size()
    }
    /// Voxels per axis.
    #[getter]
    fn resolution(&self) -> usize {
        self.inner.spec().resolution()
    }
    /// Side of one voxel (metres).
    #[getter]
    fn voxel_size(&self) -> f64 {
        self.inner.spec().voxel_size()
    }

    /// Integrates one silhouette.
    fn integrate(
        &mut self,
        py: Python<'_>,
        mask: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2world: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let m = mask_arg(mask, "mask", 2)?;
        let cam = camera;
        check_tail(
            "mask",
            m.shape(),
            &[cam.height as usize, cam.width as usize],
            &format!("({}, {}) to match the camera", cam.height, cam.width),
        )?;
        let pose = pose_arg(cam2world, "cam2world")?;
        let bytes = m.bytes();
        let inner = &mut self.inner;
        detached(py, move || inner.integrate(&cam, &pose, bytes))
    }

    /// Integrates N silhouettes; nothing changes if any input is invalid. `threads`: carve
    /// on exactly that many threads (1 to 256) rather than as many as the work is worth;
    /// the counts are the same. Counts saturate at 2**32 - 1.
    #[pyo3(signature = (masks, camera, cam2worlds, *, threads = None))]
    fn integrate_many(
        &mut self,
        py: Python<'_>,
        masks: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2worlds: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let threads = match threads {
            None => None,
            Some(obj) => Some(int_arg(
                obj,
                "threads",
                1,
                MAX_CARVE_THREADS,
                &format!("must be between 1 and {MAX_CARVE_THREADS}"),
            )? as usize),
        };
        let m = mask_arg(masks, "masks", 3)?;
        let cam = camera;
        check_tail(
            "masks",
            m.shape(),
            &[cam.height as usize, cam.width as usize],
            &format!("(N, {}, {}) to match the camera", cam.height, cam.width),
        )?;
        let poses = poses_arg(cam2worlds, "cam2worlds")?;
        if poses.len() != m.shape()[0] {
            return Err(ShapeError::new_err(format!(
                "cam2worlds: expected one pose per mask ({}), got {}",
                m.shape()[0],
                poses.len()
            )));
        }
        let bytes = m.bytes();
        let inner = &mut self.inner;
        detached(py, move || match threads {
            None => inner.integrate_many(&cam, &poses, bytes),
            Some(t) => inner.integrate_many_with_threads(&cam, &poses, bytes, t),
        })
    }

    /// `(segmented, visible)` counts as uint32 (R, R, R) arrays.
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<CountArrays<'py>> {
        let r = self.inner.spec().resolution();
        Ok((
            volume(py, r, self.inner.segmented().to_vec())?,
            volume(py, r, self.inner.visible().to_vec())?,
        ))
    }

    /// Occupancy (eq. 10) as float32 (R, R, R).
    fn occupancy<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let r = self.inner.spec().resolution();
        let inner = &self.inner;
        let v = py.detach(|| inner.occupancy());
        volume(py, r, v)
    }

    /// High-confidence grid: occupancy with values below `lam` set to 0.
    #[pyo3(signature = (lam = 0.9))]
    fn high_confidence<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = named::lam)] lam: f64,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let lam = check_lambda(lam).py()?;
        let r = self.inner.spec().resolution();
        let inner = &self.inner;
        let v = py.detach(|| inner.high_confidence(lam));
        volume(py, r, v)
    }

    /// Number of non-zero voxels of the high-confidence grid.
    #[pyo3(signature = (lam = 0.9))]
    fn count_high_confidence(
        &self,
        #[pyo3(from_py_with = named::lam)] lam: f64,
    ) -> PyResult<usize> {
        Ok(self.inner.count_high_confidence(check_lambda(lam).py()?))
    }

    /// Sets all counts back to 0.
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// An independent copy.
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.clone(),
        }
    }

    fn __copy__(&self) -> Self {
        self.copy()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.copy()
    }

    /// A grid with the given counts (uint32 (R, R, R) each).
    #[staticmethod]
    #[pyo3(signature = (origin, size, segmented, visible))]
    fn from_counts(
        origin: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::size)] size: f64,
        segmented: &Bound<'_, PyAny>,
        visible: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let s = array_arg::<u32>(segmented, "segmented", "uint32", Some(3))?;
        let v = array_arg::<u32>(visible, "visible", "uint32", Some(3))?;
        let r = s.shape[0];
        if s.shape != [r, r, r] || v.shape != s.shape {
            return Err(ShapeError::new_err(format!(
                "segmented, visible: expected two cubic (R, R, R) arrays of one shape, got {} and {}",
                shape_str(&s.shape),
                shape_str(&v.shape)
            )));
        }
        let max = heapgrasp_core::grid::MAX_RESOLUTION;
        if r == 0 || r > max {
            return Err(InvalidValueError::new_err(format!(
                "segmented, visible: a grid has 1 to {max} voxels per axis, got shape {}",
                shape_str(&s.shape)
            )));
        }
        let spec = GridSpec::new(vec3_arg(origin, "origin")?, size, r).py()?;
        Ok(Self {
            inner: OccupancyGrid::from_counts(spec, s.as_slice().to_vec(), v.as_slice().to_vec())
                .py()?,
        })
    }

    fn __repr__(&self) -> String {
        let s = self.inner.spec();
        format!(
            "OccupancyGrid(origin={:?}, size={}, resolution={})",
            s.origin(),
            s.size(),
            s.resolution()
        )
    }
}
