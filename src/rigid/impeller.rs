//! Impellers: a flat disk or a pitched-blade turbine (PBT) on a co-rotating shaft, as one
//! rigid shape made of parts, and their prescribed rotation with a linear start-up ramp.
//!
//! The paper (Derksen 2020) stirs with a disk or a four-bladed 45° PBT of diameter `D`; its
//! Figure 1 with the dimensions is not available, so the defaults follow physics.md §2 and
//! every dimension is a parameter ([`ImpellerGeometry`]).
//!
//! **Frame.** The impeller frame has its origin on the axis in the impeller's mid-plane and
//! its `z` axis along the axis of rotation, pointing up (towards the lid, where the shaft
//! goes). The impeller is a prescribed body: it turns about its origin
//! ([`RampedRotation`]), so unlike the particles its frame is not a principal frame and its
//! mass properties are nominal (see [`Impeller`]).

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use super::body::PrescribedMotion;
use super::shape::{check_depth, ring, shrink, Marker, RetractionError, Shape};
use super::{integrate, Cuboid, Cylinder, Mat3, Quat, Vec3};

/// The direction a pitched-blade turbine pumps when it turns at positive angular velocity
/// about `+z` (counter-clockwise seen from above).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pumping {
    /// Down (the paper): each blade's leading edge is its upper edge.
    Down,
    /// Up: each blade's leading edge is its lower edge.
    Up,
}

/// Which impeller, with the dimensions of its kind (lattice units; angles in radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ImpellerKind {
    /// A flat disk of the impeller diameter and the given thickness, no blades.
    Disk {
        /// Thickness along the axis (physics.md §2: 4 Δ at full scale, ≈ 0.03 D).
        thickness: f64,
    },
    /// Flat blades pitched about their radial centre line, on a cylindrical hub.
    PitchedBlade {
        /// Number of blades, equally spaced in angle (the paper: 4).
        blades: usize,
        /// Pitch angle between the blade's width direction and the horizontal plane
        /// (the paper: 45° = π/4).
        pitch: f64,
        /// Blade width, measured along the blade surface (physics.md §2: 0.2 D).
        blade_width: f64,
        /// Blade thickness (physics.md §2: 3 Δ at full scale).
        blade_thickness: f64,
        /// Hub diameter (physics.md §2: 0.2 D).
        hub_diameter: f64,
        /// Hub height along the axis (default: the blades' vertical extent,
        /// `w sin θ + t cos θ`, so that every blade root is inside the hub).
        hub_height: f64,
        /// Pumping direction.
        pumping: Pumping,
    },
}

/// The dimensions of an impeller and its shaft (lattice units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpellerGeometry {
    /// Impeller diameter `D`: the disk's diameter, or twice the radial reach of a blade's
    /// centre line (a blade's flat outer end has corners slightly beyond `D/2`:
    /// `√((D/2)² + (w cos θ/2)²)`).
    pub diameter: f64,
    /// Disk or pitched-blade turbine.
    pub kind: ImpellerKind,
    /// Shaft diameter (physics.md §2: 0.08 D).
    pub shaft_diameter: f64,
    /// Shaft length from the impeller mid-plane up to its top end (the lid, in a tank).
    /// Zero: no shaft.
    pub shaft_length: f64,
}

impl ImpellerGeometry {
    /// The disk of physics.md §2 at grid scale `s` (full scale `s = 1`: `D = 132`,
    /// thickness 4), with a shaft of diameter `0.08 D` and length `shaft_length`.
    pub fn paper_disk(scale: f64, shaft_length: f64) -> Self {
        let d = 132.0 * scale;
        Self {
            diameter: d,
            kind: ImpellerKind::Disk { thickness: 4.0 * scale },
            shaft_diameter: 0.08 * d,
            shaft_length,
        }
    }

    /// The pitched-blade turbine of physics.md §2 at grid scale `s`: 4 blades at 45°, width
    /// `0.2 D`, thickness `3 s`, hub diameter `0.2 D`, pumping down; shaft `0.08 D`.
    pub fn paper_pbt(scale: f64, shaft_length: f64) -> Self {
        let d = 132.0 * scale;
        let (pitch, w, t) = (PI / 4.0, 0.2 * d, 3.0 * scale);
        Self {
            diameter: d,
            kind: ImpellerKind::PitchedBlade {
                blades: 4,
                pitch,
                blade_width: w,
                blade_thickness: t,
                hub_diameter: 0.2 * d,
                hub_height: blade_vertical_extent(pitch, w, t),
                pumping: Pumping::Down,
            },
            shaft_diameter: 0.08 * d,
            shaft_length,
        }
    }

    /// Half the impeller's height along the axis (shaft excluded): half the disk thickness,
    /// or half the hub height (which [`ImpellerGeometry::validate`] requires to cover the
    /// blades' vertical extent).
    pub fn half_height(&self) -> f64 {
        match self.kind {
            ImpellerKind::Disk { thickness } => 0.5 * thickness,
            ImpellerKind::PitchedBlade { hub_height, .. } => 0.5 * hub_height,
        }
    }

    /// Checks that the dimensions describe a connected impeller. The error names the
    /// dimension (as the case file's key) and the allowed range.
    pub fn validate(&self) -> Result<(), GeometryError> {
        let err = |key: &'static str, value: f64, allowed: String| Err(GeometryError { key, value, allowed });
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !pos(self.diameter) {
            return err("diameter", self.diameter, "> 0".into());
        }
        match self.kind {
            ImpellerKind::Disk { thickness } => {
                if !pos(thickness) || thickness >= self.diameter {
                    return err(
                        "thickness",
                        thickness,
                        format!("0 < thickness < diameter = {}", self.diameter),
                    );
                }
            }
            ImpellerKind::PitchedBlade {
                blades,
                pitch,
                blade_width,
                blade_thickness,
                hub_diameter,
                hub_height,
                ..
            } => {
                if !(1..=16).contains(&blades) {
                    return err("blades", blades as f64, "1 ..= 16".into());
                }
                if !(pitch.is_finite() && pitch > 0.0 && pitch < 0.5 * PI) {
                    return err("pitch_deg", pitch.to_degrees(), "0 < pitch < 90".into());
                }
                if !pos(hub_diameter) || hub_diameter >= self.diameter {
                    return err(
                        "hub_diameter",
                        hub_diameter,
                        format!("0 < hub_diameter < diameter = {}", self.diameter),
                    );
                }
                if !pos(blade_width) {
                    return err("blade_width", blade_width, "> 0".into());
                }
                if !pos(blade_thickness) || blade_thickness >= blade_width {
                    return err(
                        "blade_thickness",
                        blade_thickness,
                        format!("0 < blade_thickness < blade_width = {blade_width}"),
                    );
                }
                // The blade's root (at half the hub radius) must be inside the hub: its
                // farthest corner from the axis, in the horizontal plane, is at
                // √((r_h/2)² + y_max²) with y_max the blade's half extent across.
                let rh = 0.5 * hub_diameter;
                let y_max = 0.5 * (blade_width * pitch.cos() + blade_thickness * pitch.sin());
                if 0.25 * rh * rh + y_max * y_max >= rh * rh {
                    return err(
                        "hub_diameter",
                        hub_diameter,
                        format!(
                            "> {:.4} (so that the blade roots are inside the hub)",
                            2.0 * y_max / 0.75f64.sqrt()
                        ),
                    );
                }
                let need = blade_vertical_extent(pitch, blade_width, blade_thickness);
                if !(hub_height.is_finite() && hub_height >= need - 1e-9) {
                    return err(
                        "hub_height",
                        hub_height,
                        format!(">= {need:.4} (the blades' vertical extent)"),
                    );
                }
            }
        }
        let top = self.half_height();
        if self.shaft_length != 0.0 {
            if !(self.shaft_length.is_finite() && self.shaft_length > top) {
                return err(
                    "shaft_length",
                    self.shaft_length,
                    format!("0 (no shaft) or > {top} (above the impeller)"),
                );
            }
            let limit = match self.kind {
                ImpellerKind::Disk { .. } => self.diameter,
                ImpellerKind::PitchedBlade { hub_diameter, .. } => hub_diameter,
            };
            if !pos(self.shaft_diameter) || self.shaft_diameter >= limit {
                return err("shaft_diameter", self.shaft_diameter, format!("0 < shaft_diameter < {limit}"));
            }
        }
        Ok(())
    }
}

impl ImpellerGeometry {
    /// Checks that every part stays solid when the forcing markers are retracted by `depth`
    /// ([`Shape::retracted_markers`]): the disk's or the blades' thickness, the blade width,
    /// the hub's diameter and height and the shaft's diameter must each exceed `2 depth`.
    /// The error names the dimension by its case-file key.
    ///
    /// # Errors
    /// The first dimension not larger than `2 depth`, or a negative depth.
    pub fn check_retraction(&self, depth: f64) -> Result<(), RetractionError> {
        check_depth(depth)?;
        let s = "impeller";
        shrink(s, "diameter", self.diameter, depth)?;
        match self.kind {
            ImpellerKind::Disk { thickness } => {
                shrink(s, "thickness", thickness, depth)?;
            }
            ImpellerKind::PitchedBlade { blade_width, blade_thickness, hub_diameter, hub_height, .. } => {
                shrink(s, "blade_thickness", blade_thickness, depth)?;
                shrink(s, "blade_width", blade_width, depth)?;
                shrink(s, "hub_diameter", hub_diameter, depth)?;
                shrink(s, "hub_height", hub_height, depth)?;
            }
        }
        if self.shaft_length > 0.0 {
            shrink(s, "shaft_diameter", self.shaft_diameter, depth)?;
        }
        Ok(())
    }
}

/// The vertical extent of a blade of width `w` and thickness `t` pitched at `θ`:
/// `w sin θ + t cos θ`.
pub fn blade_vertical_extent(pitch: f64, width: f64, thickness: f64) -> f64 {
    width * pitch.sin() + thickness * pitch.cos()
}

/// An impeller dimension out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("impeller {key} = {value} is out of range: allowed {allowed}")]
pub struct GeometryError {
    /// The dimension's case-file key.
    pub key: &'static str,
    /// Its value.
    pub value: f64,
    /// The allowed range.
    pub allowed: String,
}

/// How a part's markers are made.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PartMarkers {
    /// The part shape's own markers.
    Shape,
    /// A shaft: the mantle of a `z`-axis cylinder of radius `r` from `z0` to `z1` (impeller
    /// frame), open at both ends (its bottom is inside the impeller, its top at the lid).
    Tube { r: f64, z0: f64, z1: f64 },
}

/// One solid part: a shape placed at `offset` with rotation `rotation` (part → impeller).
#[derive(Clone, Debug)]
struct Part {
    shape: Arc<dyn Shape>,
    offset: Vec3,
    rotation: Mat3,
    markers: PartMarkers,
}

impl Part {
    fn to_part(&self, p: &Vec3) -> Vec3 {
        self.rotation.tr_mul(&(p - self.offset))
    }

    fn signed_distance(&self, p: &Vec3) -> f64 {
        self.shape.signed_distance(&self.to_part(p))
    }
}

/// An impeller and its shaft: the union of its parts (a disk, or a hub with flat blades;
/// a shaft), as a [`Shape`].
///
/// - **Signed distance**: the minimum of the parts' exact signed distances. Outside the
///   impeller this is the exact Euclidean distance to the union (contacts prune with it);
///   inside it is the depth in the deepest part (a lower bound of the depth in the union).
/// - **Chords**: for `offset ≥ 0` the hull of the parts' chords (a superset); for `offset < 0`
///   the longest part chord (a subset), as [`Shape::chord`] asks.
/// - **Markers**: each part's markers ([`Cylinder`] for the disk and the hub, [`Cuboid`] for the
///   blades, rings on the open shaft mantle), minus those strictly inside another part. So
///   the markers cover the exposed surface, and their weights sum to its area up to the
///   discretisation of the cut lines (verified against the exact area for the disk and a
///   refined quadrature for the PBT: within 1 %).
/// - **[`Shape::surface_area`]**: the exposed area, exact for the disk impeller; for the PBT
///   the parts' areas minus the areas inside other parts, by the same construction at a
///   spacing of `D/1320` (0.1 at full scale; a refined quadrature).
/// - **Mass properties**: nominal (parts summed, overlaps counted twice, about the impeller
///   origin, diagonal only). An impeller's motion is prescribed, so they never enter.
#[derive(Clone, Debug)]
pub struct Impeller {
    geometry: ImpellerGeometry,
    parts: Vec<Part>,
    /// The exposed area, computed on first use (the PBT's quadrature takes a fraction of a
    /// second at full scale).
    area: std::sync::OnceLock<f64>,
}

impl Impeller {
    /// The impeller of `geometry`.
    ///
    /// # Errors
    /// If the geometry is invalid ([`ImpellerGeometry::validate`]).
    pub fn new(geometry: ImpellerGeometry) -> Result<Self, GeometryError> {
        geometry.validate()?;
        let mut parts = Vec::new();
        let r_imp = 0.5 * geometry.diameter;
        match geometry.kind {
            ImpellerKind::Disk { thickness } => {
                parts.push(Part {
                    shape: Arc::new(Cylinder::new(geometry.diameter, thickness)),
                    offset: Vec3::zeros(),
                    rotation: Mat3::identity(),
                    markers: PartMarkers::Shape,
                });
            }
            ImpellerKind::PitchedBlade {
                blades,
                pitch,
                blade_width,
                blade_thickness,
                hub_diameter,
                hub_height,
                pumping,
            } => {
                parts.push(Part {
                    shape: Arc::new(Cylinder::new(hub_diameter, hub_height)),
                    offset: Vec3::zeros(),
                    rotation: Mat3::identity(),
                    markers: PartMarkers::Shape,
                });
                // A blade is a box from half the hub radius out to D/2; box axes: x radial,
                // y across the blade towards its leading edge (the direction of motion),
                // z through its thickness. Pitched about x: pumping down lifts the leading
                // edge.
                let r0 = 0.25 * hub_diameter;
                let length = r_imp - r0;
                let tilt = match pumping {
                    Pumping::Down => pitch,
                    Pumping::Up => -pitch,
                };
                let shape: Arc<dyn Shape> =
                    Arc::new(Cuboid::new(Vec3::new(length, blade_width, blade_thickness)));
                for k in 0..blades {
                    let phi = TAU * k as f64 / blades as f64;
                    let rz = Quat::from_axis_angle(&Vec3::z_axis(), phi);
                    let rx = Quat::from_axis_angle(&Vec3::x_axis(), tilt);
                    let rotation = (rz * rx).to_rotation_matrix().into_inner();
                    parts.push(Part {
                        shape: shape.clone(),
                        offset: rz * Vec3::new(r0 + 0.5 * length, 0.0, 0.0),
                        rotation,
                        markers: PartMarkers::Shape,
                    });
                }
            }
        }
        let top = geometry.half_height();
        if geometry.shaft_length > 0.0 {
            // The shaft's solid reaches down to the mid-plane (its bottom end is inside the
            // disk or hub); its markers only cover the exposed mantle.
            let l = geometry.shaft_length;
            parts.push(Part {
                shape: Arc::new(Cylinder::new(geometry.shaft_diameter, l)),
                offset: Vec3::new(0.0, 0.0, 0.5 * l),
                rotation: Mat3::identity(),
                markers: PartMarkers::Tube { r: 0.5 * geometry.shaft_diameter, z0: top, z1: l },
            });
        }
        Ok(Self { geometry, parts, area: std::sync::OnceLock::new() })
    }

    /// The dimensions.
    pub fn geometry(&self) -> &ImpellerGeometry {
        &self.geometry
    }

    /// The exposed area: exact for the disk; for the PBT by a refined marker quadrature.
    fn exposed_area(&self) -> f64 {
        let g = &self.geometry;
        let shaft = if g.shaft_length > 0.0 {
            let r = 0.5 * g.shaft_diameter;
            Some((r, PI * r * r))
        } else {
            None
        };
        match g.kind {
            ImpellerKind::Disk { thickness } => {
                let r = 0.5 * g.diameter;
                let disk = 2.0 * PI * r * r + TAU * r * thickness;
                // The shaft covers a disc of the disk's top face and adds its open mantle.
                disk + shaft.map_or(0.0, |(rs, foot)| TAU * rs * (g.shaft_length - 0.5 * thickness) - foot)
            }
            ImpellerKind::PitchedBlade { .. } => {
                // A quadrature that converges to the exposed area as the spacing goes to 0:
                // the same construction as the markers, at a fraction of the default spacing.
                let h = 0.1 * g.diameter / 132.0;
                self.markers(h).iter().map(|m| m.area).sum()
            }
        }
    }

    /// The markers of part `i` (impeller frame) at `spacing`, retracted by `depth`
    /// ([`Shape::retracted_markers`]; 0: on the surface), before removing those inside other
    /// parts. The shaft's open mantle moves in to radius `r − depth` and starts `depth`
    /// lower, on the retracted top of the disk or hub; its top stays at the lid.
    fn part_markers(&self, i: usize, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        let part = &self.parts[i];
        Ok(match part.markers {
            PartMarkers::Shape => part
                .shape
                .retracted_markers(spacing, depth)?
                .into_iter()
                .map(|m| Marker {
                    position: part.rotation * m.position + part.offset,
                    normal: part.rotation * m.normal,
                    area: m.area,
                })
                .collect(),
            PartMarkers::Tube { r, z0, z1 } => {
                let (r, z0) = (r - depth, z0 - depth);
                let nz = (((z1 - z0) / spacing).round() as usize).max(1);
                let hz = (z1 - z0) / nz as f64;
                let m = ((TAU * r / spacing).round() as usize).max(3);
                let mut out = Vec::with_capacity(nz * m);
                for k in 0..nz {
                    let z = z0 + (k as f64 + 0.5) * hz;
                    let phase = if k % 2 == 1 { PI / m as f64 } else { 0.0 };
                    ring(&mut out, m, r, z, phase, TAU * r * hz / m as f64, |c, s| Vec3::new(c, s, 0.0));
                }
                out
            }
        })
    }

    /// The radius of the smallest cylinder about the axis that holds the impeller: `D/2` for
    /// the disk; for the PBT the blade tips' outer corners, `√((D/2)² + y²)` with `y` the
    /// blade's half extent across, `(w cos θ + t sin θ)/2`.
    pub fn radial_reach(&self) -> f64 {
        let r = 0.5 * self.geometry.diameter;
        match self.geometry.kind {
            ImpellerKind::Disk { .. } => r,
            ImpellerKind::PitchedBlade { pitch, blade_width, blade_thickness, .. } => {
                r.hypot(0.5 * (blade_width * pitch.cos() + blade_thickness * pitch.sin()))
            }
        }
    }

    /// The extent `(z_lo, z_hi)` along the axis, shaft included.
    pub fn axial_extent(&self) -> (f64, f64) {
        let half = self.geometry.half_height();
        (-half, half.max(self.geometry.shaft_length))
    }

    /// The number of parts (disk or hub and blades, and the shaft).
    pub fn part_count(&self) -> usize {
        self.parts.len()
    }

    /// The signed distance of `p` (impeller frame) to part `i` alone.
    pub fn part_signed_distance(&self, i: usize, p: &Vec3) -> f64 {
        self.parts[i].signed_distance(p)
    }

    /// The markers at `spacing` with the index of the part each comes from.
    pub fn markers_by_part(&self, spacing: f64) -> Vec<(usize, Marker)> {
        self.retracted_markers_by_part(spacing, 0.0).expect("depth 0 is always possible")
    }

    /// The markers at `spacing` retracted by `depth` ([`Shape::retracted_markers`]), with the
    /// index of the part each comes from: each part's retracted markers minus those strictly
    /// inside another *retracted* part (`sd_j < −depth`). Where two parts meet at a concave
    /// edge (a blade entering the hub, the shaft on the disk), the retracted parts' surfaces
    /// meet on the inner parallel surface of the union, so the kept markers lie at depth
    /// `depth` in the union (the deepest part's depth, as [`Impeller`]'s signed distance
    /// measures it inside).
    ///
    /// # Errors
    /// A part too thin for `depth` ([`ImpellerGeometry::check_retraction`]).
    pub fn retracted_markers_by_part(
        &self,
        spacing: f64,
        depth: f64,
    ) -> Result<Vec<(usize, Marker)>, RetractionError> {
        self.geometry.check_retraction(depth)?;
        let mut out = Vec::new();
        for i in 0..self.parts.len() {
            for m in self.part_markers(i, spacing, depth)? {
                let inside_other = (0..self.parts.len())
                    .any(|j| j != i && self.parts[j].signed_distance(&m.position) < -depth);
                if !inside_other {
                    out.push((i, m));
                }
            }
        }
        Ok(out)
    }
}

impl Shape for Impeller {
    fn name(&self) -> &'static str {
        match self.geometry.kind {
            ImpellerKind::Disk { .. } => "disk impeller",
            ImpellerKind::PitchedBlade { .. } => "pitched-blade turbine",
        }
    }

    /// Nominal: the parts' volumes summed (overlaps counted twice; never used for a
    /// prescribed body).
    fn volume(&self) -> f64 {
        self.parts.iter().map(|p| p.shape.volume()).sum()
    }

    fn surface_area(&self) -> f64 {
        *self.area.get_or_init(|| self.exposed_area())
    }

    /// Nominal: the diagonal of the parts' inertia tensors about the impeller origin, summed.
    fn principal_moments_unit_density(&self) -> Vec3 {
        let mut total = Mat3::zeros();
        for p in &self.parts {
            let i_body = Mat3::from_diagonal(&p.shape.principal_moments_unit_density());
            let v = p.shape.volume();
            let c = p.offset;
            let shift = Mat3::identity() * c.norm_squared() - c * c.transpose();
            total += p.rotation * i_body * p.rotation.transpose() + shift * v;
        }
        total.diagonal()
    }

    fn signed_distance(&self, p: &Vec3) -> f64 {
        self.parts.iter().map(|part| part.signed_distance(p)).fold(f64::INFINITY, f64::min)
    }

    fn bounding_radius(&self) -> f64 {
        self.parts.iter().map(|p| p.offset.norm() + p.shape.bounding_radius()).fold(0.0, f64::max)
    }

    fn half_extents(&self, rotation: &Mat3, offset: f64) -> Vec3 {
        let mut e = Vec3::zeros();
        for p in &self.parts {
            let c = rotation * p.offset;
            let ep = p.shape.half_extents(&(rotation * p.rotation), offset);
            e = e.sup(&(c.abs() + ep));
        }
        e
    }

    fn chord(&self, p: &Vec3, dir: &Vec3, offset: f64) -> Option<(f64, f64)> {
        let mut out: Option<(f64, f64)> = None;
        for part in &self.parts {
            let q = part.to_part(p);
            let d = part.rotation.tr_mul(dir);
            if let Some((a, b)) = part.shape.chord(&q, &d, offset) {
                out = Some(match out {
                    None => (a, b),
                    // Superset: the hull of the parts' chords.
                    Some((a0, b0)) if offset >= 0.0 => (a0.min(a), b0.max(b)),
                    // Subset: the longest chord.
                    Some((a0, b0)) => {
                        if b - a > b0 - a0 {
                            (a, b)
                        } else {
                            (a0, b0)
                        }
                    }
                });
            }
        }
        out
    }

    fn markers(&self, spacing: f64) -> Vec<Marker> {
        assert!(spacing.is_finite() && spacing > 0.0, "marker spacing must be positive, got {spacing}");
        self.markers_by_part(spacing).into_iter().map(|(_, m)| m).collect()
    }

    /// [`Impeller::retracted_markers_by_part`] without the part indices.
    fn retracted_markers(&self, spacing: f64, depth: f64) -> Result<Vec<Marker>, RetractionError> {
        assert!(spacing.is_finite() && spacing > 0.0, "marker spacing must be positive, got {spacing}");
        Ok(self.retracted_markers_by_part(spacing, depth)?.into_iter().map(|(_, m)| m).collect())
    }
}

/// Rotation about a fixed axis through the body's origin, at `N` revolutions per time step
/// after a linear ramp from rest over `T` steps (the paper: `N = 1/4000`, `T = 4000`):
///
/// `Ω(t) = 2πN · min(t/T, 1)`, angle `θ(t) = 2πN t²/(2T)` for `t < T`, `2πN (t − T/2)` after.
///
/// The displacement over a step is the exact rotation by `θ(t + Δt) − θ(t)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RampedRotation {
    /// Unit axis of rotation (world frame); positive `N` turns counter-clockwise about it.
    pub axis: Vec3,
    /// Revolutions per time step `N` after the ramp.
    pub revolutions_per_step: f64,
    /// Ramp length `T` in time steps (0: no ramp).
    pub ramp_steps: f64,
}

impl RampedRotation {
    /// The angular speed `Ω(t)`.
    pub fn angular_speed(&self, t: f64) -> f64 {
        let full = TAU * self.revolutions_per_step;
        if self.ramp_steps > 0.0 && t < self.ramp_steps {
            full * t.max(0.0) / self.ramp_steps
        } else {
            full
        }
    }

    /// The angle turned since `t = 0`, `θ(t)`.
    pub fn angle(&self, t: f64) -> f64 {
        let full = TAU * self.revolutions_per_step;
        let t = t.max(0.0);
        if self.ramp_steps > 0.0 && t < self.ramp_steps {
            full * t * t / (2.0 * self.ramp_steps)
        } else {
            full * (t - 0.5 * self.ramp_steps)
        }
    }
}

impl PrescribedMotion for RampedRotation {
    fn velocity(&self, _t: f64) -> Vec3 {
        Vec3::zeros()
    }

    fn angular_velocity(&self, t: f64) -> Vec3 {
        self.axis * self.angular_speed(t)
    }

    fn displacement(&self, t: f64, dt: f64) -> (Vec3, Quat) {
        let dtheta = self.angle(t + dt) - self.angle(t);
        (Vec3::zeros(), integrate::rotation_quaternion(&(self.axis * dtheta)))
    }
}

#[cfg(test)]
mod tests;
