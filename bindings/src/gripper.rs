//! The gripper's box model (`heapgrasp_core::gripper`) from a mapping of
//! `GripperGeometry`'s fields, for `antipodal_grasps` and `GraspLabeller`.

use heapgrasp_core::gripper::HandGeometry;
use pyo3::prelude::*;

/// `GripperGeometry`'s fields as a [`HandGeometry`]: `number(key)` and `pair(key)` read
/// and check one entry each (the caller's messages), in the fields' order;
/// `max_opening` where the caller has read it already, else read last.
pub fn hand_geometry(
    number: impl Fn(&str) -> PyResult<f64>,
    pair: impl Fn(&str) -> PyResult<[f64; 2]>,
    max_opening: Option<f64>,
) -> PyResult<HandGeometry> {
    Ok(HandGeometry {
        finger_width: number("finger_width")?,
        finger_tip: number("finger_tip")?,
        finger_base: number("finger_base")?,
        finger_split: number("finger_split")?,
        tip_thickness: number("tip_thickness")?,
        base_thickness: number("base_thickness")?,
        palm_front: number("palm_front")?,
        palm_split: number("palm_split")?,
        palm_back: number("palm_back")?,
        palm_front_half: pair("palm_front_half")?,
        palm_back_half: pair("palm_back_half")?,
        max_opening: match max_opening {
            Some(v) => v,
            None => number("max_opening")?,
        },
    })
}
