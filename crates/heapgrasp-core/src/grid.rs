//! The cubic voxel grid every volume of heapgrasp lives on (the scene cube of HEAPGrasp §IV-A).
//!
//! # Convention
//! A grid is a cube with minimum corner `origin` (world frame, metres), side `size`
//! (metres) and `resolution` R voxels per axis. Volumes are flat C-order buffers of
//! length R³ indexed `[a, b, c]` = (x, y, z) index, so the flat index is
//! `(a * R + b) * R + c`. Voxel `[a, b, c]` has its centre at
//! `origin + ([a, b, c] + 0.5) * size / R`.

use nalgebra::Point3;

use crate::error::{Error, Result};

/// Largest accepted resolution: 512³ voxels already take 0.5 GiB per u32 volume.
pub const MAX_RESOLUTION: usize = 512;

/// Geometry of a cubic voxel grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    origin: [f64; 3],
    size: f64,
    resolution: usize,
}

impl GridSpec {
    /// Creates a grid after validating its parameters.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for a non-finite origin; [`Error::Value`] for a size that is
    /// not finite and > 0, or a resolution outside `1..=MAX_RESOLUTION`.
    ///
    /// # Example
    /// ```
    /// use heapgrasp_core::GridSpec;
    /// let g = GridSpec::new([0.0, 0.0, 0.0], 0.3, 40).unwrap();
    /// assert_eq!(g.voxel_count(), 64_000);
    /// assert!((g.voxel_size() - 0.0075).abs() < 1e-12);
    /// assert!(GridSpec::new([0.0; 3], -1.0, 40).is_err());
    /// ```
    pub fn new(origin: [f64; 3], size: f64, resolution: usize) -> Result<Self> {
        if let Some(i) = origin.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                name: "origin".into(),
                position: format!("[{i}]"),
            });
        }
        if !(size.is_finite() && size > 0.0) {
            return Err(Error::value(
                "size",
                size,
                "grid side must be finite and > 0 metres",
            ));
        }
        if resolution == 0 || resolution > MAX_RESOLUTION {
            return Err(Error::value(
                "resolution",
                resolution,
                format!("must be between 1 and {MAX_RESOLUTION} voxels per axis"),
            ));
        }
        Ok(Self {
            origin,
            size,
            resolution,
        })
    }

    /// Minimum corner of the cube, world frame.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Side length of the cube, metres.
    pub fn size(&self) -> f64 {
        self.size
    }

    /// Voxels per axis, R.
    pub fn resolution(&self) -> usize {
        self.resolution
    }

    /// Side length of one voxel, `size / R`.
    pub fn voxel_size(&self) -> f64 {
        self.size / self.resolution as f64
    }

    /// Total voxel count, R³.
    pub fn voxel_count(&self) -> usize {
        self.resolution * self.resolution * self.resolution
    }

    /// Flat C-order index of voxel `[a, b, c]`.
    #[inline]
    pub fn flat_index(&self, a: usize, b: usize, c: usize) -> usize {
        (a * self.resolution + b) * self.resolution + c
    }

    /// Inverse of [`GridSpec::flat_index`].
    #[inline]
    pub fn unflatten(&self, i: usize) -> [usize; 3] {
        let r = self.resolution;
        [i / (r * r), (i / r) % r, i % r]
    }

    /// World-frame centre of voxel `[a, b, c]`.
    #[inline]
    pub fn voxel_center(&self, a: usize, b: usize, c: usize) -> Point3<f64> {
        let h = self.voxel_size();
        Point3::new(
            self.origin[0] + (a as f64 + 0.5) * h,
            self.origin[1] + (b as f64 + 0.5) * h,
            self.origin[2] + (c as f64 + 0.5) * h,
        )
    }

    /// Checks that a flat volume has R³ values.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `name` otherwise.
    pub fn check_volume(&self, name: &str, len: usize) -> Result<()> {
        if len != self.voxel_count() {
            let r = self.resolution;
            return Err(Error::shape(
                name,
                format!("({r}, {r}, {r})"),
                format!("{len} values"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voxel_centres_follow_the_convention() {
        let g = GridSpec::new([1.0, 2.0, 3.0], 0.3, 3).unwrap();
        let c = g.voxel_center(0, 1, 2);
        assert!((c - Point3::new(1.05, 2.15, 3.25)).norm() < 1e-12);
    }

    #[test]
    fn flat_index_round_trips() {
        let g = GridSpec::new([0.0; 3], 1.0, 7).unwrap();
        for i in [0, 1, 48, 342] {
            let [a, b, c] = g.unflatten(i);
            assert_eq!(g.flat_index(a, b, c), i);
        }
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        assert!(GridSpec::new([0.0; 3], 0.0, 4).is_err());
        assert!(GridSpec::new([0.0; 3], f64::NAN, 4).is_err());
        assert!(GridSpec::new([0.0; 3], 1.0, 0).is_err());
        assert!(GridSpec::new([0.0; 3], 1.0, MAX_RESOLUTION + 1).is_err());
        assert!(GridSpec::new([f64::INFINITY, 0.0, 0.0], 1.0, 4).is_err());
    }
}
