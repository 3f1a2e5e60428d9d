//! `PinholeCamera`.

use heapgrasp_core::PinholeCamera;
use pyo3::prelude::*;

use crate::convert::{int_arg, named};
use crate::errors::IntoPyResult;

/// An ideal pinhole camera (no distortion); OpenCV axes, pixel centres at integers.
#[pyclass(
    name = "PinholeCamera",
    module = "heapgrasp._core",
    frozen,
    eq,
    from_py_object
)]
#[derive(Clone, PartialEq)]
pub struct PyPinholeCamera {
    pub inner: PinholeCamera,
}

#[pymethods]
impl PyPinholeCamera {
    #[new]
    #[pyo3(signature = (width, height, fx, fy, cx, cy))]
    fn new(
        width: &Bound<'_, PyAny>,
        height: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::fx)] fx: f64,
        #[pyo3(from_py_with = named::fy)] fy: f64,
        #[pyo3(from_py_with = named::cx)] cx: f64,
        #[pyo3(from_py_with = named::cy)] cy: f64,
    ) -> PyResult<Self> {
        let side = |name: &str, v: &Bound<'_, PyAny>| -> PyResult<u32> {
            let max = i64::from(heapgrasp_core::camera::MAX_IMAGE_SIDE);
            let what = format!("must be between 1 and {max} pixels");
            Ok(int_arg(v, name, 1, max, &what)? as u32)
        };
        let inner = PinholeCamera::new(
            side("width", width)?,
            side("height", height)?,
            fx,
            fy,
            cx,
            cy,
        )
        .py()?;
        Ok(Self { inner })
    }

    /// Image width in pixels.
    #[getter]
    fn width(&self) -> u32 {
        self.inner.width
    }
    /// Image height in pixels.
    #[getter]
    fn height(&self) -> u32 {
        self.inner.height
    }
    /// Focal length along x (pixels).
    #[getter]
    fn fx(&self) -> f64 {
        self.inner.fx
    }
    /// Focal length along y (pixels).
    #[getter]
    fn fy(&self) -> f64 {
        self.inner.fy
    }
    /// Principal point x (pixels).
    #[getter]
    fn cx(&self) -> f64 {
        self.inner.cx
    }
    /// Principal point y (pixels).
    #[getter]
    fn cy(&self) -> f64 {
        self.inner.cy
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        format!(
            "PinholeCamera(width={}, height={}, fx={}, fy={}, cx={}, cy={})",
            c.width, c.height, c.fx, c.fy, c.cx, c.cy
        )
    }

    fn __getnewargs__(&self) -> (u32, u32, f64, f64, f64, f64) {
        let c = &self.inner;
        (c.width, c.height, c.fx, c.fy, c.cx, c.cy)
    }
}
