//! `GraspLabeller`.

use heapgrasp_core::grasp_label::{GraspLabeller, GraspScene, HandParts, LabelParams};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyMapping;

use crate::convert::{
    array_arg, check_tail, detached, float_arg, floats_arg, int_arg, items_arg, mapping_item,
    pose_arg, poses_arg, type_name,
};
use crate::errors::{IntoPyResult, InvalidValueError};
use crate::gripper::hand_geometry;

/// Most convex pieces one object may have.
const MAX_PIECES: usize = 4096;

/// Labels as NumPy arrays: success bool, width float32, object int32, reason uint8.
type Labels<'py> = (
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<i32>>,
    Bound<'py, PyArray1<u8>>,
);

/// `hand[key]` as a number; a missing key or a non-number raises `InvalidValueError`.
fn hand_item<'py>(d: &Bound<'py, PyMapping>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    mapping_item(d, "hand", key)
}

/// `(V, 3)` float64 arrays, copied.
fn vertex_arrays(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Vec<f64>>> {
    let items = items_arg(
        obj,
        name,
        MAX_PIECES,
        "(V, 3) float64 arrays",
        &format!("at most {MAX_PIECES} pieces"),
    )?;
    items
        .iter()
        .enumerate()
        .map(|(k, item)| {
            let name = format!("{name}[{k}]");
            let a = array_arg::<f64>(item, &name, "float64", Some(2))?;
            check_tail(&name, &a.shape, &[3], "(V, 3)")?;
            Ok(a.as_slice().to_vec())
        })
        .collect()
}

/// The hand: a mapping of `GripperGeometry`'s fields (its boxes), or of convex parts
/// (`palm`, `left`, `right`: sequences of `(V, 3)` arrays; `max_opening`).
fn hand_arg(hand: &Bound<'_, PyAny>) -> PyResult<HandParts> {
    let d = hand.cast::<PyMapping>().map_err(|_| {
        InvalidValueError::new_err(format!(
            "hand: expected a mapping (GripperGeometry's fields, or palm/left/right/max_opening), got {}",
            type_name(hand)
        ))
    })?;
    if d.contains("palm")? {
        let parts = |k: &str| vertex_arrays(&hand_item(d, k)?, &format!("hand[{k:?}]"));
        let optional = |k: &str| -> PyResult<f64> {
            if d.contains(k)? {
                float_arg(&hand_item(d, k)?, &format!("hand[{k:?}]"))
            } else {
                Ok(0.0)
            }
        };
        return Ok(HandParts {
            palm: parts("palm")?,
            left: parts("left")?,
            right: parts("right")?,
            max_opening: float_arg(&hand_item(d, "max_opening")?, "hand[\"max_opening\"]")?,
            palm_threshold: optional("palm_threshold")?,
            finger_threshold: optional("finger_threshold")?,
        });
    }
    let f = |k: &str| float_arg(&hand_item(d, k)?, &format!("hand[{k:?}]"));
    let pair = |k: &str| floats_arg::<2>(&hand_item(d, k)?, &format!("hand[{k:?}]"));
    let geometry = hand_geometry(f, pair, None)?;
    geometry.validate().py()?;
    Ok(geometry.parts())
}

/// Exact-geometry grasp labels on convex object pieces and a table.
#[pyclass(name = "GraspLabeller", module = "heapgrasp._core")]
pub struct PyGraspLabeller {
    inner: GraspLabeller,
}

#[pymethods]
impl PyGraspLabeller {
    #[new]
    #[pyo3(signature = (hand, *, table_z, friction, pregrasp_distance, hand_margin, object_margin, min_width, approach_lag = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        hand: &Bound<'_, PyAny>,
        table_z: &Bound<'_, PyAny>,
        friction: &Bound<'_, PyAny>,
        pregrasp_distance: &Bound<'_, PyAny>,
        hand_margin: &Bound<'_, PyAny>,
        object_margin: &Bound<'_, PyAny>,
        min_width: &Bound<'_, PyAny>,
        approach_lag: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let zero_or =
            |v: Option<&Bound<'_, PyAny>>, name: &str| v.map_or(Ok(0.0), |v| float_arg(v, name));
        let hand = hand_arg(hand)?;
        let hand_margin = float_arg(hand_margin, "hand_margin")?;
        let params = LabelParams {
            pregrasp_distance: float_arg(pregrasp_distance, "pregrasp_distance")?,
            friction: float_arg(friction, "friction")?,
            hand_margin,
            approach_lag: zero_or(approach_lag, "approach_lag")?,
            object_margin: float_arg(object_margin, "object_margin")?,
            min_width: float_arg(min_width, "min_width")?,
        };
        let scene = GraspScene::new(float_arg(table_z, "table_z")?).py()?;
        Ok(Self {
            inner: GraspLabeller::new(scene, &hand, params).py()?,
        })
    }

    /// Adds object `id` at `obj2world` made of `pieces`, each a `(V, 3)` float64 array
    /// of object-frame vertices collided as its convex hull, with a contact `threshold`.
    #[pyo3(signature = (id, obj2world, pieces, threshold = None))]
    fn add_object(
        &mut self,
        id: &Bound<'_, PyAny>,
        obj2world: &Bound<'_, PyAny>,
        pieces: &Bound<'_, PyAny>,
        threshold: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let threshold = threshold.map_or(Ok(0.0), |t| float_arg(t, "threshold"))?;
        let id = int_arg(
            id,
            "id",
            0,
            i64::from(i32::MAX),
            "expected an int in [0, 2**31 - 1]",
        )?;
        let pose = pose_arg(obj2world, "obj2world")?;
        let arrays = vertex_arrays(pieces, "pieces")?;
        let slices: Vec<&[f64]> = arrays.iter().map(Vec::as_slice).collect();
        // `id` was range-checked by `int_arg`.
        let id = i32::try_from(id).unwrap_or(i32::MAX);
        self.inner.add_object(id, pose, &slices, threshold).py()
    }

    /// Labels grasps `tcp2world` (N, 4, 4) float64 on `threads` threads (0: all).
    #[pyo3(signature = (tcp2world, *, threads = None))]
    fn label<'py>(
        &self,
        py: Python<'py>,
        tcp2world: &Bound<'py, PyAny>,
        threads: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Labels<'py>> {
        let threads = match threads {
            None => 0,
            Some(t) => int_arg(t, "threads", 0, 4096, "expected an int in [0, 4096]")? as usize,
        };
        let poses = poses_arg(tcp2world, "tcp2world")?;
        let inner = &self.inner;
        let labels = detached(py, || Ok(inner.label(&poses, threads)))?;
        Ok((
            PyArray1::from_vec(py, labels.iter().map(|l| l.success).collect()),
            PyArray1::from_vec(py, labels.iter().map(|l| l.width).collect()),
            PyArray1::from_vec(py, labels.iter().map(|l| l.object).collect()),
            PyArray1::from_vec(py, labels.iter().map(|l| l.reason as u8).collect()),
        ))
    }

    /// The reasons' names, indexed by their codes.
    #[staticmethod]
    fn reasons() -> Vec<&'static str> {
        heapgrasp_core::grasp_label::Reason::ALL
            .iter()
            .map(|r| r.name())
            .collect()
    }

    /// World z of the table's top.
    #[getter]
    fn table_z(&self) -> f64 {
        self.inner.scene().table_z()
    }

    /// Number of objects.
    #[getter]
    fn object_count(&self) -> usize {
        self.inner.scene().len()
    }

    /// Number of convex pieces over all objects.
    #[getter]
    fn piece_count(&self) -> usize {
        self.inner.scene().piece_count()
    }

    fn __repr__(&self) -> String {
        format!(
            "GraspLabeller(objects={}, pieces={}, table_z={})",
            self.inner.scene().len(),
            self.inner.scene().piece_count(),
            self.inner.scene().table_z()
        )
    }
}
