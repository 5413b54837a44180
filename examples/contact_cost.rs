//! Contact cost per fluid step for the paper's densest case: 1644 cylinders `ℓ/d = 1`,
//! `d = 12`, in a settled bed at full scale (251 × 251 × 240).
//!
//! ```text
//! cargo run --release --example contact_cost -- [N] [LD] [SCALE]
//! ```
//!
//! The bed is made without fluid, which would take hours here: the paper's random loose
//! placement (φ = 0.148 of the box, seeded), then dry settling under a strong gravity with a
//! linear drag (terminal speed 0.05) and Table 1's contacts until the largest speed is below
//! 1e-3 (or 6000 steps). Then one fluid step's worth of contacts, `Contacts::advance` with the
//! default sub-steps, is timed (best of 5), with the number of touching pairs and marker pairs;
//! then the same with the damping implicit at `IMPLICIT_SUBSTEPS` (and the share of its sparse
//! solve).
//! Compare with the fluid step (`cargo xtask bench`: 88 ms at full scale, 2 threads).

use std::sync::Arc;
use std::time::Instant;

use slurry::case::Case;
use slurry::contact::{
    ContactParams, Contacts, Damping, ImplicitSolver, Walls, DEFAULT_SUBSTEPS, IMPLICIT_SUBSTEPS,
};
use slurry::rigid::{Marker, Vec3};

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("numeric arguments")).collect();
    let n = args.first().copied().unwrap_or(1644.0) as usize;
    let ld = args.get(1).copied().unwrap_or(1.0);
    let scale = args.get(2).copied().unwrap_or(1.0);
    let dims = [(251.0 * scale).round(), (251.0 * scale).round(), (240.0 * scale).round()];
    let d = 12.0 * scale;
    let text = format!(
        "[domain]\nnx = {}\nny = {}\nnz = {}\n[fluid]\nnu = 0.05\n[boundaries]\nx_min = \"no_slip\"\nx_max = \"no_slip\"\n\
         y_min = \"no_slip\"\ny_max = \"no_slip\"\nz_min = \"no_slip\"\nz_max = \"no_slip\"\n[run]\nsteps = 1\noutput_every = 1\n\
         [[random_particles]]\nshape = \"cylinder\"\ndiameter = {d}\nlength = {}\ndensity = 1.25\ncount = {n}\nseed = 2020\n",
        dims[0],
        dims[1],
        dims[2],
        ld * d
    );
    let case = Case::parse(&text, "contact_cost.toml").expect("valid case");
    let mut bodies = case.bodies().expect("placement");
    let markers: Vec<Arc<Vec<Marker>>> = {
        let m = Arc::new(bodies[0].shape().markers(slurry::rigid::DEFAULT_MARKER_SPACING));
        vec![m; bodies.len()]
    };
    let markers: Vec<&[Marker]> = markers.iter().map(|m| m.as_slice()).collect();
    let walls = Walls::closed_box([dims[0] as usize, dims[1] as usize, dims[2] as usize]);
    let mut ct = Contacts::new(ContactParams::default(), walls, &bodies, &markers).expect("valid parameters");
    let g = Vec3::new(0.0, 0.0, -2e-3);
    let weight = bodies[0].net_weight(g, 1.0);
    let drag = weight.norm() / 0.05;
    // A cached bed (positions and orientations as text, one body per line), so that the cost
    // can be measured again without settling again.
    let cache = std::env::temp_dir().join(format!("slurry-contact-cost-{n}-{ld}-{scale}.txt"));
    let t0 = Instant::now();
    let mut steps = 0;
    if let Ok(text) = std::fs::read_to_string(&cache) {
        for (b, line) in bodies.iter_mut().zip(text.lines()) {
            let v: Vec<f64> = line.split_whitespace().map(|x| x.parse().expect("cached bed")).collect();
            let q = slurry::rigid::Quat::new_unchecked(slurry::rigid::nalgebra::Quaternion::new(
                v[3], v[4], v[5], v[6],
            ));
            *b = b.clone().with_position(Vec3::new(v[0], v[1], v[2])).with_orientation(q);
        }
        println!("bed read from {}", cache.display());
    }
    while !cache.exists() {
        slurry::contact::step_bodies(Some(&mut ct), &mut bodies, &markers, 2, |_, b| {
            (weight - b.velocity * drag, -b.angular_velocity * (drag * d * d / 4.0))
        });
        steps += 1;
        let vmax = bodies.iter().map(|b| b.velocity.norm()).fold(0.0, f64::max);
        if steps % 500 == 0 {
            eprintln!("  settling: step {steps}, max speed {vmax:.2e}, {:.0} s", t0.elapsed().as_secs_f64());
        }
        if (steps > 200 && vmax < 1e-3) || steps >= 6000 {
            let text: String = bodies
                .iter()
                .map(|b| {
                    let (p, q) = (b.position, b.orientation.into_inner());
                    format!("{:e} {:e} {:e} {:e} {:e} {:e} {:e}\n", p.x, p.y, p.z, q.w, q.i, q.j, q.k)
                })
                .collect();
            std::fs::write(&cache, text).expect("write the bed cache");
            break;
        }
    }
    let top = bodies.iter().map(|b| b.position.z).fold(0.0, f64::max);
    println!(
        "{n} cylinders l/d = {ld}, d = {d}: dry bed after {steps} steps ({:.0} s), top centre at z = {top:.1}",
        t0.elapsed().as_secs_f64()
    );
    // One fluid step's contacts: at rest, so only the bed's standing contacts are timed.
    for b in &mut bodies {
        b.velocity = Vec3::zeros();
        b.angular_velocity = Vec3::zeros();
    }
    let skin = std::env::var("SKIN").ok().map(|s| s.parse().expect("SKIN"));
    if let Some(skin) = skin {
        ct.set_skin(skin);
    }
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let saved = bodies.clone();
        let t = Instant::now();
        ct.advance(&mut bodies, &markers, DEFAULT_SUBSTEPS);
        best = best.min(t.elapsed().as_secs_f64());
        bodies = saved;
    }
    let st = *ct.stats();
    let (rebuilds, listed, walls_listed) = ct.list_stats();
    println!("pair list: {rebuilds} rebuilds, {listed} marker pairs and {walls_listed} wall pairs listed");
    println!(
        "contacts per fluid step ({DEFAULT_SUBSTEPS} sub-steps, {} threads): {:.1} ms; candidate pairs {}, touching pairs {}, \
         marker pairs {}, wall contacts {}",
        rayon::current_num_threads(),
        best * 1e3,
        st.candidate_pairs,
        st.touching_pairs,
        st.marker_pairs,
        st.wall_contacts
    );
    for solver in [ImplicitSolver::Cholesky, ImplicitSolver::ConjugateGradient] {
        let implicit = ContactParams { damping: Damping::Implicit, ..ContactParams::default() };
        let mut ci = Contacts::new(implicit, walls, &bodies, &markers).expect("valid parameters");
        ci.set_implicit_solver(solver);
        if let Some(skin) = skin {
            ci.set_skin(skin);
        }
        let saved = bodies.clone();
        ci.advance(&mut bodies, &markers, IMPLICIT_SUBSTEPS);
        bodies = saved;
        let mut best = (f64::INFINITY, 0.0, 0.0);
        let it0 = ci.implicit_cg_iterations();
        for _ in 0..5 {
            let saved = bodies.clone();
            let before = ci.implicit_solve_time();
            let t = Instant::now();
            ci.advance(&mut bodies, &markers, IMPLICIT_SUBSTEPS);
            let dt = t.elapsed().as_secs_f64();
            let after = ci.implicit_solve_time();
            if dt < best.0 {
                best = (dt, after.0 - before.0, after.1 - before.1);
            }
            bodies = saved;
        }
        let iterations = (ci.implicit_cg_iterations() - it0) as f64 / (5 * IMPLICIT_SUBSTEPS) as f64;
        println!(
            "implicit damping ({IMPLICIT_SUBSTEPS} sub-steps, {solver:?}): {:.1} ms per fluid step, of which assembly \
             {:.1} ms and the linear solve {:.1} ms; {} free bodies in the solve; {iterations:.1} CG iterations per solve",
            best.0 * 1e3,
            best.1 * 1e3,
            best.2 * 1e3,
            ci.implicit_solve_time().2
        );
    }
}
