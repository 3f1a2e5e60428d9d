//! The projection kernel shared by carving, TSDF fusion and view scoring.
//!
//! For one view, camera coordinates of voxel centres are affine in the voxel index:
//! `P(a, b, c) = P0 + a·Ea + b·Eb + c·Ec`. [`VoxelProjector`] precomputes these terms in
//! f64 once per view; a grid column `(a, b, ·)` is then walked in f32 with one fused
//! multiply-add per coordinate and one reciprocal per voxel, which the compiler
//! vectorises. Pixel coordinates follow [`crate::camera`]'s convention. Computing in f32
//! moves a pixel coordinate by at most ~1e-4 px against an f64 evaluation, so only
//! voxels whose f64 pixel coordinate lies within that of a pixel border can land on the
//! neighbouring pixel: that is the only difference allowed against a reference.

use crate::camera::{PinholeCamera, Pose};
use crate::grid::GridSpec;

/// Per-view constants to project the voxel centres of one grid into one camera.
#[derive(Debug, Clone, Copy)]
pub struct VoxelProjector {
    p0: [f64; 3],
    ea: [f64; 3],
    eb: [f64; 3],
    ec: [f64; 3],
    /// Intrinsics in f32 with the +0.5 of the rounding convention folded into `cx`, `cy`.
    pub(crate) intr: Intrinsics32,
}

/// Intrinsics prepared for the f32 kernels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Intrinsics32 {
    pub fx: f32,
    pub fy: f32,
    pub cx_half: f32,
    pub cy_half: f32,
    pub width_f: f32,
    pub height_f: f32,
    pub width: u32,
}

impl Intrinsics32 {
    pub(crate) fn new(cam: &PinholeCamera) -> Self {
        Self {
            fx: cam.fx as f32,
            fy: cam.fy as f32,
            cx_half: (cam.cx + 0.5) as f32,
            cy_half: (cam.cy + 0.5) as f32,
            width_f: cam.width as f32,
            height_f: cam.height as f32,
            width: cam.width,
        }
    }

    /// Flat pixel index `v * width + u` of camera point `(x, y, z)`, or `None` if it is
    /// behind the camera or outside the image.
    #[inline(always)]
    pub(crate) fn pixel(&self, x: f32, y: f32, z: f32) -> Option<u32> {
        let inv = 1.0 / z;
        let uf = self.fx * x * inv + self.cx_half;
        let vf = self.fy * y * inv + self.cy_half;
        let inside =
            (z > 0.0) & (uf >= 0.0) & (uf < self.width_f) & (vf >= 0.0) & (vf < self.height_f);
        inside.then(|| (vf as u32) * self.width + uf as u32)
    }

    /// Branch-free form of [`Intrinsics32::pixel`] for vectorised loops: returns
    /// `(inside, index)` where `index` is 0 when `inside` is false.
    #[inline(always)]
    pub(crate) fn pixel_masked(&self, x: f32, y: f32, z: f32) -> (bool, u32) {
        let inv = 1.0 / z;
        let uf = self.fx * x * inv + self.cx_half;
        let vf = self.fy * y * inv + self.cy_half;
        let inside =
            (z > 0.0) & (uf >= 0.0) & (uf < self.width_f) & (vf >= 0.0) & (vf < self.height_f);
        let u = if inside { uf as u32 } else { 0 };
        let v = if inside { vf as u32 } else { 0 };
        (inside, v * self.width + u)
    }
}

/// A grid column `(a, b, ·)` in camera coordinates: `P(c) = base + c·step`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Column {
    pub base: [f32; 3],
    pub step: [f32; 3],
}

impl VoxelProjector {
    /// Precomputes the projection of `grid`'s voxel centres into `camera` at `cam2world`.
    pub fn new(grid: &GridSpec, camera: &PinholeCamera, cam2world: &Pose) -> Self {
        let world2cam = cam2world.inverse();
        let r = world2cam.rotation();
        let h = grid.voxel_size();
        let o = grid.origin();
        let c0 = nalgebra::Point3::new(o[0] + 0.5 * h, o[1] + 0.5 * h, o[2] + 0.5 * h);
        let p0 = world2cam.transform_point(&c0);
        let col = |j: usize| [r[(0, j)] * h, r[(1, j)] * h, r[(2, j)] * h];
        Self {
            p0: [p0.x, p0.y, p0.z],
            ea: col(0),
            eb: col(1),
            ec: col(2),
            intr: Intrinsics32::new(camera),
        }
    }

    /// Camera-frame coordinates of the centre of voxel `[a, b, c]` (f64).
    pub fn camera_point(&self, a: usize, b: usize, c: usize) -> [f64; 3] {
        let (a, b, c) = (a as f64, b as f64, c as f64);
        std::array::from_fn(|k| self.p0[k] + a * self.ea[k] + b * self.eb[k] + c * self.ec[k])
    }

    /// `[P0, Ea, Eb, Ec]` in f32: camera point of voxel `[a, b, c]` is `P0 + a·Ea + b·Eb + c·Ec`.
    pub(crate) fn affine_f32(&self) -> [[f32; 3]; 4] {
        [self.p0, self.ea, self.eb, self.ec].map(|v| v.map(|x| x as f32))
    }

    /// The column `(a, b, ·)`.
    #[inline]
    pub(crate) fn column(&self, a: usize, b: usize) -> Column {
        let base = self.camera_point(a, b, 0);
        Column {
            base: base.map(|x| x as f32),
            step: self.ec.map(|x| x as f32),
        }
    }

    /// Flat pixel index of the centre of voxel `[a, b, c]`, or `None` when not in view.
    pub fn pixel_of(&self, a: usize, b: usize, c: usize) -> Option<u32> {
        let col = self.column(a, b);
        let cf = c as f32;
        self.intr.pixel(
            col.base[0] + cf * col.step[0],
            col.base[1] + cf * col.step[1],
            col.base[2] + cf * col.step[2],
        )
    }
}

/// Packs a `(height, width)` byte mask (nonzero = set) into bits: pixel `i` is bit
/// `i % 32` of word `i / 32`. The packed mask of a 320×240 frame is 9.6 kB and stays in
/// L1 while a kernel gathers from it.
pub fn pack_mask(mask: &[u8], words: &mut Vec<u32>) {
    words.clear();
    words.resize(mask.len().div_ceil(32), 0);
    #[cfg(target_arch = "x86_64")]
    if crate::carve::kernel_level() == crate::carve::KernelLevel::Avx512 {
        // SAFETY: the CPU has AVX-512BW (checked by kernel_level).
        unsafe { pack_mask_avx512(mask, words) };
        return;
    }
    pack_mask_generic(mask, words);
}

fn pack_mask_generic(mask: &[u8], words: &mut [u32]) {
    for (w, chunk) in words.iter_mut().zip(mask.chunks(32)) {
        *w = chunk
            .iter()
            .enumerate()
            .fold(0u32, |acc, (k, &b)| acc | (u32::from(b != 0) << k));
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
fn pack_mask_avx512(mask: &[u8], words: &mut [u32]) {
    use std::arch::x86_64::*;
    let full = mask.len() / 64;
    for i in 0..full {
        // SAFETY: bytes 64 i .. 64 i + 64 lie inside `mask`.
        let v = unsafe { _mm512_loadu_si512(mask.as_ptr().add(64 * i).cast()) };
        let bits: u64 = _mm512_test_epi8_mask(v, v);
        words[2 * i] = bits as u32;
        words[2 * i + 1] = (bits >> 32) as u32;
    }
    pack_mask_generic(&mask[64 * full..], &mut words[2 * full..]);
}

/// Reads bit `i` of a packed mask. The caller guarantees `i / 32 < words.len()`.
#[inline(always)]
pub(crate) fn mask_bit(words: &[u32], i: u32) -> u32 {
    debug_assert!(((i >> 5) as usize) < words.len());
    // SAFETY: callers only pass indices of pixels inside the image, and `words` holds
    // ceil(width * height / 32) words (checked where the packed mask is built).
    let w = unsafe { *words.get_unchecked((i >> 5) as usize) };
    (w >> (i & 31)) & 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn projector_matches_the_reference_projection() {
        let grid = GridSpec::new([-0.15, -0.15, 0.0], 0.3, 8).unwrap();
        let cam = PinholeCamera::new(64, 48, 50.0, 52.0, 31.5, 23.5).unwrap();
        // Camera 0.6 m above the grid centre looking down (z axis = -world z).
        let m = [
            1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.75, 0.0, 0.0, 0.0, 1.0,
        ];
        let pose = Pose::from_row_major("cam2world", &m).unwrap();
        let proj = VoxelProjector::new(&grid, &cam, &pose);
        let w2c = pose.inverse();
        for (a, b, c) in [(0, 0, 0), (3, 4, 5), (7, 7, 7), (1, 6, 2)] {
            let pc = w2c.transform_point(&grid.voxel_center(a, b, c));
            let expected = cam.project(&pc).map(|(u, v)| v * 64 + u);
            assert_eq!(proj.pixel_of(a, b, c), expected, "voxel {a} {b} {c}");
            let cp = proj.camera_point(a, b, c);
            assert!((Point3::from(cp) - pc).norm() < 1e-12);
        }
    }

    #[test]
    fn pack_mask_sets_the_right_bits() {
        let mut mask = vec![0u8; 70];
        mask[0] = 1;
        mask[33] = 255;
        mask[69] = 7;
        let mut words = Vec::new();
        pack_mask(&mask, &mut words);
        assert_eq!(words.len(), 3);
        assert_eq!(words[0], 1);
        assert_eq!(words[1], 2);
        assert_eq!(words[2], 1 << 5);
        assert_eq!(mask_bit(&words, 69), 1);
        assert_eq!(mask_bit(&words, 68), 0);
    }

    #[test]
    fn dispatched_pack_mask_equals_the_portable_one() {
        // (With AVX-512 the dispatched pack takes 64 bytes a step, then the portable tail.)
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for len in 0usize..300 {
            let mask: Vec<u8> = (0..len)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    // Any nonzero byte is set, 0x80 and 0xff included.
                    [0u8, 1, 0x80, 0xff][(x % 4) as usize]
                })
                .collect();
            let (mut dispatched, mut portable) = (Vec::new(), vec![0; len.div_ceil(32)]);
            pack_mask(&mask, &mut dispatched);
            pack_mask_generic(&mask, &mut portable);
            assert_eq!(dispatched, portable, "{len} bytes");
        }
    }
}
