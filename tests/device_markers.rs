//! The immersed-boundary markers on the device (`slurry::device::DeviceMarkers`) against the
//! CPU's `ibm` transfer and `coupling::Coupled`, on the Vulkan adapter the machine has (a GPU,
//! or Mesa's lavapipe in CI: `cargo xtask setup` installs it).
//!
//! The scene: a box periodic in x and y and walled in z, with odd sizes, a smooth nonuniform
//! flow and force field, and bodies (spheres and tilted cylinders, moving and spinning) placed
//! across the periodic seams and next to the walls, so that stencils wrap and lose points to a
//! wall. The device computes in f32 what the CPU computes in f64 from the same f32 fluid; each
//! tolerance below is a bound on that difference, derived where it is used, and each test
//! prints what it measured. Device runs themselves are compared bitwise.
//!
//! Without a Vulkan adapter these tests fail, with a message that names `cargo xtask setup`.

use std::sync::{Arc, OnceLock};

use slurry::coupling::{Coupled, CouplingParams};
use slurry::device::{Context, DeviceCoupled, DeviceFluid, DeviceMarkers};
use slurry::ibm::{interpolate, spread, DeltaKernel, FnField, Stencils};
use slurry::lattice::{Face, Grid};
use slurry::lbm::{Boundaries, FaceBoundary, Fluid, FluidParams};
use slurry::rigid::{Cylinder, Marker, Motion, Quat, RigidBody, Shape, Sphere, Vec3};
use slurry::util::SplitMix64;

/// The unit round-off of f32.
const EPS: f64 = f32::EPSILON as f64 / 2.0;

fn ctx() -> &'static Context {
    static CTX: OnceLock<Context> = OnceLock::new();
    CTX.get_or_init(|| match Context::new() {
        Ok(c) => c,
        Err(e) => panic!("the device tests need a Vulkan adapter: {e}"),
    })
}

const GRID: [usize; 3] = [21, 18, 23];
/// Amplitude and wavenumbers of the flow: `|u| ≤ U0`, `|∂u/∂x| ≤ G` (below).
const U0: f64 = 0.04;
const K: [f64; 3] = [
    2.0 * std::f64::consts::PI / GRID[0] as f64,
    2.0 * std::f64::consts::PI / GRID[1] as f64,
    std::f64::consts::PI / GRID[2] as f64,
];

/// The host fluid: periodic in x and y, walls in z, the smooth flow, a smooth force field, and
/// `steps` steps taken (an odd count leaves the populations in the AA pattern's shifted layout).
fn fluid(steps: u64) -> Fluid<f32> {
    let g = Grid::new(GRID[0], GRID[1], GRID[2]);
    let b =
        Boundaries::periodic().with(Face::ZMin, FaceBoundary::NoSlip).with(Face::ZMax, FaceBoundary::NoSlip);
    let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.08).with_body_force([2e-6, -1e-6, 0.0]), b).unwrap();
    f.initialize(|x, y, z| {
        let (x, y, z) = (x as f64, y as f64, z as f64 + 0.5);
        let s = (K[0] * x + K[1] * y).sin() * (K[2] * z).sin();
        let c = (K[0] * x - 2.0 * K[1] * y).cos() * (K[2] * z).sin();
        (1.0 + 1e-3 * s, [U0 * s, -U0 * c, 0.5 * U0 * s * c])
    });
    f.enable_force_field();
    for z in 0..g.nz {
        for y in 0..g.ny {
            for x in 0..g.nx {
                let s = ((x * 5 + y * 11 + z * 3) as f64 * 0.37).sin();
                f.set_force(x, y, z, [1e-5 * s, -2e-5 * s, 5e-6]);
            }
        }
    }
    f.run(steps);
    f
}

/// Bodies across the periodic seams and next to the walls (z ∈ [−½, 22.5]), moving and
/// spinning, with their forcing markers (retracted as the coupling's default).
fn bodies() -> Vec<RigidBody> {
    let mut rng = SplitMix64(7);
    let mut out = Vec::new();
    let placements = [
        (Vec3::new(0.3, 9.0, 11.0), true),
        (Vec3::new(10.5, 17.6, 2.6), false),
        (Vec3::new(20.7, 0.2, 17.5), true),
        (Vec3::new(6.2, 5.9, 2.3), false),
        (Vec3::new(14.1, 11.3, 19.2), false),
    ];
    for (i, (p, cyl)) in placements.into_iter().enumerate() {
        let shape: Arc<dyn Shape> = if cyl {
            Arc::new(Cylinder::new(4.0 + i as f64, 7.0))
        } else {
            Arc::new(Sphere::new(3.0 + i as f64))
        };
        let v = Vec3::new(rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03));
        let w = Vec3::new(rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01));
        let q =
            Quat::from_euler_angles(rng.uniform(-3.0, 3.0), rng.uniform(-1.5, 1.5), rng.uniform(-3.0, 3.0));
        out.push(
            RigidBody::new(shape, 1.2, Motion::constant(v, w))
                .with_position(p)
                .with_orientation(q)
                .with_velocities(v, w),
        );
    }
    out
}

fn marker_sets(bodies: &[RigidBody]) -> Vec<Vec<Marker>> {
    bodies.iter().map(|b| b.shape().retracted_markers(0.8, 0.36).unwrap()).collect()
}

/// The CPU's world positions and solid velocities of the markers (f64), and each marker's
/// distance from its body's centre.
fn cpu_markers(bodies: &[RigidBody], sets: &[Vec<Marker>]) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<f64>) {
    let (mut x, mut u, mut r) = (Vec::new(), Vec::new(), Vec::new());
    for (b, set) in bodies.iter().zip(sets) {
        for m in set {
            let (xw, _, uw) = b.marker_world(m);
            x.push([xw.x, xw.y, xw.z]);
            u.push([uw.x, uw.y, uw.z]);
            r.push(m.position.norm());
        }
    }
    (x, u, r)
}

/// A bound on the rounding of a marker's position relative to its body's origin on the device:
/// `R r` from f32 rotation entries and coordinates (each rounded, three products and two sums:
/// ≤ 6 u |r|), the f32 offset of the centre (≤ u), their sum (≤ u (|r| + 1)); with a margin of
/// two: `δx ≤ 16 u (|r| + 1)`.
fn position_error(r: f64) -> f64 {
    16.0 * EPS * (r + 1.0)
}

/// The device's position error of each marker, measured: its arm `R r` against the CPU's
/// `X − c` (f64), plus the rounding of the f32 sum `frac + R r` (`≤ u (|r| + 1)`), twice for
/// margin; at most [`position_error`].
fn measured_position_error(
    markers: &DeviceMarkers,
    bodies: &[RigidBody],
    pos: &[[f64; 3]],
    radius: &[f64],
) -> Vec<f64> {
    let arms = markers.marker_arms().unwrap();
    let mut owner = Vec::new();
    for (b, body) in bodies.iter().enumerate() {
        owner.extend(std::iter::repeat_n(b, body.shape().retracted_markers(0.8, 0.36).unwrap().len()));
    }
    (0..pos.len())
        .map(|m| {
            let c = bodies[owner[m]].position;
            let d = (0..3).map(|a| (arms[m][a] as f64 - (pos[m][a] - c[a])).abs()).fold(0.0, f64::max);
            let e = 2.0 * (d + EPS * (radius[m] + 1.0));
            assert!(e <= position_error(radius[m]), "marker {m}: arm error {d:.3e}");
            e
        })
        .collect()
}

fn setup(
    steps: u64,
    workgroup: u32,
) -> (Fluid<f32>, DeviceFluid, Vec<RigidBody>, Vec<Vec<Marker>>, DeviceMarkers) {
    setup_with(steps, workgroup, DeltaKernel::Roma3)
}

fn setup_with(
    steps: u64,
    workgroup: u32,
    kernel: DeltaKernel,
) -> (Fluid<f32>, DeviceFluid, Vec<RigidBody>, Vec<Vec<Marker>>, DeviceMarkers) {
    let host = fluid(steps);
    let dev = DeviceFluid::new(ctx(), &host, 64).expect("device fluid");
    let bodies = bodies();
    let sets = marker_sets(&bodies);
    let refs: Vec<&[Marker]> = sets.iter().map(|s| s.as_slice()).collect();
    let mut markers = DeviceMarkers::new(&dev, &refs, kernel, workgroup).expect("device markers");
    markers.set_bodies(&bodies);
    (host, dev, bodies, sets, markers)
}

/// Interpolation at the markers of the smooth flow, at an even and an odd time (both AA
/// layouts), against `ibm::interpolate` of the CPU fluid's own `macroscopic` velocity, for the
/// three kernels.
///
/// The bound per marker: the marker's position error `δx` (measured from its arm, see
/// `measured_position_error`) moves the interpolant by at most
/// `Σ_n |∂δ_n/∂X| δx |u_n − u(X)|`. Per axis, a 1-D weight `φ_k/S` (`S` the kept weights' sum,
/// 1 away from a wall and at least ½ next to one, where the dropped points mirror the kept
/// ones at worst) has `|d(φ_k/S)/dx| ≤ 2L + 4WL` with `|φ'| ≤ L = 1` for every kernel and `W`
/// points; three axes, `W` points each, the nodes within `h√3` of the marker (`h` the
/// support), where `|u_n − u(X)| ≤ h√3 G`: `≤ 3W(2 + 4W) h√3 G δx`. And f32 round-off: the
/// moments `ρ`, `j` are sums of 19 terms `|h_i| ≤ S` (≤ 18 roundings each), `u` one division
/// and one fused term, the weights a few roundings each and the `W³`-term accumulation:
/// `≤ 64 u (S + U) W³/27` with `S` the largest `Σ|h_i|` of the fluid and `U` its largest
/// speed.
#[test]
fn interpolation_matches_the_cpu() {
    for (kernel, steps) in [
        (DeltaKernel::Roma3, 0),
        (DeltaKernel::Roma3, 1),
        (DeltaKernel::Linear, 1),
        (DeltaKernel::Peskin4, 0),
    ] {
        let (host, mut dev, bodies, sets, mut markers) = setup_with(steps, 64, kernel);
        let t = std::time::Instant::now();
        // The first placement clears the whole field (the coupling owns it); the host's field
        // goes up again, so that the velocity's F/2 term is tested with a field.
        markers.place(&dev).unwrap();
        dev.set_force_field(&host).unwrap();
        markers.interpolate(&dev).unwrap();
        let got = markers.marker_velocities().unwrap();
        let seconds = t.elapsed().as_secs_f64();
        let (pos, _, radius) = cpu_markers(&bodies, &sets);
        let dx = measured_position_error(&markers, &bodies, &pos, &radius);
        let g = host.grid();
        let mut st = Stencils::new(kernel);
        st.build(g, [true, true, false], &pos).unwrap();
        let field = FnField {
            nodes: g.nodes(),
            f: |n: usize| {
                let [x, y, z] = g.coords(n);
                host.macroscopic(x, y, z).1
            },
        };
        let mut want = vec![[0.0; 3]; pos.len()];
        interpolate(&field, &st, &mut want);
        let mut s_max = 0.0f64;
        let mut u_max = 0.0f64;
        for n in 0..g.nodes() {
            let [x, y, z] = g.coords(n);
            let h = host.shifted_populations(x, y, z);
            s_max = s_max.max(h.iter().map(|v| (*v as f64).abs()).sum());
            u_max = u_max.max(host.macroscopic(x, y, z).1.iter().fold(0.0f64, |a, v| a.max(v.abs())));
        }
        let grad = U0 * 1.5 * K.iter().fold(0.0f64, |a, &k| a.max(k)) * 3.0;
        let (w, h) = (kernel.width() as f64, kernel.support());
        let (mut worst, mut worst_ratio) = (0.0f64, 0.0f64);
        for m in 0..pos.len() {
            let tol = 3.0 * w * (2.0 + 4.0 * w) * h * 3f64.sqrt() * grad * dx[m]
                + 64.0 * EPS * (s_max + u_max) * w.powi(3) / 27.0;
            for a in 0..3 {
                let d = (got[m][a] as f64 - want[m][a]).abs();
                worst = worst.max(d);
                worst_ratio = worst_ratio.max(d / tol);
                assert!(
                    d <= tol,
                    "marker {m} axis {a}: device {} CPU {} (|Δ| {d:.3e} > {tol:.3e})",
                    got[m][a],
                    want[m][a]
                );
            }
        }
        println!(
            "interpolation ({}) at {} markers, time {steps}: max |Δu| {worst:.3e} (largest |Δu|/bound \
             {worst_ratio:.1e}), place + interpolate + download {seconds:.3} s on {}",
            kernel.name(),
            pos.len(),
            dev.adapter()
        );
    }
}

/// Random marker forces spread into the force field, against `ibm::spread` in f64, for the
/// three kernels.
///
/// The bound per node, from every marker `m` whose stencil holds it: the 3-D weight moves by at
/// most `3 (2 + 4W) δx_m` (`δx_m` measured, `measured_position_error`) (three 1-D factors, each `|d(φ_k/S)/dx| ≤ 2L + 4WL`, `L = 1`, as in
/// `interpolation_matches_the_cpu`), and is rounded a few times more (`≤ 8 u w`); the product
/// `w F` and the final conversion each round once (`≤ u`), the fixed point by `2⁻⁴¹` per term:
/// together `Σ_m (3 (2 + 4W) δx_m + 10 u w_m) |F_m| + 2⁻⁴¹ + u |F_n|`. Every node is compared,
/// so the field the host uploaded (non-zero everywhere) must have been cleared by the first
/// placement.
#[test]
fn spreading_matches_the_cpu() {
    for kernel in DeltaKernel::ALL {
        spreading_matches_the_cpu_with(kernel);
    }
}

fn spreading_matches_the_cpu_with(kernel: DeltaKernel) {
    let (host, dev, bodies, sets, mut markers) = setup_with(0, 64, kernel);
    let (pos, _, radius) = cpu_markers(&bodies, &sets);
    let mut rng = SplitMix64(3);
    let forces: Vec<[f32; 3]> =
        (0..pos.len()).map(|_| [0; 3].map(|_| rng.uniform(-1e-3, 1e-3) as f32)).collect();
    let t = std::time::Instant::now();
    markers.place(&dev).unwrap();
    markers.spread_forces(&dev, &forces).unwrap();
    let got = dev.download_force::<f32>().unwrap();
    let seconds = t.elapsed().as_secs_f64();
    let dx = measured_position_error(&markers, &bodies, &pos, &radius);
    let g = host.grid();
    let mut st = Stencils::new(kernel);
    st.build(g, [true, true, false], &pos).unwrap();
    let f64_forces: Vec<[f64; 3]> = forces.iter().map(|f| f.map(|v| v as f64)).collect();
    let mut want = vec![[0.0; 3]; g.nodes()];
    spread(&f64_forces, &st, &mut want);
    let mut bound = vec![2f64.powi(-41); g.nodes()];
    for m in 0..pos.len() {
        let fm = forces[m].iter().fold(0.0f64, |a, v| a.max((*v as f64).abs()));
        let dw = 3.0 * (2.0 + 4.0 * kernel.width() as f64) * dx[m];
        st.for_each_node(m, |n, w| bound[n] += (dw + 10.0 * EPS * w) * fm);
    }
    let layout = host.padded_layout();
    let stride = got.len() / 3;
    let (mut worst, mut worst_ratio, mut touched) = (0.0f64, 0.0f64, 0);
    for n in 0..g.nodes() {
        let [x, y, z] = g.coords(n);
        let p = layout.index(x, y, z);
        for a in 0..3 {
            let d = got[a * stride + p] as f64 - want[n][a];
            let tol = bound[n] + EPS * want[n][a].abs();
            worst = worst.max(d.abs());
            worst_ratio = worst_ratio.max(d.abs() / tol);
            assert!(
                d.abs() <= tol,
                "node {x} {y} {z} axis {a}: device {} CPU {} (> {tol:.3e})",
                got[a * stride + p],
                want[n][a]
            );
        }
        touched += (want[n] != [0.0; 3]) as usize;
    }
    println!(
        "spreading ({}) of {} markers onto {touched} nodes: max |ΔF| {worst:.3e} (largest |ΔF|/bound \
         {worst_ratio:.1e}), place + spread + download {seconds:.3} s on {}",
        kernel.name(),
        pos.len(),
        dev.adapter()
    );
    // Total force conserved: the sum of the field equals the sum of the forces.
    let mut sums = [0.0f64; 3];
    for n in 0..g.nodes() {
        let [x, y, z] = g.coords(n);
        for a in 0..3 {
            sums[a] += got[a * stride + layout.index(x, y, z)] as f64;
        }
    }
    for a in 0..3 {
        let total: f64 = f64_forces.iter().map(|f| f[a]).sum();
        let abs: f64 = f64_forces.iter().map(|f| f[a].abs()).sum();
        // Each marker's weights sum to 1 within ~10 u, each node rounds once: 16 u Σ|F|.
        assert!((sums[a] - total).abs() <= 16.0 * EPS * abs, "axis {a}: Σ field {} vs Σ F {total}", sums[a]);
    }
}

/// Two forcing iterations and the loads, bitwise the same for work groups of 1, 7 and 64
/// threads and from run to run; the loads are the sums of the markers' forces and moments.
#[test]
fn forcing_is_deterministic_and_loads_sum_the_markers() {
    let mut runs = Vec::new();
    for wg in [1, 7, 64, 64] {
        let (_host, dev, bodies, _sets, mut markers) = setup(1, wg);
        let t = std::time::Instant::now();
        markers.force(&dev, 2).unwrap();
        let loads = markers.loads().unwrap();
        let seconds = t.elapsed().as_secs_f64();
        let field = dev.download_force::<f32>().unwrap();
        let forces = markers.marker_forces().unwrap();
        let arms = markers.marker_arms().unwrap();
        println!("work group {wg}: {} markers, two iterations and loads {seconds:.3} s", markers.len());
        if wg == 1 {
            check_loads(&bodies, &markers, &forces, &arms, &loads);
        }
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let flat = |v: &[[f32; 3]]| bits(v.as_flattened());
        let load_bits: Vec<u64> = loads
            .iter()
            .flat_map(|(f, t)| f.iter().chain(t.iter()).map(|v| v.to_bits()).collect::<Vec<_>>())
            .collect();
        runs.push((wg, bits(&field), flat(&forces), load_bits));
    }
    let (_, f0, m0, l0) = &runs[0];
    assert!(f0.iter().any(|&b| b != 0), "the field was forced");
    for (wg, f, m, l) in &runs[1..] {
        assert!(f == f0, "force field differs with work group {wg}");
        assert!(m == m0, "marker forces differ with work group {wg}");
        assert!(l == l0, "loads differ with work group {wg}");
    }
}

/// The loads against `(−Σ F_m, −Σ r_m × F_m)` summed in f64 from the device's own marker
/// forces and arms. The device sums in f32 in chunks of `CHUNK` markers, then the chunks: a
/// recursive sum of `n` terms errs by at most `(n − 1) u Σ|x|`, so by at most
/// `(CHUNK + chunks) u Σ|x|` here; a cross product's components round twice more (`2 u |r||F|`).
fn check_loads(
    bodies: &[RigidBody],
    markers: &DeviceMarkers,
    forces: &[[f32; 3]],
    arms: &[[f32; 3]],
    loads: &[(Vec3, Vec3)],
) {
    let _ = markers;
    let mut start = 0;
    let sets = marker_sets(bodies);
    for (b, set) in sets.iter().enumerate() {
        let n = set.len();
        let terms = (slurry::device::markers::CHUNK + n.div_ceil(slurry::device::markers::CHUNK)) as f64;
        let (mut f, mut t, mut fa, mut ta) = (Vec3::zeros(), Vec3::zeros(), 0.0f64, 0.0f64);
        for m in start..start + n {
            let fm = Vec3::new(forces[m][0] as f64, forces[m][1] as f64, forces[m][2] as f64);
            let r = Vec3::new(arms[m][0] as f64, arms[m][1] as f64, arms[m][2] as f64);
            f -= fm;
            t -= r.cross(&fm);
            fa += fm.abs().max();
            ta += 2.0 * r.abs().max() * fm.abs().max();
        }
        let (df, dt) = ((loads[b].0 - f).abs().max(), (loads[b].1 - t).abs().max());
        let (tf, tt) = (terms * EPS * fa, (terms + 2.0) * EPS * ta);
        println!("body {b}: {n} markers, |ΔF| {df:.3e} (bound {tf:.3e}), |ΔT| {dt:.3e} (bound {tt:.3e})");
        assert!(df <= tf, "body {b}: F {} vs Σ {}", loads[b].0, f);
        assert!(dt <= tt, "body {b}: T {} vs Σ {}", loads[b].1, t);
        assert!(f.norm() > 0.0);
        start += n;
    }
}

/// The coupled step of a fixed sphere and a prescribed cylinder moving and spinning through a
/// channel flow driven by a body force (its stencils move: the previous step's forcing is
/// cleared), two forcing iterations, fluid and markers on the device (`DeviceCoupled`), against
/// the CPU's `Coupled<f32>`: the loads' IBM part step by step, the bodies' poses bitwise (both
/// follow the prescribed motion on the host), and the velocity fields at the end.
///
/// The bound on the loads: the CPU forms the marker forces from f64 weights and its field with
/// one f32 rounding per addition; the device from f32 weights (`δx ≤ 16 u (r + 1)`) and the
/// fixed-point sums. The relative difference of a load is then a few `δx |∇u|/|U − u|` plus
/// `n u` per sum, about `1e-6`; the fluids differ by a few ulp per step as well
/// (tests/device_fluid.rs). `1e-4` of the load's size bounds both over 30 steps; the velocity
/// fields (|u| ≤ 0.05) by `1e-6`, the bound of tests/device_fluid.rs for 200 steps.
#[test]
fn coupled_step_matches_the_cpu() {
    let channel = || {
        let g = Grid::new(17, 15, 19);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.1).with_body_force([2e-5, 0.0, 0.0]), b).unwrap();
        f.initialize(|_, _, z| (1.0, [0.02 * (z as f64 + 0.5) / 19.0, 0.0, 0.0]));
        f
    };
    let sphere = RigidBody::new(Arc::new(Sphere::new(6.0)), 1.0, Motion::Fixed)
        .with_position(Vec3::new(4.3, 7.1, 9.4))
        .with_orientation(Quat::from_euler_angles(0.3, 0.2, 0.1));
    let (v, w) = (Vec3::new(-0.05, 0.02, 0.01), Vec3::new(0.0, 0.01, -0.02));
    let cylinder = RigidBody::new(Arc::new(Cylinder::new(4.0, 6.0)), 1.0, Motion::constant(v, w))
        .with_position(Vec3::new(13.0, 7.5, 8.0))
        .with_orientation(Quat::from_euler_angles(1.0, 0.4, -0.2))
        .with_velocities(v, w);
    let params = CouplingParams { iterations: 2, ..CouplingParams::default() };
    let bodies = vec![sphere, cylinder];
    let mut cpu = Coupled::new(channel(), bodies.clone(), params).unwrap();
    let mut dev = DeviceCoupled::new(ctx(), channel(), bodies, params, 64).unwrap();
    assert_eq!(dev.markers(1), cpu.markers(1), "the CPU's forcing markers");
    let steps = 30;
    let mut worst = 0.0f64;
    let mut seconds = 0.0;
    for step in 0..steps {
        cpu.step().unwrap();
        let t = std::time::Instant::now();
        dev.step().unwrap();
        seconds += t.elapsed().as_secs_f64();
        for b in 0..2 {
            let (f, torque) = dev.ibm_loads(b);
            let l = cpu.loads(b);
            let scale = l.ibm_force.norm();
            let rel = ((f - l.ibm_force).norm() / scale).max((torque - l.ibm_torque).norm() / scale);
            worst = worst.max(rel);
            assert!(
                rel < 1e-4,
                "step {step} body {b}: device F {f} T {torque}, CPU F {} T {}",
                l.ibm_force,
                l.ibm_torque
            );
            assert_eq!(dev.bodies()[b].position, cpu.bodies()[b].position);
            assert_eq!(dev.bodies()[b].orientation, cpu.bodies()[b].orientation);
        }
    }
    let mirror = dev.download().unwrap();
    let (_, ud) = mirror.fields();
    let (_, uc) = cpu.fluid().fields();
    let du =
        ud.iter().zip(&uc).flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs())).fold(0.0, f64::max);
    assert!(du < 1e-6, "velocity fields differ by {du:.3e}");
    println!(
        "a fixed sphere and a moving cylinder, {} markers, {steps} coupled steps: IBM loads within {worst:.3e} \
         of |F| of the CPU's, velocities within {du:.3e}; {:.2} ms a step on {}",
        dev.device_markers().len(),
        1e3 * seconds / steps as f64,
        dev.device_fluid().adapter()
    );
}

/// The whole coupled step with contacts (on the host): two free spheres falling onto the
/// bottom wall and onto each other, contacts (Table 1) within reach from the first step,
/// against the CPU's `Coupled<f32>` over 40 steps. The contact forces are stiff functions of
/// the gaps, so the differences of the hydrodynamic loads (the bound of
/// `free_bodies_fall_as_on_the_cpu`) are carried through them: the velocities are compared
/// with `1e-4` of each step's total load (hydrodynamic, weight and contact) over the mass,
/// summed over the steps, and the averaged contact loads with `1e-3` of their size.
#[test]
fn free_bodies_with_contacts_as_on_the_cpu() {
    let channel = || {
        let g = Grid::new(15, 14, 18);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.1), b).unwrap();
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        f
    };
    let low = RigidBody::new(Arc::new(Sphere::new(6.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(6.0, 7.0, 3.1))
        .with_velocities(Vec3::new(0.0, 0.0, -0.01), Vec3::zeros());
    let high = RigidBody::new(Arc::new(Sphere::new(5.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(8.5, 7.4, 8.3))
        .with_velocities(Vec3::new(0.0, 0.0, -0.02), Vec3::new(0.01, 0.0, 0.0));
    let params = CouplingParams {
        gravity: [0.0, 0.0, -2e-4],
        contacts: Some(slurry::contact::ContactParams::default()),
        ..CouplingParams::default()
    };
    let bodies = vec![low, high];
    let mut cpu = Coupled::new(channel(), bodies.clone(), params).unwrap();
    let mut dev = DeviceCoupled::new(ctx(), channel(), bodies, params, 64).unwrap();
    let steps = 40;
    let mut bound = [0.0f64; 2];
    let (mut worst_v, mut worst_c, mut contact_max) = (0.0f64, 0.0f64, 0.0f64);
    let mut seconds = 0.0;
    for step in 0..steps {
        cpu.step().unwrap();
        let t = std::time::Instant::now();
        dev.step().unwrap();
        seconds += t.elapsed().as_secs_f64();
        for b in 0..2 {
            let (bc, bd) = (&cpu.bodies()[b], &dev.bodies()[b]);
            let (lc, ld) = (cpu.loads(b), dev.loads(b));
            let weight = bc.net_weight(Vec3::from(params.gravity), 1.0).norm();
            let total = lc.force().norm() + weight + lc.contact_force.norm();
            bound[b] += 1e-4 * total / bc.mass();
            let dv = (bd.velocity - bc.velocity).norm();
            worst_v = worst_v.max(dv / bound[b]);
            assert!(
                dv <= bound[b],
                "step {step} body {b}: v {} vs {} (> {:.2e})",
                bd.velocity,
                bc.velocity,
                bound[b]
            );
            let dc = (ld.contact_force - lc.contact_force).norm();
            let size = lc.contact_force.norm();
            contact_max = contact_max.max(size);
            if size > 0.0 {
                worst_c = worst_c.max(dc / size);
            }
            assert!(
                dc <= 1e-3 * size + 1e-12,
                "step {step} body {b}: contact {} vs {}",
                ld.contact_force,
                lc.contact_force
            );
        }
    }
    assert!(contact_max > 1e-4, "the contacts acted: largest averaged contact force {contact_max:.3e}");
    println!(
        "two free spheres with contacts, {steps} steps: velocities within {worst_v:.3e} of the bound, contact \
         forces within {worst_c:.3e} (largest {contact_max:.3e}); {:.2} ms a step on {}",
        1e3 * seconds / steps as f64,
        dev.device_fluid().adapter()
    );
}

/// Free bodies under gravity, the whole coupled step but the contacts with the fluid, markers
/// and interior sums on the device (`DeviceCoupled`), against the CPU's `Coupled<f32>`: a
/// sphere (γ = 1.25) and a tilted cylinder falling and turning in a box walled in z, 40 steps.
///
/// The bound: each step's hydrodynamic load differs from the CPU's by at most `1e-4` of its
/// size (the IBM part, as `coupled_step_matches_the_cpu` bounds it, and the interior rate,
/// whose sums agree to the f32 momenta's rounding, `interior_sums_match_the_cpu`), so a body's
/// velocity by at most `Σ_k 1e-4 (|F_k| + m g')/m` (the implicit shell reaction only divides by
/// `m + K > m`; the drag damps the differences rather than growing them over 40 steps), its
/// position by the sum of those.
#[test]
fn free_bodies_fall_as_on_the_cpu() {
    let channel = || {
        let g = Grid::new(16, 15, 26);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.1), b).unwrap();
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        f
    };
    let sphere = RigidBody::new(Arc::new(Sphere::new(6.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(4.2, 7.3, 16.4))
        .with_velocities(Vec3::new(0.0, 0.0, -0.002), Vec3::new(0.0, 0.003, 0.0));
    let cylinder = RigidBody::new(Arc::new(Cylinder::new(4.0, 8.0)), 1.25, Motion::Free)
        .with_position(Vec3::new(11.8, 7.6, 12.1))
        .with_orientation(Quat::from_euler_angles(0.6, 0.3, 0.0));
    let params = CouplingParams { gravity: [0.0, 0.0, -2e-4], ..CouplingParams::default() };
    let bodies = vec![sphere, cylinder];
    let mut cpu = Coupled::new(channel(), bodies.clone(), params).unwrap();
    let mut dev = DeviceCoupled::new(ctx(), channel(), bodies, params, 64).unwrap();
    let steps = 40;
    let mut bound = [0.0f64; 2];
    let mut bound_x = [0.0f64; 2];
    let (mut worst_v, mut worst_x) = (0.0f64, 0.0f64);
    let mut seconds = 0.0;
    for step in 0..steps {
        cpu.step().unwrap();
        let t = std::time::Instant::now();
        dev.step().unwrap();
        seconds += t.elapsed().as_secs_f64();
        for b in 0..2 {
            let (bc, bd) = (&cpu.bodies()[b], &dev.bodies()[b]);
            let m = bc.mass();
            let weight = bc.net_weight(Vec3::from(params.gravity), 1.0).norm();
            bound[b] += 1e-4 * (cpu.hydrodynamic_force(b).norm() + weight) / m;
            bound_x[b] += bound[b];
            let dv = (bd.velocity - bc.velocity).norm();
            let dx = (bd.position - bc.position).norm();
            worst_v = worst_v.max(dv / bound[b]);
            worst_x = worst_x.max(dx / bound_x[b]);
            assert!(
                dv <= bound[b],
                "step {step} body {b}: v {} vs {} (> {:.2e})",
                bd.velocity,
                bc.velocity,
                bound[b]
            );
            assert!(dx <= bound_x[b], "step {step} body {b}: x {} vs {}", bd.position, bc.position);
            let dw = (bd.angular_velocity - bc.angular_velocity).norm();
            let r = bc.shape().bounding_radius();
            assert!(
                dw * r <= bound[b] * 2.0,
                "step {step} body {b}: ω {} vs {}",
                bd.angular_velocity,
                bc.angular_velocity
            );
        }
    }
    let v = cpu.bodies()[0].velocity.z;
    assert!(v < -1e-4, "the sphere falls: v_z = {v}");
    println!(
        "two free bodies, {steps} coupled steps: velocities within {worst_v:.3e} of the bound, positions within \
         {worst_x:.3e} of theirs (sphere v_z {v:.4e}); {:.2} ms a step on {}",
        1e3 * seconds / steps as f64,
        dev.device_fluid().adapter()
    );
}

/// The whole device step (fluid, markers, interior sums; bodies and contacts on the host) is
/// bitwise the same for work groups of 1, 7 and 64 threads: two free spheres with contacts,
/// 12 steps, the bodies' states and the fluid's populations and force field compared bit for
/// bit.
#[test]
fn device_coupled_step_is_bitwise_the_same_for_any_work_group() {
    let mut runs = Vec::new();
    for wg in [1, 7, 64] {
        let g = Grid::new(13, 12, 14);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.1).with_body_force([1e-5, 0.0, 0.0]), b).unwrap();
        f.initialize(|x, _, z| (1.0, [0.01 * (z as f64 / 14.0), 0.002 * (x as f64 / 13.0), 0.0]));
        let a = RigidBody::new(Arc::new(Sphere::new(5.0)), 1.25, Motion::Free)
            .with_position(Vec3::new(4.0, 6.0, 2.8));
        let c = RigidBody::new(Arc::new(Cylinder::new(3.0, 6.0)), 1.25, Motion::Free)
            .with_position(Vec3::new(9.0, 6.5, 8.0))
            .with_orientation(Quat::from_euler_angles(0.4, 0.7, 0.0));
        let params = CouplingParams {
            gravity: [0.0, 0.0, -2e-4],
            contacts: Some(slurry::contact::ContactParams::default()),
            ..CouplingParams::default()
        };
        let mut dev = DeviceCoupled::new(ctx(), f, vec![a, c], params, wg).unwrap();
        dev.run(12).unwrap();
        let states: Vec<u64> = dev
            .bodies()
            .iter()
            .flat_map(|b| {
                let q = b.orientation.into_inner();
                [b.position, b.velocity, b.angular_velocity]
                    .iter()
                    .flat_map(|v| v.iter().copied().collect::<Vec<_>>())
                    .chain([q.w, q.i, q.j, q.k])
                    .map(f64::to_bits)
                    .collect::<Vec<_>>()
            })
            .collect();
        let host = dev.download().unwrap();
        let pops: Vec<u64> = host.populations_all().iter().map(|v| v.to_bits()).collect();
        let force: Vec<u32> =
            dev.device_fluid().download_force::<f32>().unwrap().iter().map(|v| v.to_bits()).collect();
        runs.push((wg, states, pops, force));
    }
    let (_, s0, p0, f0) = &runs[0];
    for (wg, s, p, f) in &runs[1..] {
        assert!(s == s0, "bodies differ with work group {wg}");
        assert!(p == p0, "populations differ with work group {wg}");
        assert!(f == f0, "force field differs with work group {wg}");
    }
}

/// A device run restored from its snapshot continues bitwise as the uninterrupted one; the
/// snapshot is a CPU state, which `Coupled<f32>` restores and continues within the tolerance of
/// `free_bodies_with_contacts_as_on_the_cpu`.
#[test]
fn device_coupled_restores_bitwise() {
    let scene = || {
        let g = Grid::new(13, 12, 14);
        let b = Boundaries::periodic()
            .with(Face::ZMin, FaceBoundary::NoSlip)
            .with(Face::ZMax, FaceBoundary::NoSlip);
        let mut f = Fluid::<f32>::new(g, FluidParams::trt(0.1), b).unwrap();
        f.initialize(|_, _, _| (1.0, [0.0; 3]));
        let a = RigidBody::new(Arc::new(Sphere::new(5.0)), 1.25, Motion::Free)
            .with_position(Vec3::new(4.0, 6.0, 2.8))
            .with_velocities(Vec3::new(0.0, 0.0, -0.01), Vec3::zeros());
        let c = RigidBody::new(Arc::new(Cylinder::new(3.0, 6.0)), 1.25, Motion::Free)
            .with_position(Vec3::new(9.0, 6.5, 8.0))
            .with_orientation(Quat::from_euler_angles(0.4, 0.7, 0.0));
        let params = CouplingParams {
            gravity: [0.0, 0.0, -2e-4],
            contacts: Some(slurry::contact::ContactParams::default()),
            ..CouplingParams::default()
        };
        (f, vec![a, c], params)
    };
    let bits = |d: &mut DeviceCoupled| {
        let mut v: Vec<u64> = d
            .bodies()
            .iter()
            .flat_map(|b| [b.position, b.velocity, b.angular_velocity].map(|x| x.map(f64::to_bits)))
            .flat_map(|x| x.iter().copied().collect::<Vec<_>>())
            .collect();
        v.extend(d.download().unwrap().populations_all().iter().map(|x| x.to_bits()));
        v
    };
    let (f, bodies, params) = scene();
    let mut a = DeviceCoupled::new(ctx(), f, bodies, params, 64).unwrap();
    a.run(6).unwrap();
    let state = a.snapshot().unwrap();
    a.run(6).unwrap();
    let (f, bodies, params) = scene();
    let mut b = DeviceCoupled::new(ctx(), f, bodies, params, 64).unwrap();
    b.restore(&state).unwrap();
    b.run(6).unwrap();
    assert!(bits(&mut a) == bits(&mut b), "the restored device run continues bitwise");
    // The CPU continues the device's state.
    let (f, bodies, params) = scene();
    let mut cpu = Coupled::new(f, bodies, params).unwrap();
    cpu.restore(&state).unwrap();
    cpu.run(6).unwrap();
    for k in 0..2 {
        let dv = (cpu.bodies()[k].velocity - a.bodies()[k].velocity).norm();
        assert!(
            dv < 1e-4 * a.bodies()[k].velocity.norm() + 1e-9,
            "body {k}: CPU continuation differs by {dv:.3e}"
        );
    }
}

/// The interior-fluid sums on the device against the CPU's (`Coupled::interior_momentum`)
/// over one coupled step: a free sphere across the periodic seam, a free tilted cylinder next
/// to a wall, a fixed cuboid, and a prescribed cylinder (no interior term), in the smooth flow.
///
/// The bounds, over the `N ≤ (4/3)π(R + 1)³` nodes with `α > 0` of a body of bounding radius
/// `R`: each `α` moves with the f32 signed distance, by at most `8 u (R + 1)` (the node's
/// offset and the body frame's rotation rounded, a norm); each momentum by the f32 moments'
/// rounding, at most `32 u S` (`S` the largest `Σ|h_i|`), and after the step by the fluids'
/// own difference (a few ulp of each population: within the same `32 u S`). So
/// `|ΔV| ≤ 8 u (R + 1) N`, `|ΔP| ≤ N (8 u (R + 1) j + 64 u S)` (`j` the largest momentum),
/// `|ΔL| ≤ (R + 1) |ΔP|`; the difference after − before, where the sums' own size cancels,
/// within twice the bound on P (the compensated sums add no rounding of their size).
#[test]
fn interior_sums_match_the_cpu() {
    // The coupling owns the force field, zero away from the bodies from the start.
    let mut host = fluid(0);
    host.clear_force_field();
    let g = host.grid();
    let (mut s_max, mut j_max) = (0.0f64, 0.0f64);
    for n in 0..g.nodes() {
        let [x, y, z] = g.coords(n);
        let h = host.shifted_populations(x, y, z);
        s_max = s_max.max(h.iter().map(|v| (*v as f64).abs()).sum());
        j_max = j_max.max(host.macroscopic(x, y, z).1.iter().fold(0.0f64, |a, v| a.max(v.abs())) * 1.01);
    }
    let mut bodies = bodies();
    bodies[1] =
        RigidBody::new(Arc::new(slurry::rigid::Cuboid::new(Vec3::new(3.0, 4.0, 2.5))), 1.0, Motion::Fixed)
            .with_position(Vec3::new(10.5, 16.6, 3.6))
            .with_orientation(Quat::from_euler_angles(0.2, 0.5, -0.3));
    for i in [0, 2, 3] {
        let b = &bodies[i];
        bodies[i] = RigidBody::new(b.shape().clone(), 1.2, Motion::Free)
            .with_position(b.position)
            .with_orientation(b.orientation)
            .with_velocities(b.velocity, b.angular_velocity);
    }
    let params = CouplingParams { iterations: 1, ..CouplingParams::default() };
    let mut dev = DeviceFluid::new(ctx(), &host, 64).unwrap();
    let mut cpu = Coupled::new(host, bodies.clone(), params).unwrap();
    let sets: Vec<Vec<Marker>> = (0..bodies.len()).map(|b| cpu.markers(b).to_vec()).collect();
    let refs: Vec<&[Marker]> = sets.iter().map(|s| s.as_slice()).collect();
    let mut markers = DeviceMarkers::new(&dev, &refs, params.kernel, 64).unwrap();
    markers.enable_interior(&bodies).unwrap();
    markers.set_bodies(&bodies);
    let t = std::time::Instant::now();
    markers.interior(&dev, false).unwrap();
    markers.force(&dev, 1).unwrap();
    dev.step().unwrap();
    markers.interior(&dev, true).unwrap();
    let got = markers.interior_sums().unwrap();
    let seconds = t.elapsed().as_secs_f64();
    cpu.step().unwrap();
    for (b, body) in bodies.iter().enumerate() {
        let want = cpu.interior_momentum(b);
        let r = body.shape().bounding_radius() + 1.0;
        let n = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let tol_v = 8.0 * EPS * r * n;
        let tol_p = n * (8.0 * EPS * r * j_max + 64.0 * EPS * s_max);
        let tol_l = r * tol_p;
        let mut worst = [0.0f64; 4];
        for (slot, (gs, ws)) in got[b].iter().zip([want.before, want.after]).enumerate() {
            let (dp, dl, dv) = ((gs.0 - ws.0).abs().max(), (gs.1 - ws.1).abs().max(), (gs.2 - ws.2).abs());
            assert!(dv <= tol_v, "body {b} slot {slot}: V {} vs {} (> {tol_v:.2e})", gs.2, ws.2);
            assert!(dp <= tol_p, "body {b} slot {slot}: P {} vs {} (> {tol_p:.2e})", gs.0, ws.0);
            assert!(dl <= tol_l, "body {b} slot {slot}: L {} vs {} (> {tol_l:.2e})", gs.1, ws.1);
            worst[0] = worst[0].max(dv / tol_v);
            worst[1] = worst[1].max(dp);
            worst[2] = worst[2].max(dl);
        }
        let dd = ((got[b][1].0 - got[b][0].0) - (want.after.0 - want.before.0)).abs().max();
        assert!(dd <= 2.0 * tol_p, "body {b}: P_after − P_before differs by {dd:.3e}");
        worst[3] = dd;
        println!(
            "body {b} ({}): V {:.4} vs {:.4}, |ΔP| {:.2e}, |ΔL| {:.2e} (bound {tol_p:.1e}, {tol_l:.1e}), \
             |Δ(P_after − P_before)| {:.2e} of |P_after − P_before| {:.2e}",
            body.shape().name(),
            got[b][0].2,
            want.before.2,
            worst[1],
            worst[2],
            worst[3],
            (want.after.0 - want.before.0).abs().max()
        );
    }
    println!("interior sums before and after, forcing and fluid step: {seconds:.3} s on {}", dev.adapter());
}
