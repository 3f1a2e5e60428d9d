//! Pinhole cameras and rigid poses: the projection convention every kernel shares.
//!
//! # Conventions
//! - A pose is a rigid transform given as a row-major 4x4 `cam2world` matrix
//!   (camera frame to world frame). Camera axes follow OpenCV: x right, y down,
//!   z forward (the optical axis).
//! - A point with camera coordinates `(x, y, z)`, `z > 0`, falls on pixel
//!   `(u, v) = (floor(fx*x/z + cx + 0.5), floor(fy*y/z + cy + 0.5))`. It is in the
//!   image iff `0 <= u < width` and `0 <= v < height`. Pixel `(u, v)` therefore has
//!   its centre at continuous image coordinates exactly `(u, v)`.
//! - Images and masks are row-major `(height, width)` buffers indexed `[v, u]`.

use nalgebra::{Matrix3, Matrix4, Point3, Vector3};

use crate::error::{Error, Result};

/// Largest accepted image side, in pixels: larger values are almost surely a mistake
/// and would make per-frame buffers absurd.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// Tolerance on `R^T R - I` (max abs entry) and on `det R - 1` for a pose to count as rigid.
pub const RIGID_TOLERANCE: f64 = 1e-4;

/// Intrinsics of an ideal pinhole camera (no distortion).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels.
    pub cx: f64,
    /// Principal point y, in pixels.
    pub cy: f64,
}

impl PinholeCamera {
    /// Creates a camera after validating every parameter.
    ///
    /// # Errors
    /// [`Error::Value`] if a side is 0 or above [`MAX_IMAGE_SIDE`], a focal length is not
    /// strictly positive, or any parameter is not finite.
    ///
    /// # Example
    /// ```
    /// use heapgrasp_core::PinholeCamera;
    /// let cam = PinholeCamera::new(640, 480, 540.0, 540.0, 320.0, 240.0).unwrap();
    /// assert_eq!(cam.pixel_count(), 640 * 480);
    /// assert!(PinholeCamera::new(0, 480, 540.0, 540.0, 320.0, 240.0).is_err());
    /// ```
    pub fn new(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self> {
        for (name, side) in [("width", width), ("height", height)] {
            if side == 0 || side > MAX_IMAGE_SIDE {
                return Err(Error::value(
                    name,
                    side,
                    format!("must be between 1 and {MAX_IMAGE_SIDE} pixels"),
                ));
            }
        }
        for (name, f) in [("fx", fx), ("fy", fy)] {
            if !(f.is_finite() && f > 0.0) {
                return Err(Error::value(name, f, "focal length must be finite and > 0"));
            }
        }
        for (name, c) in [("cx", cx), ("cy", cy)] {
            if !c.is_finite() {
                return Err(Error::value(name, c, "principal point must be finite"));
            }
        }
        Ok(Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        })
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Projects a camera-frame point to its pixel `(u, v)`, or `None` when it is behind
    /// the camera (`z <= 0`) or outside the image. This is the reference form of the
    /// projection convention; kernels use vectorised equivalents of it.
    pub fn project(&self, p_cam: &Point3<f64>) -> Option<(u32, u32)> {
        if !(p_cam.z > 0.0) {
            return None;
        }
        let uf = self.fx * p_cam.x / p_cam.z + self.cx + 0.5;
        let vf = self.fy * p_cam.y / p_cam.z + self.cy + 0.5;
        if uf >= 0.0 && uf < self.width as f64 && vf >= 0.0 && vf < self.height as f64 {
            Some((uf as u32, vf as u32))
        } else {
            None
        }
    }

    /// Direction (camera frame, z = 1) of the ray through the centre of pixel `(u, v)`.
    pub fn pixel_ray(&self, u: f64, v: f64) -> Vector3<f64> {
        Vector3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0)
    }

    /// Checks that a row-major image buffer has this camera's size.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `name` when `len != width * height`.
    pub fn check_image(&self, name: &str, len: usize) -> Result<()> {
        if len != self.pixel_count() {
            return Err(Error::shape(
                name,
                format!("({}, {}) to match the camera", self.height, self.width),
                format!("{len} pixels"),
            ));
        }
        Ok(())
    }
}

/// A rigid transform `a2b` (rotation then translation), validated on construction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
}

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// Builds a pose from a row-major 4x4 homogeneous matrix.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf entries; [`Error::NotRigid`] when the last row is
    /// not `[0, 0, 0, 1]`, or the rotation block is not orthonormal with determinant +1
    /// within [`RIGID_TOLERANCE`].
    ///
    /// # Example
    /// ```
    /// use heapgrasp_core::Pose;
    /// let m = [1.0, 0.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.0, 0.0, 0.0, 1.0];
    /// let pose = Pose::from_row_major("cam2world", &m).unwrap();
    /// assert_eq!(pose.translation().z, 0.3);
    /// let mut scaled = m;
    /// scaled[0] = 2.0;
    /// assert!(Pose::from_row_major("cam2world", &scaled).is_err());
    /// ```
    pub fn from_row_major(name: &str, m: &[f64; 16]) -> Result<Self> {
        if let Some(i) = m.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                name: name.to_owned(),
                position: format!("[{}, {}]", i / 4, i % 4),
            });
        }
        let last = [m[12], m[13], m[14], m[15]];
        if last != [0.0, 0.0, 0.0, 1.0] {
            return Err(Error::NotRigid {
                name: name.to_owned(),
                reason: format!("last row must be [0, 0, 0, 1], got {last:?}"),
            });
        }
        let rotation = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
        let ortho = (rotation.transpose() * rotation - Matrix3::identity()).amax();
        let det = rotation.determinant();
        if ortho > RIGID_TOLERANCE || (det - 1.0).abs() > RIGID_TOLERANCE {
            return Err(Error::NotRigid {
                name: name.to_owned(),
                reason: format!(
                    "rotation block must be orthonormal with det +1 (max |R^T R - I| = {ortho:.3e}, det = {det:.6})"
                ),
            });
        }
        Ok(Self {
            rotation,
            translation: Vector3::new(m[3], m[7], m[11]),
        })
    }

    /// A camera pose at `eye` looking at `target` (OpenCV axes: z toward the target,
    /// x = z × `up` to the image right, y = z × x pointing down). When the viewing
    /// direction is parallel to `up`, `+y` of the world serves as `up` instead, so a
    /// camera looking straight down sees world +y toward the top of the image.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for non-finite inputs, [`Error::Value`] when `eye == target`.
    pub fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3]) -> Result<Self> {
        for (name, v) in [("eye", eye), ("target", target), ("up", up)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(Error::NonFinite {
                    name: name.to_owned(),
                    position: format!("[{i}]"),
                });
            }
        }
        let eye_v = Vector3::from(eye);
        let dir = Vector3::from(target) - eye_v;
        let dist = dir.norm();
        if !(dist > 1e-12) {
            return Err(Error::value(
                "target",
                format!("{target:?}"),
                "must differ from eye",
            ));
        }
        let z = dir / dist;
        let mut x = z.cross(&Vector3::from(up));
        if x.norm() < 1e-9 {
            x = z.cross(&Vector3::y());
        }
        let x = x.normalize();
        let y = z.cross(&x);
        Ok(Self {
            rotation: Matrix3::from_columns(&[x, y, z]),
            translation: eye_v,
        })
    }

    /// The rotation block.
    pub fn rotation(&self) -> &Matrix3<f64> {
        &self.rotation
    }

    /// The translation.
    pub fn translation(&self) -> &Vector3<f64> {
        &self.translation
    }

    /// The inverse transform (`b2a` for an `a2b` pose).
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Applies the transform to a point.
    pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * p.coords + self.translation)
    }

    /// Composition `self * other` (apply `other` first).
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The homogeneous 4x4 matrix.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

/// Parses `n` consecutive row-major 4x4 poses from a flat `(n, 4, 4)` buffer.
///
/// # Errors
/// [`Error::Shape`] when the length is not a multiple of 16; otherwise the first error of
/// [`Pose::from_row_major`], with the pose index in the name (e.g. `cam2worlds[3]`).
pub fn poses_from_flat(name: &str, flat: &[f64]) -> Result<Vec<Pose>> {
    if !flat.len().is_multiple_of(16) {
        return Err(Error::shape(
            name,
            "(N, 4, 4)",
            format!("{} values", flat.len()),
        ));
    }
    flat.chunks_exact(16)
        .enumerate()
        .map(|(i, chunk)| {
            let mut m = [0.0; 16];
            m.copy_from_slice(chunk);
            Pose::from_row_major(&format!("{name}[{i}]"), &m)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> PinholeCamera {
        PinholeCamera::new(320, 240, 270.0, 270.0, 160.0, 120.0).unwrap()
    }

    #[test]
    fn principal_point_projects_to_its_pixel() {
        assert_eq!(cam().project(&Point3::new(0.0, 0.0, 1.0)), Some((160, 120)));
    }

    #[test]
    fn behind_and_outside_points_are_not_projected() {
        assert_eq!(cam().project(&Point3::new(0.0, 0.0, -1.0)), None);
        assert_eq!(cam().project(&Point3::new(0.0, 0.0, 0.0)), None);
        assert_eq!(cam().project(&Point3::new(10.0, 0.0, 1.0)), None);
    }

    #[test]
    fn pixel_borders_follow_the_floor_convention() {
        let c = cam();
        // u = 270 x + 160.5 crosses 0 at x = -160.5/270.
        assert_eq!(
            c.project(&Point3::new(-160.4 / 270.0, 0.0, 1.0)),
            Some((0, 120))
        );
        assert_eq!(c.project(&Point3::new(-160.6 / 270.0, 0.0, 1.0)), None);
    }

    #[test]
    fn pixel_ray_hits_its_own_pixel() {
        let c = cam();
        let d = c.pixel_ray(17.0, 33.0);
        assert_eq!(c.project(&Point3::from(d * 2.5)), Some((17, 33)));
    }

    #[test]
    fn look_at_points_the_optical_axis_at_the_target() {
        let c = cam();
        let target = [0.1, -0.2, 0.05];
        for eye in [[0.5, 0.1, 0.4], [0.1, -0.2, 0.6], [-0.3, 0.3, 0.0]] {
            let pose = Pose::look_at(eye, target, [0.0, 0.0, 1.0]).unwrap();
            let m = pose.to_matrix();
            let mut flat = [0.0; 16];
            for i in 0..16 {
                flat[i] = m[(i / 4, i % 4)];
            }
            assert!(Pose::from_row_major("pose", &flat).is_ok());
            let t = pose.inverse().transform_point(&Point3::from(target));
            assert_eq!(c.project(&t), Some((160, 120)));
        }
        assert!(Pose::look_at([0.0; 3], [0.0; 3], [0.0, 0.0, 1.0]).is_err());
    }

    #[test]
    fn pose_inverse_round_trips() {
        let a = std::f64::consts::FRAC_PI_3;
        let m = [
            a.cos(),
            -a.sin(),
            0.0,
            0.1,
            a.sin(),
            a.cos(),
            0.0,
            -0.2,
            0.0,
            0.0,
            1.0,
            0.5,
            0.0,
            0.0,
            0.0,
            1.0,
        ];
        let p = Pose::from_row_major("p", &m).unwrap();
        let q = Point3::new(0.3, -0.4, 0.7);
        let back = p.inverse().transform_point(&p.transform_point(&q));
        assert!((back - q).norm() < 1e-12);
    }

    #[test]
    fn bad_poses_are_rejected_with_their_name() {
        let mut m = [0.0; 16];
        m[0] = 1.0;
        m[5] = 1.0;
        m[10] = -1.0; // reflection
        m[15] = 1.0;
        let err = Pose::from_row_major("cam2world", &m).unwrap_err();
        assert!(matches!(err, Error::NotRigid { ref name, .. } if name == "cam2world"));
        m[10] = f64::NAN;
        assert!(matches!(
            Pose::from_row_major("x", &m),
            Err(Error::NonFinite { .. })
        ));
        assert!(poses_from_flat("poses", &[0.0; 15]).is_err());
    }
}
