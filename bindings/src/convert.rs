//! Argument conversion: every array crossing the boundary is checked here once (dtype,
//! shape, C-contiguity) and borrowed without copying, with errors that name the argument.

use heapgrasp_core::{Pose, Result as CoreResult};
use numpy::{
    Element, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::errors::{IntoPyResult, ShapeError};

/// A borrowed, C-contiguous, dtype-checked NumPy array.
pub struct ArrayArg<'py, T: Element> {
    array: PyReadonlyArrayDyn<'py, T>,
    /// The array's shape.
    pub shape: Vec<usize>,
}

impl<T: Element> ArrayArg<'_, T> {
    /// The data, flat in C order.
    pub fn as_slice(&self) -> &[T] {
        // Contiguity was checked when the argument was built.
        self.array.as_slice().unwrap_or(&[])
    }
}

/// A shape as Python prints it: `(3,)`, `(4, 4)`.
pub fn shape_str(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// Borrows `obj` as an array of `T` with `ndim` dimensions (any if `None`).
pub fn array_arg<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype_name: &str,
    ndim: Option<usize>,
) -> PyResult<ArrayArg<'py, T>> {
    let untyped = obj.cast::<PyUntypedArray>().map_err(|_| {
        ShapeError::new_err(format!(
            "{name}: expected a numpy.ndarray of {dtype_name}, got {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_else(|_| "?".into())
        ))
    })?;
    let shape = untyped.shape().to_vec();
    let typed = obj.cast::<PyArrayDyn<T>>().map_err(|_| {
        ShapeError::new_err(format!(
            "{name}: expected dtype {dtype_name}, got {} (shape {})",
            untyped.dtype(),
            shape_str(&shape)
        ))
    })?;
    if let Some(n) = ndim {
        if shape.len() != n {
            return Err(ShapeError::new_err(format!(
                "{name}: expected a {n}-D array, got shape {}",
                shape_str(&shape)
            )));
        }
    }
    if !untyped.is_c_contiguous() {
        return Err(ShapeError::new_err(format!(
            "{name}: array must be C-contiguous (use numpy.ascontiguousarray)"
        )));
    }
    Ok(ArrayArg {
        array: typed.readonly(),
        shape,
    })
}

/// A mask argument: bool or uint8 (nonzero = set).
pub enum MaskArg<'py> {
    /// dtype bool.
    Bool(ArrayArg<'py, bool>),
    /// dtype uint8.
    U8(ArrayArg<'py, u8>),
}

impl MaskArg<'_> {
    /// The mask bytes (bool is stored as one byte 0/1).
    pub fn bytes(&self) -> &[u8] {
        match self {
            MaskArg::Bool(a) => {
                let s = a.as_slice();
                // SAFETY: bool has the size and alignment of u8, and 0/1 are valid u8.
                unsafe { std::slice::from_raw_parts(s.as_ptr().cast::<u8>(), s.len()) }
            }
            MaskArg::U8(a) => a.as_slice(),
        }
    }

    /// The mask's shape.
    pub fn shape(&self) -> &[usize] {
        match self {
            MaskArg::Bool(a) => &a.shape,
            MaskArg::U8(a) => &a.shape,
        }
    }
}

/// Whether `obj` is a NumPy array of dtype `T` (whatever its shape and layout).
pub fn has_dtype<T: Element>(obj: &Bound<'_, PyAny>) -> bool {
    obj.cast::<PyArrayDyn<T>>().is_ok()
}

/// Borrows a bool or uint8 mask array with `ndim` dimensions. The dtype picks the branch
/// first, so a bool array of the wrong shape or layout is reported as such (not as a
/// dtype mismatch).
pub fn mask_arg<'py>(obj: &Bound<'py, PyAny>, name: &str, ndim: usize) -> PyResult<MaskArg<'py>> {
    if has_dtype::<bool>(obj) {
        return array_arg::<bool>(obj, name, "bool", Some(ndim)).map(MaskArg::Bool);
    }
    array_arg::<u8>(obj, name, "bool or uint8", Some(ndim)).map(MaskArg::U8)
}

/// Checks that a shape's trailing dimensions equal `tail`.
pub fn check_tail(name: &str, shape: &[usize], tail: &[usize], what: &str) -> PyResult<()> {
    if shape.len() < tail.len() || &shape[shape.len() - tail.len()..] != tail {
        return Err(ShapeError::new_err(format!(
            "{name}: expected shape {what}, got {}",
            shape_str(shape)
        )));
    }
    Ok(())
}

/// A (4, 4) float64 rigid transform.
pub fn pose_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Pose> {
    let a = array_arg::<f64>(obj, name, "float64", Some(2))?;
    check_tail(name, &a.shape, &[4, 4], "(4, 4)")?;
    let mut m = [0.0; 16];
    m.copy_from_slice(a.as_slice());
    Pose::from_row_major(name, &m).py()
}

/// An (N, 4, 4) float64 stack of rigid transforms.
pub fn poses_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Pose>> {
    let a = array_arg::<f64>(obj, name, "float64", Some(3))?;
    check_tail(name, &a.shape, &[4, 4], "(N, 4, 4)")?;
    heapgrasp_core::poses_from_flat(name, a.as_slice()).py()
}

/// A 3-vector given as any sequence of 3 floats.
pub fn vec3_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 3]> {
    let v: Vec<f64> = obj
        .extract()
        .map_err(|_| ShapeError::new_err(format!("{name}: expected a sequence of 3 floats")))?;
    <[f64; 3]>::try_from(v.as_slice())
        .map_err(|_| ShapeError::new_err(format!("{name}: expected 3 values, got {}", v.len())))
}

/// Runs `f` with the GIL released and converts its core error.
pub fn detached<T: Send, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    F: FnOnce() -> CoreResult<T> + Send,
{
    py.detach(f).py()
}

/// An integer argument in `lo..=hi`; other ints (negative, huge) raise `InvalidValueError`
/// naming the argument instead of pyo3's `OverflowError`.
pub fn int_arg(obj: &Bound<'_, PyAny>, name: &str, lo: i64, hi: i64, what: &str) -> PyResult<i64> {
    let bad = || {
        crate::errors::InvalidValueError::new_err(format!(
            "{name}: {what} (got {})",
            obj.repr()
                .map(|r| r.to_string())
                .unwrap_or_else(|_| "?".into())
        ))
    };
    let v: i64 = obj.extract().map_err(|_| bad())?;
    if v < lo || v > hi {
        return Err(bad());
    }
    Ok(v)
}
