//! The interior-fluid sums of `coupling::interior` on the device: per body with an interior
//! term (fixed and free bodies; prescribed bodies have none), `P = Σ α j`, `L = Σ α r × j`,
//! `V = Σ α` over the nodes near it, `α = clamp(½ − sd, 0, 1)`, for the fluid before the
//! forcing and after the fluid step (the bodies where they were during the step).
//!
//! **Where the nodes come from.** The CPU walks the body's rows from the shape's chords and
//! evaluates the signed distance at the partial nodes (on the host, in f64). Here each body
//! has a fixed box of `W³` nodes from `⌊c − (R + ½)⌋` on (`R` the bounding radius, `W =
//! ⌈2R + 1⌉ + 2`), every node with `sd < ½` inside it, one thread per x-row of the box; the
//! signed distance is evaluated on the device for the shapes whose formula it has (sphere,
//! cylinder, cuboid, their dimensions recovered from the shape's volume and moments and
//! checked against its own signed distance), in f32. A row visits only its nodes within the
//! chord of the shape grown by 0.51 (a superset of `sd < ½` with a margin for the chord's
//! f32 rounding, and one node more at each end), so the work is the grown shape's volume plus
//! one thread per row of the box: for the paper's `ℓ/d = 4` cylinder at full scale (`d = 12`,
//! `W = 53`) about 7·10³ nodes instead of the box's 1.5·10⁵. The skipped nodes have `α = 0`
//! and would add nothing: the sums are bitwise those of the whole box (checked when the culling
//! was written, on the scene of `tests/device_markers.rs`).
//!
//! **Order and accuracy.** Each row sums its nodes in x order, each body its rows in order,
//! whatever the work-group size: deterministic. The sums are kept with a running compensation
//! (Neumaier), so that `P_after − P_before`, a small difference of two large sums, keeps the
//! accuracy of the f32 momenta (`j` from 19 populations: a few ulp of `Σ|h_i|` per node)
//! instead of the f32 rounding of the sums' size. The host adds each sum and its
//! compensation in f64.

use super::{bind, make_kernel, DeviceMarkers, Kernel};
use crate::device::{DeviceError, DeviceFluid};
use crate::rigid::{Cuboid, Cylinder, Motion, RigidBody, Shape, Sphere, Vec3};

/// The interior kernels and their buffers.
pub(super) struct Interior {
    rows: Kernel,
    bodies: Kernel,
    out: wgpu::Buffer,
}

/// The device's description of a body's shape: kind (1 sphere, 2 cylinder, 3 cuboid) and
/// dimensions (radius or half extents, half-length), recovered from its volume and principal
/// moments and checked against its signed distance; `None` for another shape.
fn describe(shape: &dyn Shape) -> Option<(u32, [f64; 3])> {
    let v = shape.volume();
    let i = shape.principal_moments_unit_density();
    let (kind, dims, check): (u32, [f64; 3], Box<dyn Shape>) = match shape.name() {
        "sphere" => {
            let r = (3.0 * v / (4.0 * std::f64::consts::PI)).cbrt();
            (1, [r, 0.0, 0.0], Box::new(Sphere::new(2.0 * r)))
        }
        "cylinder" => {
            // I_axis = V a²/2 about body z; V = π a² ℓ.
            let a = (2.0 * i.z / v).sqrt();
            let l = v / (std::f64::consts::PI * a * a);
            (2, [a, 0.5 * l, 0.0], Box::new(Cylinder::new(2.0 * a, l)))
        }
        "cuboid" => {
            // I_x = V (a_y² + a_z²)/3 with half extents a.
            let h = |p: f64, q: f64, r: f64| (1.5 * (q + r - p) / v).max(0.0).sqrt();
            let a = [h(i.x, i.y, i.z), h(i.y, i.z, i.x), h(i.z, i.x, i.y)];
            (3, a, Box::new(Cuboid::new(Vec3::new(2.0 * a[0], 2.0 * a[1], 2.0 * a[2]))))
        }
        _ => return None,
    };
    let r = shape.bounding_radius();
    let same = [[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [1.0, 0.4, -0.7], [-0.6, 0.9, 1.3], [0.2, 0.1, -1.2]]
        .iter()
        .all(|p| {
            let p = Vec3::new(p[0], p[1], p[2]) * r;
            (shape.signed_distance(&p) - check.signed_distance(&p)).abs() <= 1e-9 * r
        });
    same.then_some((kind, dims))
}

impl DeviceMarkers {
    /// Turns the interior sums on for `bodies` (those of the marker sets, in order): each
    /// fixed or free body gets its box of rows (module docs); prescribed bodies none.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for a fixed or free body whose shape the device cannot
    /// evaluate (not a sphere, cylinder or cuboid), or a body count that is not the marker
    /// sets'.
    pub fn enable_interior(&mut self, bodies: &[RigidBody]) -> Result<(), DeviceError> {
        if bodies.len() != self.n_bodies {
            return Err(DeviceError::Mismatch(format!(
                "{} bodies for {} marker sets",
                bodies.len(),
                self.n_bodies
            )));
        }
        let mut shapes: Vec<u32> = Vec::with_capacity(8 * bodies.len());
        let mut rows: Vec<[u32; 4]> = Vec::new();
        for (b, body) in bodies.iter().enumerate() {
            if matches!(body.motion(), Motion::Prescribed(_)) {
                shapes.extend([0; 8]);
                continue;
            }
            let Some((kind, dims)) = describe(body.shape().as_ref()) else {
                return Err(DeviceError::Mismatch(format!(
                    "body {b}: the device has no signed distance for a {} (sphere, cylinder, cuboid)",
                    body.shape().name()
                )));
            };
            let reach = body.shape().bounding_radius() + 0.5;
            let w = (2.0 * reach).ceil() as u32 + 2;
            shapes.extend([kind, w, rows.len() as u32, 0]);
            shapes.extend([dims[0], dims[1], dims[2], reach].map(|v| (v as f32).to_bits()));
            for iz in 0..w {
                for iy in 0..w {
                    rows.push([b as u32, iy, iz, 0]);
                }
            }
        }
        let n_rows = rows.len();
        let device = &self.device;
        let cast = bytemuck::cast_slice::<u32, u8>;
        let shapes = super::storage(device, "shapes", cast(&shapes), 0);
        let row_table = super::storage(device, "rows", cast(rows.as_flattened()), 0);
        let row_sums = super::storage(device, "row sums", &[], 64 * n_rows);
        let out = super::storage(device, "interior", &[], 128 * self.n_bodies);
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut pairs: Vec<(u32, &wgpu::Buffer)> = vec![(bind::PARAMS, &self.params)];
        pairs.extend(self.pops.iter().enumerate().map(|(q, b)| (bind::F0 + q as u32, b)));
        pairs.extend([
            (bind::BODIES, &self.bodies),
            (bind::SHAPES, &shapes),
            (bind::ROWS, &row_table),
            (bind::ROW_SUMS, &row_sums),
            (bind::INTERIOR, &out),
        ]);
        let rows_kernel = make_kernel(device, &self.module, &self.constants, "interior_rows", &pairs, n_rows);
        let bodies_kernel = make_kernel(
            device,
            &self.module,
            &self.constants,
            "interior_bodies",
            &[
                (bind::PARAMS, &self.params),
                (bind::SHAPES, &shapes),
                (bind::ROW_SUMS, &row_sums),
                (bind::INTERIOR, &out),
            ],
            self.n_bodies,
        );
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(DeviceError::Wgpu(e.to_string()));
        }
        // The 2-D dispatch's rows wide enough for the interior rows too (every kernel reads the
        // row width from the parameters).
        let max_groups = self.device.limits().max_compute_workgroups_per_dimension;
        let groups = (n_rows.max(1) as u64).div_ceil(self.workgroup as u64).min(max_groups as u64) as u32;
        self.row_groups = self.row_groups.max(groups);
        self.params_words[8] = self.row_groups * self.workgroup;
        self.params_words[13] = n_rows as u32;
        // Room in the staging buffer for the loads, the status and the sums in one read.
        let need = (32 * self.n_bodies + 16 + 128 * self.n_bodies) as u64;
        if self.staging.size() < need {
            self.staging = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ibm staging"),
                size: need.next_multiple_of(16),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        self.interior = Some(Interior { rows: rows_kernel, bodies: bodies_kernel, out });
        Ok(())
    }

    /// The interior sums of every body from `fluid` as it stands, with the bodies of the last
    /// [`DeviceMarkers::set_bodies`], into slot `after` (`false`: before the forcing, phase 3;
    /// `true`: after the fluid step, phase 7). Does not wait.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] for another device fluid, or when the interior sums are off.
    pub fn interior(&mut self, fluid: &DeviceFluid, after: bool) -> Result<(), DeviceError> {
        if self.interior.is_none() {
            return Err(DeviceError::Mismatch("the interior sums are off: call enable_interior".into()));
        }
        self.params_words[14] = after as u32;
        self.prepare(fluid)?;
        if let Some(i) = &self.interior {
            self.submit(&[&i.rows, &i.bodies], false);
        }
        Ok(())
    }

    /// Per body the interior sums `[(P, L, V) before, (P, L, V) after]` of the last
    /// [`DeviceMarkers::interior`] calls (zero for prescribed bodies), each sum plus its
    /// compensation in f64 (112 bytes a body). Waits for the device.
    ///
    /// # Errors
    /// [`DeviceError::Mismatch`] when the interior sums are off; the read-back's.
    #[allow(clippy::type_complexity)]
    pub fn interior_sums(&self) -> Result<Vec<[(Vec3, Vec3, f64); 2]>, DeviceError> {
        let Some(i) = &self.interior else {
            return Err(DeviceError::Mismatch("the interior sums are off: call enable_interior".into()));
        };
        let mut v = vec![0.0f32; 32 * self.n_bodies];
        self.read(&[(&i.out, 128 * self.n_bodies)], bytemuck::cast_slice_mut(&mut v))?;
        Ok(self.parse_sums(&v))
    }

    /// [`DeviceMarkers::loads`] and [`DeviceMarkers::interior_sums`] in one read-back (one
    /// wait for the device per step).
    ///
    /// # Errors
    /// As the two.
    #[allow(clippy::type_complexity)]
    pub fn loads_and_interior_sums(
        &self,
    ) -> Result<(Vec<(Vec3, Vec3)>, Vec<[(Vec3, Vec3, f64); 2]>), DeviceError> {
        let Some(i) = &self.interior else {
            return Err(DeviceError::Mismatch("the interior sums are off: call enable_interior".into()));
        };
        let k = &self.kernels;
        self.submit(&[&k.chunk_loads, &k.body_loads], false);
        let (nb, sums) = (self.n_bodies, 128 * self.n_bodies);
        let mut words = vec![0u32; (32 * nb + 16 + sums) / 4];
        self.read(
            &[(&self.loads, 32 * nb), (&self.status, 16), (&i.out, sums)],
            bytemuck::cast_slice_mut(&mut words),
        )?;
        let loads = self.parse_loads(&words)?;
        let v: Vec<f32> = words[8 * nb + 4..].iter().map(|w| f32::from_bits(*w)).collect();
        Ok((loads, self.parse_sums(&v)))
    }

    /// The sums from the interior output's values (each sum plus its compensation, in f64).
    #[allow(clippy::type_complexity)]
    fn parse_sums(&self, v: &[f32]) -> Vec<[(Vec3, Vec3, f64); 2]> {
        (0..self.n_bodies)
            .map(|b| {
                [0, 1].map(|slot| {
                    let e = &v[32 * b + 16 * slot..32 * b + 16 * slot + 16];
                    let x = |k: usize| e[k] as f64 + e[8 + k] as f64;
                    (Vec3::new(x(0), x(1), x(2)), Vec3::new(x(3), x(4), x(5)), x(6))
                })
            })
            .collect()
    }
}
