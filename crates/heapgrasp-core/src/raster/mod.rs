//! Ground-truth silhouettes, depth and labels of triangle meshes: the fast mask source
//! for simulation and for the hypothetical views of eq. 14.
//!
//! # Semantics
//! A pixel `(u, v)` is set iff the ray from the camera centre through the pixel centre
//! (continuous image coordinates exactly `(u, v)`, see [`crate::camera`]) hits a
//! triangle in front of the camera; depth is the camera-frame z of the nearest hit.
//! Rays through a pixel centre lying exactly on a triangle edge count as hits.
//!
//! # Method
//! Triangles are rasterised in homogeneous coordinates: with the vertices `V0, V1, V2`
//! in the camera frame and the ray direction `d = ((u-cx)/fx, (v-cy)/fy, 1)`, the ray
//! hits the triangle iff the three edge functions `d·(V1×V2)`, `d·(V2×V0)`, `d·(V0×V1)`
//! share the sign of `det = V0·(V1×V2)`; the hit depth is `det / Σ eᵢ`. This is exact ray
//! casting done per row: each row's covered pixels form one interval found from three
//! linear inequalities, so a mask row is filled with a memset. No near-plane clipping is
//! needed, and two triangles sharing an edge evaluate that edge with exactly negated
//! coefficients, so closed silhouettes have no cracks.
//!
//! Closed, consistently oriented meshes (every edge shared by exactly two faces with
//! opposite directions) skip back faces when the camera is outside their bounding
//! sphere: the first hit of any ray is then a front face, so the result is unchanged.
//! Their silhouettes (masks only, not depth or labels) are filled from the contour
//! edges alone, row by row by winding number (module `contour`), with the same edge lines;
//! [`MeshScene::render_mask_faces`] is the face-by-face reference it is tested against.
//! [`MeshScene::cast_ray`] answers single rays exactly with parry3d's BVH.
//!
//! The file runs past 800 lines only because its unit tests sit beside the code (the
//! crate's rule, from `mod tests` on); the kernel itself is under 800.

use std::collections::{BTreeMap, HashMap};

use nalgebra::{Point3, Vector3};
use parry3d::math::Vector as PVec;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;

use crate::camera::{PinholeCamera, Pose};
use crate::error::{Error, Result};
use crate::rounding::{ceil_fast, floor_fast};

mod contour;

/// Largest accepted vertex or face count of one mesh.
pub const MAX_MESH_ELEMENTS: usize = 1 << 26;

/// One rigid triangle mesh of a [`MeshScene`].
#[derive(Clone)]
struct Mesh {
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    obj2world: Pose,
    /// +1 / -1: sign of the enclosed volume of a closed mesh (outward CCW = +1); 0 if open.
    orientation: f64,
    sphere_center: Point3<f64>,
    sphere_radius: f64,
    bvh: TriMesh,
    /// `[i, j, f_ij, f_ji]` per undirected edge of a closed mesh (empty if open): the
    /// adjacency the contour fill needs.
    edges: Vec<[u32; 4]>,
}

/// An inclusive pixel rectangle `[u0, u1] × [v0, v1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub u0: u32,
    /// Last column (inclusive).
    pub u1: u32,
    /// First row.
    pub v0: u32,
    /// Last row (inclusive).
    pub v1: u32,
}

impl PixelRect {
    /// The whole image of `camera`.
    pub fn full(camera: &PinholeCamera) -> Self {
        Self {
            u0: 0,
            u1: camera.width - 1,
            v0: 0,
            v1: camera.height - 1,
        }
    }
}

/// A set of rigid triangle meshes with world poses.
#[derive(Clone, Default)]
pub struct MeshScene {
    meshes: BTreeMap<u64, Mesh>,
    next_id: u64,
}

impl std::fmt::Debug for MeshScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshScene")
            .field("meshes", &self.meshes.len())
            .field("triangles", &self.triangle_count())
            .finish()
    }
}

impl MeshScene {
    /// An empty scene.
    pub fn new() -> Self {
        Self {
            meshes: BTreeMap::new(),
            next_id: 1,
        }
    }

    /// Adds a mesh (`vertices`: V×3 object-frame coordinates, flat; `faces`: F×3 vertex
    /// indices, flat) at pose `obj2world`, and returns its id (ids start at 1 and are
    /// never reused, so 0 can mean "background" in label images).
    ///
    /// # Errors
    /// [`Error::Shape`] if a buffer is not a multiple of 3 long; [`Error::NonFinite`] for
    /// NaN/inf vertices; [`Error::Mesh`] for no faces, fewer than 3 vertices, a face
    /// index out of range, or more than [`MAX_MESH_ELEMENTS`] elements.
    pub fn add_mesh(&mut self, vertices: &[f64], faces: &[u32], obj2world: Pose) -> Result<u64> {
        let mesh = Mesh::new(vertices, faces, obj2world)?;
        let id = self.next_id.max(1);
        self.next_id = id + 1;
        self.meshes.insert(id, mesh);
        Ok(id)
    }

    /// Moves mesh `id` to `obj2world`.
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] if the scene holds no such mesh.
    pub fn set_pose(&mut self, id: u64, obj2world: Pose) -> Result<()> {
        let mesh = self.meshes.get_mut(&id).ok_or(Error::UnknownMesh { id })?;
        mesh.obj2world = obj2world;
        Ok(())
    }

    /// The pose of mesh `id`.
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] if the scene holds no such mesh.
    pub fn pose(&self, id: u64) -> Result<Pose> {
        self.meshes
            .get(&id)
            .map(|m| m.obj2world)
            .ok_or(Error::UnknownMesh { id })
    }

    /// Removes mesh `id`.
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] if the scene holds no such mesh.
    pub fn remove(&mut self, id: u64) -> Result<()> {
        self.meshes
            .remove(&id)
            .map(|_| ())
            .ok_or(Error::UnknownMesh { id })
    }

    /// Ids of the meshes, ascending.
    pub fn ids(&self) -> Vec<u64> {
        self.meshes.keys().copied().collect()
    }

    /// Number of meshes.
    pub fn len(&self) -> usize {
        self.meshes.len()
    }

    /// Whether the scene holds no mesh.
    pub fn is_empty(&self) -> bool {
        self.meshes.is_empty()
    }

    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.meshes.values().map(|m| m.faces.len()).sum()
    }

    /// Whether mesh `id` is closed and consistently oriented (back faces may be culled).
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] if the scene holds no such mesh.
    pub fn is_closed(&self, id: u64) -> Result<bool> {
        self.meshes
            .get(&id)
            .map(|m| m.orientation != 0.0)
            .ok_or(Error::UnknownMesh { id })
    }

    /// The silhouette mask, `(height, width)` row-major, 1 where a ray hits a mesh.
    pub fn render_mask(&self, camera: &PinholeCamera, cam2world: &Pose) -> Vec<u8> {
        self.full_mask(camera, cam2world, true)
    }

    /// A whole-image mask into a new buffer (`use_contours`: see [`MeshScene::fill_mask`]).
    fn full_mask(&self, camera: &PinholeCamera, cam2world: &Pose, use_contours: bool) -> Vec<u8> {
        let mut out = vec![0u8; camera.pixel_count()];
        let rect = PixelRect::full(camera);
        let mut scratch = RasterScratch::default();
        self.fill_mask(
            camera,
            cam2world,
            rect,
            &mut out,
            &mut scratch,
            use_contours,
        );
        out
    }

    /// Renders the silhouette inside `rect` into `out` (a camera-sized buffer): pixels
    /// of `rect` are set to 0 or 1, pixels outside it are left as they are. `scratch`
    /// is reused between calls to avoid allocation.
    pub fn render_mask_into(
        &self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        rect: PixelRect,
        out: &mut [u8],
        scratch: &mut RasterScratch,
    ) {
        let w = camera.width as usize;
        for v in rect.v0..=rect.v1 {
            let row = v as usize * w;
            out[row + rect.u0 as usize..=row + rect.u1 as usize].fill(0);
        }
        self.fill_mask(camera, cam2world, rect, out, scratch, true);
    }

    /// The silhouette mask rasterised face by face, without the contour fill of
    /// [`MeshScene::render_mask`]: the reference that fill is tested and benchmarked
    /// against (the two differ at most at pixel centres within rounding of a contour
    /// vertex, see module `contour`).
    pub fn render_mask_faces(&self, camera: &PinholeCamera, cam2world: &Pose) -> Vec<u8> {
        self.full_mask(camera, cam2world, false)
    }

    /// Depth (camera-frame z of the nearest hit, metres; 0 where no mesh is hit) and
    /// labels (id of the nearest mesh; 0 where none), both `(height, width)` row-major.
    pub fn render_depth_labels(
        &self,
        camera: &PinholeCamera,
        cam2world: &Pose,
    ) -> (Vec<f32>, Vec<u32>) {
        let n = camera.pixel_count();
        let w = camera.width as usize;
        let mut depth = vec![f64::INFINITY; n];
        let mut labels = vec![0u32; n];
        let mut scratch = RasterScratch::default();
        let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
        self.rasterize(
            camera,
            cam2world,
            PixelRect::full(camera),
            &mut scratch,
            |row, u0, u1, tri| {
                let y = (row as f64 - cy) / fy;
                let beta = tri.beta0 + tri.beta_y * y;
                for u in u0..=u1 {
                    let x = (u as f64 - cx) / fx;
                    let z = tri.det / (tri.alpha_sum * x + beta);
                    let i = row * w + u;
                    if z > 0.0 && z < depth[i] {
                        depth[i] = z;
                        labels[i] = tri.id as u32;
                    }
                }
            },
        );
        let depth = depth
            .into_iter()
            .map(|z| if z.is_finite() { z as f32 } else { 0.0 })
            .collect();
        (depth, labels)
    }

    /// Depth image only; see [`MeshScene::render_depth_labels`].
    pub fn render_depth(&self, camera: &PinholeCamera, cam2world: &Pose) -> Vec<f32> {
        self.render_depth_labels(camera, cam2world).0
    }

    /// Casts a ray from `origin` along `direction` (world frame; need not be unit
    /// length) and returns the distance to the first hit (metres along the normalised
    /// direction) and the id of the mesh hit, or `None`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] or [`Error::Value`] for a non-finite or zero direction.
    pub fn cast_ray(&self, origin: [f64; 3], direction: [f64; 3]) -> Result<Option<(f64, u64)>> {
        for (name, v) in [("origin", origin), ("direction", direction)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(Error::NonFinite {
                    name: name.to_owned(),
                    position: format!("[{i}]"),
                });
            }
        }
        let dir = Vector3::from(direction);
        let norm = dir.norm();
        if !(norm > 0.0) {
            return Err(Error::value(
                "direction",
                format!("{direction:?}"),
                "must be non-zero",
            ));
        }
        let dir = dir / norm;
        let mut best: Option<(f64, u64)> = None;
        for (&id, mesh) in &self.meshes {
            let w2o = mesh.obj2world.inverse();
            let o = w2o.transform_point(&Point3::from(origin));
            let d = w2o.rotation() * dir;
            let ray = Ray::new(
                PVec::new(o.x as f32, o.y as f32, o.z as f32),
                PVec::new(d.x as f32, d.y as f32, d.z as f32),
            );
            let limit = best.map_or(f32::MAX, |(t, _)| t as f32);
            if let Some(t) = mesh.bvh.cast_local_ray(&ray, limit, false) {
                let t = f64::from(t);
                if best.is_none_or(|(b, _)| t < b) {
                    best = Some((t, id));
                }
            }
        }
        Ok(best)
    }

    /// Core loop: calls `span(row, u0, u1, tri)` for every maximal run of covered pixel
    /// centres of every (non-culled) triangle inside `rect`.
    fn rasterize<F>(
        &self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        rect: PixelRect,
        scratch: &mut RasterScratch,
        mut span: F,
    ) where
        F: FnMut(usize, usize, usize, &TriangleRow),
    {
        let frame = FrameSetup::new(cam2world);
        for (&id, mesh) in &self.meshes {
            if let Some(view) = frame.project(mesh, camera, rect, scratch) {
                rasterize_faces(mesh, id, view.cull, camera, rect, scratch, &mut span);
            }
        }
    }

    /// The silhouette inside `rect`, every closed mesh seen from outside filled from its
    /// contour ([`contour`]), the others face by face.
    fn fill_mask(
        &self,
        camera: &PinholeCamera,
        cam2world: &Pose,
        rect: PixelRect,
        out: &mut [u8],
        scratch: &mut RasterScratch,
        use_contours: bool,
    ) {
        let w = camera.width as usize;
        let frame = FrameSetup::new(cam2world);
        scratch.events.clear();
        for (&id, mesh) in &self.meshes {
            let Some(view) = frame.project(mesh, camera, rect, scratch) else {
                continue;
            };
            if use_contours && view.cull && view.all_in_front && !mesh.edges.is_empty() {
                scratch.front.clear();
                scratch.front.extend(mesh.faces.iter().map(|f| {
                    let [a, b, c] = f.map(|i| Vector3::from(scratch.cam[i as usize]));
                    let det = a.dot(&b.cross(&c));
                    det != 0.0 && det * mesh.orientation < 0.0
                }));
                scratch.events.push_contour(
                    camera,
                    rect,
                    &mesh.edges,
                    &scratch.cam,
                    &scratch.uv,
                    &scratch.front,
                    -mesh.orientation,
                );
            } else {
                rasterize_faces(
                    mesh,
                    id,
                    view.cull,
                    camera,
                    rect,
                    scratch,
                    &mut |row, u0, u1, _: &TriangleRow| {
                        out[row * w + u0..=row * w + u1].fill(1);
                    },
                );
            }
        }
        scratch.events.fill(w, out);
    }
}

/// What every mesh of one frame shares: the world-to-camera transform and the centre.
struct FrameSetup {
    world2cam: Pose,
    cam_center_world: Point3<f64>,
}

/// How one mesh is seen in a frame (see [`FrameSetup::project`]).
struct MeshView {
    /// Closed mesh, camera outside its bounding sphere: back faces can be skipped.
    cull: bool,
    /// Every vertex strictly in front of the camera (all projections finite).
    all_in_front: bool,
}

impl FrameSetup {
    fn new(cam2world: &Pose) -> Self {
        Self {
            world2cam: cam2world.inverse(),
            cam_center_world: Point3::from(*cam2world.translation()),
        }
    }

    /// Transforms and projects `mesh`'s vertices into `scratch` (once per frame), or
    /// `None` when its bounding sphere cannot touch `rect`.
    fn project(
        &self,
        mesh: &Mesh,
        camera: &PinholeCamera,
        rect: PixelRect,
        scratch: &mut RasterScratch,
    ) -> Option<MeshView> {
        let (fx, fy, cx, cy) = (camera.fx, camera.fy, camera.cx, camera.cy);
        let o2c = self.world2cam.compose(&mesh.obj2world);
        // Object-level culling against the bounding sphere.
        let sc = o2c.transform_point(&mesh.sphere_center);
        let r = mesh.sphere_radius;
        if sc.z + r <= 0.0 || !sphere_may_touch(camera, &sc, r, rect) {
            return None;
        }
        let cull = mesh.orientation != 0.0
            && (mesh.obj2world.transform_point(&mesh.sphere_center) - self.cam_center_world).norm()
                > r;
        // Each vertex is transformed and projected once per frame; a vertex behind the
        // camera gets NaN image coordinates, which disables the box test of
        // `rasterize_faces`.
        scratch.cam.clear();
        scratch.uv.clear();
        let mut all_in_front = true;
        for p in &mesh.vertices {
            let q = o2c.transform_point(&Point3::from(*p));
            scratch.cam.push([q.x, q.y, q.z]);
            scratch.uv.push(if q.z > 0.0 {
                let iz = 1.0 / q.z;
                [fx * q.x * iz + cx, fy * q.y * iz + cy]
            } else {
                all_in_front = false;
                [f64::NAN, f64::NAN]
            });
        }
        Some(MeshView { cull, all_in_front })
    }
}

/// Calls `span(row, u0, u1, tri)` for the covered runs of every drawn face of `mesh`
/// (vertices already in `scratch`, see [`FrameSetup::project`]).
fn rasterize_faces<F>(
    mesh: &Mesh,
    id: u64,
    cull: bool,
    camera: &PinholeCamera,
    rect: PixelRect,
    scratch: &RasterScratch,
    span: &mut F,
) where
    F: FnMut(usize, usize, usize, &TriangleRow),
{
    for f in &mesh.faces {
        let [i0, i1, i2] = f.map(|i| i as usize);
        let mut bounds = (
            rect.u0 as f64,
            rect.u1 as f64,
            rect.v0 as f64,
            rect.v1 as f64,
        );
        let (p0, p1, p2) = (scratch.uv[i0], scratch.uv[i1], scratch.uv[i2]);
        if !(p0[0].is_nan() || p1[0].is_nan() || p2[0].is_nan()) {
            // The pixel centres a triangle can cover lie in the box of its projected
            // vertices; BOX_SLACK px guards against rounding, and the exact decision is
            // the edge functions'.
            let umin = p0[0].min(p1[0]).min(p2[0]) - BOX_SLACK;
            let umax = p0[0].max(p1[0]).max(p2[0]) + BOX_SLACK;
            let vmin = p0[1].min(p1[1]).min(p2[1]) - BOX_SLACK;
            let vmax = p0[1].max(p1[1]).max(p2[1]) + BOX_SLACK;
            bounds = (
                bounds.0.max(ceil_fast(umin)),
                bounds.1.min(floor_fast(umax)),
                bounds.2.max(ceil_fast(vmin)),
                bounds.3.min(floor_fast(vmax)),
            );
            if bounds.0 > bounds.1 || bounds.2 > bounds.3 {
                continue;
            }
        } else if scratch.cam[i0][2] <= 0.0
            && scratch.cam[i1][2] <= 0.0
            && scratch.cam[i2][2] <= 0.0
        {
            continue; // wholly behind the camera: no forward ray reaches it
        }
        let [a, b, c] = [i0, i1, i2].map(|i| Vector3::from(scratch.cam[i]));
        let n0 = b.cross(&c);
        let det = a.dot(&n0);
        if det == 0.0 || (cull && det * mesh.orientation > 0.0) {
            continue;
        }
        rasterize_triangle(
            camera,
            bounds,
            id,
            [n0, c.cross(&a), a.cross(&b)],
            det,
            span,
        );
    }
}

/// Slack (pixels) of the projected-vertex box test.
const BOX_SLACK: f64 = 1e-6;

/// Reusable per-frame buffers of the rasteriser (camera-frame vertices and their
/// projections), so rendering many frames allocates nothing.
#[derive(Debug, Default, Clone)]
pub struct RasterScratch {
    cam: Vec<[f64; 3]>,
    uv: Vec<[f64; 2]>,
    front: Vec<bool>,
    events: contour::Events,
}

/// Per-triangle data handed to span callbacks: on pixel `(u, v)` the hit depth is
/// `det / (alpha_sum·x + beta0 + beta_y·y)` with `x = (u − cx)/fx`, `y = (v − cy)/fy`.
pub(crate) struct TriangleRow {
    id: u64,
    det: f64,
    alpha_sum: f64,
    beta0: f64,
    beta_y: f64,
}

/// Whether a camera-frame sphere can cover a pixel centre of `rect` (conservative).
fn sphere_may_touch(camera: &PinholeCamera, c: &Point3<f64>, r: f64, rect: PixelRect) -> bool {
    let zl = c.z - r;
    if zl <= 1e-9 {
        return true; // straddles the camera plane: no cheap bound
    }
    let zh = c.z + r;
    let bound = |lo: f64, hi: f64, f: f64, cc: f64| {
        let q = [lo / zl, lo / zh, hi / zl, hi / zh];
        let mn = q.iter().copied().fold(f64::INFINITY, f64::min);
        let mx = q.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (f * mn + cc, f * mx + cc)
    };
    let (u_lo, u_hi) = bound(c.x - r, c.x + r, camera.fx, camera.cx);
    let (v_lo, v_hi) = bound(c.y - r, c.y + r, camera.fy, camera.cy);
    u_hi >= rect.u0 as f64 - 1.0
        && u_lo <= rect.u1 as f64 + 1.0
        && v_hi >= rect.v0 as f64 - 1.0
        && v_lo <= rect.v1 as f64 + 1.0
}

/// Emits the covered pixel runs of one triangle inside `bounds` (columns u0..=u1, rows
/// v0..=v1, as f64), given its edge normals `V1×V2, V2×V0, V0×V1` and `det = V0·(V1×V2)`.
#[inline]
fn rasterize_triangle<F>(
    camera: &PinholeCamera,
    bounds: (f64, f64, f64, f64),
    id: u64,
    normals: [Vector3<f64>; 3],
    det: f64,
    span: &mut F,
) where
    F: FnMut(usize, usize, usize, &TriangleRow),
{
    let (u_lo_box, u_hi_box, v_lo, v_hi) = bounds;
    let s = det.signum();
    let (inv_fx, inv_fy, cx, cy) = (1.0 / camera.fx, 1.0 / camera.fy, camera.cx, camera.cy);
    // eᵢ(u, v) = αᵢ·u + βᵢ(v) with αᵢ = s·Aᵢ/fx and βᵢ(v) = s·(Bᵢ·y + Cᵢ) − αᵢ·cx,
    // y = (v − cy)/fy; so βᵢ(v) = β0ᵢ + v·βvᵢ. Each edge bounds the row's pixels at
    // u = −βᵢ(v)/αᵢ = pᵢ + v·qᵢ. A shared edge has exactly negated (αᵢ, β0ᵢ, βvᵢ) in its two
    // triangles (negation commutes with every rounding used here), hence bit-identical
    // pᵢ and qᵢ: no cracks, and pixel centres exactly on the edge go to both triangles.
    let mut lower: [(f64, f64); 3] = [(f64::NEG_INFINITY, 0.0); 3];
    let mut upper: [(f64, f64); 3] = [(f64::INFINITY, 0.0); 3];
    let mut flat: [(f64, f64); 3] = [(0.0, 0.0); 3];
    let (mut n_lo, mut n_hi, mut n_flat) = (0, 0, 0);
    for n in &normals {
        let a = s * n.x * inv_fx;
        let b_y = s * n.y * inv_fy;
        let b0 = s * n.z - b_y * cy - a * cx;
        if a == 0.0 {
            flat[n_flat] = (b0, b_y);
            n_flat += 1;
            continue;
        }
        let inv_a = 1.0 / a;
        let line = (-b0 * inv_a, -b_y * inv_a);
        if a > 0.0 {
            lower[n_lo] = line;
            n_lo += 1;
        } else {
            upper[n_hi] = line;
            n_hi += 1;
        }
    }
    let tri = TriangleRow {
        id,
        det: s * det,
        alpha_sum: normals.iter().map(|n| s * n.x).sum(),
        beta0: normals.iter().map(|n| s * n.z).sum(),
        beta_y: normals.iter().map(|n| s * n.y).sum(),
    };
    for v in (v_lo as i64)..=(v_hi as i64) {
        let vf = v as f64;
        if flat[..n_flat].iter().any(|&(b0, by)| b0 + vf * by < 0.0) {
            continue;
        }
        let lo = lower[..n_lo]
            .iter()
            .fold(u_lo_box, |m, &(p, q)| m.max(ceil_fast(p + vf * q)));
        let hi = upper[..n_hi]
            .iter()
            .fold(u_hi_box, |m, &(p, q)| m.min(floor_fast(p + vf * q)));
        if lo <= hi {
            span(v as usize, lo as usize, hi as usize, &tri);
        }
    }
}

impl Mesh {
    fn new(vertices: &[f64], faces: &[u32], obj2world: Pose) -> Result<Self> {
        if !vertices.len().is_multiple_of(3) {
            return Err(Error::shape(
                "vertices",
                "(V, 3)",
                format!("{} values", vertices.len()),
            ));
        }
        if !faces.len().is_multiple_of(3) {
            return Err(Error::shape(
                "faces",
                "(F, 3)",
                format!("{} values", faces.len()),
            ));
        }
        let nv = vertices.len() / 3;
        let nf = faces.len() / 3;
        if nv < 3 || nf == 0 {
            return Err(Error::Mesh {
                name: "faces".into(),
                reason: format!("need at least 3 vertices and 1 face, got {nv} and {nf}"),
            });
        }
        if nv > MAX_MESH_ELEMENTS || nf > MAX_MESH_ELEMENTS {
            return Err(Error::Mesh {
                name: "vertices".into(),
                reason: format!(
                    "at most {MAX_MESH_ELEMENTS} vertices and faces, got {nv} and {nf}"
                ),
            });
        }
        if let Some(i) = vertices.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                name: "vertices".into(),
                position: format!("[{}, {}]", i / 3, i % 3),
            });
        }
        if let Some(i) = faces.iter().position(|&f| f as usize >= nv) {
            return Err(Error::Mesh {
                name: "faces".into(),
                reason: format!(
                    "faces[{}, {}] = {} is not a vertex index (V = {nv})",
                    i / 3,
                    i % 3,
                    faces[i]
                ),
            });
        }
        let verts: Vec<[f64; 3]> = vertices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let tris: Vec<[u32; 3]> = faces.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let orientation = closed_orientation(&verts, &tris);
        let edges = if orientation != 0.0 {
            contour::closed_edges(&tris).unwrap_or_default()
        } else {
            Vec::new()
        };
        let (lo, hi) = verts.iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    std::array::from_fn(|k| lo[k].min(p[k])),
                    std::array::from_fn(|k| hi[k].max(p[k])),
                )
            },
        );
        let sphere_center = Point3::from(std::array::from_fn(|k| 0.5 * (lo[k] + hi[k])));
        let sphere_radius = verts
            .iter()
            .map(|p| (Point3::from(*p) - sphere_center).norm())
            .fold(0.0, f64::max)
            * (1.0 + 1e-9)
            + 1e-12;
        let bvh = TriMesh::new(
            verts
                .iter()
                .map(|p| PVec::new(p[0] as f32, p[1] as f32, p[2] as f32))
                .collect(),
            tris.clone(),
        )
        .map_err(|e| Error::Mesh {
            name: "faces".into(),
            reason: format!("{e:?}"),
        })?;
        Ok(Self {
            vertices: verts,
            faces: tris,
            obj2world,
            orientation,
            sphere_center,
            sphere_radius,
            bvh,
            edges,
        })
    }
}

/// +1 or -1 (sign of the enclosed volume) for a closed, consistently oriented mesh whose
/// every directed edge appears once and is matched by its reverse; 0 otherwise.
fn closed_orientation(verts: &[[f64; 3]], tris: &[[u32; 3]]) -> f64 {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(tris.len() * 3);
    for t in tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if a == b {
                return 0.0;
            }
            *edges.entry((a, b)).or_insert(0) += 1;
        }
    }
    let closed = edges
        .iter()
        .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1));
    if !closed {
        return 0.0;
    }
    let volume: f64 = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| Vector3::from(verts[i as usize]));
            a.dot(&b.cross(&c))
        })
        .sum();
    if volume > 0.0 {
        1.0
    } else if volume < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Axis-aligned box centred at the origin, outward CCW faces.
    pub(crate) fn box_mesh(hx: f64, hy: f64, hz: f64) -> (Vec<f64>, Vec<u32>) {
        crate::primitives::box_mesh([hx, hy, hz])
    }

    fn translation(x: f64, y: f64, z: f64) -> Pose {
        Pose::from_row_major(
            "p",
            &[
                1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, z, 0.0, 0.0, 0.0, 1.0,
            ],
        )
        .unwrap()
    }

    fn camera() -> PinholeCamera {
        PinholeCamera::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap()
    }

    fn scene() -> (MeshScene, Pose) {
        let mut s = MeshScene::new();
        let (v, f) = box_mesh(0.05, 0.03, 0.04);
        s.add_mesh(&v, &f, translation(0.02, -0.01, 0.0)).unwrap();
        let (v, f) = box_mesh(0.02, 0.02, 0.02);
        s.add_mesh(&v, &f, translation(-0.06, 0.05, 0.05)).unwrap();
        let cam2world = Pose::look_at([0.25, 0.2, 0.3], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
        (s, cam2world)
    }

    #[test]
    fn boxes_are_closed() {
        let (s, _) = scene();
        assert!(s.ids().iter().all(|&id| s.is_closed(id).unwrap()));
    }

    #[test]
    fn mask_depth_and_labels_agree_with_parry_ray_casts() {
        let (s, cam2world) = scene();
        let cam = camera();
        let mask = s.render_mask(&cam, &cam2world);
        let (depth, labels) = s.render_depth_labels(&cam, &cam2world);
        let mut hits = 0;
        for v in 0..cam.height {
            for u in 0..cam.width {
                let i = (v * cam.width + u) as usize;
                let d_cam = cam.pixel_ray(u as f64, v as f64);
                let d_world = cam2world.rotation() * d_cam;
                let o = cam2world.translation();
                let hit = s
                    .cast_ray([o.x, o.y, o.z], [d_world.x, d_world.y, d_world.z])
                    .unwrap();
                assert_eq!(mask[i] == 1, hit.is_some(), "pixel ({u}, {v})");
                assert_eq!(mask[i] == 1, depth[i] > 0.0);
                if let Some((t, id)) = hit {
                    hits += 1;
                    let z = t / d_cam.norm();
                    assert!(
                        (f64::from(depth[i]) - z).abs() < 1e-4,
                        "depth at ({u}, {v})"
                    );
                    assert_eq!(labels[i] as u64, id);
                }
            }
        }
        assert!(hits > 100, "the boxes should cover part of the image");
    }

    #[test]
    fn culling_does_not_change_the_mask_of_closed_meshes() {
        let (s, cam2world) = scene();
        let cam = camera();
        let mask = s.render_mask(&cam, &cam2world);
        // The same boxes with one face duplicated are open: nothing is culled.
        let mut open = MeshScene::new();
        for id in s.ids() {
            let m = &s.meshes[&id];
            let mut f: Vec<u32> = m.faces.iter().flatten().copied().collect();
            f.extend_from_within(0..3);
            let v: Vec<f64> = m.vertices.iter().flatten().copied().collect();
            let nid = open.add_mesh(&v, &f, m.obj2world).unwrap();
            assert!(!open.is_closed(nid).unwrap());
        }
        assert_eq!(open.render_mask(&cam, &cam2world), mask);
    }

    #[test]
    fn camera_inside_a_box_sees_it_everywhere() {
        let mut s = MeshScene::new();
        let (v, f) = box_mesh(1.0, 1.0, 1.0);
        s.add_mesh(&v, &f, Pose::identity()).unwrap();
        let cam = camera();
        let mask = s.render_mask(&cam, &Pose::identity());
        assert!(mask.iter().all(|&m| m == 1));
        let depth = s.render_depth(&cam, &Pose::identity());
        assert!((f64::from(depth[(24 * 64 + 32) as usize]) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn meshes_behind_the_camera_are_invisible() {
        let mut s = MeshScene::new();
        let (v, f) = box_mesh(0.1, 0.1, 0.1);
        s.add_mesh(&v, &f, translation(0.0, 0.0, -1.0)).unwrap();
        assert!(s
            .render_mask(&camera(), &Pose::identity())
            .iter()
            .all(|&m| m == 0));
    }

    #[test]
    fn scissored_rendering_matches_the_full_render_inside_the_rect() {
        // Inside the rect the contour fill, against the whole face-by-face mask.
        let (s, cam2world) = scene();
        let cam = camera();
        let full = s.render_mask_faces(&cam, &cam2world);
        let rect = PixelRect {
            u0: 10,
            u1: 40,
            v0: 5,
            v1: 30,
        };
        let mut out = vec![7u8; cam.pixel_count()];
        s.render_mask_into(
            &cam,
            &cam2world,
            rect,
            &mut out,
            &mut RasterScratch::default(),
        );
        for v in 0..cam.height {
            for u in 0..cam.width {
                let i = (v * cam.width + u) as usize;
                let inside = (10..=40).contains(&u) && (5..=30).contains(&v);
                assert_eq!(out[i], if inside { full[i] } else { 7 });
            }
        }
    }

    #[test]
    fn bad_meshes_and_ids_are_rejected() {
        let mut s = MeshScene::new();
        assert!(matches!(
            s.add_mesh(&[0.0; 9], &[0, 1, 3], Pose::identity()),
            Err(Error::Mesh { .. })
        ));
        assert!(matches!(
            s.add_mesh(&[0.0; 8], &[0, 1, 2], Pose::identity()),
            Err(Error::Shape { .. })
        ));
        assert!(matches!(
            s.add_mesh(&[f64::NAN; 9], &[0, 1, 2], Pose::identity()),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(s.remove(42), Err(Error::UnknownMesh { id: 42 })));
        assert!(s.cast_ray([0.0; 3], [0.0; 3]).is_err());
    }
}
