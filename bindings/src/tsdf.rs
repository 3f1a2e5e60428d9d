//! `TSDFVolume`.

use heapgrasp_core::tsdf::TsdfVolume;
use heapgrasp_core::PinholeCamera;
use numpy::PyArray3;
use pyo3::prelude::*;

use crate::convert::{array_arg, check_tail, detached, named, pose_arg};
use crate::errors::IntoPyResult;
use crate::occupancy::{spec_args, volume};

/// Truncated signed distance volume fused from depth images (the VGN baseline's input).
#[pyclass(name = "TSDFVolume", module = "heapgrasp._core")]
pub struct PyTsdfVolume {
    pub inner: TsdfVolume,
}

#[pymethods]
impl PyTsdfVolume {
    #[new]
    #[pyo3(signature = (origin, size = 0.30, resolution = None, truncation = 0.03))]
    fn new(
        origin: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::size)] size: f64,
        resolution: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = named::truncation)] truncation: f64,
    ) -> PyResult<Self> {
        let spec = spec_args(origin, size, resolution)?;
        Ok(Self {
            inner: TsdfVolume::new(spec, truncation).py()?,
        })
    }

    /// Truncation distance (metres).
    #[getter]
    fn truncation(&self) -> f64 {
        self.inner.truncation()
    }
    /// Voxels per axis.
    #[getter]
    fn resolution(&self) -> usize {
        self.inner.spec().resolution()
    }
    /// Side of the cube (metres).
    #[getter]
    fn size(&self) -> f64 {
        self.inner.spec().size()
    }
    /// Minimum corner of the cube (world frame, metres).
    #[getter]
    fn origin(&self) -> (f64, f64, f64) {
        let o = self.inner.spec().origin();
        (o[0], o[1], o[2])
    }

    /// Fuses one depth image (float32 (H, W), metres; 0 or NaN = missing).
    fn integrate(
        &mut self,
        py: Python<'_>,
        depth_m: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::camera)] camera: PinholeCamera,
        cam2world: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let d = array_arg::<f32>(depth_m, "depth_m", "float32", Some(2))?;
        let cam = camera;
        check_tail(
            "depth_m",
            &d.shape,
            &[cam.height as usize, cam.width as usize],
            &format!("({}, {}) to match the camera", cam.height, cam.width),
        )?;
        let pose = pose_arg(cam2world, "cam2world")?;
        let depth = d.as_slice();
        let inner = &mut self.inner;
        detached(py, move || inner.integrate(&cam, &pose, depth))
    }

    /// TSDF values in [-1, 1] (0 where never observed), float32 (R, R, R).
    fn values<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        volume(
            py,
            self.inner.spec().resolution(),
            self.inner.values().to_vec(),
        )
    }

    /// Observation weights (0 where never observed), float32 (R, R, R).
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        volume(
            py,
            self.inner.spec().resolution(),
            self.inner.weights().to_vec(),
        )
    }

    /// Forgets every observation.
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// An independent copy.
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.clone(),
        }
    }

    fn __repr__(&self) -> String {
        let s = self.inner.spec();
        format!(
            "TSDFVolume(origin={:?}, size={}, resolution={}, truncation={})",
            s.origin(),
            s.size(),
            s.resolution(),
            self.inner.truncation()
        )
    }
}
