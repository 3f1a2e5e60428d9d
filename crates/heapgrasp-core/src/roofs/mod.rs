//! The silhouette check after roof trimming: which trimmed voxels the silhouettes show
//! to be real.
//!
//! Every HEAPGrasp view lies within θ_max = π/5 of the vertical (Table I), so the visual
//! hull of eq. 10 over-estimates heights, and the Python package trims the hull's roofs
//! before grasp planning (`heapgrasp.perception.roofs.trim_roofs`). Trimming can also cut real
//! parts narrower than its disc (a bottle's neck, a bowl's rim). The silhouettes cannot
//! say which hull voxels are real, but every pixel of a mask is a ray that hits an
//! object. A roof is explained away, because the rays through it go on to hit the
//! object under it; a real part that was cut leaves pixels that no kept voxel covers.
//! [`keep_silhouettes`] finds those voxels.
//!
//! # The rule
//! - Each voxel is drawn as the pixel box around the projection of its circumscribed
//!   sphere ([`footprint`]).
//! - For every view, the mask's pixels that no kept voxel's box covers are
//!   *unexplained*. A 3 × 3 binary opening (with pixels outside the image counting as
//!   unset) then drops the slivers one or two pixels wide that discretisation leaves at
//!   the silhouette's rim.
//! - Level by level from the bottom (ascending z index), the cut voxels whose box holds
//!   an unexplained pixel in some view are *needed*. Then the pixels of every view that
//!   their boxes cover are explained. So a real part low down, once back, explains the
//!   pixels that a roof above it would otherwise claim.
//! - Each column is raised back to its highest needed voxel: every cut voxel at or
//!   below it is restored.
//!
//! This is a port of the NumPy implementation of `keep_silhouettes` (kept as the
//! test reference `tests/reference_roofs.py`) with the same floating-point operations
//! per voxel. Only the camera transform (here `Rᵀ`, `-Rᵀt` of the rigid pose, there a
//! LAPACK inverse and a BLAS product) may differ in the last bit, which moves a box
//! edge only when a coordinate lies within an ulp of a pixel boundary.

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::grid::GridSpec;

/// Cameras closer than this (metres, along the optical axis) to a voxel centre do not
/// see it (the reference's `z > 1e-3`).
pub const NEAR: f64 = 1e-3;

/// One captured silhouette: its camera, `cam2world` pose and `(height, width)` mask.
#[derive(Debug, Clone, Copy)]
pub struct SilhouetteView<'a> {
    /// Intrinsics of the view.
    pub camera: PinholeCamera,
    /// Camera-to-world pose.
    pub cam2world: Pose,
    /// Row-major `(height, width)` mask, `true` on the objects.
    pub mask: &'a [bool],
}

/// The cubic grid the volumes live on, as the silhouette check needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelLattice {
    /// World position of the grid's minimum corner (metres).
    pub origin: [f64; 3],
    /// Edge of a voxel (metres).
    pub voxel_size: f64,
    /// Voxels per axis.
    pub resolution: usize,
}

impl VoxelLattice {
    /// Validates the lattice.
    ///
    /// # Errors
    /// [`Error::NonFinite`] naming `origin`; [`Error::Value`] naming `voxel_size` (not
    /// finite and > 0) or `resolution` (outside `1..=`[`MAX_RESOLUTION`](crate::grid::MAX_RESOLUTION)).
    pub fn new(origin: [f64; 3], voxel_size: f64, resolution: usize) -> Result<Self> {
        if !(voxel_size.is_finite() && voxel_size > 0.0) {
            return Err(Error::value(
                "voxel_size",
                voxel_size,
                "must be finite and > 0 metres",
            ));
        }
        let side = voxel_size * resolution.max(1) as f64;
        if !side.is_finite() {
            return Err(Error::value(
                "voxel_size",
                voxel_size,
                format!("times the resolution ({resolution}) must be finite"),
            ));
        }
        // The origin and the resolution are checked as any grid's are.
        GridSpec::new(origin, side, resolution)?;
        Ok(Self {
            origin,
            voxel_size,
            resolution,
        })
    }

    /// Number of voxels, R³.
    pub fn voxel_count(&self) -> usize {
        self.resolution.pow(3)
    }

    /// Centre of voxel `[a, b, c]`: `origin + (index + 0.5) * voxel_size`.
    fn centre(&self, index: [usize; 3]) -> [f64; 3] {
        let mut c = [0.0; 3];
        for k in 0..3 {
            c[k] = self.origin[k] + (index[k] as f64 + 0.5) * self.voxel_size;
        }
        c
    }

    /// `[a, b, c]` of the flat C-order index `i`.
    fn unflatten(&self, i: usize) -> [usize; 3] {
        let r = self.resolution;
        [i / (r * r), (i / r) % r, i % r]
    }
}

/// Inclusive pixel box `[u0, u1] × [v0, v1]`, clipped to the image and not empty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelBox {
    /// First column.
    pub u0: usize,
    /// Last column.
    pub u1: usize,
    /// First row.
    pub v0: usize,
    /// Last row.
    pub v1: usize,
}

/// A view's camera with the world-to-camera transform and the voxels' box radius
/// precomputed.
struct Projector {
    camera: PinholeCamera,
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
    /// `0.5 * sqrt(3) * voxel_size`: the circumscribed sphere's radius.
    radius: f64,
}

impl Projector {
    fn new(view: &SilhouetteView<'_>, voxel_size: f64) -> Self {
        let world2cam = view.cam2world.inverse();
        let (r, t) = (world2cam.rotation(), world2cam.translation());
        Self {
            camera: view.camera,
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation: [t.x, t.y, t.z],
            radius: 0.5 * 3.0f64.sqrt() * voxel_size,
        }
    }

    /// [`footprint`] of a voxel centred at `c`.
    fn footprint(&self, c: [f64; 3]) -> Option<PixelBox> {
        let row = |j: usize| {
            let r = self.rotation[j];
            c[0] * r[0] + c[1] * r[1] + c[2] * r[2] + self.translation[j]
        };
        let (x, y, z) = (row(0), row(1), row(2));
        if !(z > NEAR) {
            return None;
        }
        let cam = &self.camera;
        let (w, h) = (f64::from(cam.width), f64::from(cam.height));
        let u = cam.fx * x / z + cam.cx;
        let v = cam.fy * y / z + cam.cy;
        let half = self.radius / z;
        let (ru, rv) = (cam.fx * half, cam.fy * half);
        let u0 = (u - ru - 0.5).ceil().clamp(0.0, w);
        let u1 = (u + ru + 0.5).floor().clamp(-1.0, w - 1.0);
        let v0 = (v - rv - 0.5).ceil().clamp(0.0, h);
        let v1 = (v + rv + 0.5).floor().clamp(-1.0, h - 1.0);
        if u1 < u0 || v1 < v0 {
            return None;
        }
        // Non-empty boxes lie inside the image, so the casts are exact.
        Some(PixelBox {
            u0: u0 as usize,
            u1: u1 as usize,
            v0: v0 as usize,
            v1: v1 as usize,
        })
    }
}

/// The pixel box, clipped to the image, that holds the projection of the sphere
/// circumscribing a voxel of edge `voxel_size` centred at world point `centre`; `None`
/// when the centre is less than [`NEAR`] in front of the camera or the box misses the
/// image.
///
/// With the centre at camera coordinates `(x, y, z)`, `(u, v) = (fx x / z + cx,
/// fy y / z + cy)` and box radii `ru = fx ρ / z`, `rv = fy ρ / z` (`ρ = √3/2 ·
/// voxel_size`), the box is `[ceil(u - ru - 0.5), floor(u + ru + 0.5)]` ×
/// `[ceil(v - rv - 0.5), floor(v + rv + 0.5)]`: every pixel whose square meets the disc's
/// bounding square.
///
/// # Example
/// ```
/// use heapgrasp_core::roofs::{footprint, SilhouetteView};
/// use heapgrasp_core::{PinholeCamera, Pose};
/// let camera = PinholeCamera::new(64, 48, 50.0, 50.0, 31.5, 23.5).unwrap();
/// let mask = vec![false; 64 * 48];
/// let eye = Pose::look_at([0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]).unwrap();
/// let view = SilhouetteView { camera, cam2world: eye, mask: &mask };
/// let b = footprint(&view, 0.01, [0.0; 3]).unwrap();
/// assert!(b.u0 <= 31 && b.u1 >= 32 && b.v0 <= 23 && b.v1 >= 24);
/// assert!(footprint(&view, 0.01, [0.0, 0.0, 2.0]).is_none()); // behind the camera
/// ```
pub fn footprint(view: &SilhouetteView<'_>, voxel_size: f64, centre: [f64; 3]) -> Option<PixelBox> {
    Projector::new(view, voxel_size).footprint(centre)
}

/// A row-major boolean image.
struct Image {
    width: usize,
    pixels: Vec<bool>,
}

impl Image {
    /// Whether any pixel of `b` is set.
    fn any_in(&self, b: PixelBox) -> bool {
        (b.v0..=b.v1).any(|v| {
            let row = &self.pixels[v * self.width..(v + 1) * self.width];
            row[b.u0..=b.u1].iter().any(|&p| p)
        })
    }

    /// Clears the pixels of `b`; returns how many were set.
    fn clear(&mut self, b: PixelBox) -> usize {
        let mut n = 0;
        for v in b.v0..=b.v1 {
            for p in &mut self.pixels[v * self.width + b.u0..=v * self.width + b.u1] {
                n += usize::from(*p);
                *p = false;
            }
        }
        n
    }
}

/// Union of the pixel boxes, as an image (a difference image of the boxes' corners,
/// integrated over rows and columns).
fn paint(width: usize, height: usize, boxes: impl Iterator<Item = PixelBox>) -> Vec<bool> {
    let stride = width + 1;
    let mut diff = vec![0i32; (height + 1) * stride];
    for b in boxes {
        diff[b.v0 * stride + b.u0] += 1;
        diff[b.v0 * stride + b.u1 + 1] -= 1;
        diff[(b.v1 + 1) * stride + b.u0] -= 1;
        diff[(b.v1 + 1) * stride + b.u1 + 1] += 1;
    }
    for v in 0..height {
        let mut run = 0;
        for u in 0..=width {
            run += diff[v * stride + u];
            diff[v * stride + u] = run;
        }
    }
    let mut out = vec![false; width * height];
    for u in 0..width {
        let mut run = 0;
        for v in 0..height {
            run += diff[v * stride + u];
            out[v * width + u] = run > 0;
        }
    }
    out
}

/// `scipy.ndimage.binary_opening(image, structure=np.ones((3, 3)))`: a 3 × 3 erosion
/// then a 3 × 3 dilation, with pixels outside the image unset (scipy's
/// `border_value=0`).
///
/// Both passes are separable (three pixels of a row, then three rows) and run only over
/// the bounding box of the set pixels: the erosion lies strictly inside it, so its
/// dilation does not leave it either.
///
/// Panics if `pixels.len() != width * height`; [`keep_silhouettes`] checks every mask
/// against its camera first.
pub(crate) fn binary_opening_3x3(pixels: &[bool], width: usize, height: usize) -> Vec<bool> {
    assert_eq!(pixels.len(), width * height, "image size");
    let mut out = vec![false; pixels.len()];
    let Some((u0, u1, v0, v1)) = bounding_box(pixels, width) else {
        return out;
    };
    let (w, h) = (u1 - u0 + 1, v1 - v0 + 1);
    let win = |v: usize| &pixels[(v0 + v) * width + u0..=(v0 + v) * width + u1];
    // Erosion: a pixel stays when its row triple and those above and below are all set.
    // Outside the image counts as unset, and so does outside the box, which holds every
    // set pixel: the box's edges erode away.
    let mut rows = vec![false; w * h];
    for v in 0..h {
        let src = win(v);
        let dst = &mut rows[v * w..(v + 1) * w];
        for u in 1..w.saturating_sub(1) {
            dst[u] = src[u - 1] && src[u] && src[u + 1];
        }
    }
    let mut eroded = vec![false; w * h];
    for v in 1..h.saturating_sub(1) {
        for u in 0..w {
            eroded[v * w + u] = rows[(v - 1) * w + u] && rows[v * w + u] && rows[(v + 1) * w + u];
        }
    }
    // Dilation: any pixel of the 3 x 3 neighbourhood, within the window.
    for v in 0..h {
        let src = &eroded[v * w..(v + 1) * w];
        let dst = &mut rows[v * w..(v + 1) * w];
        for u in 0..w {
            dst[u] = src[u] || (u > 0 && src[u - 1]) || (u + 1 < w && src[u + 1]);
        }
    }
    for v in 0..h {
        let row = &mut out[(v0 + v) * width + u0..=(v0 + v) * width + u1];
        for (u, o) in row.iter_mut().enumerate() {
            *o = rows[v * w + u]
                || (v > 0 && rows[(v - 1) * w + u])
                || (v + 1 < h && rows[(v + 1) * w + u]);
        }
    }
    out
}

/// Columns `u0..=u1` and rows `v0..=v1` of the set pixels, or `None` if none is set.
fn bounding_box(pixels: &[bool], width: usize) -> Option<(usize, usize, usize, usize)> {
    let mut found: Option<(usize, usize, usize, usize)> = None;
    for (v, row) in pixels.chunks_exact(width).enumerate() {
        let (Some(first), Some(last)) = (row.iter().position(|&p| p), row.iter().rposition(|&p| p))
        else {
            continue;
        };
        found = Some(match found {
            None => (first, last, v, v),
            Some((a, b, c, _)) => (a.min(first), b.max(last), c, v),
        });
    }
    found
}

fn check_volume(name: &str, volume: &[bool], lattice: &VoxelLattice) -> Result<()> {
    if volume.len() != lattice.voxel_count() {
        let r = lattice.resolution;
        return Err(Error::shape(
            name,
            format!("({r}, {r}, {r})"),
            format!("{} values", volume.len()),
        ));
    }
    Ok(())
}

/// The voxels of `full` that the trimming cut (`full && !trimmed`) and that the views'
/// silhouettes show to be real (the rule in the [module docs](self)), as a flat C-order
/// `R³` mask.
///
/// `full` is the hull before trimming, `trimmed` after it (a voxel of `trimmed` outside
/// `full` is simply kept). Views may be any subset of those the hull was carved from,
/// in any order: the result does not depend on their order.
///
/// # Errors
/// [`Error::Shape`] naming `full` or `trimmed` when its length is not R³, or
/// `masks[i]` when a mask does not match its camera.
///
/// # Example
/// A roof left above a cube by one view, cut by the trimming, is explained by the cube
/// under it, so nothing comes back.
/// ```
/// use heapgrasp_core::primitives::box_mesh;
/// use heapgrasp_core::roofs::{keep_silhouettes, SilhouetteView, VoxelLattice};
/// use heapgrasp_core::{MeshScene, PinholeCamera, Pose};
/// let (r, at) = (20, |a: usize, b: usize, c: usize| (a * 20 + b) * 20 + c);
/// let lattice = VoxelLattice::new([-0.1, -0.1, 0.0], 0.01, r).unwrap();
/// // The real object: a 4 cm cube on the floor (voxels 8..12, 8..12, 0..4).
/// let (vertices, faces) = box_mesh([0.02, 0.02, 0.02]);
/// // Centred at z = 0.02 (`look_at` only places it; a cube has no front).
/// let on_floor = Pose::look_at([0.0, 0.0, 0.02], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
/// let mut scene = MeshScene::new();
/// scene.add_mesh(&vertices, &faces, on_floor).unwrap();
/// let camera = PinholeCamera::new(80, 60, 80.0, 80.0, 39.5, 29.5).unwrap();
/// let pose = Pose::look_at([0.0, -0.3, 0.3], [0.0, 0.0, 0.02], [0.0, 0.0, 1.0]).unwrap();
/// let mask: Vec<bool> = scene.render_mask(&camera, &pose).iter().map(|&m| m > 0).collect();
/// let views = [SilhouetteView { camera, cam2world: pose, mask: &mask }];
/// // The hull: the cube and a roof two voxels high on it, which the trimming cut.
/// let mut full = vec![false; r * r * r];
/// let mut trimmed = full.clone();
/// for a in 8..12 {
///     for b in 8..12 {
///         for c in 0..6 {
///             full[at(a, b, c)] = true;
///             trimmed[at(a, b, c)] = c < 4;
///         }
///     }
/// }
/// let back = keep_silhouettes(&lattice, &full, &trimmed, &views).unwrap();
/// assert!(!back.contains(&true));
/// ```
pub fn keep_silhouettes(
    lattice: &VoxelLattice,
    full: &[bool],
    trimmed: &[bool],
    views: &[SilhouetteView<'_>],
) -> Result<Vec<bool>> {
    check_volume("full", full, lattice)?;
    check_volume("trimmed", trimmed, lattice)?;
    for (i, view) in views.iter().enumerate() {
        view.camera
            .check_image(&format!("masks[{i}]"), view.mask.len())?;
    }
    let mut restored = vec![false; full.len()];
    let cut: Vec<usize> = (0..full.len())
        .filter(|&i| full[i] && !trimmed[i])
        .collect();
    if cut.is_empty() || views.is_empty() {
        return Ok(restored);
    }
    let kept: Vec<[f64; 3]> = (0..full.len())
        .filter(|&i| trimmed[i])
        .map(|i| lattice.centre(lattice.unflatten(i)))
        .collect();
    let cut_index: Vec<[usize; 3]> = cut.iter().map(|&i| lattice.unflatten(i)).collect();

    // Per view: the unexplained pixels, how many there are, and the cut voxels' boxes.
    let mut unexplained = Vec::with_capacity(views.len());
    let mut remaining = Vec::with_capacity(views.len());
    let mut cut_boxes = Vec::with_capacity(views.len());
    for view in views {
        let proj = Projector::new(view, lattice.voxel_size);
        let (w, h) = (view.camera.width as usize, view.camera.height as usize);
        let covered = paint(w, h, kept.iter().filter_map(|&c| proj.footprint(c)));
        let open: Vec<bool> = view
            .mask
            .iter()
            .zip(&covered)
            .map(|(&m, &c)| m && !c)
            .collect();
        let pixels = binary_opening_3x3(&open, w, h);
        remaining.push(pixels.iter().filter(|&&p| p).count());
        unexplained.push(Image { width: w, pixels });
        cut_boxes.push(
            cut_index
                .iter()
                .map(|&ix| proj.footprint(lattice.centre(ix)))
                .collect::<Vec<_>>(),
        );
    }

    // Level by level from the bottom: `cut` is in C order, so sort by z, stably.
    let mut order: Vec<usize> = (0..cut.len()).collect();
    order.sort_by_key(|&k| cut_index[k][2]);
    let mut needed = vec![false; cut.len()];
    let mut now = Vec::new();
    for level in order.chunk_by(|&a, &b| cut_index[a][2] == cut_index[b][2]) {
        now.clear();
        now.extend(level.iter().copied().filter(|&k| {
            unexplained
                .iter()
                .zip(&remaining)
                .zip(&cut_boxes)
                .any(|((un, &n), boxes)| n > 0 && boxes[k].is_some_and(|b| un.any_in(b)))
        }));
        for &k in &now {
            needed[k] = true;
        }
        for ((un, n), boxes) in unexplained
            .iter_mut()
            .zip(remaining.iter_mut())
            .zip(&cut_boxes)
        {
            for &k in &now {
                if *n == 0 {
                    break;
                }
                if let Some(b) = boxes[k] {
                    *n -= un.clear(b);
                }
            }
        }
    }

    // Raise each column back to its highest needed voxel.
    let r = lattice.resolution;
    let mut top = vec![None::<usize>; r * r];
    for (k, ix) in cut_index.iter().enumerate() {
        if needed[k] {
            let t = &mut top[ix[0] * r + ix[1]];
            *t = Some(t.map_or(ix[2], |z| z.max(ix[2])));
        }
    }
    for (k, &i) in cut.iter().enumerate() {
        let ix = cut_index[k];
        if top[ix[0] * r + ix[1]].is_some_and(|z| ix[2] <= z) {
            restored[i] = true;
        }
    }
    Ok(restored)
}

#[cfg(test)]
mod tests;
