//! The solids torque on the impeller split into the two parts of Table 1's contact law, the
//! elastic force (`δ < δ0`) and the lubrication (`δ < δ_d`), from a stirred run's particle
//! history: which part the collisional power number `Po_c` comes from.
//!
//! `cargo run --release -p slurry-verification --example po_c_split RUN_DIR [REVOLUTIONS]`
//!
//! `RUN_DIR` is a `slurry reproduce` run directory (`OUT/run`: `case.toml`, `particles.h5`,
//! `timeseries.csv`). Over the frames of the last `REVOLUTIONS` (default 10) the particles are
//! set to each frame's state and the impeller to its pose and angular velocity at the frame's
//! step, and the contact loads are evaluated three times ([`Contacts::compute`], the run's
//! markers, walls and parameters): the whole law, the elastic part alone and the lubrication
//! alone. Every marker pair's force is the sum of its two parts, so the two parts add up to the
//! whole (to rounding). Printed: the mean `Po_c` of each, and, for comparison, the run's own
//! `po_solids` at the same output steps (the run averages each step's contact torque over its
//! sub-steps, evaluated at mid-sub-step poses; here the instant of the frame).
//!
//! Why: at s = 1/4 our `Po_c` is about twice the paper's while `Po_f` is short by about as
//! much (reproduce/JOURNAL.md, "The split of the torque, not its total"). Table 1's lubrication
//! acts from a gap of one lattice spacing, a third of d at s = 1/4: if it carries most of
//! `Po_c`, the excess is the contact model standing in for flow that the grid would resolve at
//! full scale.

use std::path::PathBuf;

use slurry::case::Case;
use slurry::contact::{ContactParams, Contacts, Walls};
use slurry::io::read_particle_history_from;
use slurry::lattice::Face;
use slurry::rigid::nalgebra::Quaternion;
use slurry::rigid::{Motion, Quat, RigidBody, Vec3};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let dir =
        PathBuf::from(args.next().ok_or_else(|| anyhow::anyhow!("usage: po_c_split RUN_DIR [REVOLUTIONS]"))?);
    let window: f64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(10.0);
    let case = Case::from_file(dir.join("case.toml"))?;
    let setup = case
        .impeller_setup()
        .map_err(|k| anyhow::anyhow!("{k}"))?
        .ok_or_else(|| anyhow::anyhow!("no impeller"))?;
    let coupling = case.coupling_params();
    let params = coupling.contacts.ok_or_else(|| anyhow::anyhow!("the case has no contacts"))?;
    let inits = case.particle_inits().map_err(|k| anyhow::anyhow!("{k}"))?;
    let mut bodies: Vec<RigidBody> = inits.iter().map(|p| p.body()).collect();
    bodies.push(setup.body());
    let imp = bodies.len() - 1;
    let markers: Vec<_> = bodies.iter().map(|b| b.shape().markers(coupling.marker_spacing)).collect();
    let g = case.grid();
    let b = case.boundaries();
    let walled: [bool; 3] = std::array::from_fn(|a| !b.get(Face::from_axis(a, true)).is_periodic());
    let walls = || Walls::bounce_back([g.nx, g.ny, g.nz], walled);
    let parts = [
        ("whole law", params),
        ("elastic part", ContactParams { lubrication: false, ..params }),
        ("lubrication part", ContactParams { elastic: false, ..params }),
    ];
    let mut contacts = parts
        .iter()
        .map(|(_, p)| Contacts::new(*p, walls(), &bodies, &markers))
        .collect::<Result<Vec<_>, _>>()?;

    // The frames of the window: the output interval from the last two frames.
    let steps_per_rev = 1.0 / setup.speed().abs();
    let path = dir.join("particles.h5");
    let total = read_particle_history_from(&path, usize::MAX)?.frames_in_file;
    let tail = read_particle_history_from(&path, total.saturating_sub(2))?;
    anyhow::ensure!(tail.frames.len() == 2, "{}: fewer than two frames", path.display());
    let (end, dt) = (tail.frames[1].step, (tail.frames[1].step - tail.frames[0].step) as f64);
    let first = total.saturating_sub((window * steps_per_rev / dt).round() as usize + 1);
    let hist = read_particle_history_from(&path, first)?;
    anyhow::ensure!(
        hist.statics.len() == imp,
        "particles.h5 has {} particles, the case {imp}",
        hist.statics.len()
    );

    // The run's po_solids at the frames' steps.
    let text = std::fs::read_to_string(dir.join("timeseries.csv"))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |n: &str| header.iter().position(|c| *c == n).ok_or_else(|| anyhow::anyhow!("no column {n}"));
    let (is, ip) = (col("step")?, col("po_solids")?);
    let run_po: std::collections::HashMap<u64, f64> = lines
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Some((f.get(is)?.parse().ok()?, f.get(ip)?.parse().ok()?))
        })
        .collect();

    let motion = match bodies[imp].motion() {
        Motion::Prescribed(m) => m.clone(),
        _ => anyhow::bail!("the impeller is not prescribed"),
    };
    let (q0, x0) = (bodies[imp].orientation, bodies[imp].position);
    let mut sums = [0.0; 3];
    let (mut run_sum, mut n_run) = (0.0, 0usize);
    for f in &hist.frames {
        for (b, body) in bodies[..imp].iter_mut().enumerate() {
            body.position = Vec3::from(f.position[b]);
            let [w, x, y, z] = f.quaternion[b];
            body.orientation = Quat::new_unchecked(Quaternion::new(w, x, y, z));
            body.velocity = Vec3::from(f.velocity[b]);
            body.angular_velocity = Vec3::from(f.angular_velocity[b]);
        }
        let t = f.step as f64;
        let (dx, dq) = motion.displacement(0.0, t);
        let im = &mut bodies[imp];
        im.position = x0 + dx;
        im.orientation = dq * q0;
        im.velocity = motion.velocity(t);
        im.angular_velocity = motion.angular_velocity(t);
        im.time = t;
        for (k, c) in contacts.iter_mut().enumerate() {
            let loads = c.compute(&bodies, &markers);
            sums[k] += setup.power_number(-loads[imp].torque.z);
        }
        if let Some(p) = run_po.get(&f.step) {
            run_sum += p;
            n_run += 1;
        }
    }
    let n = hist.frames.len() as f64;
    println!(
        "{}: {} frames, steps {}–{end} (t N {:.1}–{:.1})",
        dir.display(),
        hist.frames.len(),
        hist.frames[0].step,
        hist.frames[0].step as f64 / steps_per_rev,
        end as f64 / steps_per_rev
    );
    println!("| contact law | mean Po_c at the frames | share of the whole |");
    println!("|---|---|---|");
    for (k, (name, _)) in parts.iter().enumerate() {
        println!("| {name} | {:.3} | {:.1} % |", sums[k] / n, 100.0 * sums[k] / sums[0]);
    }
    println!(
        "| the run's po_solids at the same {n_run} steps (sub-step averages) | {:.3} | |",
        run_sum / n_run.max(1) as f64
    );
    Ok(())
}
