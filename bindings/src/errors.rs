//! The Python exception hierarchy and the mapping of core errors onto it.
//!
//! `HeapgraspError` derives from `ValueError`, so callers that catch `ValueError` keep
//! working; each core error variant has its own subclass.

use heapgrasp_core::Error;
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(
    _core,
    HeapgraspError,
    PyValueError,
    "Base class of every heapgrasp error (a ValueError)."
);
create_exception!(
    _core,
    ShapeError,
    HeapgraspError,
    "An array has the wrong shape, dtype or memory layout."
);
create_exception!(
    _core,
    InvalidValueError,
    HeapgraspError,
    "A parameter is outside its valid range."
);
create_exception!(
    _core,
    NonFiniteError,
    HeapgraspError,
    "An array holds NaN or infinity where finite values are required."
);
create_exception!(
    _core,
    NotRigidError,
    HeapgraspError,
    "A 4x4 matrix that must be a rigid transform is not one."
);
create_exception!(
    _core,
    MeshError,
    HeapgraspError,
    "A mesh cannot be used (bad face indices, no faces, ...)."
);
create_exception!(
    _core,
    UnknownMeshError,
    HeapgraspError,
    "A mesh id that the scene does not hold."
);

/// A core error on its way to Python.
pub struct CoreError(pub Error);

impl From<Error> for CoreError {
    fn from(e: Error) -> Self {
        Self(e)
    }
}

impl From<CoreError> for PyErr {
    fn from(e: CoreError) -> Self {
        let msg = e.0.to_string();
        match e.0 {
            Error::Shape { .. } => ShapeError::new_err(msg),
            Error::Value { .. } => InvalidValueError::new_err(msg),
            Error::NonFinite { .. } => NonFiniteError::new_err(msg),
            Error::NotRigid { .. } => NotRigidError::new_err(msg),
            Error::Mesh { .. } => MeshError::new_err(msg),
            Error::UnknownMesh { .. } => UnknownMeshError::new_err(msg),
        }
    }
}

/// `core_result.py()?` turns a core error into the matching Python exception.
pub trait IntoPyResult<T> {
    /// Converts the error side.
    fn py(self) -> PyResult<T>;
}

impl<T> IntoPyResult<T> for Result<T, Error> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| CoreError(e).into())
    }
}

/// Registers the exception classes on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("HeapgraspError", py.get_type::<HeapgraspError>())?;
    m.add("ShapeError", py.get_type::<ShapeError>())?;
    m.add("InvalidValueError", py.get_type::<InvalidValueError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add("NotRigidError", py.get_type::<NotRigidError>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("UnknownMeshError", py.get_type::<UnknownMeshError>())?;
    Ok(())
}
