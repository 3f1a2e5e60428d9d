//! Argument conversion: every argument crossing the boundary is checked here once and
//! arrays are borrowed without copying, with errors that name the argument.
//!
//! Arrays: dtype, number of dimensions, C-contiguity and alignment. Numbers: a Python or
//! NumPy bool is never taken for a number (`True` is not a size), and an object that is
//! not a number raises `InvalidValueError` rather than pyo3's `TypeError`. Sequences are
//! read item by item up to the length the call needs, so a lazy sequence of astronomical
//! length (`range(10**18)`) is refused without allocating for it.

use heapgrasp_core::{PinholeCamera, Pose, Result as CoreResult};
use numpy::{
    Element, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyKeyError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyMapping, PyString};

use crate::camera::PyPinholeCamera;
use crate::errors::{IntoPyResult, InvalidValueError, ShapeError};

/// A borrowed, C-contiguous, dtype-checked NumPy array.
pub struct ArrayArg<'py, T: Element> {
    array: PyReadonlyArrayDyn<'py, T>,
    /// The array's shape.
    pub shape: Vec<usize>,
}

impl<T: Element> ArrayArg<'_, T> {
    /// The data, flat in C order.
    pub fn as_slice(&self) -> &[T] {
        // Contiguity and alignment were checked when the argument was built.
        self.array.as_slice().unwrap_or(&[])
    }
}

impl ArrayArg<'_, bool> {
    /// The data as raw bytes, flat in C order. A bool array that is a view of other data
    /// (`np.uint8(...).view(bool)`) can hold any byte, so bool arrays are never read as
    /// `&[bool]` directly (see [`BoolArg`]).
    pub fn bytes(&self) -> &[u8] {
        let len: usize = self.shape.iter().product();
        if len == 0 {
            return &[];
        }
        // SAFETY: the array is C-contiguous and holds `len` one-byte elements (checked when
        // the argument was built); every byte is a valid u8; the read-only borrow keeps it
        // alive and unaliased by Rust writers.
        unsafe { std::slice::from_raw_parts(self.array.data().cast::<u8>().cast_const(), len) }
    }
}

/// A borrowed bool array whose elements are valid `bool`s: bytes other than 0 and 1 (a
/// bool view of other data) are read as NumPy reads them, nonzero = `True`, in a copy.
pub struct BoolArg<'py> {
    arg: ArrayArg<'py, bool>,
    normalized: Option<Vec<bool>>,
}

impl BoolArg<'_> {
    /// The array's shape.
    pub fn shape(&self) -> &[usize] {
        &self.arg.shape
    }

    /// The data, flat in C order.
    pub fn as_slice(&self) -> &[bool] {
        match &self.normalized {
            Some(v) => v,
            None => {
                let b = self.arg.bytes();
                // SAFETY: every byte is 0 or 1 (checked when the argument was built), the
                // bit patterns of `false` and `true`; bool has the size and alignment of u8.
                unsafe { std::slice::from_raw_parts(b.as_ptr().cast::<bool>(), b.len()) }
            }
        }
    }
}

/// Borrows `obj` as a bool array with `ndim` dimensions (see [`BoolArg`]).
pub fn bool_arg<'py>(obj: &Bound<'py, PyAny>, name: &str, ndim: usize) -> PyResult<BoolArg<'py>> {
    let arg = array_arg::<bool>(obj, name, "bool", Some(ndim))?;
    let normalized = if arg.bytes().iter().any(|&b| b > 1) {
        Some(arg.bytes().iter().map(|&b| b != 0).collect())
    } else {
        None
    };
    Ok(BoolArg { arg, normalized })
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
    let array = typed.readonly();
    // A C-contiguous array whose data is not aligned for its dtype (a view at an odd
    // byte offset of a buffer) cannot be borrowed as a slice.
    if array.as_slice().is_err() {
        return Err(ShapeError::new_err(format!(
            "{name}: array data must be aligned for its dtype (copy it: numpy.array(x))"
        )));
    }
    Ok(ArrayArg { array, shape })
}

/// A mask argument: bool or uint8 (nonzero = set).
pub enum MaskArg<'py> {
    /// dtype bool.
    Bool(ArrayArg<'py, bool>),
    /// dtype uint8.
    U8(ArrayArg<'py, u8>),
}

impl MaskArg<'_> {
    /// The mask bytes, nonzero = set (a bool array's raw bytes).
    pub fn bytes(&self) -> &[u8] {
        match self {
            MaskArg::Bool(a) => a.bytes(),
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
    floats_arg::<3>(obj, name)
}

/// `N` floats given as any sequence (list, tuple, 1-D array, iterable) of `N` numbers.
/// Strings, bools and sequences holding bools are refused; at most `N + 1` items are
/// read, so an endless or astronomically long iterable costs nothing.
pub fn floats_arg<const N: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; N]> {
    let bad = || ShapeError::new_err(format!("{name}: expected a sequence of {N} floats"));
    if is_bool(obj)
        || obj.is_instance_of::<PyString>()
        || obj.is_instance_of::<PyBytes>()
        || obj.is_instance_of::<PyByteArray>()
    {
        return Err(bad());
    }
    let iter = obj.try_iter().map_err(|_| bad())?;
    let mut out = [0.0; N];
    let mut n = 0;
    for item in iter {
        let item = item?;
        if n == N {
            let got = obj
                .len()
                .map_or_else(|_| format!("more than {N}"), |l| l.to_string());
            return Err(ShapeError::new_err(format!(
                "{name}: expected {N} values, got {got}"
            )));
        }
        if is_bool(&item) {
            return Err(bad());
        }
        out[n] = item.extract::<f64>().map_err(|_| bad())?;
        n += 1;
    }
    if n != N {
        return Err(ShapeError::new_err(format!(
            "{name}: expected {N} values, got {n}"
        )));
    }
    Ok(out)
}

/// Whether `obj` is a Python bool or a NumPy bool scalar.
pub fn is_bool(obj: &Bound<'_, PyAny>) -> bool {
    if obj.is_instance_of::<PyBool>() {
        return true;
    }
    let ty = obj.get_type();
    let in_numpy = ty.module().is_ok_and(|m| matches!(m.to_str(), Ok("numpy")));
    in_numpy
        && ty
            .name()
            .is_ok_and(|n| matches!(n.to_str(), Ok("bool" | "bool_")))
}

/// `repr(obj)`, cut to 80 characters, for error messages.
pub fn short_repr(obj: &Bound<'_, PyAny>) -> String {
    let r = obj
        .repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "?".into());
    if r.chars().count() > 80 {
        format!("{}...", r.chars().take(77).collect::<String>())
    } else {
        r
    }
}

/// The name of `obj`'s type, for error messages.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// A real-number argument: an int, a float or a NumPy scalar (not a bool, not an array
/// with dimensions); anything else raises `InvalidValueError` naming the argument. The
/// range is the core's to check.
pub fn float_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    let bad = || {
        InvalidValueError::new_err(format!(
            "{name}: expected a real number, got {}",
            short_repr(obj)
        ))
    };
    if is_bool(obj) || obj.cast::<PyUntypedArray>().is_ok_and(|a| a.ndim() > 0) {
        return Err(bad());
    }
    obj.extract::<f64>().map_err(|_| bad())
}

/// A `PinholeCamera` argument.
pub fn camera_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<PinholeCamera> {
    obj.cast::<PyPinholeCamera>()
        .map(|c| c.get().inner)
        .map_err(|_| {
            InvalidValueError::new_err(format!(
                "{name}: expected a PinholeCamera, got {}",
                type_name(obj)
            ))
        })
}

/// A borrowed instance of the pyclass `T` (`what`: its Python name with an article).
pub fn instance_arg<'py, T: pyo3::PyClass>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<PyRef<'py, T>> {
    let b = obj.cast::<T>().map_err(|_| {
        InvalidValueError::new_err(format!("{name}: expected {what}, got {}", type_name(obj)))
    })?;
    Ok(b.try_borrow()?)
}

/// The items of the sequence or iterable `obj` (not a string), at most `max` of them; a
/// non-iterable raises `ShapeError` naming the argument (`what` describes the items), and
/// so do more than `max` items (`expect` says how many the call takes). Reads at most
/// `max + 1` items.
pub fn items_arg<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    max: usize,
    what: &str,
    expect: &str,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let bad = || ShapeError::new_err(format!("{name}: expected a sequence of {what}"));
    if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() || is_bool(obj) {
        return Err(bad());
    }
    let mut out = Vec::new();
    for item in obj.try_iter().map_err(|_| bad())? {
        if out.len() == max {
            let got = obj
                .len()
                .map_or_else(|_| format!("more than {max}"), |l| l.to_string());
            return Err(ShapeError::new_err(format!(
                "{name}: expected {expect}, got {got}"
            )));
        }
        out.push(item?);
    }
    Ok(out)
}

/// Extractors for `#[pyo3(from_py_with = ...)]`, one per argument name, so that a bad
/// value raises a `HeapgraspError` naming the argument (pyo3's own extraction raises
/// `TypeError` and takes `True` for `1.0`).
pub mod named {
    use super::*;

    macro_rules! float_args {
        ($($f:ident),* $(,)?) => {$(
            #[doc = concat!("The real-number argument `", stringify!($f), "`.")]
            pub fn $f(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
                float_arg(obj, stringify!($f))
            }
        )*};
    }
    float_args!(fx, fy, cx, cy, size, lam, truncation, voxel_size, sigma, threshold);

    /// The `PinholeCamera` argument `camera`.
    pub fn camera(obj: &Bound<'_, PyAny>) -> PyResult<PinholeCamera> {
        camera_arg(obj, "camera")
    }
}

/// Runs `f` with the GIL released and converts its core error.
pub fn detached<T: Send, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    F: FnOnce() -> CoreResult<T> + Send,
{
    py.detach(f).py()
}

/// An integer argument in `lo..=hi`; other ints (negative, huge), bools and non-ints raise
/// `InvalidValueError` naming the argument instead of pyo3's `OverflowError` / `TypeError`.
pub fn int_arg(obj: &Bound<'_, PyAny>, name: &str, lo: i64, hi: i64, what: &str) -> PyResult<i64> {
    let bad = || InvalidValueError::new_err(format!("{name}: {what} (got {})", short_repr(obj)));
    if is_bool(obj) {
        return Err(bad());
    }
    let v: i64 = obj.extract().map_err(|_| bad())?;
    if v < lo || v > hi {
        return Err(bad());
    }
    Ok(v)
}

/// `d[key]` of the mapping argument `what`; a missing key raises `InvalidValueError`
/// naming it (`what: missing key "key"`), other errors pass through.
pub fn mapping_item<'py>(
    d: &Bound<'py, PyMapping>,
    what: &str,
    key: &str,
) -> PyResult<Bound<'py, PyAny>> {
    d.get_item(key).map_err(|e| {
        if e.is_instance_of::<PyKeyError>(d.py()) {
            InvalidValueError::new_err(format!("{what}: missing key {key:?}"))
        } else {
            e
        }
    })
}
