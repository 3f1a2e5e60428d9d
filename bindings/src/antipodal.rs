//! `antipodal_grasps`.

use heapgrasp_core::antipodal::{self, AntipodalParams, AntipodalScene};
use heapgrasp_core::Error;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyMapping;

use crate::convert::{
    array_arg, bool_arg, floats_arg, is_bool, mapping_item, shape_str, type_name,
};
use crate::errors::{CoreError, InvalidValueError, ShapeError};
use crate::gripper::hand_geometry;

/// `params[key]`; a missing key raises `InvalidValueError` naming it.
fn item<'py>(d: &Bound<'py, PyMapping>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    mapping_item(d, "params", key)
}

fn float(d: &Bound<'_, PyMapping>, key: &str) -> PyResult<f64> {
    let v = item(d, key)?;
    let bad = || InvalidValueError::new_err(format!("params[{key:?}]: expected a number"));
    if is_bool(&v) {
        return Err(bad());
    }
    v.extract::<f64>().map_err(|_| bad())
}

fn int(d: &Bound<'_, PyMapping>, key: &str) -> PyResult<i64> {
    let v = item(d, key)?;
    let bad = || InvalidValueError::new_err(format!("params[{key:?}]: expected an int"));
    if is_bool(&v) {
        return Err(bad());
    }
    v.extract::<i64>().map_err(|_| bad())
}

fn pair(d: &Bound<'_, PyMapping>, key: &str) -> PyResult<[f64; 2]> {
    floats_arg::<2>(&item(d, key)?, "").map_err(|_| {
        InvalidValueError::new_err(format!("params[{key:?}]: expected a pair of numbers"))
    })
}

fn planner_params(d: &Bound<'_, PyAny>) -> PyResult<AntipodalParams> {
    let d = d.cast::<PyMapping>().map_err(|_| {
        InvalidValueError::new_err(format!(
            "params: expected a mapping of names to numbers, got {}",
            type_name(d)
        ))
    })?;
    let f = |k: &str| float(d, k);
    let (voxel_size, origin_z) = (f("voxel_size")?, f("origin_z")?);
    let max_opening = f("max_opening")?;
    let (opening_margin, clearance) = (f("opening_margin")?, f("clearance")?);
    Ok(AntipodalParams {
        voxel_size,
        origin_z,
        opening_margin,
        clearance,
        hand: hand_geometry(f, |k| pair(d, k), Some(max_opening))?,
        pregrasp_distance: f("pregrasp_distance")?,
        table_z: f("table_z")?,
        table_clearance: f("table_clearance")?,
        min_depth: f("min_depth")?,
        target_depth: f("target_depth")?,
        min_patch: int(d, "min_patch")?,
        min_contact_height: f("min_contact_height")?,
        ledge_factor: f("ledge_factor")?,
        friction_angle: f("friction_angle")?,
    })
}

/// The core names a bad parameter by its field (`max_opening`, `palm_front_half[0]`);
/// the caller passed it as `params["max_opening"]`.
fn in_params(e: Error) -> PyErr {
    let key = |name: &str| {
        let (field, index) = name.split_once('[').map_or((name, ""), |(f, i)| (f, i));
        if index.is_empty() {
            format!("params[{field:?}]")
        } else {
            format!("params[{field:?}][{index}")
        }
    };
    match e {
        Error::Value {
            name,
            value,
            reason,
        } if PARAM_NAMES.contains(&name.split('[').next().unwrap_or("")) => {
            CoreError(Error::Value {
                name: key(&name),
                value,
                reason,
            })
            .into()
        }
        e => CoreError(e).into(),
    }
}

/// The keys of `params`.
const PARAM_NAMES: [&str; 25] = [
    "voxel_size",
    "origin_z",
    "max_opening",
    "opening_margin",
    "clearance",
    "finger_width",
    "finger_tip",
    "finger_base",
    "finger_split",
    "tip_thickness",
    "base_thickness",
    "palm_front",
    "palm_split",
    "palm_back",
    "palm_front_half",
    "palm_back_half",
    "pregrasp_distance",
    "table_z",
    "table_clearance",
    "min_depth",
    "target_depth",
    "min_patch",
    "min_contact_height",
    "ledge_factor",
    "friction_angle",
];

/// Each candidate's best antipodal grasp over `rotations` (K, 3, 3) with `tilts` (K,):
/// (quality float64 (N,), orientation index int64 (N,), width float64 (N,)).
#[pyfunction]
#[pyo3(signature = (occupied, gradient, labels, centroids, candidates, rotations, tilts, params))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn antipodal_grasps<'py>(
    py: Python<'py>,
    occupied: &Bound<'py, PyAny>,
    gradient: &Bound<'py, PyAny>,
    labels: &Bound<'py, PyAny>,
    centroids: &Bound<'py, PyAny>,
    candidates: &Bound<'py, PyAny>,
    rotations: &Bound<'py, PyAny>,
    tilts: &Bound<'py, PyAny>,
    params: &Bound<'py, PyAny>,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    let occ = bool_arg(occupied, "occupied", 3)?;
    let r = occ.shape()[0];
    let cube = |name: &str, shape: &[usize], want: &[usize]| -> PyResult<()> {
        if shape != want {
            return Err(ShapeError::new_err(format!(
                "{name}: expected shape {}, got {}",
                shape_str(want),
                shape_str(shape)
            )));
        }
        Ok(())
    };
    cube("occupied", occ.shape(), &[r, r, r])?;
    if r == 0 {
        return Err(ShapeError::new_err(
            "occupied: expected an (R, R, R) volume with R >= 1, got shape (0, 0, 0)",
        ));
    }
    let grad = array_arg::<f64>(gradient, "gradient", "float64", Some(4))?;
    cube("gradient", &grad.shape, &[3, r, r, r])?;
    let lab = array_arg::<i32>(labels, "labels", "int32", Some(3))?;
    cube("labels", &lab.shape, &[r, r, r])?;
    let cen = array_arg::<f64>(centroids, "centroids", "float64", Some(2))?;
    cube("centroids", &cen.shape[1..], &[3])?;
    let cand = array_arg::<i64>(candidates, "candidates", "int64", Some(2))?;
    cube("candidates", &cand.shape[1..], &[3])?;
    let rot = array_arg::<f64>(rotations, "rotations", "float64", Some(3))?;
    cube("rotations", &rot.shape[1..], &[3, 3])?;
    let tilt = array_arg::<f64>(tilts, "tilts", "float64", Some(1))?;
    let cand_idx = cand
        .as_slice()
        .chunks_exact(3)
        .map(|p| {
            let mut out = [0usize; 3];
            for (o, &x) in out.iter_mut().zip(p) {
                *o = usize::try_from(x).map_err(|_| {
                    InvalidValueError::new_err(format!(
                        "candidates: voxel indices must be >= 0, got {p:?}"
                    ))
                })?;
            }
            Ok(out)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let cen_rows: Vec<[f64; 3]> = cen
        .as_slice()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let rots: Vec<[[f64; 3]; 3]> = rot
        .as_slice()
        .chunks_exact(9)
        .map(|m| [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]])
        .collect();
    let params = planner_params(params)?;
    let (occ_s, grad_s, lab_s, tilt_s) = (
        occ.as_slice(),
        grad.as_slice(),
        lab.as_slice(),
        tilt.as_slice(),
    );
    let best = py
        .detach(move || {
            let scene = AntipodalScene {
                resolution: r,
                occupied: occ_s,
                gradient: grad_s,
                labels: lab_s,
                centroids: &cen_rows,
                candidates: &cand_idx,
            };
            antipodal::best_grasps(&scene, &params, &rots, tilt_s)
        })
        .map_err(in_params)?;
    let orientation: Vec<i64> = best.orientation.into_iter().map(|k| k as i64).collect();
    Ok((
        PyArray1::from_vec(py, best.quality),
        PyArray1::from_vec(py, orientation),
        PyArray1::from_vec(py, best.width),
    ))
}
