//! `heapgrasp._core`: thin pyo3 bindings of `heapgrasp-core`.
//!
//! Each file wraps one core module: it validates and borrows the NumPy arguments
//! ([`convert`]), releases the GIL around the core call, and maps core errors onto the
//! `HeapgraspError` hierarchy ([`errors`]). No algorithm lives here.

mod antipodal;
mod camera;
mod clouds;
mod convert;
mod errors;
mod filter;
mod grasp_label;
mod gripper;
mod hand_points;
mod occupancy;
mod raster;
mod roofs;
mod score;
mod synthesis;
mod tsdf;
mod visibility;

use pyo3::prelude::*;

/// Name of the SIMD build of the carving kernel in use: "avx512", "avx2" or "baseline".
#[pyfunction]
fn kernel_level() -> &'static str {
    heapgrasp_core::carve::kernel_level().name()
}

/// Why `HEAPGRASP_KERNEL` was not honoured (an unknown value, or a level this CPU
/// lacks), or None.
#[pyfunction]
fn kernel_request_problem() -> Option<String> {
    heapgrasp_core::carve::kernel_request().err()
}

/// Number of threads the kernels use (`HEAPGRASP_NUM_THREADS` or the CPU count).
#[pyfunction]
fn num_threads() -> usize {
    heapgrasp_core::parallel::num_threads()
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<camera::PyPinholeCamera>()?;
    m.add_class::<occupancy::PyOccupancyGrid>()?;
    m.add_class::<raster::PyMeshScene>()?;
    m.add_class::<tsdf::PyTsdfVolume>()?;
    m.add_class::<grasp_label::PyGraspLabeller>()?;
    m.add_function(wrap_pyfunction!(score::score_views, m)?)?;
    m.add_function(wrap_pyfunction!(antipodal::antipodal_grasps, m)?)?;
    m.add_function(wrap_pyfunction!(hand_points::hand_point_counts, m)?)?;
    m.add_function(wrap_pyfunction!(hand_points::first_free_pose, m)?)?;
    m.add_function(wrap_pyfunction!(clouds::seen_empty, m)?)?;
    m.add_function(wrap_pyfunction!(clouds::voxel_downsample, m)?)?;
    m.add_function(wrap_pyfunction!(clouds::depth_voxels, m)?)?;
    m.add_function(wrap_pyfunction!(synthesis::point_normals, m)?)?;
    m.add_function(wrap_pyfunction!(synthesis::contact_patches, m)?)?;
    m.add_function(wrap_pyfunction!(synthesis::antipodal_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(visibility::grasp_region, m)?)?;
    m.add_function(wrap_pyfunction!(visibility::surfel_visibility, m)?)?;
    m.add_function(wrap_pyfunction!(roofs::keep_silhouettes, m)?)?;
    m.add_function(wrap_pyfunction!(filter::gaussian_filter3d, m)?)?;
    m.add_function(wrap_pyfunction!(filter::maximum_filter3d, m)?)?;
    m.add_function(wrap_pyfunction!(filter::nms3d, m)?)?;
    m.add_function(wrap_pyfunction!(kernel_level, m)?)?;
    m.add_function(wrap_pyfunction!(kernel_request_problem, m)?)?;
    m.add_function(wrap_pyfunction!(num_threads, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
