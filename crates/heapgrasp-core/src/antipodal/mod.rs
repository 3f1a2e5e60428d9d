//! Antipodal grasps on a voxel occupancy grid: the per-orientation search of
//! `heapgrasp.planning.antipodal.AntipodalPlanner` (Natarajan et al. §3.3 adapted to HEAPGrasp's
//! high-confidence grid `Ŝ≥λ`, written as the per-voxel grasp volumes of eq. 11).
//!
//! The Python planner prepares the scene (connected blobs, their centroids, the
//! smoothed occupancy's gradient, the candidate TCPs); [`best_grasps`] puts the gripper
//! on the lattice ([`GripperCells::from_params`]) and tries every TCP orientation at every candidate and keeps
//! each candidate's best grasp. For one orientation (see the Python module docstring for
//! the method in words):
//!
//! 1. the grid is resampled on a lattice aligned with the TCP axes (module `lattice`);
//! 2. *closing region*: the nearest rows on each side where a finger fits bound the
//!    object segment between the fingers; the opening is symmetric about the TCP;
//! 3. *collision-free approach*: fingers and palm swept from the pre-grasp pose must be
//!    free of the conservative lattice and above the table;
//! 4. *contacts* on the nearest-voxel lattice: engagement depth, a ledge below the
//!    fingertips, contact patches and their normals in the friction cone, and the
//!    quality (module `contacts`).
//!
//! The arithmetic follows the NumPy implementation it replaces step by step (a Python
//! test compares the two on measured grids); orientations run in parallel and are
//! merged in order, so the result does not depend on the thread count.

mod contacts;
mod lattice;

use crate::camera::RIGID_TOLERANCE;
use crate::error::{Error, Result};
use crate::gripper::HandGeometry;
use crate::parallel;
use crate::rounding::{ceil_fast, floor_fast};
use lattice::{
    and, band_any, clampi, cumsum_j, free_from, free_to, integral_xz, next_true, prev_true, to_tcp,
    Lattice, Shared, Vol, EPS,
};

/// An inclusive range of lattice offsets.
pub type CellRange = (i64, i64);

/// The gripper's boxes as lattice offsets (inclusive) for the grid's voxel size.
#[derive(Debug, Clone, PartialEq)]
pub struct GripperCells {
    /// Finger width (across, lattice axis 0).
    pub x_pad: CellRange,
    /// Finger width plus clearance.
    pub x_clear: CellRange,
    /// Finger width plus the contact-plane fit margin.
    pub x_fit: CellRange,
    /// Pad length along the approach: palm front to fingertip.
    pub z_contact: CellRange,
    /// Tip part of the finger.
    pub z_thin: CellRange,
    /// Base part, swept from the pre-grasp pose.
    pub z_thick: CellRange,
    /// Rows a fingertip needs at least.
    pub n_thin: i64,
    /// Rows a finger base needs at least.
    pub n_thick: i64,
    /// The palm's two boxes (front and back part, swept back), each `(x, y, z)` ranges.
    pub palm: [[CellRange; 3]; 2],
}

/// Widening (cells) of the finger pad over which the contact plane is fitted.
const FIT_MARGIN: i64 = 1;

/// Largest gripper length, in voxels, that [`best_grasps`] accepts (a Panda hand is
/// about 300 voxels long on the finest 512³ grid of 0.30 m).
pub const MAX_GRIPPER_CELLS: i64 = 1 << 16;

/// Lattice offsets (inclusive range) whose cell centre lies in `[lo, hi]`.
fn cell_range(lo: f64, hi: f64, v: f64) -> CellRange {
    (
        ceil_fast(lo / v - EPS) as i64,
        floor_fast(hi / v + EPS) as i64,
    )
}

impl GripperCells {
    /// The boxes of `p`'s gripper on a lattice of `p.voxel_size` cells: the finger pad
    /// and its clearances across, the pad, tip and swept base along the approach, the
    /// rows a finger needs, and the palm (front and back part, swept back to the
    /// pre-grasp pose), each widened by the clearance.
    pub fn from_params(p: &AntipodalParams) -> Self {
        let v = p.voxel_size;
        let clr = p.clearance;
        let pre = p.pregrasp_distance;
        let hand = &p.hand;
        let half_w = 0.5 * hand.finger_width;
        let x_pad = cell_range(-half_w, half_w, v);
        let palm_box = |half: [f64; 2], z0: f64, z1: f64| {
            [
                cell_range(-half[0] - clr, half[0] + clr, v),
                cell_range(-half[1] - clr, half[1] + clr, v),
                cell_range(z0 - clr, z1 + clr, v),
            ]
        };
        Self {
            x_pad,
            x_clear: cell_range(-half_w - clr, half_w + clr, v),
            x_fit: (x_pad.0 - FIT_MARGIN, x_pad.1 + FIT_MARGIN),
            z_contact: cell_range(hand.palm_front, hand.finger_tip, v),
            z_thin: cell_range(hand.finger_split, hand.finger_tip + clr, v),
            z_thick: cell_range(hand.finger_base - pre - clr, hand.finger_split, v),
            n_thin: (floor_fast(hand.tip_thickness / v + EPS) as i64).max(1),
            n_thick: (floor_fast(hand.base_thickness / v + EPS) as i64).max(1),
            palm: [
                palm_box(hand.palm_front_half, hand.palm_split, hand.palm_front),
                palm_box(hand.palm_back_half, hand.palm_back - pre, hand.palm_split),
            ],
        }
    }
}

/// Gripper geometry (metres, TCP frame: z the approach, fingers closing along y) and the
/// planner's thresholds; the fields of `AntipodalPlanner` and `GripperGeometry`.
#[derive(Debug, Clone, PartialEq)]
pub struct AntipodalParams {
    /// Voxel edge (m).
    pub voxel_size: f64,
    /// World z of the grid's bottom face.
    pub origin_z: f64,
    /// The gripper's boxes and maximum opening.
    pub hand: HandGeometry,
    /// Extra opening of the executor over the planned width (m).
    pub opening_margin: f64,
    /// Margin between contacts and fingers and around the gripper (m).
    pub clearance: f64,
    /// Distance of the pre-grasp pose back along the approach (m).
    pub pregrasp_distance: f64,
    /// World z of the table.
    pub table_z: f64,
    /// How close any part of the gripper may come to the table (m).
    pub table_clearance: f64,
    /// Minimum engagement along the approach (m).
    pub min_depth: f64,
    /// Engagement from which the depth factor is 1 (m).
    pub target_depth: f64,
    /// Minimum contact patch per finger (cells).
    pub min_patch: i64,
    /// Minimum height of each contact at its extreme (m).
    pub min_contact_height: f64,
    /// Quality factor of a grasp above a ledge.
    pub ledge_factor: f64,
    /// Half-angle of the friction cone (rad).
    pub friction_angle: f64,
}

impl AntipodalParams {
    /// The Franka Panda hand (the collision meshes of `pybullet_data/franka_panda`) with
    /// `AntipodalPlanner()`'s defaults, for a grid of `voxel_size` whose bottom face is
    /// at `origin_z` on a table at z = 0.
    pub fn panda(voxel_size: f64, origin_z: f64) -> Self {
        Self {
            voxel_size,
            origin_z,
            hand: HandGeometry::panda(),
            opening_margin: 0.01,
            clearance: 0.003,
            pregrasp_distance: 0.05,
            table_z: 0.0,
            table_clearance: 0.005,
            min_depth: 0.012,
            target_depth: 0.022,
            min_patch: 2,
            min_contact_height: 0.0075,
            ledge_factor: 0.4,
            friction_angle: 35f64.to_radians(),
        }
    }

    fn check(&self) -> Result<()> {
        let fields: Vec<(&str, f64)> = [
            ("voxel_size", self.voxel_size),
            ("origin_z", self.origin_z),
            ("max_opening", self.hand.max_opening),
            ("opening_margin", self.opening_margin),
            ("clearance", self.clearance),
        ]
        .into_iter()
        .chain(self.hand.named_lengths())
        .chain([
            ("pregrasp_distance", self.pregrasp_distance),
            ("table_z", self.table_z),
            ("table_clearance", self.table_clearance),
            ("min_depth", self.min_depth),
            ("target_depth", self.target_depth),
            ("min_contact_height", self.min_contact_height),
            ("ledge_factor", self.ledge_factor),
            ("friction_angle", self.friction_angle),
        ])
        .collect();
        for &(name, x) in &fields {
            if !x.is_finite() {
                return Err(Error::value(name, x, "must be finite"));
            }
        }
        if !(self.voxel_size > 0.0) {
            return Err(Error::value("voxel_size", self.voxel_size, "must be > 0"));
        }
        if !(self.hand.max_opening > 0.0) {
            return Err(Error::value(
                "max_opening",
                self.hand.max_opening,
                "must be > 0",
            ));
        }
        // The gripper goes on the lattice as cell offsets: keep every length (all fields
        // but the voxel size, the two world heights and the dimensionless ones) within
        // MAX_GRIPPER_CELLS voxels, so that no offset overflows and no scan runs for ages.
        let limit = MAX_GRIPPER_CELLS as f64 * self.voxel_size;
        let dimensionless = [
            "voxel_size",
            "origin_z",
            "table_z",
            "ledge_factor",
            "friction_angle",
        ];
        for &(name, x) in &fields {
            if !dimensionless.contains(&name) && !(x.abs() <= limit) {
                return Err(Error::value(
                    name,
                    x,
                    format!(
                        "a gripper length must be at most {MAX_GRIPPER_CELLS} voxels \
                         ({limit:.3e} m at voxel_size {})",
                        self.voxel_size
                    ),
                ));
            }
        }
        if !(0..=i64::from(u32::MAX)).contains(&self.min_patch) {
            return Err(Error::value(
                "min_patch",
                self.min_patch,
                "must be between 0 and 2**32 - 1 cells",
            ));
        }
        Ok(())
    }
}

/// The scene as the Python planner prepares it (all arrays C order, grid `r³`).
#[derive(Debug, Clone, Copy)]
pub struct AntipodalScene<'a> {
    /// Grid resolution `r`.
    pub resolution: usize,
    /// Occupied voxels (`r³`), artefact blobs already removed.
    pub occupied: &'a [bool],
    /// `(3, r, r, r)`: gradient of the smoothed occupancy along x, y, z.
    pub gradient: &'a [f64],
    /// `r³` connected-blob labels of `occupied` (0: empty).
    pub labels: &'a [i32],
    /// Centroid of each label (row 0 unused), relative to the grid origin (m).
    pub centroids: &'a [[f64; 3]],
    /// Voxel indices of the candidate TCPs.
    pub candidates: &'a [[usize; 3]],
}

impl AntipodalScene<'_> {
    fn check(&self) -> Result<()> {
        let r = self.resolution;
        let r3 = r * r * r;
        if r == 0 {
            return Err(Error::value("resolution", r, "must be >= 1"));
        }
        for (name, len, want) in [
            ("occupied", self.occupied.len(), r3),
            ("gradient", self.gradient.len(), 3 * r3),
            ("labels", self.labels.len(), r3),
        ] {
            if len != want {
                return Err(Error::shape(
                    name,
                    format!("{want} values"),
                    format!("{len}"),
                ));
            }
        }
        if let Some(i) = self.gradient.iter().position(|g| !g.is_finite()) {
            return Err(Error::NonFinite {
                name: "gradient".into(),
                position: format!("[{i}]"),
            });
        }
        let n_labels = self.centroids.len();
        if let Some(&l) = self
            .labels
            .iter()
            .find(|&&l| l < 0 || l as usize >= n_labels)
        {
            return Err(Error::value(
                "labels",
                l,
                format!("labels index centroids ({n_labels} rows)"),
            ));
        }
        if let Some(p) = self.candidates.iter().find(|p| p.iter().any(|&x| x >= r)) {
            return Err(Error::value(
                "candidates",
                format!("{p:?}"),
                format!("voxel indices must be < {r}"),
            ));
        }
        Ok(())
    }
}

/// Each candidate's best grasp over all orientations.
#[derive(Debug, Clone, PartialEq)]
pub struct BestGrasps {
    /// Quality in [0, 1] (0: no valid grasp at this candidate).
    pub quality: Vec<f64>,
    /// Index of the orientation of the best grasp (0 where quality is 0).
    pub orientation: Vec<usize>,
    /// Planned opening (m).
    pub width: Vec<f64>,
}

/// Valid grasps of one orientation: (candidate, quality, width).
type Found = Vec<(usize, f64, f64)>;

/// Tries every orientation (`rotations[k]`: TCP-to-world, columns TCP x, y, z; `tilts[k]`
/// its tilt from straight down) at every candidate and keeps, per candidate, the first
/// orientation of highest quality.
///
/// # Errors
/// [`Error::Shape`] for arrays of the wrong length, [`Error::Value`] /
/// [`Error::NonFinite`] for invalid parameters (a gripper length beyond
/// [`MAX_GRIPPER_CELLS`] voxels included), labels, candidates, rotations or tilts;
/// [`Error::NotRigid`] for a rotation that is not orthonormal with det +1 (within
/// [`RIGID_TOLERANCE`]).
pub fn best_grasps(
    scene: &AntipodalScene<'_>,
    params: &AntipodalParams,
    rotations: &[[[f64; 3]; 3]],
    tilts: &[f64],
) -> Result<BestGrasps> {
    scene.check()?;
    params.check()?;
    if rotations.len() != tilts.len() {
        return Err(Error::shape(
            "tilts",
            format!("{} values (one per rotation)", rotations.len()),
            format!("{}", tilts.len()),
        ));
    }
    if let Some(k) = rotations
        .iter()
        .position(|m| m.iter().flatten().any(|x| !x.is_finite()))
    {
        return Err(Error::NonFinite {
            name: "rotations".into(),
            position: format!("[{k}]"),
        });
    }
    if let Some(k) = tilts.iter().position(|t| !t.is_finite()) {
        return Err(Error::NonFinite {
            name: "tilts".into(),
            position: format!("[{k}]"),
        });
    }
    // A matrix that is not a rotation would stretch the lattice without bound.
    if let Some((k, ortho, det)) = rotations.iter().enumerate().find_map(|(k, m)| {
        let (ortho, det) = rotation_error(m);
        (ortho > RIGID_TOLERANCE || (det - 1.0).abs() > RIGID_TOLERANCE).then_some((k, ortho, det))
    }) {
        return Err(Error::NotRigid {
            name: format!("rotations[{k}]"),
            reason: format!(
                "must be orthonormal with det +1 (max |R^T R - I| = {ortho:.3e}, det = {det:.6})"
            ),
        });
    }
    let cells = &GripperCells::from_params(params);
    let n = scene.candidates.len();
    let mut best = BestGrasps {
        quality: vec![0.0; n],
        orientation: vec![0; n],
        width: vec![0.0; n],
    };
    if n == 0 || !scene.occupied.iter().any(|&x| x) || rotations.is_empty() {
        return Ok(best);
    }
    let shared = Shared::new(
        scene.occupied,
        scene.resolution,
        params.voxel_size,
        scene.candidates,
    );
    let work = rotations.len() * n;
    let threads = parallel::threads_for(work, 1 << 12, rotations.len());
    let per_orientation: Vec<Found> = parallel::map_ranges(rotations.len(), threads, |range| {
        range
            .map(|k| {
                let ctx = Orientation {
                    scene,
                    sh: &shared,
                    cells,
                    p: params,
                    rot: &rotations[k],
                    tilt: tilts[k],
                };
                ctx.evaluate()
            })
            .collect::<Vec<_>>()
    })
    .into_iter()
    .flatten()
    .collect();
    for (k, found) in per_orientation.into_iter().enumerate() {
        for (idx, q, w) in found {
            if q > best.quality[idx] {
                best.quality[idx] = q;
                best.orientation[idx] = k;
                best.width[idx] = w;
            }
        }
    }
    Ok(best)
}

/// `(max |RᵀR - I|, det R)` of a 3 × 3 matrix given by rows.
fn rotation_error(m: &[[f64; 3]; 3]) -> (f64, f64) {
    let mut ortho = 0.0f64;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            ortho = ortho.max((dot - want).abs());
        }
    }
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    (ortho, det)
}

/// `y0` up to `x0`, `y1` from `x1`, linear in between.
#[inline]
pub(crate) fn ramp(x: f64, x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let t = ((x - x0) / (x1 - x0).max(1e-12)).clamp(0.0, 1.0);
    y0 + (y1 - y0) * t
}

/// The whole-lattice tables of one orientation that the per-candidate tests read.
struct Tables {
    /// Next / previous row holding object in the finger pad's band (conservative).
    band_next: Vol<i32>,
    band_prev: Vol<i32>,
    /// Cumulative counts along rows of the finger bands (tip, base).
    c_thin: Vol<i32>,
    c_thick: Vol<i32>,
    /// First row `>= j` where a finger fits on the + side, last `<= j` on the − side.
    fit_next: Vol<i32>,
    fit_prev: Vol<i32>,
    /// Cumulative counts of the pad band over the grid's side faces.
    c_side: Option<Vol<i32>>,
    /// 3-D integral (box sums) of the conservative lattice.
    s3: Vol<i32>,
}

struct Orientation<'a> {
    scene: &'a AntipodalScene<'a>,
    sh: &'a Shared,
    cells: &'a GripperCells,
    p: &'a AntipodalParams,
    rot: &'a [[f64; 3]; 3],
    tilt: f64,
}

impl Orientation<'_> {
    fn tables(&self, lat: &Lattice) -> Tables {
        let cells = self.cells;
        let s2 = integral_xz(&lat.q);
        let band_c = band_any(&s2, cells.x_pad, cells.z_contact);
        let c_thin = cumsum_j(&band_any(&s2, cells.x_clear, cells.z_thin));
        let c_thick = cumsum_j(&band_any(&s2, cells.x_clear, cells.z_thick));
        let fit_plus = and(
            &free_from(&c_thin, cells.n_thin),
            &free_from(&c_thick, cells.n_thick),
        );
        let fit_minus = and(
            &free_to(&c_thin, cells.n_thin),
            &free_to(&c_thick, cells.n_thick),
        );
        let c_side = lat.side.as_ref().and_then(|side| {
            side.data
                .iter()
                .any(|&x| x)
                .then(|| cumsum_j(&band_any(&integral_xz(side), cells.x_pad, cells.z_contact)))
        });
        // s3[i, j + 1, k] = Σ_{j' <= j} s2[i, j', k].
        let mut s3 = Vol::filled(s2.a, s2.b + 1, s2.c, 0i32);
        for i in 0..s2.a {
            for j in 0..s2.b {
                for k in 0..s2.c {
                    let t = s3.idx(i, j + 1, k);
                    s3.data[t] = s3.at(i, j, k) + s2.at(i, j, k);
                }
            }
        }
        Tables {
            band_next: next_true(&band_c),
            band_prev: prev_true(&band_c),
            c_thin,
            c_thick,
            fit_next: next_true(&fit_plus),
            fit_prev: prev_true(&fit_minus),
            c_side,
            s3,
        }
    }

    fn evaluate(&self) -> Found {
        let v = self.p.voxel_size;
        let lat = Lattice::new(self.sh, self.rot);
        let (a, b, c) = (lat.q.a as i64, lat.q.b as i64, lat.q.c as i64);
        let t = self.tables(&lat);
        let nn = contacts::NearestTables::new(&lat.q_nn, self.cells);
        let mut found = Vec::new();
        for (idx, centre) in self.sh.cand_centres.iter().enumerate() {
            let u = to_tcp(centre, self.rot);
            let ucell: [f64; 3] = std::array::from_fn(|d| (u[d] - lat.lo[d]) / v);
            let dims = [a, b, c];
            let cell: [i64; 3] =
                std::array::from_fn(|d| clampi(ucell[d].round_ties_even() as i64, 0, dims[d] - 1));
            let dy = (ucell[1] - cell[1] as f64) * v;
            let Some(g) = self.closing(&t, cell, dy, b) else {
                continue;
            };
            if !self.approach_free(&t, cell, dy, &g, [a, b, c], centre[2]) {
                continue;
            }
            let ctx = contacts::Candidate {
                ic: cell[0],
                jc: cell[1],
                kc: cell[2],
                hi_row: g.hi_row,
                lo_row: g.lo_row,
                h_act: g.h_act,
            };
            let Some(q) = contacts::quality(self, &lat, &nn, &ctx) else {
                continue;
            };
            // Centring: the object off the TCP.
            let q = q * ramp(0.5 * (g.e_plus - g.e_minus).abs(), 0.5 * v, 0.02, 1.0, 0.85);
            found.push((idx, q, g.width));
        }
        found
    }

    /// Step 1: the closing region; `None` if no grasp closes here.
    fn closing(&self, t: &Tables, cell: [i64; 3], dy: f64, b: i64) -> Option<Closing> {
        let v = self.p.voxel_size;
        let [ic, jc, kc] = cell.map(|x| x as usize);
        let hi_row = i64::from(t.fit_next.at(ic, jc, kc)) - 1;
        let lo_row = i64::from(t.fit_prev.at(ic, jc, kc)) + 1;
        let hi_cl = clampi(hi_row, 0, b - 1) as usize;
        let lo_cl = clampi(lo_row, 0, b - 1) as usize;
        let y_hi = i64::from(t.band_prev.at(ic, hi_cl, kc));
        let y_lo = i64::from(t.band_next.at(ic, lo_cl, kc));
        if !(hi_row >= lo_row && y_hi >= lo_row && y_lo <= hi_row) {
            return None;
        }
        let jc = cell[1];
        let e_plus = ((y_hi - jc) as f64 + 0.5) * v - dy;
        let e_minus = ((jc - y_lo) as f64 + 0.5) * v + dy;
        let width = 2.0 * (e_plus.max(e_minus) + self.p.clearance);
        if !(width <= self.p.hand.max_opening + EPS) {
            return None;
        }
        if let Some(c_side) = &t.c_side {
            // The segment must not touch a side face of the grid.
            let lo_s = clampi(y_lo, 0, b) as usize;
            let hi_s = clampi(y_hi + 1, 0, b) as usize;
            if c_side.at(ic, hi_s.max(lo_s), kc) != c_side.at(ic, lo_s, kc) {
                return None;
            }
        }
        let h_act = 0.5 * self.p.hand.max_opening.min(width + self.p.opening_margin);
        Some(Closing {
            hi_row,
            lo_row,
            e_plus,
            e_minus,
            width,
            h_act,
        })
    }

    /// Step 2: fingers (where the executor opens them) and palm swept from the
    /// pre-grasp pose are free of the lattice and above the table.
    fn approach_free(
        &self,
        t: &Tables,
        cell: [i64; 3],
        dy: f64,
        g: &Closing,
        dims: [i64; 3],
        centre_z: f64,
    ) -> bool {
        let p = self.p;
        let v = p.voxel_size;
        let clr = p.clearance;
        let [a, b, c] = dims;
        let [ic, jc, kc] = cell;
        let h = g.h_act;
        for (cum, th) in [
            (&t.c_thin, p.hand.tip_thickness),
            (&t.c_thick, p.hand.base_thickness),
        ] {
            for (y0, y1) in [(h - clr, h + th + clr), (-h - th - clr, -h + clr)] {
                let r0 = clampi(jc + ceil_fast((dy + y0) / v - EPS) as i64, 0, b);
                let r1 = clampi(jc + floor_fast((dy + y1) / v + EPS) as i64 + 1, 0, b);
                let (i, k) = (ic as usize, kc as usize);
                if cum.at(i, r0.max(r1) as usize, k) != cum.at(i, r0 as usize, k) {
                    return false;
                }
            }
        }
        let s3 = &t.s3;
        for [(i0, i1), (j0, j1), (k0, k1)] in self.cells.palm {
            let ia = clampi(ic + i0, 0, a) as usize;
            let ib = clampi(ic + i1 + 1, 0, a) as usize;
            let ja = clampi(jc + j0, 0, b) as usize;
            let jb = clampi(jc + j1 + 1, 0, b) as usize;
            let ka = clampi(kc + k0, 0, c) as usize;
            let kb = clampi(kc + k1 + 1, 0, c) as usize;
            let total =
                s3.at(ib, jb, kb) - s3.at(ia, jb, kb) - s3.at(ib, ja, kb) - s3.at(ib, jb, ka)
                    + s3.at(ia, ja, kb)
                    + s3.at(ia, jb, ka)
                    + s3.at(ib, ja, ka)
                    - s3.at(ia, ja, ka);
            if total != 0 {
                return false;
            }
        }
        // Table: the lowest point of every swept box.
        let pz = self.p.origin_z + centre_z;
        let rz = self.rot[2];
        let pre = p.pregrasp_distance;
        let floor = p.table_z + p.table_clearance;
        let hand = &p.hand;
        let low_x = -rz[0].abs() * (0.5 * hand.finger_width);
        for (th, z0, z1) in [
            (hand.tip_thickness, hand.finger_split - pre, hand.finger_tip),
            (
                hand.base_thickness,
                hand.finger_base - pre,
                hand.finger_split,
            ),
        ] {
            let low_z = (rz[2] * z0).min(rz[2] * z1);
            for (y0, y1) in [(h, h + th), (-h - th, -h)] {
                let low_y = (rz[1] * y0).min(rz[1] * y1);
                if !(pz + low_x + low_y + low_z >= floor) {
                    return false;
                }
            }
        }
        for (half, z0, z1) in [
            (hand.palm_front_half, hand.palm_split, hand.palm_front),
            (hand.palm_back_half, hand.palm_back - pre, hand.palm_split),
        ] {
            let low = -rz[0].abs() * half[0] - rz[1].abs() * half[1] + (rz[2] * z0).min(rz[2] * z1);
            if !(pz + low >= floor) {
                return false;
            }
        }
        true
    }
}

/// The closing region of one candidate (step 1).
struct Closing {
    hi_row: i64,
    lo_row: i64,
    e_plus: f64,
    e_minus: f64,
    width: f64,
    h_act: f64,
}

#[cfg(test)]
mod tests;
