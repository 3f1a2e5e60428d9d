//! # heapgrasp-core
//!
//! The pure-Rust geometry core of heapgrasp: pinhole cameras and rigid poses, the
//! Shape-from-Silhouette occupancy grid of HEAPGrasp (eq. 9–10), TSDF fusion for the VGN
//! baseline, ground-truth silhouettes and depth of triangle meshes, exact view scoring
//! over all candidate trajectories (eq. 14), the antipodal grasp search, the silhouette
//! check that follows roof trimming, and the 3-D Gaussian smoothing and non-maximum
//! suppression of grasp post-processing (§IV-B).
//!
//! It knows nothing about Python: functions take slices plus dimensions and return
//! owned results, and every fallible call returns [`Result`] with a typed [`Error`].
//!
//! ## Conventions (shared by every module and by the Python package)
//! - Poses are row-major 4x4 f64 `cam2world` matrices; camera axes are OpenCV's
//!   (x right, y down, z forward).
//! - A camera point `(x, y, z)`, `z > 0`, falls on pixel
//!   `(floor(fx·x/z + cx + 0.5), floor(fy·y/z + cy + 0.5))`, in the image iff
//!   `0 <= u < width` and `0 <= v < height`; masks are `(height, width)` indexed `[v, u]`.
//! - A grid is a cube (`origin` = minimum corner, `size`, `resolution` R); voxel
//!   `[a, b, c]` (x, y, z index, C order) has its centre at
//!   `origin + (index + 0.5) * size / R`.

// `!(x > 0.0)` is how the core rejects NaN together with out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod antipodal;
pub mod camera;
pub mod carve;
pub mod error;
pub mod filter;
pub mod grasp_label;
pub mod grid;
pub mod gripper;
pub mod nms;
pub mod occupancy;
pub mod parallel;
pub mod primitives;
pub mod projector;
pub mod raster;
pub mod roofs;
mod rounding;
pub mod score;
pub mod tsdf;
pub mod viewsphere;

pub use camera::{poses_from_flat, PinholeCamera, Pose};
pub use error::{Error, Result};
pub use grid::GridSpec;
pub use occupancy::OccupancyGrid;
pub use raster::MeshScene;
